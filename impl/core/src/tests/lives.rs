//! A controller's life cycle as the core decides it: when one that failed itself leaves, how a
//! new life starts (after a stall, a lost carrier, a takeover), and whose round phase it
//! follows.

use super::*;

fn with_exit_delay(c: Core, delay_ms: u64) -> Core {
    let mut c = c;
    c.config = c.config.with_failed_exit_delay_ms(delay_ms);
    c
}

#[test]
fn a_failed_controller_leaves_after_announcing_it_and_the_delay() {
    let mut c = with_exit_delay(formed_c(3), 300);
    let commands = c.step(Input::LocalFault, 850);
    assert!(
        commands.iter().any(|command| matches!(
            command,
            Command::Failed {
                exit_in_ms: Some(300),
                ..
            }
        )),
        "{commands:?}"
    );
    // The delay counts from the failure (850 + 300); the heartbeats meanwhile say FAILED.
    let meanwhile = advance(&mut c, 1_149);
    assert!(!meanwhile.iter().any(|c| matches!(c, Command::Exit(_))));
    assert!(meanwhile.iter().any(|command| matches!(
        command,
        Command::PublishHeartbeat(h) if h.phase == Phase::Failed
    )));
    assert_eq!(c.next_deadline().at_ms, 1_150);
    assert_eq!(c.next_deadline().timer, Timer::Exit);
    let leave = advance(&mut c, 1_150);
    assert!(
        matches!(leave.as_slice(), [Command::Exit(failure)] if failure.id == 3),
        "{leave:?}"
    );
    // Once.
    assert_ne!(c.next_deadline().timer, Timer::Exit);
}

#[test]
fn it_never_leaves_before_a_heartbeat_said_failed() {
    let mut c = with_exit_delay(formed_c(3), 0);
    c.step(Input::LocalFault, 850);
    // Its heartbeat (due at 812, overdue) goes first, then it leaves.
    assert_eq!(c.due_timer(850), Some(Timer::Heartbeat));
    let commands = advance(&mut c, 850);
    assert!(
        matches!(
            commands.as_slice(),
            [Command::PublishHeartbeat(h), Command::Exit(_)] if h.phase == Phase::Failed
        ),
        "{commands:?}"
    );
}

#[test]
fn without_a_delay_configured_a_failed_controller_stays() {
    let mut c = formed_c(3);
    c.step(Input::LocalFault, 850);
    for command in advance(&mut c, 5_000) {
        assert!(!matches!(command, Command::Exit(_)), "{command:?}");
    }
    assert_eq!(c.report().phase, Phase::Failed);
}

#[test]
fn a_new_life_after_a_stall_is_a_new_incarnation_that_hears_the_round_it_resumes_in() {
    let mut c = with_exit_delay(formed_c(2), 300);
    let commands = c.step(
        Input::StartAgain {
            cause: Restart::Stalled { stalled_ms: 4_000 },
            incarnation: 9,
        },
        5_100,
    );
    // It names itself: its peers may never have lost it.
    assert_eq!(
        commands,
        vec![
            Command::NewLife {
                cause: Restart::Stalled { stalled_ms: 4_000 }
            },
            Command::RaiseAlarm {
                about: 2,
                reason: AlarmReason::Stalled
            }
        ]
    );
    assert_eq!(c.report().incarnation, 9);
    assert_eq!(c.report().phase, Phase::Initializing);
    assert_eq!(
        c.config().failed_exit_delay_ms,
        Some(300),
        "the config stays"
    );
    // As the model's resumed controller, it hears this round's heartbeats (the adapter drops
    // the ones the kernel kept during the stall by their send time: sent before this round);
    // their arrival sets no round phase before the next boundary.
    c.step(Input::Heartbeat(steady(1, assignment(&[(1, 0)]))), 5_200);
    assert!(!c.follows_phase_at(5_249));
    assert!(c.follows_phase_at(5_250));
    assert_eq!(c.inbox.len(), 1);
    assert!(
        c.sent_before_this_round(4_999),
        "sent before the round of 5000"
    );
    assert!(!c.sent_before_this_round(5_062));
}

#[test]
fn a_deposed_controller_speaks_at_the_rounds_heartbeat_slot() {
    let mut c = formed_c(1);
    let commands = c.step(
        Input::StartAgain {
            cause: Restart::Deposed,
            incarnation: 5,
        },
        1_000,
    );
    assert_eq!(
        commands,
        vec![Command::NewLife {
            cause: Restart::Deposed
        }]
    );
    assert_eq!(c.next_deadline().at_ms, 1_062);
    assert_eq!(c.next_deadline().timer, Timer::Heartbeat);
    // What its starved links deliver in the rest of the round waited in their queue: heard
    // (each by its send time), but no guide to the round's phase.
    assert!(!c.follows_phase_at(1_249));
    assert!(c.follows_phase_at(1_250));
}

#[test]
fn a_newcomer_is_told_to_move_its_clock_onto_the_primarys_phase() {
    let mut c = core(3, 0, 0);
    let from_primary = steady(1, assignment(&[(1, 0), (2, 0)]));
    // 100 ms ahead: the Primary's heartbeat, sent 62 ms into its round, arrives 163 ms into
    // ours (1 ms of transit expected).
    let commands = c.step(Input::HeartbeatArrival(from_primary), 2_500 + 163);
    assert_eq!(
        commands,
        vec![Command::MoveClock {
            by_ms: -100,
            following: 1
        }]
    );
    // A higher id sets no phase.
    let from_c4 = heartbeat(4, Phase::Initializing);
    assert_eq!(c.step(Input::HeartbeatArrival(from_c4), 2_763), vec![]);
}

#[test]
fn a_life_begun_after_a_stall_clears_its_stalled_alarm_after_the_settle_bound() {
    let mut c = formed_c(2);
    let period_ms = c.config().heartbeat_period_ms;
    let stalled = |c: &mut Core, at_ms| {
        c.step(
            Input::StartAgain {
                cause: Restart::Stalled { stalled_ms: 300 },
                incarnation: at_ms,
            },
            at_ms,
        )
    };
    let cleared = Command::ClearAlarm {
        about: 2,
        reason: AlarmReason::Stalled,
    };
    assert!(stalled(&mut c, 5_000).contains(&Command::RaiseAlarm {
        about: 2,
        reason: AlarmReason::Stalled
    }));
    let until_ms = 5_000 + STALL_ALARM_ROUNDS * period_ms;
    assert!(!advance(&mut c, until_ms - 1).contains(&cleared));
    assert!(advance(&mut c, until_ms + period_ms).contains(&cleared));
    assert!(
        !advance(&mut c, until_ms + 10 * period_ms).contains(&cleared),
        "once"
    );
    // Another cause of a new life is named by others (a cable, a takeover), not by itself.
    let detached = c.step(
        Input::StartAgain {
            cause: Restart::Detached,
            incarnation: 99,
        },
        until_ms + 11 * period_ms,
    );
    assert!(!detached
        .iter()
        .any(|command| matches!(command, Command::RaiseAlarm { .. })));
}
