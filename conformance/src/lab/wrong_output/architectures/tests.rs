//! The duplex's and the pair's wrong-output judges on literal reports: each saying no and yes.

use super::super::tests::{life, recorded, report};
use super::super::{Kind, OutAndBack, OutputReport};
use super::{failures, mismatch_bound_ms};
use crate::lab::architecture::Architecture;
use crate::lab::observe::Observations;
use crate::lab::procs::Life;

fn judged(architecture: Architecture, report: &OutputReport, lives: &[Life]) -> Vec<String> {
    let observed = Observations::default();
    let recorded = recorded(architecture, report, &observed, lives);
    failures(architecture, report, &recorded)
}

/// A duplex whose Primary C1 was wrong: it stayed, and the servo took its wrong commands.
fn duplex_report(kind: Kind) -> OutputReport {
    let mut report = report(kind);
    report.servo_owner_path = vec!["C1".into()];
    report.out_and_back = vec![OutAndBack {
        life: "C1".into(),
        ..OutAndBack::default()
    }];
    report
}

fn both_running() -> Vec<Life> {
    vec![life(1, 1, 0.0, None, None), life(2, 1, 0.0, None, None)]
}

fn any(failed: &[String], text: &str) -> bool {
    failed.iter().any(|f| f.contains(text))
}

#[test]
fn a_duplex_keeps_its_wrong_primary_and_delivers_its_commands() {
    let wrong = duplex_report(Kind::WrongPrimary);
    assert_eq!(
        judged(Architecture::Duplex, &wrong, &both_running()),
        Vec::<String>::new()
    );
    let mut none = duplex_report(Kind::WrongPrimary);
    none.servo.samples = 0;
    let failed = judged(Architecture::Duplex, &none, &both_running());
    assert!(any(&failed, "took no wrong command"), "{failed:?}");
    let mut moved = duplex_report(Kind::WrongPrimary);
    moved.servo_owner_path.push("C2".into());
    let failed = judged(Architecture::Duplex, &moved, &both_running());
    assert!(any(&failed, "owners C1 -> C2"), "{failed:?}");
    let left = vec![
        life(1, 1, 0.0, Some(2100.0), Some("exit status: 75")),
        life(2, 1, 0.0, None, None),
    ];
    let failed = judged(Architecture::Duplex, &wrong, &left);
    assert!(any(&failed, "C1 (exit status: 75) exited"), "{failed:?}");
}

#[test]
fn a_duplex_standby_that_is_wrong_reaches_no_reader() {
    let mut standby = duplex_report(Kind::WrongSecondary);
    let failed = judged(Architecture::Duplex, &standby, &both_running());
    assert!(any(&failed, "took 6 wrong samples"), "{failed:?}");
    standby.servo.samples = 0;
    assert_eq!(
        judged(Architecture::Duplex, &standby, &both_running()),
        Vec::<String>::new()
    );
}

/// A pair whose owner C1 was wrong: caught at 30 ms, exited 75, back; nothing wrong taken.
fn pair_report() -> OutputReport {
    let mut report = report(Kind::WrongPrimary);
    report.servo.samples = 0;
    report.servo.distinct = 0;
    report.out_and_back[0].decided_after_ms = None;
    report.out_and_back[0].mismatch_after_ms = Some(30.0);
    report
}

fn c1_restarted() -> Vec<Life> {
    vec![
        life(1, 1, 0.0, Some(2100.0), Some("exit status: 75")),
        life(2, 1, 0.0, None, None),
        life(1, 2, 3100.0, None, None),
    ]
}

#[test]
fn a_pair_member_that_disagrees_leaves_before_writing() {
    let caught = pair_report();
    assert_eq!(
        judged(Architecture::Pair, &caught, &c1_restarted()),
        Vec::<String>::new()
    );
    let mut late = pair_report();
    late.out_and_back[0].mismatch_after_ms = Some(mismatch_bound_ms() + 1.0);
    let failed = judged(Architecture::Pair, &late, &c1_restarted());
    assert!(any(&failed, "logged its lockstep mismatch"), "{failed:?}");
    let mut never = pair_report();
    never.out_and_back[0].mismatch_after_ms = None;
    never.out_and_back[0].exit = None;
    let failed = judged(Architecture::Pair, &never, &c1_restarted());
    assert!(
        any(&failed, "never logged a lockstep mismatch"),
        "{failed:?}"
    );
    assert!(any(&failed, "expected exit status 75"), "{failed:?}");
    let mut delivered = pair_report();
    delivered.servo.samples = 2;
    let failed = judged(Architecture::Pair, &delivered, &c1_restarted());
    assert!(any(&failed, "took 2 wrong samples"), "{failed:?}");
    let mut back = pair_report();
    back.servo_owner_path.push("C1#2".into());
    let failed = judged(Architecture::Pair, &back, &c1_restarted());
    assert!(any(&failed, "never back"), "{failed:?}");
    let mut partner = c1_restarted();
    partner[1].exit = Some("exit status: 75".into());
    let failed = judged(Architecture::Pair, &caught, &partner);
    assert!(
        any(&failed, "expected the right member to stay"),
        "{failed:?}"
    );
}

#[test]
fn a_pair_member_that_did_not_own_the_actuator_leaves_it_where_it_was() {
    let mut other = pair_report();
    other.servo_owner_path = vec!["C2".into()];
    assert_eq!(
        judged(Architecture::Pair, &other, &c1_restarted()),
        Vec::<String>::new()
    );
    other.servo_owner_path.push("C1#2".into());
    let failed = judged(Architecture::Pair, &other, &c1_restarted());
    assert!(any(&failed, "its owner throughout"), "{failed:?}");
}

#[test]
fn the_summary_tells_a_lockstep_mismatch_from_an_odd_one_out() {
    let mut caught = pair_report();
    caught.out_and_back[0].exit = Some("exit status: 75".into());
    let text = super::super::summary(&caught);
    assert!(
        text.contains("C1: lockstep mismatch 30 ms after the fault, exited"),
        "{text}"
    );
    assert!(!text.contains("odd one out"), "{text}");
    let voting = super::super::summary(&report(Kind::WrongPrimary));
    assert!(
        voting.contains("C1: odd one out on output 75 ms after the fault"),
        "{voting}"
    );
    assert!(!voting.contains("lockstep mismatch"), "{voting}");
}
