//! F17: a Secondary takes over from a Primary whose commands arrive late, the Primary starts
//! again when it hears it, and the takeover is released once the old life is gone.

use super::*;

const FORMED_AT_MS: u64 = 750;

fn result() -> Assignment {
    assignment(&[(1, 0), (2, 0), (3, 0)])
}

fn arrival(from: ControllerId, arrival: Arrival) -> Input {
    Input::Commands { from, arrival }
}

#[test]
fn a_secondary_takes_over_at_35_when_the_primary_is_late_and_the_tertiary_on_time() {
    let mut c2 = formed_c(2);
    assert_eq!(c2.state().output, Some(Strength(20)));
    let t = FORMED_AT_MS + 10;
    assert_eq!(c2.step(arrival(1, Arrival::Late), t), vec![]);
    assert_eq!(
        c2.step(arrival(3, Arrival::OnTime), t + 5),
        vec![Command::SetOutput {
            role: Some(Role::Secondary),
            strength: Some(TAKEOVER_STRENGTH)
        }]
    );
    assert_eq!(c2.state().took_over_from, Some(holder(1, 0)));
    // Its heartbeats name the life it took over from; the ready writer is new to nobody, but
    // the strength it reports established is still the old one for this round.
    let published = advance(&mut c2, FORMED_AT_MS + 62);
    let Some(Command::PublishHeartbeat(sent)) = published.first() else {
        panic!("a heartbeat is due: {published:?}");
    };
    assert_eq!(sent.took_over_from, Some(holder(1, 0)));
    assert_eq!(sent.strength, Some(TAKEOVER_STRENGTH));
    // A round's end keeps it while the old life is still heard.
    let keep = [steady(1, result()), steady(3, result())];
    deliver(&mut c2, &keep, FORMED_AT_MS + 100);
    advance(&mut c2, FORMED_AT_MS + PERIOD_MS);
    assert_eq!(c2.state().output, Some(TAKEOVER_STRENGTH));
}

#[test]
fn without_a_tertiary_on_time_a_late_primary_is_left_alone() {
    for tertiary in [Arrival::Unheard, Arrival::Late] {
        let mut c2 = formed_c(2);
        let t = FORMED_AT_MS + 10;
        c2.step(arrival(1, Arrival::Late), t);
        assert_eq!(c2.step(arrival(3, tertiary), t), vec![], "{tertiary:?}");
        assert_eq!(c2.state().output, Some(Strength(20)));
        assert_eq!(c2.state().took_over_from, None);
    }
}

#[test]
fn a_tertiary_on_time_before_the_primarys_late_sample_proves_nothing() {
    // The Secondary's own link starved (`lab run random --seed 5`): the Primary's sample is
    // the first to come late, while the Tertiary's last came before the queue built up.
    let mut c2 = formed_c(2);
    let t = FORMED_AT_MS + 10;
    c2.step(arrival(3, Arrival::OnTime), t);
    assert_eq!(c2.step(arrival(1, Arrival::Late), t + 5), vec![]);
    assert_eq!(c2.state().took_over_from, None);
    // The Tertiary's next sample comes late too: still nothing.
    assert_eq!(c2.step(arrival(3, Arrival::Late), t + 20), vec![]);
    assert_eq!(c2.state().output, Some(Strength(20)));
}

#[test]
fn only_the_secondary_takes_over_and_only_from_the_primary() {
    // The Tertiary sees the Primary late and the Secondary on time: not its call.
    let mut c3 = formed_c(3);
    c3.step(arrival(1, Arrival::Late), FORMED_AT_MS + 10);
    assert_eq!(
        c3.step(arrival(2, Arrival::OnTime), FORMED_AT_MS + 10),
        vec![]
    );
    // The Secondary sees the Tertiary late: nothing to take over.
    let mut c2 = formed_c(2);
    c2.step(arrival(3, Arrival::Late), FORMED_AT_MS + 10);
    assert_eq!(
        c2.step(arrival(1, Arrival::OnTime), FORMED_AT_MS + 10),
        vec![]
    );
}

