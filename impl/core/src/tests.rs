//! Rule-by-rule tests: literal inputs, literal command vectors. The round is 250 ms, so
//! round boundaries fall at 250, 500, ... and heartbeats go out 62 ms after each boundary.
//! `lives`: leaving after failing, new lives, and following the Primary's phase.

use super::*;

mod architectures;
mod lives;

const PERIOD_MS: u64 = 250;

fn rounds() -> Rounds {
    Rounds {
        dead_after_rounds: 2,
        window_rounds: 2,
    }
}

fn core(id: ControllerId, incarnation: Incarnation, now_ms: u64) -> Core {
    Core::new(
        CoreConfig::new(id, incarnation, PERIOD_MS, rounds()),
        now_ms,
    )
}

fn holder(id: ControllerId, incarnation: Incarnation) -> Holder {
    Holder { id, incarnation }
}

/// `P=ids[0] S=ids[1] T=ids[2]`, incarnation 0 each unless given.
fn assignment(holders: &[(ControllerId, Incarnation)]) -> Assignment {
    Assignment::from_ranked(holders.iter().map(|&(id, inc)| holder(id, inc)))
}

fn heartbeat(id: ControllerId, phase: Phase) -> Heartbeat {
    Heartbeat {
        phase,
        ..Heartbeat::initial(id, 0)
    }
}

fn steady(id: ControllerId, agreed: Assignment) -> Heartbeat {
    let role = agreed.role_of(id);
    Heartbeat {
        id,
        incarnation: 0,
        phase: Phase::Steady,
        role,
        strength: role.map(Role::strength),
        agreed: Some(agreed),
        vote: Some(agreed),
        epoch: 1,
        provisional: false,
        established_strength: role.map(Role::strength),
        took_over_from: None,
    }
}

/// Runs every timer due up to `now_ms`, concatenating the commands.
fn advance(core: &mut Core, now_ms: u64) -> Vec<Command> {
    let mut out = Vec::new();
    while core.next_deadline().at_ms <= now_ms {
        let due = core.next_deadline();
        out.extend(core.step(Input::Timer(due.timer), due.at_ms));
    }
    out
}

/// Fires the timer due at `now_ms` (none due: nothing happens).
fn fire(core: &mut Core, now_ms: u64) -> Vec<Command> {
    match core.due_timer(now_ms) {
        Some(timer) => core.step(Input::Timer(timer), now_ms),
        None => Vec::new(),
    }
}

fn deliver(core: &mut Core, heartbeats: &[Heartbeat], now_ms: u64) {
    for h in heartbeats {
        assert_eq!(core.step(Input::Heartbeat(*h), now_ms), vec![]);
    }
}

/// Controller `id` of a formed three-controller system (P=1 S=2 T=3): steady at t = 500,
/// commanding at its role's strength from t = 750.
fn formed_c(id: ControllerId) -> Core {
    let mut c = core(id, 0, 0);
    let mut t = 0;
    let peers: Vec<ControllerId> = [1, 2, 3].into_iter().filter(|&p| p != id).collect();
    let result = assignment(&[(1, 0), (2, 0), (3, 0)]);
    // Round 1: three heads heard -> window closes, votes. Round 2: the peers' votes agree.
    for heard in [
        peers
            .iter()
            .map(|&p| heartbeat(p, Phase::Initializing))
            .collect::<Vec<_>>(),
        peers
            .iter()
            .map(|&p| Heartbeat {
                vote: Some(result),
                ..heartbeat(p, Phase::Voting)
            })
            .collect(),
    ] {
        advance(&mut c, t + 62);
        deliver(&mut c, &heard, t + 100);
        t += PERIOD_MS;
        advance(&mut c, t);
    }
    assert_eq!(c.state().phase, Phase::Steady);
    // Round 3: the peers report their strengths established; the standbys raise theirs once
    // the roles above them have (F13).
    advance(&mut c, t + 62);
    let established: Vec<Heartbeat> = peers.iter().map(|&p| steady(p, result)).collect();
    deliver(&mut c, &established, t + 100);
    advance(&mut c, t + PERIOD_MS);
    c
}

