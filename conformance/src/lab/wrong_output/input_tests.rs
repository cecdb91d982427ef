//! The judges of a Primary wrong on input (`wrong-input-primary`) or in its law
//! (`wrong-law-primary`), masked in its output: it must leave on input (on its law),
//! alarmed by name, within its bound; the voting reader need not name it.

use super::delivered::Delivered;
use super::tests::{judged, lives, report};
use super::*;

/// C1 reading another camera from 2000 ms: it left on input after 5 foreign frames, 2 of them
/// judged a frame late, its input alarm with its decision; the voting reader named nobody.
fn wrong_input_report() -> OutputReport {
    let mut report = report(Kind::WrongInputPrimary);
    report.injections[0].wrong = WrongAnswer::ForeignInput;
    report.voter.dissents_raised.clear();
    report.servo.distinct = 5;
    report.servo.last_ms = Some(2005.0 + 6.0 * camera_period_ms());
    let out = &mut report.out_and_back[0];
    out.decided_after_ms = Some(230.0);
    out.odd_after_fault = Some(5);
    out.late = Some(2);
    out.odd_on = Some("input".into());
    out.input_alarm_after_ms = Some(230.0);
    out.dissent_raised_after_ms = None;
    out.dissent_cleared_after_ms = None;
    report
}

#[test]
fn a_primary_wrong_on_input_must_leave_on_input_alarmed_within_its_bound() {
    let observed = Observations::default();
    let lives = lives();
    assert_eq!(
        judged(&wrong_input_report(), &observed, &lives),
        Vec::<String>::new(),
        "the voting reader cannot name it, and need not"
    );
    let mut unalarmed = wrong_input_report();
    unalarmed.out_and_back[0].input_alarm_after_ms = None;
    let failed = judged(&unalarmed, &observed, &lives);
    assert!(
        failed
            .iter()
            .any(|f| f.contains("no input_disagrees alarm")),
        "{failed:?}"
    );
    let mut on_output = wrong_input_report();
    on_output.out_and_back[0].odd_on = Some("output".into());
    let failed = judged(&on_output, &observed, &lives);
    assert!(
        failed.iter().any(|f| f.contains("expected on input")),
        "{failed:?}"
    );
    // 5 foreign frames + 1 + 2 late periods, the flag's 100 ms and the slack: 386.7 ms.
    let bound = super::verdict::decision_bound_of_ms(Kind::WrongInputPrimary, 2);
    assert!((bound - 386.67).abs() < 0.01, "{bound}");
    let mut slow = wrong_input_report();
    slow.out_and_back[0].decided_after_ms = Some(400.0);
    slow.out_and_back[0].input_alarm_after_ms = Some(400.0);
    let failed = judged(&slow, &observed, &lives);
    assert_eq!(
        failed.len(),
        2,
        "the decision and the alarm both late: {failed:?}"
    );
    let mut many = wrong_input_report();
    many.servo.distinct = 8;
    let failed = judged(&many, &observed, &lives);
    assert!(
        failed
            .iter()
            .any(|f| f.contains("8 distinct wrong commands (expected at most 5")),
        "{failed:?}"
    );
    // Only three inputs can outvote one: neither the duplex nor the pair runs it.
    use crate::lab::architecture::Architecture;
    let input = wrong_input_report().scenario;
    assert!(not_run_under(input, Architecture::Voting).is_none());
    assert!(not_run_under(input, Architecture::Duplex).is_some());
    assert!(not_run_under(input, Architecture::Pair).is_some());
}

/// C1 with its pan gain at 150% from 2000 ms: its commands within the tolerance (none wrong at
/// the readers), it left on its law at its second odd raw answer, its law alarm with its
/// decision; the voting reader named nobody.
fn wrong_law_report() -> OutputReport {
    let mut report = report(Kind::WrongLawPrimary);
    report.injections[0].wrong = WrongAnswer::Gain(LAW_GAIN_PERCENT);
    report.voter.dissents_raised.clear();
    report.servo = Delivered::default();
    let out = &mut report.out_and_back[0];
    out.decided_after_ms = Some(150.0);
    out.odd_after_fault = Some(2);
    out.late = Some(0);
    out.odd_on = Some("law".into());
    out.law_alarm_after_ms = Some(150.0);
    out.dissent_raised_after_ms = None;
    out.dissent_cleared_after_ms = None;
    report
}

#[test]
fn a_primary_with_a_wrong_law_must_leave_on_its_law_alarmed_by_name() {
    let observed = Observations::default();
    let lives = lives();
    assert_eq!(
        judged(&wrong_law_report(), &observed, &lives),
        Vec::<String>::new(),
        "its output agrees: the voting reader cannot name it, and need not"
    );
    let mut unalarmed = wrong_law_report();
    unalarmed.out_and_back[0].law_alarm_after_ms = None;
    // An input alarm is not the law's.
    unalarmed.out_and_back[0].input_alarm_after_ms = Some(150.0);
    let failed = judged(&unalarmed, &observed, &lives);
    assert!(
        failed.iter().any(|f| f.contains("no law_disagrees alarm")),
        "{failed:?}"
    );
    let mut on_output = wrong_law_report();
    on_output.out_and_back[0].odd_on = Some("output".into());
    let failed = judged(&on_output, &observed, &lives);
    assert!(
        failed.iter().any(|f| f.contains("expected on law")),
        "{failed:?}"
    );
    let mut after_leaving = wrong_law_report();
    after_leaving.out_and_back[0].law_alarm_after_ms = Some(900.0);
    let failed = judged(&after_leaving, &observed, &lives);
    assert!(
        failed.iter().any(|f| f.contains("after its decision")),
        "{failed:?}"
    );
    let mut never = wrong_law_report();
    never.out_and_back[0].decided_after_ms = None;
    let failed = judged(&never, &observed, &lives);
    assert!(
        failed.iter().any(|f| f.contains("never reported")),
        "{failed:?}"
    );
    use crate::lab::architecture::Architecture;
    let law = wrong_law_report().scenario;
    assert!(not_run_under(law, Architecture::Voting).is_none());
    assert!(not_run_under(law, Architecture::Duplex).is_some());
    assert!(not_run_under(law, Architecture::Pair).is_some());
}
