//! The wrong-output judges on literal observations: each one saying no and yes.

use super::delivered::{Delivered, Judging};
use super::readings::{Accepted, Frame, NoMajority, OddOneOut};
use super::verdict::{decision_bound_ms, failures, wrong_span_bound_ms};
use super::*;
use crate::lab::clock::LabClock;
use crate::lab::observe::ActuatorSample;
use crate::lab::procs::Line;

pub(super) fn life(
    id: u8,
    number: u32,
    started_ms: f64,
    ended_ms: Option<f64>,
    exit: Option<&str>,
) -> Life {
    Life {
        id,
        number,
        pid: 0,
        clock_offset_s: 0.0,
        clock_rate: 1.0,
        started_ms,
        started_wall_ms: 0.0,
        ended_ms,
        paused: Vec::new(),
        exit: exit.map(String::from),
    }
}

/// C1 asked for pan +300 at 2000 ms; it left at 2100 ms.
fn c1_wrong() -> Vec<Injection> {
    vec![Injection {
        id: 1,
        life: "C1".into(),
        wrong: WrongAnswer::Offset(300),
        from_ms: 2000.0,
        healed_ms: Some(5000.0),
    }]
}

pub(super) fn lives() -> Vec<Life> {
    vec![
        life(1, 1, 0.0, Some(2100.0), Some("exit status: 75")),
        life(2, 1, 0.0, None, None),
        life(3, 1, 0.0, None, None),
        life(1, 2, 3100.0, None, None),
    ]
}

fn accepted(at_ms: f64, agreeing: &[u8], pan: u16) -> Accepted {
    Accepted {
        at_ms,
        input: at_ms as u64,
        input_at_ms: at_ms - 5.0,
        agreeing: agreeing.to_vec(),
        pan,
        tilt: 500,
    }
}

/// The right controllers' commands every frame from 1000 to 4000 ms, pan 500.
fn right_votes() -> Vec<Accepted> {
    (0..90)
        .map(|frame| accepted(1000.0 + f64::from(frame) * camera_period_ms(), &[2, 3], 500))
        .collect()
}

fn sample(at_ms: f64, participant: &str, pan: u16) -> ActuatorSample {
    ActuatorSample {
        at_ms,
        participant: participant.into(),
        writer_entity: String::new(),
        own_ms: at_ms,
        pan_tilt: Some((pan, 500)),
    }
}

/// Participants `p1`, `p2` are C1's and C2's first lives.
fn life_of(participant: &str, _at_ms: f64) -> String {
    match participant {
        "p1" => "C1".into(),
        "p2" => "C2".into(),
        other => format!("?{other}"),
    }
}

#[test]
fn a_wrong_controllers_sample_far_from_every_right_command_is_wrong() {
    let (votes, injections, lives) = (right_votes(), c1_wrong(), lives());
    let judging = Judging::new(&votes, &injections, &lives);
    let samples = [
        // Before the asking: not judged, whatever it is.
        sample(1990.0, "p1", 900),
        // Two wrong answers, each re-published once, 60 ms apart.
        sample(2010.0, "p1", 800),
        sample(2020.0, "p1", 800),
        sample(2043.0, "p1", 810),
        sample(2070.0, "p1", 810),
        // Within the tolerance of the right command: right.
        sample(2075.0, "p1", 520),
        // The Secondary's, after the change: right by definition.
        sample(2200.0, "p2", 900),
    ];
    let wrong = judging.exclusive(&samples, life_of);
    assert_eq!((wrong.samples, wrong.distinct), (4, 2));
    assert_eq!(
        (wrong.first_ms, wrong.span_ms()),
        (Some(2010.0), Some(60.0))
    );
    assert_eq!(wrong.from, ["C1"]);
}

