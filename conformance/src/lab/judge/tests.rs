//! The judges on literal measurements: each one failing and passing.

use super::*;

fn span(from_ms: f64, owner: &str) -> OwnerSpan {
    OwnerSpan {
        from_ms,
        to_ms: from_ms + 50.0,
        owner: owner.into(),
    }
}

#[test]
fn each_owner_change_counts_for_the_latest_fault() {
    let spans = [
        span(0.0, "C1"),
        span(1100.0, "C2"),
        span(5200.0, "C1"),
        span(9000.0, "C3"),
    ];
    let faults = [
        FaultRecord {
            label: "cut".into(),
            applied_ms: 1000.0,
            healed_ms: Some(4000.0),
            target: None,
            alarm_within_ms: None,
        },
        FaultRecord {
            label: "kill".into(),
            applied_ms: 8000.0,
            healed_ms: Some(9500.0),
            target: None,
            alarm_within_ms: None,
        },
    ];
    let counted = changes_per_fault(&faults, &spans, None);
    assert_eq!((counted[0].servo, counted[1].servo), (2, 1));
}

#[test]
fn a_change_after_a_heal_counts_for_the_healed_fault() {
    let spans = [span(0.0, "C1"), span(4000.0, "C2"), span(10100.0, "C3")];
    let faults = [
        FaultRecord {
            label: "clock".into(),
            applied_ms: 1000.0,
            healed_ms: Some(10000.0),
            target: None,
            alarm_within_ms: None,
        },
        FaultRecord {
            label: "kill".into(),
            applied_ms: 3000.0,
            healed_ms: Some(5000.0),
            target: None,
            alarm_within_ms: None,
        },
    ];
    let counted = changes_per_fault(&faults, &spans, Some(&spans));
    assert_eq!((counted[0].servo, counted[1].servo), (1, 1));
    assert_eq!(counted[0].connext, Some(1));
}

#[test]
fn overlap_counts_only_two_or_more_at_once() {
    let intervals = vec![
        vec![(0.0, 100.0)],
        vec![(50.0, 300.0)],
        vec![(250.0, 400.0)],
    ];
    assert_eq!(overlap_ms(&intervals, 0.0), 100.0);
    assert_eq!(overlap_ms(&intervals, 280.0), 20.0);
    assert_eq!(overlap_ms(&[vec![(0.0, 100.0)]], 0.0), 0.0);
}

use crate::lab::expect::{self, Expected};
use crate::lab::faults::{Direction, Fault, Target};

/// A fault's changes: `servo` and `connext` are the times (lab ms) of its owner changes.
fn changed(fault: &str, healed_ms: f64, servo: &[f64], connext: &[f64]) -> FaultChanges {
    FaultChanges {
        fault: fault.into(),
        healed_ms: Some(healed_ms),
        servo: servo.len(),
        connext: Some(connext.len()),
        servo_at_ms: servo.to_vec(),
        connext_at_ms: Some(connext.to_vec()),
    }
}

/// A run that passes a kill of the Primary: one change at each reader, the gaps of the
/// readers' deadlines, settled in 4 rounds.
fn kill_run() -> Metrics {
    Metrics {
        changes_per_fault: vec![changed("kill -9 C1, restart", 5000.0, &[2100.0], &[2200.0])],
        servo_gap: Some((110.0, 2100.0)),
        connext_gap: Some((210.0, 2200.0)),
        settle_rounds: Some(4),
        settled_ms: Some(6000.0),
        ..Metrics::default()
    }
}

fn kill() -> Expected {
    expect::for_faults(&[Fault::Kill(Target::Primary)])
}

#[test]
fn a_run_within_every_bound_passes() {
    assert_eq!(failures(&kill_run(), &kill(), Ok(())), Vec::<String>::new());
}

#[test]
fn each_reader_has_its_own_gap_bound() {
    let with_gaps = |servo: f64, connext: f64| Metrics {
        servo_gap: Some((servo, 2100.0)),
        connext_gap: Some((connext, 2200.0)),
        ..kill_run()
    };
    // rl servo: 100 ms deadline + 10 ms republish + 20 ms; Connext: 200 ms deadline + 10 ms
    // republish + 20 ms.
    assert!(failures(&with_gaps(130.0, 230.0), &kill(), Ok(())).is_empty());
    assert_eq!(
        failures(&with_gaps(131.0, 230.0), &kill(), Ok(())),
        ["a command gap of 131 ms at rl servo, ending at 2.1 s (expected at most 130 ms)"]
    );
    // 210 ms would pass at Connext; at rl servo it is two of its deadlines.
    assert_eq!(failures(&with_gaps(210.0, 210.0), &kill(), Ok(())).len(), 1);
    assert_eq!(
        failures(&with_gaps(110.0, 231.0), &kill(), Ok(())),
        ["a command gap of 231 ms at Connext, ending at 2.2 s (expected at most 230 ms)"]
    );
}