#[test]
fn the_first_heartbeat_goes_out_at_start_then_a_quarter_period_after_each_boundary() {
    let mut c = core(1, 7, 1010);
    assert_eq!(
        c.next_deadline(),
        Deadline {
            at_ms: 1010,
            timer: Timer::Heartbeat
        }
    );
    assert_eq!(
        fire(&mut c, 1010),
        vec![Command::PublishHeartbeat(Heartbeat {
            id: 1,
            incarnation: 7,
            phase: Phase::Initializing,
            role: None,
            strength: None,
            agreed: None,
            vote: None,
            epoch: 0,
            provisional: false,
            established_strength: None,
            took_over_from: None,
        }),]
    );
    assert_eq!(
        c.next_deadline(),
        Deadline {
            at_ms: 1250,
            timer: Timer::RoundEnd
        }
    );
    assert_eq!(fire(&mut c, 1250), vec![]);
    assert_eq!(
        c.next_deadline(),
        Deadline {
            at_ms: 1312,
            timer: Timer::Heartbeat
        },
        "heartbeat at boundary + period/4"
    );
}

#[test]
fn three_heads_close_the_window_and_the_vote_goes_by_lowest_id() {
    let mut c = core(2, 0, 0);
    advance(&mut c, 62);
    deliver(
        &mut c,
        &[
            heartbeat(3, Phase::Initializing),
            heartbeat(1, Phase::Initializing),
        ],
        100,
    );
    let vote = assignment(&[(1, 0), (2, 0), (3, 0)]);
    assert_eq!(
        fire(&mut c, 250),
        vec![Command::PublishVote(VoteRecord {
            from: 2,
            incarnation: 0,
            vote: Some(vote)
        })]
    );
    assert_eq!(c.state().phase, Phase::Voting);
    assert_eq!(c.state().role, None, "no role before agreement");
}

#[test]
fn a_majority_of_identical_votes_gives_the_role_and_its_strength() {
    let c = formed_c(2);
    assert_eq!(c.state().role, Some(Role::Secondary));
    assert_eq!(c.state().output, Some(Strength(20)));
    let mut c = core(1, 0, 0);
    let vote = assignment(&[(1, 0), (2, 0), (3, 0)]);
    advance(&mut c, 62);
    deliver(
        &mut c,
        &[
            heartbeat(2, Phase::Initializing),
            heartbeat(3, Phase::Initializing),
        ],
        100,
    );
    advance(&mut c, 250);
    advance(&mut c, 312);
    // One peer's vote agrees: 2 of 3 is a majority.
    deliver(
        &mut c,
        &[
            Heartbeat {
                vote: Some(vote),
                ..heartbeat(2, Phase::Voting)
            },
            heartbeat(3, Phase::Voting),
        ],
        400,
    );
    assert_eq!(
        fire(&mut c, 500),
        vec![Command::SetOutput {
            role: Some(Role::Primary),
            strength: Some(Strength(30))
        }]
    );
}

#[test]
fn a_lone_controller_waits_for_the_window_then_takes_primary_at_the_provisional_strength() {
    let mut c = core(1, 0, 0);
    let commands = advance(&mut c, 499);
    assert_eq!(fire(&mut c, 500), vec![], "second quiet round");
    assert_eq!(c.state().phase, Phase::Initializing);
    assert_eq!(
        c.next_deadline(),
        Deadline {
            at_ms: 500,
            timer: Timer::WindowExpiry
        },
        "the window times out right after the round end"
    );
    let vote = assignment(&[(1, 0)]);
    assert_eq!(
        fire(&mut c, 500),
        vec![
            Command::PublishVote(VoteRecord {
                from: 1,
                incarnation: 0,
                vote: Some(vote)
            }),
            Command::SetOutput {
                role: Some(Role::Primary),
                strength: Some(PROVISIONAL_PRIMARY_STRENGTH)
            }
        ]
    );
    assert_eq!(
        commands,
        vec![Command::PublishHeartbeat(heartbeat(1, Phase::Initializing)); 2],
        "heartbeats at 0 and 312"
    );
}