#[test]
fn with_no_right_command_near_a_wrong_controllers_sample_counts_as_wrong() {
    // The voting reader held: nothing shows the sample right.
    let votes = vec![accepted(1000.0, &[2, 3], 500)];
    let (injections, lives) = (c1_wrong(), lives());
    let judging = Judging::new(&votes, &injections, &lives);
    let wrong = judging.exclusive(&[sample(2050.0, "p1", 500)], life_of);
    assert_eq!(wrong.samples, 1);
}

#[test]
fn after_the_heal_a_sample_is_judged_until_a_frame_taken_after_it_is_answered() {
    // C1 lives on past its heal at 5000 ms (the duplex): right answers from frames taken
    // from 5010 ms, accepted from 5015 ms, pan 500, and one more a second later, pan 560.
    let mut votes: Vec<Accepted> = (0..4)
        .map(|frame| accepted(5015.0 + f64::from(frame) * camera_period_ms(), &[1, 2], 500))
        .collect();
    votes.push(accepted(6200.0, &[1, 2], 560));
    let injections = c1_wrong();
    let lives = vec![life(1, 1, 0.0, None, None), life(2, 1, 0.0, None, None)];
    let judging = Judging::new(&votes, &injections, &lives);
    // Its last wrong answer re-published after the heal, before the first answer to a frame
    // taken after it; then a right answer re-published long after, beside the next frame's.
    let samples = [sample(5005.0, "p1", 800), sample(6190.0, "p1", 500)];
    let wrong = judging.exclusive(&samples, life_of);
    assert_eq!((wrong.samples, wrong.first_ms), (1, Some(5005.0)));
    // Before the heal, a sample no reference is near counts as wrong (as ever).
    let early = judging.exclusive(&[sample(3000.0, "p1", 800)], life_of);
    assert_eq!(early.samples, 1);
}

#[test]
fn the_voting_reader_is_wrong_only_on_a_command_no_right_controller_agreed_to() {
    let mut votes = right_votes();
    // A broken reader's: C1's value alone, and C1's with a right one (within the tolerance of
    // the right one's, so right).
    votes.push(accepted(2050.0, &[1], 800));
    votes.push(accepted(2060.0, &[1, 2], 510));
    // After C1's life ended its id is right again.
    votes.push(accepted(3500.0, &[1], 500));
    let (injections, lives) = (c1_wrong(), lives());
    let judging = Judging::new(&votes, &injections, &lives);
    let wrong = judging.voter(&votes);
    assert_eq!(
        (wrong.samples, wrong.from.clone()),
        (1, vec!["C1".to_string()])
    );
    let right_only = right_votes();
    assert_eq!(judging.voter(&right_only).samples, 0);
}

#[test]
fn a_controller_is_wrong_from_the_asking_to_its_heal_or_its_lifes_end() {
    let (votes, injections, lives) = (right_votes(), c1_wrong(), lives());
    let judging = Judging::new(&votes, &injections, &lives);
    assert!(!judging.wrong_at(1, 1999.0));
    assert!(judging.wrong_at(1, 2050.0));
    assert!(!judging.wrong_at(1, 2100.0), "its life ended");
    assert!(!judging.wrong_at(2, 2050.0));
}

#[test]
fn the_bounds_in_figures() {
    // N = 2 camera periods at 30 Hz and 20 ms: 86.7 ms; N + 1 periods, the voting thread's
    // 100 ms and 20 ms: 220 ms.
    assert!((wrong_span_bound_ms(0) - 86.67).abs() < 0.01);
    assert!((decision_bound_ms(0) - 220.0).abs() < 0.01);
    // One answer out before it could be judged: a period more.
    assert!((wrong_span_bound_ms(1) - 120.0).abs() < 0.01);
    assert!((decision_bound_ms(1) - 253.33).abs() < 0.01);
    assert_eq!(ODD_LIMIT, 2);
    assert_eq!(TOLERANCE, 25);
}

