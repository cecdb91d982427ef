//! The duplex's and the pair's round-end rules (crate::architectures), round by round: the
//! strengths they command at and the alarms they raise about the partner.

use super::*;
use crate::architectures::{Duplex, Pair, PAIR_STRENGTH, PAIR_YIELDED_STRENGTH, YIELDED_STRENGTH};

fn duplex_core(id: ControllerId, preempt: bool) -> Core {
    let duplex = Duplex {
        primary: 1,
        standby: 2,
        preempt,
    };
    let config =
        CoreConfig::new(id, 0, PERIOD_MS, rounds()).with_architecture(Architecture::Duplex(duplex));
    Core::new(config, 0)
}

/// The partner's heartbeat: steady, commanding (established) at `strength`.
fn partner(id: ControllerId, strength: Option<i32>) -> Heartbeat {
    Heartbeat {
        established_strength: strength.map(Strength),
        strength: strength.map(Strength),
        ..heartbeat(id, Phase::Steady)
    }
}

/// One round: `heard` arrives, then every timer up to the round's end at `end_ms` runs.
fn round(core: &mut Core, heard: &[Heartbeat], end_ms: u64) -> Vec<Command> {
    deliver(core, heard, end_ms - 1);
    advance(core, end_ms)
}

fn outputs(commands: &[Command]) -> Vec<Option<Strength>> {
    commands
        .iter()
        .filter_map(|c| match c {
            Command::SetOutput { strength, .. } => Some(*strength),
            _ => None,
        })
        .collect()
}

#[test]
fn a_preempting_primary_commands_at_30_from_its_first_round_alone() {
    let mut c1 = duplex_core(1, true);
    let commands = round(&mut c1, &[], 250);
    assert_eq!(outputs(&commands), vec![Some(Strength(30))]);
    assert_eq!(c1.status().report.role, Some(Role::Primary));
    assert_eq!(c1.status().report.phase, Phase::Steady);
}

#[test]
fn a_returning_primary_without_preemption_yields_to_a_commanding_standby() {
    let mut c1 = duplex_core(1, false);
    assert_eq!(
        outputs(&round(&mut c1, &[], 250)),
        vec![Some(YIELDED_STRENGTH)]
    );
    // The Standby commands at its configured 20: the Primary stays at 10, round after round.
    for end_ms in [500, 750, 1000] {
        assert_eq!(
            outputs(&round(&mut c1, &[partner(2, Some(20))], end_ms)),
            vec![]
        );
        assert_eq!(c1.state().output, Some(YIELDED_STRENGTH));
    }
    // The Standby goes silent: at the deadline (2 rounds) it is lost, and the Primary takes 30.
    assert_eq!(outputs(&round(&mut c1, &[], 1250)), vec![]);
    let commands = round(&mut c1, &[], 1500);
    assert_eq!(outputs(&commands), vec![Some(Strength(30))]);
    assert!(commands.contains(&Command::RaiseAlarm {
        about: 2,
        reason: AlarmReason::Lost
    }));
    // It comes back: the alarm clears; the Primary keeps 30.
    let commands = round(&mut c1, &[partner(2, Some(10))], 1750);
    assert_eq!(
        commands
            .iter()
            .filter(|c| matches!(c, Command::ClearAlarm { .. }))
            .count(),
        1
    );
    assert_eq!(c1.state().output, Some(Strength(30)));
}

#[test]
fn a_returning_primary_with_preemption_takes_30_beside_a_commanding_standby() {
    let mut c1 = duplex_core(1, true);
    assert_eq!(
        outputs(&round(&mut c1, &[partner(2, Some(20))], 250)),
        vec![Some(Strength(30))]
    );
}

#[test]
fn two_yielded_controllers_starting_together_take_their_configured_strengths() {
    let mut c1 = duplex_core(1, false);
    let mut c2 = duplex_core(2, false);
    assert_eq!(
        outputs(&round(&mut c1, &[], 250)),
        vec![Some(YIELDED_STRENGTH)]
    );
    assert_eq!(
        outputs(&round(&mut c2, &[], 250)),
        vec![Some(YIELDED_STRENGTH)]
    );
    // Each hears the other yielded, not commanding: neither yields any longer.
    let to_c1 = partner(2, Some(10));
    let to_c2 = partner(1, Some(10));
    assert_eq!(
        outputs(&round(&mut c1, &[to_c1], 500)),
        vec![Some(Strength(30))]
    );
    assert_eq!(
        outputs(&round(&mut c2, &[to_c2], 500)),
        vec![Some(Strength(20))]
    );
}

#[test]
fn a_standby_without_preemption_never_yields_to_a_primary() {
    // Yielding is for the controller whose configured strength is the higher one.
    let mut c2 = duplex_core(2, false);
    round(&mut c2, &[], 250);
    assert_eq!(
        outputs(&round(&mut c2, &[partner(1, Some(30))], 500)),
        vec![Some(Strength(20))]
    );
}