#[test]
fn a_peer_silent_for_the_dead_man_deadline_is_lost_alarmed_and_re_voted() {
    let mut c = formed_c(2);
    let result = assignment(&[(1, 0), (2, 0), (3, 0)]);
    // Round ending 1000: C3 heard, C1 silent (1 of 2 rounds): nothing happens.
    advance(&mut c, 812);
    deliver(&mut c, &[steady(3, result)], 850);
    assert_eq!(advance(&mut c, 1000), vec![]);
    // Round ending 1250: C1 silent for the second round: lost.
    advance(&mut c, 1062);
    deliver(&mut c, &[steady(3, result)], 1100);
    let new_vote = assignment(&[(2, 0), (3, 0)]);
    assert_eq!(
        fire(&mut c, 1250),
        vec![
            Command::PublishVote(VoteRecord {
                from: 2,
                incarnation: 0,
                vote: Some(new_vote)
            }),
            Command::RaiseAlarm {
                about: 1,
                reason: AlarmReason::Lost
            }
        ]
    );
    assert_eq!(c.state().phase, Phase::Voting);
    assert_eq!(
        c.state().output,
        Some(Strength(20)),
        "keeps commanding at its old strength"
    );
    // Round ending 1500: C3's heartbeat carries the same vote: promoted.
    advance(&mut c, 1312);
    deliver(
        &mut c,
        &[Heartbeat {
            phase: Phase::Voting,
            vote: Some(new_vote),
            ..steady(3, result)
        }],
        1350,
    );
    assert_eq!(
        fire(&mut c, 1500),
        vec![Command::SetOutput {
            role: Some(Role::Primary),
            strength: Some(Strength(30))
        }]
    );
}

#[test]
fn a_late_joiner_takes_the_lowest_free_role() {
    // C1 and C2 run P=1 S=2; C3 starts and hears them.
    let running = assignment(&[(1, 0), (2, 0)]);
    let mut c = core(3, 5, 0);
    advance(&mut c, 62);
    deliver(&mut c, &[steady(1, running), steady(2, running)], 100);
    let vote = assignment(&[(1, 0), (2, 0), (3, 5)]);
    assert_eq!(
        fire(&mut c, 250),
        vec![Command::PublishVote(VoteRecord {
            from: 3,
            incarnation: 5,
            vote: Some(vote)
        })]
    );
    assert!(c.state().late_joiner);
    // The incumbents agree on the new result: it becomes Tertiary.
    advance(&mut c, 312);
    let agreed_by_incumbents = |from| Heartbeat {
        vote: Some(vote),
        agreed: Some(vote),
        ..steady(from, running)
    };
    deliver(
        &mut c,
        &[agreed_by_incumbents(1), agreed_by_incumbents(2)],
        350,
    );
    assert_eq!(
        fire(&mut c, 500),
        vec![Command::SetOutput {
            role: Some(Role::Tertiary),
            strength: Some(Strength(10))
        }]
    );
}

#[test]
fn a_fourth_controller_is_ignored() {
    let running = assignment(&[(1, 0), (2, 0), (3, 0)]);
    let mut c = core(4, 0, 0);
    advance(&mut c, 62);
    deliver(
        &mut c,
        &[steady(1, running), steady(2, running), steady(3, running)],
        100,
    );
    advance(&mut c, 250);
    assert_eq!(c.state().vote, Some(running), "its vote leaves it out");
    advance(&mut c, 312);
    deliver(
        &mut c,
        &[steady(1, running), steady(2, running), steady(3, running)],
        350,
    );
    assert_eq!(fire(&mut c, 500), vec![]);
    assert_eq!(c.state().phase, Phase::Steady);
    assert_eq!((c.state().role, c.state().output), (None, None));
}