pub(super) fn report(kind: Kind) -> OutputReport {
    OutputReport {
        scenario: OutputScenario {
            kind,
            camera: Camera::Exclusive,
        },
        injections: c1_wrong(),
        voter: VoterFigures {
            accepted: 400,
            dissents_raised: vec!["C1 at 2.04 s".into()],
            ..VoterFigures::default()
        },
        servo: Delivered {
            samples: 6,
            distinct: 2,
            first_ms: Some(2005.0),
            last_ms: Some(2070.0),
            from: vec!["C1".into()],
        },
        connext: None,
        servo_owner_path: vec!["C1".into(), "C2".into()],
        connext_owner_path: None,
        out_and_back: vec![OutAndBack {
            life: "C1".into(),
            decided_after_ms: Some(75.0),
            mismatch_after_ms: None,
            odd_after_fault: Some(2),
            odd_before_fault: Some(0),
            late: Some(0),
            exited_after_ms: Some(100.0),
            exit: Some("exit status: 75".into()),
            back_after_ms: Some(2500.0),
            back_life: Some("C1#2".into()),
            back_as: Some("tertiary".into()),
            dissent_raised_after_ms: Some(40.0),
            dissent_cleared_after_ms: Some(2700.0),
            odd_on: Some("output".into()),
            input_alarm_after_ms: None,
            law_alarm_after_ms: None,
        }],
        tracking: tracking::Tracking::default(),
        failures: Vec::new(),
    }
}

/// What the judges read of a run of `report`'s scenario under `architecture`, with no fault
/// but the wrong output and no owners recorded.
pub(super) fn recorded<'a>(
    architecture: crate::lab::architecture::Architecture,
    report: &'a OutputReport,
    observed: &'a Observations,
    lives: &'a [Life],
) -> Recorded<'a> {
    Recorded {
        architecture,
        observed,
        lives,
        injections: &report.injections,
        faults: &[],
        servo_owners: &[],
        connext_owners: None,
        judged_from_ms: 1000.0,
        end_ms: 15000.0,
    }
}

pub(super) fn judged(
    report: &OutputReport,
    observed: &Observations,
    lives: &[Life],
) -> Vec<String> {
    let architecture = crate::lab::architecture::Architecture::Voting;
    failures(report, &recorded(architecture, report, observed, lives))
}

#[test]
fn a_wrong_primary_that_left_within_its_bounds_passes() {
    let observed = Observations::default();
    assert_eq!(
        judged(&report(Kind::WrongPrimary), &observed, &lives()),
        Vec::<String>::new()
    );
}

#[test]
fn a_wrong_primary_fails_on_each_bound_it_misses() {
    let observed = Observations::default();
    let lives = lives();
    let mut three = report(Kind::WrongPrimary);
    three.servo.distinct = 3;
    three.servo.last_ms = Some(2100.0);
    let failed = judged(&three, &observed, &lives);
    assert!(
        failed
            .iter()
            .any(|f| f.contains("3 distinct wrong commands")),
        "{failed:?}"
    );
    assert!(
        failed
            .iter()
            .any(|f| f.contains("wrong commands for 95 ms")),
        "{failed:?}"
    );
    // One answer out before it could be judged admits the third, and 95 ms, not a fourth.
    three.out_and_back[0].late = Some(1);
    assert_eq!(judged(&three, &observed, &lives), Vec::<String>::new());
    three.servo.distinct = 4;
    let failed = judged(&three, &observed, &lives);
    assert!(
        failed
            .iter()
            .any(|f| f.contains("4 distinct wrong commands")),
        "{failed:?}"
    );
    let mut back = report(Kind::WrongPrimary);
    back.servo_owner_path.push("C1#2".into());
    assert!(judged(&back, &observed, &lives)[0].contains("never back"));
    let mut late = report(Kind::WrongPrimary);
    late.out_and_back[0].decided_after_ms = Some(300.0);
    late.out_and_back[0].exit = Some("signal: 9 (SIGKILL)".into());
    late.out_and_back[0].back_as = Some("secondary".into());
    let failed = judged(&late, &observed, &lives);
    assert_eq!(failed.len(), 3, "{failed:?}");
    let mut taken = report(Kind::WrongPrimary);
    taken.voter.wrong.samples = 2;
    taken.voter.no_majority = 1;
    taken.voter.dissents_raised.push("C3 at 2.10 s".into());
    let failed = judged(&taken, &observed, &lives);
    assert!(
        failed
            .iter()
            .any(|f| f.starts_with("the voting reader accepted 2 wrong")),
        "{failed:?}"
    );
    assert!(
        failed.iter().any(|f| f.contains("no majority 1 times")),
        "{failed:?}"
    );
    assert!(
        failed
            .iter()
            .any(|f| f.contains("about a right controller")),
        "{failed:?}"
    );
}