#[test]
fn a_duplex_standby_ignores_late_commands_and_a_third_id() {
    let mut c2 = duplex_core(2, true);
    round(&mut c2, &[partner(1, Some(30)), partner(3, Some(30))], 250);
    assert!(!c2.watches_arrivals());
    let commands = c2.step(
        Input::Commands {
            from: 1,
            arrival: Arrival::OnTime,
        },
        300,
    );
    assert_eq!(commands, vec![]);
    assert_eq!(c2.status().sees.into_iter().collect::<Vec<_>>(), vec![1]);
}

fn pair_core(id: ControllerId) -> Core {
    let pair = Pair { members: [1, 2] };
    let config =
        CoreConfig::new(id, 0, PERIOD_MS, rounds()).with_architecture(Architecture::Pair(pair));
    Core::new(config, 0)
}

#[test]
fn a_pair_member_alone_yields_until_its_partner_is_lost_then_commands_as_primary() {
    let mut c2 = pair_core(2);
    assert_eq!(
        outputs(&round(&mut c2, &[], 250)),
        vec![Some(PAIR_YIELDED_STRENGTH)]
    );
    assert_eq!(
        outputs(&round(&mut c2, &[], 500)),
        vec![Some(PAIR_STRENGTH)]
    );
    assert_eq!(c2.status().report.role, Some(Role::Primary));
}

#[test]
fn pair_members_starting_together_both_command_and_a_returning_one_yields() {
    let (mut c1, mut c2) = (pair_core(1), pair_core(2));
    round(&mut c1, &[], 250);
    round(&mut c2, &[], 250);
    // Each hears the other yielded: both take the pair's strength.
    assert_eq!(
        outputs(&round(&mut c1, &[partner(2, Some(20))], 500)),
        vec![Some(PAIR_STRENGTH)]
    );
    assert_eq!(
        outputs(&round(&mut c2, &[partner(1, Some(20))], 500)),
        vec![Some(PAIR_STRENGTH)]
    );
    // C1 returns beside C2 commanding at 30: it stays at 20 while C2 commands.
    let mut c1 = pair_core(1);
    round(&mut c1, &[], 250);
    for end_ms in [500, 750] {
        assert_eq!(
            outputs(&round(&mut c1, &[partner(2, Some(30))], end_ms)),
            vec![]
        );
        assert_eq!(c1.state().output, Some(PAIR_YIELDED_STRENGTH));
        assert_eq!(c1.status().report.role, Some(Role::Secondary));
    }
}

#[test]
fn a_pair_controller_alarms_a_failed_partner_and_a_local_fault_silences_it() {
    let mut c2 = pair_core(2);
    round(&mut c2, &[partner(1, Some(20))], 250);
    assert_eq!(c2.state().output, Some(PAIR_STRENGTH));
    let commands = round(&mut c2, &[heartbeat(1, Phase::Failed)], 500);
    assert!(commands.contains(&Command::RaiseAlarm {
        about: 1,
        reason: AlarmReason::Failed
    }));
    // A local fault (its two implementations disagreed) silences it.
    let commands = c2.step(Input::LocalFault, 600);
    assert_eq!(outputs(&commands), vec![None]);
    assert_eq!(c2.status().report.phase, Phase::Failed);
}

#[test]
fn the_network_monitors_watch_the_architectures_own_controllers() {
    use crate::network::Members;
    let duplex = Architecture::Duplex(Duplex {
        primary: 2,
        standby: 3,
        preempt: true,
    });
    assert_eq!(duplex.network_members(), Members::of(&[2, 3]));
    let pair = Architecture::Pair(Pair { members: [1, 3] });
    assert_eq!(pair.network_members(), Members::of(&[1, 3]));
    assert!(!pair.network_members().contains(2));
    assert_eq!(Architecture::Voting.network_members(), Members::ALL);
}

/// A pair member with a longer initialization window than the dead-man deadline, as the
/// defaults have (2 s against 0.5 s).
fn pair_core_with_window(id: ControllerId, window_rounds: u32) -> Core {
    let pair = Pair { members: [1, 2] };
    let rounds = Rounds {
        dead_after_rounds: 2,
        window_rounds,
    };
    let config =
        CoreConfig::new(id, 0, PERIOD_MS, rounds).with_architecture(Architecture::Pair(pair));
    Core::new(config, 0)
}