#[test]
fn a_minority_voter_is_marked_failed_after_the_grace() {
    let mut c = formed_c(1);
    let result = assignment(&[(1, 0), (2, 0), (3, 0)]);
    let dissent = assignment(&[(3, 0), (1, 0), (2, 0)]);
    let mut t = 750;
    let mut marked_at = None;
    for round in 1..=4 {
        advance(&mut c, t + 62);
        deliver(
            &mut c,
            &[
                steady(2, result),
                Heartbeat {
                    vote: Some(dissent),
                    ..steady(3, result)
                },
            ],
            t + 100,
        );
        t += PERIOD_MS;
        let out = advance(&mut c, t);
        if out.contains(&Command::RaiseAlarm {
            about: 3,
            reason: AlarmReason::Failed,
        }) {
            marked_at = Some(round);
        }
    }
    assert_eq!(marked_at, Some(4), "grace of 3 rounds, marked in the 4th");
    assert!(c.state().peers[&3].failed);
    assert_eq!(c.state().vote, Some(assignment(&[(1, 0), (2, 0)])));
}

#[test]
fn an_outvoted_controller_fails_itself_after_the_grace() {
    let mut c = formed_c(3);
    let result = assignment(&[(1, 0), (2, 0), (3, 0)]);
    let without_3 = assignment(&[(1, 0), (2, 0)]);
    let mut t = 750;
    for _ in 0..4 {
        advance(&mut c, t + 62);
        let them = |from| Heartbeat {
            vote: Some(without_3),
            ..steady(from, result)
        };
        deliver(&mut c, &[them(1), them(2)], t + 100);
        t += PERIOD_MS;
        advance(&mut c, t);
    }
    assert_eq!(c.state().phase, Phase::Failed);
    assert_eq!(c.state().output, None);
    assert_eq!(c.report().phase, Phase::Failed, "announces it");
}

#[test]
fn a_new_primary_holds_secondary_strength_while_the_old_one_claims_primary() {
    let mut c = formed_c(2);
    let result = assignment(&[(1, 0), (2, 0), (3, 0)]);
    let without_1 = assignment(&[(2, 0), (3, 0)]);
    // C1 is still heard claiming Primary (strength 30) while C2 and C3 agree without it.
    if let Some(p) = c.state.peers.get_mut(&1) {
        p.failed = true;
    }
    advance(&mut c, 812);
    deliver(
        &mut c,
        &[
            steady(1, result),
            Heartbeat {
                phase: Phase::Voting,
                vote: Some(without_1),
                ..steady(3, result)
            },
        ],
        850,
    );
    c.state.vote = Some(without_1);
    c.state.phase = Phase::Voting;
    advance(&mut c, 1000);
    assert_eq!(c.state().role, Some(Role::Primary));
    assert_eq!(
        c.state().output,
        Some(Strength(20)),
        "two writers at 30 would let DDS pick"
    );
}

#[test]
fn a_local_fault_stops_commanding_and_withdraws_the_vote() {
    let mut c = formed_c(1);
    assert_eq!(
        (c.step(Input::LocalFault, 850)),
        vec![
            Command::PublishVote(VoteRecord {
                from: 1,
                incarnation: 0,
                vote: None
            }),
            Command::SetOutput {
                role: None,
                strength: None
            },
            Command::Failed {
                failure: failure::Failure {
                    id: 1,
                    cause: failure::FailureCause::LocalFault,
                    disagreed_with: Vec::new(),
                    own_vote: Some(assignment(&[(1, 0), (2, 0), (3, 0)])),
                    their_vote: None,
                },
                exit_in_ms: None
            }
        ]
    );
    assert_eq!(c.report().phase, Phase::Failed);
}