#[test]
fn a_missing_decision_or_dissent_fails() {
    let observed = Observations::default();
    let mut silent = report(Kind::FrozenPrimary);
    silent.out_and_back[0].decided_after_ms = None;
    silent.out_and_back[0].dissent_raised_after_ms = None;
    let failed = judged(&silent, &observed, &lives());
    assert!(failed
        .iter()
        .any(|f| f.contains("never reported that it was the odd one out")));
    assert!(failed
        .iter()
        .any(|f| f.contains("never raised a dissent alarm")));
    // A frozen Primary's decision is not bound in time.
    let mut slow = report(Kind::FrozenPrimary);
    slow.injections[0].wrong = WrongAnswer::Frozen;
    slow.out_and_back[0].decided_after_ms = Some(1500.0);
    slow.out_and_back[0].dissent_raised_after_ms = Some(1490.0);
    assert_eq!(judged(&slow, &observed, &lives()), Vec::<String>::new());
    // A glitch of the same life before the fault counted: one wrong answer, too few to name.
    let mut glitch = report(Kind::WrongPrimary);
    glitch.out_and_back[0].odd_after_fault = Some(1);
    glitch.out_and_back[0].odd_before_fault = Some(1);
    glitch.out_and_back[0].dissent_raised_after_ms = None;
    assert_eq!(judged(&glitch, &observed, &lives()), Vec::<String>::new());
    let mut uncleared = report(Kind::WrongPrimary);
    uncleared.out_and_back[0].dissent_cleared_after_ms = None;
    assert!(judged(&uncleared, &observed, &lives())[0].contains("never cleared"));
}

#[test]
fn a_wrong_secondary_must_leave_the_exclusive_readers_alone() {
    let observed = Observations::default();
    let mut secondary = report(Kind::WrongSecondary);
    secondary.servo = Delivered::default();
    secondary.servo_owner_path = vec!["C1".into()];
    assert_eq!(
        judged(&secondary, &observed, &lives()),
        Vec::<String>::new()
    );
    secondary.servo.samples = 1;
    secondary.servo_owner_path.push("C2".into());
    assert_eq!(judged(&secondary, &observed, &lives()).len(), 2);
}

fn two_wrong_report() -> OutputReport {
    let mut two = report(Kind::TwoWrong);
    two.injections.push(Injection {
        id: 2,
        life: "C2".into(),
        wrong: WrongAnswer::Offset(-300),
        from_ms: 2000.5,
        healed_ms: Some(5000.0),
    });
    two.servo_owner_path = vec!["C1".into()];
    two.voter.accepting_again_after_ms = Some(40.0);
    two
}