#[test]
fn only_the_secondary_watches_arrivals() {
    let watches: Vec<bool> = (1..=3).map(|id| formed_c(id).watches_arrivals()).collect();
    assert_eq!(watches, vec![false, true, false]);
    assert!(!core(2, 0, 0).watches_arrivals());
}

#[test]
fn a_primary_that_hears_a_takeover_from_its_life_starts_again() {
    let mut c1 = formed_c(1);
    advance(&mut c1, FORMED_AT_MS + 62);
    let taker = Heartbeat {
        strength: Some(TAKEOVER_STRENGTH),
        took_over_from: Some(holder(1, 0)),
        ..steady(2, result())
    };
    deliver(&mut c1, &[taker, steady(3, result())], FORMED_AT_MS + 100);
    let commands = advance(&mut c1, FORMED_AT_MS + PERIOD_MS);
    assert!(commands.contains(&Command::StartAgain), "{commands:?}");
    // A takeover from another life of id 1 (an older one) is not this life's.
    let mut c1 = formed_c(1);
    advance(&mut c1, FORMED_AT_MS + 62);
    let older = Heartbeat {
        took_over_from: Some(holder(1, 99)),
        ..taker
    };
    deliver(&mut c1, &[older, steady(3, result())], FORMED_AT_MS + 100);
    let commands = advance(&mut c1, FORMED_AT_MS + PERIOD_MS);
    assert!(!commands.contains(&Command::StartAgain), "{commands:?}");
}

#[test]
fn the_takeover_is_released_once_the_old_life_is_gone_and_the_taker_is_the_backed_primary() {
    let mut c2 = formed_c(2);
    c2.step(arrival(1, Arrival::Late), FORMED_AT_MS + 10);
    c2.step(arrival(3, Arrival::OnTime), FORMED_AT_MS + 10);
    // C1 starts again as a new life (incarnation 5): the old one is retired at once, and the
    // new one joins below. C2 and C3 agree P=2 S=3 T=1#5.
    let mut t = FORMED_AT_MS;
    let new_result = assignment(&[(2, 0), (3, 0), (1, 5)]);
    let c1_new = Heartbeat {
        id: 1,
        incarnation: 5,
        ..heartbeat(1, Phase::Initializing)
    };
    let c3_voting = Heartbeat {
        phase: Phase::Voting,
        vote: Some(new_result),
        ..steady(3, result())
    };
    advance(&mut c2, t + 62);
    deliver(&mut c2, &[c1_new, c3_voting], t + 100);
    t += PERIOD_MS;
    advance(&mut c2, t);
    assert_eq!(c2.state().vote, Some(new_result));
    // Still at 35 until it holds the backed Primary role.
    let mut rounds = 0;
    while c2.state().output == Some(TAKEOVER_STRENGTH) && rounds < 4 {
        advance(&mut c2, t + 62);
        let c3 = Heartbeat {
            agreed: Some(new_result),
            vote: Some(new_result),
            role: Some(Role::Secondary),
            strength: Some(Strength(10)),
            established_strength: Some(Strength(10)),
            epoch: 2,
            ..steady(3, result())
        };
        let c1 = Heartbeat {
            vote: Some(new_result),
            phase: Phase::Voting,
            ..c1_new
        };
        deliver(&mut c2, &[c1, c3], t + 100);
        t += PERIOD_MS;
        advance(&mut c2, t);
        rounds += 1;
    }
    assert_eq!(c2.state().role, Some(Role::Primary));
    assert_eq!(c2.state().took_over_from, None);
    assert_eq!(c2.state().output, Some(Strength(30)));
    // The hand-over from 35 goes like a raise: the takeover writer writes on for the round in
    // which readers discover the new one.
    assert_eq!(c2.state().writer.retiring, Some(TAKEOVER_STRENGTH));
}