#[test]
fn a_partner_silent_since_the_start_is_lost_only_when_the_window_closes() {
    // Not yet discovered is not lost: the member stays below its partner for the window.
    let mut c2 = pair_core_with_window(2, 6);
    let strengths: Vec<Option<Strength>> = (1..=6u64)
        .map(|round_number| {
            round(&mut c2, &[], round_number * PERIOD_MS);
            c2.status().report.strength
        })
        .collect();
    let (yielded, commanding) = (Some(PAIR_YIELDED_STRENGTH), Some(PAIR_STRENGTH));
    assert_eq!(
        strengths,
        vec![yielded, yielded, yielded, yielded, yielded, commanding],
        "yielded through the window, the pair's strength at its close (round 6)"
    );
    assert!(c2.status().alarms.iter().any(|(id, _)| *id == 1));
    // A partner heard once, then silent: lost at the deadline, window or not.
    let mut c1 = pair_core_with_window(1, 6);
    round(&mut c1, &[partner(2, Some(PAIR_STRENGTH.0))], PERIOD_MS);
    round(&mut c1, &[], 2 * PERIOD_MS);
    let lost = outputs(&round(&mut c1, &[], 3 * PERIOD_MS));
    assert_eq!(lost, vec![Some(PAIR_STRENGTH)]);
}

/// A round whose end runs `late_ms` after its boundary at `end_ms`.
fn late_round(core: &mut Core, heard: &[Heartbeat], end_ms: u64, late_ms: u64) -> Vec<Command> {
    // The stall alarm may clear on any step: what the delivery says is kept.
    let mut out = Vec::new();
    for h in heard {
        out.extend(core.step(Input::Heartbeat(*h), end_ms - 1));
    }
    let now_ms = end_ms + late_ms;
    while let Some(timer) = core.due_timer(now_ms) {
        out.extend(core.step(Input::Timer(timer), now_ms));
    }
    out
}

#[test]
fn a_preempting_primary_back_from_a_stall_dwells_below_the_standby_until_it_runs_on_time() {
    use crate::architectures::{DUPLEX_DWELL_ROUNDS, DWELL_LATE_MS};
    let mut c1 = duplex_core(1, true);
    assert_eq!(
        outputs(&round(&mut c1, &[partner(2, Some(20))], 250)),
        vec![Some(Strength(30))]
    );
    // Its loop stalled: a new life, which dwells at 10 beside the commanding Standby.
    let cause = Restart::Stalled { stalled_ms: 300 };
    let started = c1.step(
        Input::StartAgain {
            cause,
            incarnation: 9,
        },
        600,
    );
    assert!(started.contains(&Command::NewLife { cause }));
    let standby = [partner(2, Some(20))];
    let mut end_ms = 750;
    assert_eq!(
        outputs(&round(&mut c1, &standby, end_ms)),
        vec![Some(YIELDED_STRENGTH)]
    );
    // Late round ends (a starved loop) start the dwell over, however many come.
    for _ in 0..10 {
        end_ms += PERIOD_MS;
        late_round(&mut c1, &standby, end_ms, DWELL_LATE_MS + 5);
        assert_eq!(c1.state().output, Some(YIELDED_STRENGTH));
        assert_eq!(c1.state().dwell_rounds_left, DUPLEX_DWELL_ROUNDS);
    }
    // On time again: the dwell's rounds less the one that yielded, then 30 at the last.
    for _ in 1..DUPLEX_DWELL_ROUNDS {
        end_ms += PERIOD_MS;
        assert_eq!(outputs(&round(&mut c1, &standby, end_ms)), vec![]);
        assert_eq!(c1.state().output, Some(YIELDED_STRENGTH));
    }
    end_ms += PERIOD_MS;
    assert_eq!(
        outputs(&round(&mut c1, &standby, end_ms)),
        vec![Some(Strength(30))]
    );
}

#[test]
fn a_dwelling_primary_that_loses_the_standby_keeps_10_until_its_dwell_ends() {
    use crate::architectures::DUPLEX_DWELL_ROUNDS;
    let mut c1 = duplex_core(1, true);
    round(&mut c1, &[partner(2, Some(20))], 250);
    c1.step(
        Input::StartAgain {
            cause: Restart::Stalled { stalled_ms: 300 },
            incarnation: 9,
        },
        600,
    );
    let mut end_ms = 750;
    round(&mut c1, &[partner(2, Some(20))], end_ms);
    assert_eq!(c1.state().output, Some(YIELDED_STRENGTH));
    // The Standby falls silent and is lost at the deadline (alarmed), and the Primary stays
    // at 10, the actuator's only writer, until its dwell's on-time rounds have run.
    let mut raised = false;
    for _ in 2..DUPLEX_DWELL_ROUNDS {
        end_ms += PERIOD_MS;
        let commands = advance(&mut c1, end_ms);
        raised |= commands.contains(&Command::RaiseAlarm {
            about: 2,
            reason: AlarmReason::Lost,
        });
        assert_eq!(c1.state().output, Some(YIELDED_STRENGTH));
    }
    assert!(
        raised,
        "the lost Standby is alarmed while the Primary dwells"
    );
    end_ms += PERIOD_MS;
    assert_eq!(outputs(&advance(&mut c1, end_ms)), vec![Some(Strength(30))]);
}