#[test]
fn two_wrong_controllers_must_leave_the_voting_reader_holding_and_nobody_out() {
    let running = vec![life(1, 1, 0.0, None, None), life(2, 1, 0.0, None, None)];
    let mut observed = Observations::default();
    let two = two_wrong_report();
    let failed = judged(&two, &observed, &running);
    assert_eq!(
        failed,
        ["the voting reader never held for want of a majority while both were wrong"]
    );
    observed.outputs.no_majority.push(NoMajority {
        at_ms: 2050.0,
        fresh: vec![1, 2, 3],
        hold: true,
    });
    assert_eq!(judged(&two, &observed, &running), Vec::<String>::new());
    // A frame taken while both were wrong, accepted: the right one agreed with a wrong one.
    observed.outputs.accepted.push(Accepted {
        input_at_ms: 2100.0,
        ..accepted(2110.0, &[1, 3], 800)
    });
    let failed = judged(&two, &observed, &running);
    assert!(
        failed[0].starts_with(
            "the voting reader accepted 1 commands for frames taken while both were wrong"
        ),
        "{failed:?}"
    );
    observed.outputs.accepted.clear();
    // A frame taken just before the first heal, answered after it by a healed controller and
    // the right one: the right value, taken. Without the right one, it fails.
    let before_heal = two
        .injections
        .iter()
        .filter_map(|i| i.healed_ms)
        .fold(f64::MAX, f64::min);
    observed.outputs.accepted.push(Accepted {
        input_at_ms: before_heal - 10.0,
        ..accepted(before_heal + 5.0, &[2, 3], 554)
    });
    assert_eq!(judged(&two, &observed, &running), Vec::<String>::new());
    observed.outputs.accepted[0].agreeing = vec![1, 2];
    assert_eq!(judged(&two, &observed, &running).len(), 1);
    observed.outputs.accepted.clear();
    observed.outputs.odd_one_out.push(OddOneOut {
        life: "C1".into(),
        at_ms: 2070.0,
        inputs: vec![],
        inputs_at_ms: vec![],
        odd_limit: Some(2),
        late: Some(0),
        on: None,
    });
    let exited = vec![life(1, 1, 0.0, Some(2100.0), Some("exit status: 75"))];
    let failed = judged(&two, &observed, &exited);
    assert_eq!(failed.len(), 2, "{failed:?}");
}

#[test]
fn the_readers_lines_are_read_on_the_lab_clock() {
    let clock = LabClock::start();
    let mut readings = readings::Readings::default();
    let line = |at_ms: f64, text: &str| Line {
        at_ms,
        source: String::new(),
        text: text.into(),
    };
    readings.ingest_voter(&line(
        1010.0,
        r#"{"event":"voted_command","t_ms":1000,"input":9,"agreeing":[2,3],"pan":500,"tilt":480,"frequency":60}"#,
    ), &clock);
    readings.ingest_voter(&line(
        1030.0,
        r#"{"event":"dissent","t_ms":1025,"controller_id":1,"raised":true,"input":9,"pan":800,"tilt":480,"frequency":60}"#,
    ), &clock);
    readings.ingest_voter(&line(
        1090.0,
        r#"{"event":"no_majority","t_ms":1080,"input":null,"fresh":[1,2],"action":"hold","pan":null,"tilt":null,"frequency":null}"#,
    ), &clock);
    readings.ingest_camera(&line(
        500.0,
        r#"{"event":"frame","t_ms":480,"x":111,"y":120,"error_px":6.0,"pan":500.0,"tilt":480.0}"#,
    ));
    readings.ingest_voter(&line(1100.0, "servo: a human line"), &clock);
    // The earliest read (1030 - 1025) sets the origin: 5 ms.
    assert_eq!(readings.accepted[0].at_ms, 1010.0);
    assert_eq!(readings.dissents[0].at_ms, 1030.0);
    assert!(readings.no_majority[0].hold);
    assert_eq!(
        readings.frames,
        [Frame {
            at_ms: 500.0,
            error_px: Some(6.0)
        }]
    );
    let odd = r#"{"t_ms":5000,"id":1,"incarnation":3,"event":"odd_one_out","inputs":[7,8],"odd_limit":2}"#;
    readings.ingest_controller(
        "C1",
        &line(4.0, "WARN rl: the odd one out of three"),
        true,
        &clock,
        &[],
    );
    readings.ingest_controller("C1", &line(9.0, odd), false, &clock, &[]);
    let decided = readings.odd_one_out_of("C1").cloned();
    assert_eq!(
        decided.map(|d| (d.inputs, d.odd_limit, d.on)),
        Some((vec![7, 8], Some(2), None))
    );
    // An input alarm counts only when raised, about itself, for input_disagrees.
    let alarm = |about: u8, reason: &str, raised: bool| {
        format!(
            r#"{{"t_ms":6000,"id":2,"incarnation":1,"event":"alarm","about":{about},"reason":"{reason}","raised":{raised}}}"#
        )
    };
    for other in [
        alarm(1, "input_disagrees", true),
        alarm(2, "failed", true),
        alarm(2, "input_disagrees", false),
    ] {
        readings.ingest_controller("C2", &line(10.0, &other), false, &clock, &[]);
    }
    assert_eq!(readings.input_alarm_of("C2"), None);
    let raised = alarm(2, "input_disagrees", true);
    readings.ingest_controller("C2", &line(11.0, &raised), false, &clock, &[]);
    assert_eq!(
        readings.input_alarm_of("C2"),
        Some(clock.of_wall_ms(6000.0))
    );
    // A law alarm likewise, apart from the input alarm.
    assert_eq!(readings.law_alarm_of("C2"), None);
    let law = line(12.0, &alarm(2, "law_disagrees", true));
    readings.ingest_controller("C2", &law, false, &clock, &[]);
    assert_eq!(readings.law_alarm_of("C2"), Some(clock.of_wall_ms(6000.0)));
}