#[test]
fn a_restarted_peer_is_a_new_member_and_its_alarm_is_cleared() {
    let mut c = formed_c(1);
    let result = assignment(&[(1, 0), (2, 0), (3, 0)]);
    let mut t = 750;
    for _ in 0..2 {
        advance(&mut c, t + 62);
        deliver(&mut c, &[steady(2, result)], t + 100);
        t += PERIOD_MS;
        advance(&mut c, t);
    }
    assert_eq!(c.state().peers[&3].alarm, Some(AlarmReason::Lost));
    advance(&mut c, t + 62);
    deliver(
        &mut c,
        &[
            steady(2, assignment(&[(1, 0), (2, 0)])),
            Heartbeat {
                incarnation: 9,
                ..heartbeat(3, Phase::Initializing)
            },
        ],
        t + 100,
    );
    let out = advance(&mut c, t + PERIOD_MS);
    assert!(
        out.contains(&Command::ClearAlarm {
            about: 3,
            reason: AlarmReason::Lost
        }),
        "{out:?}"
    );
    assert_eq!(
        c.state().vote,
        Some(assignment(&[(1, 0), (2, 0), (3, 9)])),
        "the restarted incarnation comes in below the live holders"
    );
}

#[test]
fn a_heartbeat_naming_our_own_id_is_reported_and_ignored() {
    let mut c = core(1, 0, 0);
    let out = c.step(
        Input::Heartbeat(Heartbeat {
            incarnation: 3,
            ..heartbeat(1, Phase::Steady)
        }),
        10,
    );
    assert_eq!(out, vec![], "no protocol output; the status counts it");
    assert_eq!(c.status().duplicate_id_heartbeats, 1);
    assert!(c.state().peers.is_empty());
}

#[test]
fn a_caller_that_fell_behind_runs_one_round_end() {
    let mut c = formed_c(1);
    // Stopped for 10 s: one round end, peers counted silent once, nobody lost. It stands for
    // the 38 boundaries after the one due at 1000 that passed unrun, and says so.
    let out = fire(&mut c, 10_700);
    assert_eq!(out, vec![Command::RoundEndsMissed { rounds: 38 }]);
    assert!(c.state().peers.values().all(|p| p.alive.is_some()));
    assert_eq!(
        c.next_deadline(),
        Deadline {
            at_ms: 10_700,
            timer: Timer::Heartbeat
        },
        "heartbeat due at once"
    );
}

#[test]
fn a_heartbeat_sent_before_this_round_began_is_late() {
    let mut c = core(1, 7, 0);
    // The round that ends at 250 began at 0: anything sent from 0 on belongs to it.
    assert!(!c.sent_before_this_round(0));
    assert!(!c.sent_before_this_round(249));
    advance(&mut c, 300);
    // Now the round 250..500 runs: sent at 249 is a round late, at 250 on time.
    assert!(c.sent_before_this_round(249));
    assert!(c.sent_before_this_round(62));
    assert!(!c.sent_before_this_round(250));
    assert!(!c.sent_before_this_round(312));
}

#[test]
fn a_heartbeat_sent_after_this_round_should_have_ended_is_the_next_rounds() {
    let mut c = core(1, 7, 0);
    // The round 0..250 runs: a peer's heartbeat of it goes out at 62, the next round's at 312.
    assert!(!c.sent_after_this_round(62));
    assert!(!c.sent_after_this_round(249));
    assert!(c.sent_after_this_round(250));
    assert!(c.sent_after_this_round(312));
    // A loop that takes the next round's heartbeat late ends this round first.
    assert_eq!(c.due_timer(312), Some(Timer::RoundEnd));
    advance(&mut c, 300);
    assert!(!c.sent_after_this_round(312), "now its own round");
}

mod late_loop;
mod takeover;
mod v2;