#[test]
fn a_lone_controller_without_a_writer_may_leave_a_longer_gap() {
    // The actuator alone with C3, which may have just been restarted: the peer deadline
    // (500 ms) and two rounds (500 ms) on top of each reader's bound.
    let expected = expect::for_faults(&[Fault::Partition {
        alone: Target::Id(3),
        actuator_with_alone: true,
    }]);
    let gaps = |servo: f64, connext: f64| Metrics {
        changes_per_fault: vec![changed("partition", 7000.0, &[2700.0], &[2700.0])],
        servo_gap: Some((servo, 2700.0)),
        connext_gap: Some((connext, 2700.0)),
        ..kill_run()
    };
    assert!(failures(&gaps(634.0, 1230.0), &expected, Ok(())).is_empty());
    assert_eq!(
        failures(&gaps(1131.0, 634.0), &expected, Ok(())),
        ["a command gap of 1131 ms at rl servo, ending at 2.7 s (expected at most 1130 ms)"]
    );
    // With the Primary the actuator keeps a writer: the readers' own bounds.
    let with_primary = expect::for_faults(&[Fault::Partition {
        alone: Target::Primary,
        actuator_with_alone: true,
    }]);
    assert_eq!(
        failures(&gaps(634.0, 210.0), &with_primary, Ok(())).len(),
        1
    );
}

/// What `both-networks-down` (net A, then net B) expects.
fn both_networks_down() -> Expected {
    let faults = [
        Fault::NetworkDown(crate::lab::lan::Net::A),
        Fault::NetworkDown(crate::lab::lan::Net::B),
    ];
    expect::for_scenario("both-networks-down", &faults).expect("a named scenario")
}

#[test]
fn both_nets_down_allow_the_time_both_were_down_and_no_more() {
    let expected = both_networks_down();
    let run = |servo: f64, connext: f64| Metrics {
        changes_per_fault: vec![
            changed("net A down", 10_000.0, &[], &[]),
            changed("net B down", 10_010.0, &[10_200.0], &[10_300.0]),
        ],
        servo_gap: Some((servo, 10_100.0)),
        connext_gap: Some((connext, 10_100.0)),
        all_faults_held_ms: 7_990.0,
        settled_ms: Some(11_500.0),
        ..kill_run()
    };
    // Measured in the matrix: 8032 ms at rl servo, 8076 ms at Connext.
    assert!(failures(&run(8032.0, 8076.0), &expected, Ok(())).is_empty());
    assert_eq!(
        failures(&run(8032.0, 8221.0), &expected, Ok(())),
        ["a command gap of 8221 ms at Connext, ending at 10.1 s (expected at most 8220 ms)"]
    );
}

#[test]
fn both_nets_down_judges_owner_changes_outside_the_merge() {
    let expected = both_networks_down();
    let run = |servo: &[f64]| Metrics {
        changes_per_fault: vec![
            changed("net A down", 10_000.0, &[], &[]),
            changed("net B down", 10_010.0, servo, &[]),
        ],
        all_faults_held_ms: 7_990.0,
        settled_ms: Some(11_500.0),
        servo_gap: Some((8000.0, 10_100.0)),
        connext_gap: Some((8000.0, 10_100.0)),
        ..kill_run()
    };
    // Between the heal and the settle: changes between provisional Primaries (F9).
    assert!(failures(&run(&[10_050.0, 10_400.0, 11_000.0]), &expected, Ok(())).is_empty());
    // While both nets are down nothing can take the actuator; after the settle nothing may.
    for at in [5_000.0, 12_000.0] {
        assert_eq!(
            failures(&run(&[10_050.0, at]), &expected, Ok(())),
            ["net B down: 1 owner changes at rl servo, 0 at Connext while it held or after the controllers settled (expected none outside the merge after its heal)"]
        );
    }
}

#[test]
fn two_at_top_strength_fails_past_what_the_faults_argue() {
    let at_top = |ms: f64| Metrics {
        two_at_top_ms: ms,
        ..kill_run()
    };
    // A kill: never two at 30; an overlap of 1 ms is the events' resolution.
    assert!(failures(&at_top(1.0), &kill(), Ok(())).is_empty());
    assert_eq!(
        failures(&at_top(5.0), &kill(), Ok(())),
        ["two controllers at top strength for 5 ms (expected at most 0 ms)"]
    );
    // One-way loss: a round for the new votes to arrive and the minority grace (3 rounds).
    let one_way = expect::for_faults(&[Fault::OneWay(Target::Primary, Direction::Out)]);
    assert!(failures(&at_top(999.0), &one_way, Ok(())).is_empty());
    assert_eq!(
        failures(&at_top(1_500.0), &one_way, Ok(())),
        ["two controllers at top strength for 1500 ms (expected at most 1000 ms)"]
    );
}