#[test]
fn the_takeover_is_held_while_the_deposed_primary_is_lost_and_released_when_heard_below_30() {
    // Samples its writer at 30 wrote may still be queued on the starved link: measured in the
    // fault lab (`tbf-primary --seed 2`), they reached the Connext reader after C2 had lost
    // C1 and come down to 30. A heartbeat of C1 that says it no longer commands at 30 left
    // the same queue after them.
    let mut c2 = formed_c(2);
    c2.step(arrival(1, Arrival::Late), FORMED_AT_MS + 10);
    c2.step(arrival(3, Arrival::OnTime), FORMED_AT_MS + 10);
    // C1's heartbeats stop: lost after two silent rounds, C2 and C3 agree P=2 S=3.
    let new_result = assignment(&[(2, 0), (3, 0)]);
    let c3_after = Heartbeat {
        role: Some(Role::Secondary),
        strength: Some(Strength(10)),
        established_strength: Some(Strength(10)),
        agreed: Some(new_result),
        vote: Some(new_result),
        epoch: 2,
        ..steady(3, result())
    };
    let mut t = FORMED_AT_MS;
    for round in 0..6 {
        advance(&mut c2, t + 62);
        let c3 = if round < 2 {
            steady(3, result())
        } else {
            c3_after
        };
        deliver(&mut c2, &[c3], t + 100);
        t += PERIOD_MS;
        advance(&mut c2, t);
    }
    assert_eq!(c2.state().role, Some(Role::Primary));
    assert_eq!(c2.state().peers[&1].alive, None, "C1 is lost");
    assert_eq!(
        c2.state().output,
        Some(TAKEOVER_STRENGTH),
        "held while C1 is unheard"
    );
    // C1 is heard again, its life alone and provisional at 15: released at that round's end.
    let c1_alone = Heartbeat {
        phase: Phase::Steady,
        role: Some(Role::Primary),
        strength: Some(Strength(15)),
        established_strength: Some(Strength(15)),
        agreed: Some(assignment(&[(1, 0)])),
        vote: Some(assignment(&[(1, 0)])),
        epoch: 1,
        provisional: true,
        ..steady(1, result())
    };
    advance(&mut c2, t + 62);
    deliver(&mut c2, &[c1_alone, c3_after], t + 100);
    t += PERIOD_MS;
    advance(&mut c2, t);
    // The merge: C1 comes in below, C2 stays Primary; released once C2 is steady again.
    let merged = assignment(&[(2, 0), (3, 0), (1, 0)]);
    let mut rounds = 0;
    while c2.state().took_over_from.is_some() && rounds < 4 {
        advance(&mut c2, t + 62);
        let c1 = Heartbeat {
            phase: Phase::Voting,
            role: None,
            strength: None,
            established_strength: None,
            vote: Some(merged),
            ..c1_alone
        };
        let c3 = Heartbeat {
            vote: Some(merged),
            ..c3_after
        };
        deliver(&mut c2, &[c1, c3], t + 100);
        t += PERIOD_MS;
        advance(&mut c2, t);
        rounds += 1;
    }
    assert_eq!(c2.state().took_over_from, None);
    assert_eq!(c2.state().role, Some(Role::Primary));
    assert_eq!(c2.state().output, Some(Strength(30)));
}

#[test]
fn a_deposed_life_starting_again_at_a_boundary_speaks_at_the_rounds_heartbeat_slot() {
    let config = CoreConfig::new(1, 9, PERIOD_MS, rounds());
    let at_boundary = Core::start_again(config, 1_000);
    assert_eq!(
        at_boundary.next_deadline(),
        Deadline {
            at_ms: 1_062,
            timer: Timer::Heartbeat
        }
    );
    // Later in a round, past the slot: at once, as any start.
    let late = Core::start_again(config, 1_100);
    assert_eq!(late.next_deadline().at_ms, 1_100);
}