#[test]
fn tracking_is_measured_per_phase() {
    let frames: Vec<Frame> = (0..100)
        .map(|i| Frame {
            at_ms: f64::from(i) * 100.0,
            // Lost for a second of the fault, 4 px off otherwise.
            error_px: (!(30..40).contains(&i)).then_some(4.0),
        })
        .collect();
    let fault = crate::lab::judge::FaultRecord {
        label: "C1's commands wrong (pan +300)".into(),
        applied_ms: 3000.0,
        healed_ms: Some(6000.0),
        target: None,
        alarm_within_ms: None,
    };
    let tracking = tracking::measure(&frames, &[fault], 1000.0, 10_000.0, Camera::Vote);
    let phases: Vec<(&str, usize, usize, Option<f64>)> = tracking
        .phases
        .iter()
        .map(|p| (p.phase.as_str(), p.frames, p.lost, p.median_px))
        .collect();
    assert_eq!(
        phases,
        [
            ("before", 20, 0, Some(4.0)),
            ("first second", 10, 10, None),
            ("fault", 30, 10, Some(4.0)),
            ("after", 40, 0, Some(4.0)),
        ]
    );
}

#[test]
fn the_wrong_output_scenarios_are_named_with_their_faults_and_not_in_ci() {
    let all = scenarios();
    let names: Vec<&str> = all.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "wrong-primary",
            "wrong-primary-vote-camera",
            "wrong-secondary",
            "frozen-primary",
            "drift-primary",
            "wrong-input-primary",
            "wrong-law-primary",
            "random-primary",
            "two-wrong"
        ]
    );
    assert!(all.iter().all(|s| !s.in_ci && s.output.is_some()));
    let two = &all[8].steps;
    assert_eq!(two.len(), 2);
    assert_eq!(
        (two[0].at_ms, two[0].lasts_ms),
        (two[1].at_ms, two[1].lasts_ms)
    );
    assert_eq!(
        WrongAnswer::Offset(-300).line(),
        "wrong-commands offset -300"
    );
    assert_eq!(WrongAnswer::Frozen.line(), "wrong-commands frozen");
    assert_eq!(WrongAnswer::Drift(20).line(), "wrong-commands drift 20");
    assert_eq!(WrongAnswer::ForeignInput.line(), "wrong-input foreign");
    assert_eq!(WrongAnswer::Gain(150).line(), "wrong-commands gain 150");
}