#[test]
fn settling_later_than_the_models_bound_or_never_fails() {
    let settled = |rounds: Option<u64>| Metrics {
        settle_rounds: rounds,
        ..kill_run()
    };
    assert!(failures(&settled(Some(10)), &kill(), Ok(())).is_empty());
    // One-way loss measured 13 and 14 rounds (the restarted Primary's late discovery).
    assert_eq!(
        failures(&settled(Some(14)), &kill(), Ok(())),
        ["settled 14 rounds after the last heal or restart (expected at most 10)"]
    );
    assert_eq!(
        failures(&settled(None), &kill(), Ok(())),
        ["never settled after the last heal or restart"]
    );
}

#[test]
fn every_fault_is_judged_on_its_own_bound() {
    // Loss at the Tertiary, then a kill: the loss's bound (0) never excuses the kill's changes.
    let expected =
        expect::for_faults(&[Fault::Loss(Target::Id(3), 20), Fault::Kill(Target::Primary)]);
    let run = |loss: &[f64], kill: &[f64]| Metrics {
        changes_per_fault: vec![
            changed("20% random loss at C3", 6_000.0, loss, loss),
            changed("kill -9 C1, restart", 10_000.0, kill, kill),
        ],
        ..kill_run()
    };
    assert!(failures(&run(&[], &[8_100.0]), &expected, Ok(())).is_empty());
    assert_eq!(
        failures(&run(&[], &[8_100.0, 10_900.0]), &expected, Ok(())),
        ["kill -9 C1, restart: 2 owner changes at rl servo, 2 at Connext (expected at most 1)"]
    );
    assert_eq!(
        failures(&run(&[3_000.0], &[8_100.0]), &expected, Ok(())),
        ["20% random loss at C3: 1 owner changes at rl servo, 1 at Connext (expected at most 0)"]
    );
}

#[test]
fn heavier_loss_allows_one_change_at_each_reader() {
    let expected = expect::for_faults(&[Fault::Loss(Target::Primary, 40)]);
    let run = |servo: &[f64], connext: &[f64]| Metrics {
        changes_per_fault: vec![changed("40% random loss at C1", 12_000.0, servo, connext)],
        ..kill_run()
    };
    assert!(failures(&run(&[3_000.0], &[3_100.0]), &expected, Ok(())).is_empty());
    // The matrix measured 0 at rl servo and 30 at Connext: the Connext reader fails it.
    let connext: Vec<f64> = (0..30).map(|i| 2_000.0 + 300.0 * f64::from(i)).collect();
    assert_eq!(
        failures(&run(&[], &connext), &expected, Ok(())),
        ["40% random loss at C1: 0 owner changes at rl servo, 30 at Connext (expected at most 1)"]
    );
}

#[test]
fn faults_that_cannot_be_paired_with_their_bounds_fail() {
    let expected =
        expect::for_faults(&[Fault::Kill(Target::Primary), Fault::Kill(Target::Primary)]);
    assert_eq!(
        failures(&kill_run(), &expected, Ok(())),
        ["1 faults recorded where the schedule has 2: their owner changes cannot be judged"]
    );
}

#[test]
fn a_rejection_a_dead_process_or_a_panic_fails() {
    assert_eq!(
        failures(
            &kill_run(),
            &kill(),
            Err(&crate::lab::validation::NotAccepted::Rejected(
                crate::validate::Rejection {
                    round: Some(26),
                    message: "round 26: no behaviour votes P=1#1".into(),
                }
            ))
        ),
        ["the model rejects the recorded events: round 26: no behaviour votes P=1#1"]
    );
    let mut observed = Observations::default();
    observed.stderr = vec![
        (
            "C2#2".into(),
            "thread 'main' panicked at impl/layer/src/runtime.rs:9:5".into(),
        ),
        ("C3".into(), "a warning, not a panic".into()),
    ];
    let broken = Metrics {
        dead: vec!["C3 (exit status 1)".into()],
        panics: panics(&observed),
        ..kill_run()
    };
    assert_eq!(
        failures(&broken, &kill(), Ok(())),
        [
            "not running at the end: C3 (exit status 1)",
            "panic: C2#2: thread 'main' panicked at impl/layer/src/runtime.rs:9:5",
        ]
    );
}

#[test]
fn all_faults_hold_from_the_last_application_to_the_first_heal() {
    let fault = |applied_ms: f64, healed_ms: Option<f64>| FaultRecord {
        label: "net down".into(),
        applied_ms,
        healed_ms,
        target: None,
        alarm_within_ms: None,
    };
    let both = [
        fault(2_000.0, Some(10_000.0)),
        fault(2_030.0, Some(10_020.0)),
    ];
    assert_eq!(all_held_ms(&both, 20_000.0), 7_970.0);
    let apart = [fault(2_000.0, Some(3_000.0)), fault(5_000.0, Some(6_000.0))];
    assert_eq!(all_held_ms(&apart, 20_000.0), 0.0);
    assert_eq!(all_held_ms(&[fault(2_000.0, None)], 20_000.0), 18_000.0);
}

/// The settle bound's rounds begin at the last heal, or at a process started after it: a
/// controller that voted itself FAILED at the heal and was restarted 2.1 s later (one-way-in:
/// settled 3.04 s after the heal, 0.87 s after the restart) is counted from its restart, as
/// the model's `Restart` resets its fault-free rounds; a restart before the heal is not.
#[test]
fn the_settle_rounds_begin_at_the_last_heal_or_a_later_restart() {
    use crate::lab::procs::Life;
    let life = |id: u8, number: u32, started_ms: f64| Life {
        id,
        number,
        pid: 0,
        clock_offset_s: 0.0,
        clock_rate: 1.0,
        started_ms,
        started_wall_ms: started_ms,
        ended_ms: None,
        paused: Vec::new(),
        exit: None,
    };
    let faults = [FaultRecord {
        label: "one-way loss: its peers' packets to C1".into(),
        applied_ms: 2_910.0,
        healed_ms: Some(5_910.0),
        target: None,
        alarm_within_ms: None,
    }];
    let first_lives = [life(1, 1, 17.0), life(2, 1, 0.0), life(3, 1, 20.0)];
    assert_eq!(quiet_from_ms(&faults, &first_lives, 910.0), 5_910.0);
    let restarted = [life(2, 1, 0.0), life(3, 1, 20.0), life(1, 2, 8_081.0)];
    let from = quiet_from_ms(&faults, &restarted, 910.0);
    assert_eq!(from, 8_081.0);
    assert_eq!(rounds_between(from, 8_954.0, 250.0), 4);
    assert_eq!(rounds_between(5_910.0, 8_954.0, 250.0), 13);
}

/// A gray process fault is judged on the first alarm naming its controller: any reporter, any
/// reason, at or after the fault, within its bound; a later one, one about another controller
/// or a clear does not do.
#[test]
fn a_gray_fault_needs_an_alarm_naming_its_controller_within_its_bound() {
    use super::super::observe::ControllerEvent;
    use rl_layer::core::AlarmReason;
    let alarm = |life: &str, at_ms: f64, about: u8, raised: bool| ControllerEvent {
        life: life.into(),
        at_ms,
        line: rl_layer::event::EventLine {
            t_ms: at_ms as u64,
            id: 1,
            incarnation: 2,
            event: Event::Alarm {
                about,
                reason: AlarmReason::Stalled,
                raised,
            },
        },
    };
    let frozen = [FaultRecord {
        label: "C1 frozen (freezer cgroup, no signal)".into(),
        applied_ms: 2_000.0,
        healed_ms: Some(2_300.0),
        target: Some(1),
        alarm_within_ms: Some(870.0),
    }];
    let judge = |events: Vec<ControllerEvent>| {
        let mut observed = Observations::default();
        observed.controller = events;
        let metrics = Metrics {
            named: alarms_naming(&frozen, &observed),
            ..kill_run()
        };
        failures(&metrics, &kill(), Ok(()))
    };
    assert!(judge(vec![
        alarm("C1#1", 1_000.0, 1, true),
        alarm("C1#2", 2_320.0, 1, true)
    ])
    .is_empty());
    assert_eq!(
        judge(vec![
            alarm("C2", 2_400.0, 3, true),
            alarm("C1#2", 2_400.0, 1, false)
        ]),
        ["C1 frozen (freezer cgroup, no signal): no alarm named C1 (expected within 870 ms)"]
    );
    assert_eq!(
        judge(vec![alarm("C2", 3_100.0, 1, true)]),
        ["C1 frozen (freezer cgroup, no signal): the first alarm naming C1 came 1100 ms after it (expected within 870 ms)"]
    );
    // One no reader saw (no owner change at either) needs none; a late one still fails.
    let unseen = |events: Vec<ControllerEvent>| {
        let mut observed = Observations::default();
        observed.controller = events;
        let metrics = Metrics {
            named: alarms_naming(&frozen, &observed),
            changes_per_fault: vec![FaultChanges {
                fault: frozen[0].label.clone(),
                connext: Some(0),
                connext_at_ms: Some(vec![]),
                ..FaultChanges::default()
            }],
            ..kill_run()
        };
        failures(&metrics, &kill(), Ok(()))
    };
    assert!(unseen(vec![]).is_empty());
    assert_eq!(
        unseen(vec![alarm("C2", 3_100.0, 1, true)]),
        ["C1 frozen (freezer cgroup, no signal): the first alarm naming C1 came 1100 ms after it (expected within 870 ms)"]
    );
}
