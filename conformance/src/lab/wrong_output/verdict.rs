//! What each wrong-output scenario promises, bound by bound, and the failures a run's report
//! shows against them. Every bound is argued from the output model (docs/protocol.md,
//! "Output voting": rules 4-6, K = N = 2) and the camera's frame period, not from a run.
//!
//! - **Voting reader, every scenario**: no wrong command accepted ("a voting receiver never
//!   accepts a wrong command": with one wrong controller the two right ones are the only
//!   pair that agrees; two wrong ones that never agree make no pair at all).
//! - **One wrong controller** (`wrong-primary`, `frozen-primary`, `random-primary`,
//!   `wrong-secondary`): it reports that it is the odd one out, exits 75 and comes back as the
//!   Tertiary (rule 4: a new incarnation in the lowest free role); the voting reader raises a
//!   dissent alarm about it, no later than its decision, clears it once the new life agrees,
//!   never names another controller, and never lacks a majority ("every input is accepted
//!   while at most one is wrong"). The alarm is required when the reader heard as many wrong
//!   answers as it counts to (`super::VOTER_DISSENT_AFTER`): the life's odd inputs after the
//!   fault, from its `odd_one_out` event; an odd input of the same life before the fault (a
//!   right answer found odd) counts towards its N, so it leaves after fewer wrong answers.
//! - **A wrong Primary** (offset or random): it decides within N + 1 camera periods of the
//!   fault; at each exclusive reader one owner change, to the Secondary, never back; at most
//!   N distinct wrong commands (K = N) and at most N camera periods between the first and
//!   the last wrong sample. Why: a fault asked for takes effect at the controller's next
//!   camera frame (at most a period after the asking), and the controller leaves when the
//!   input after its N-th odd one arrives, before answering it (rule 5): its wrong answers are
//!   to N inputs, written (and re-published) between the arrival of the first and that of the
//!   (N+1)-th, N periods; N + 1 periods from the asking to the decision. It writes nothing
//!   once it has decided. Its `odd_one_out` event is written by its voting thread, which
//!   looks at the application's fault flag at least every 100 ms (`FLAG_CHECK_MS`,
//!   impl/layer/src/runtime.rs), so the event may come that much after the decision. A frozen Primary is wrong only once the ball has moved the tolerance
//!   away, so its decision is not bound in time, but the rest is.
//! - **A Primary reading another camera** (`wrong-input-primary`): its answers are to inputs
//!   the group never has, so the voting reader compares them with nothing and names nobody;
//!   its input congruence takes it out instead (rl_layer::cross_check: [`FOREIGN_LIMIT`]
//!   foreign inputs in a row, each judged when it answers the next, once both peers have
//!   answered a newer frame). It decides within `FOREIGN_LIMIT` + 1 camera periods of the
//!   fault (and one more per late answer), raises an `input_disagrees` alarm about itself
//!   first, and leaves as a wrong Primary does; at each exclusive reader one owner change, at
//!   most `FOREIGN_LIMIT` distinct wrong commands over as many periods.
//! - **A Primary with a wrong law** (`wrong-law-primary`: its pan gain at
//!   [`super::LAW_GAIN_PERCENT`]): aligned to the group's position at every frame, its output
//!   agrees within the tolerance, so the voting reader names nobody; its raw answers (the
//!   law's step, compared exactly, rl_layer::cross_check) take it out at N odd ones: its
//!   decision on its law, a `law_disagrees` alarm about itself no later than the decision,
//!   and as a wrong Primary at each exclusive reader (one owner change; its commands, within
//!   the tolerance, are not wrong ones). Its step differs only where it is 2 or more (the
//!   gain rounds a step of 1 to 1), so the decision is bound to the frames at which the ball
//!   moves, not in time; the fault's 3 s must hold it.
//! - **A drifting Primary** (`drift-primary`): as a frozen one, wrong only once past the
//!   tolerance, so its decision is not bound in time; the rest is.
//! - **A wrong Secondary**: the exclusive readers follow the Primary throughout and take no
//!   wrong sample.
//! - **Two wrong that never agree** (`two-wrong`): the voting reader holds (`no_majority`)
//!   and accepts nothing for the frames taken while both are wrong (no two of the three
//!   answers agree: the output model's "a voting receiver holds"; a frame taken just before
//!   the heal may be answered after it, and is taken only with the right controller among the
//!   agreeing), and accepts again after the
//!   heal; nobody is the odd one out (each
//!   sees the two others disagree), so nobody leaves; the exclusive readers follow the wrong
//!   Primary throughout: only the voting reader fails safe (recorded, not bounded).
//!
//! The slack, as for the gaps (`super::super::expect::GAP_SLACK_MS`), covers the timestamps of
//! processes on a shared two-core machine.

use super::delivered::Delivered;
use super::{
    camera_period_ms, Kind, OutAndBack, OutputReport, Recorded, FOREIGN_LIMIT, ODD_LIMIT,
    VOTER_DISSENT_AFTER,
};
use crate::lab::expect::GAP_SLACK_MS;
use crate::lab::faults::WrongAnswer;

/// The longest from the first wrong sample of a wrong Primary at an exclusive reader to its
/// last: N camera periods, and the slack; `late` periods more when that many of its answers
/// went out before they could be judged at their next input (its `odd_one_out` event says).
pub fn wrong_span_bound_ms(late: u64) -> f64 {
    (ODD_LIMIT as u64 + late) as f64 * camera_period_ms() + GAP_SLACK_MS
}

/// The wrong answers of one life a kind of fault lets out before the controller leaves: N for
/// an output fault, [`FOREIGN_LIMIT`] for an input the group never has.
pub fn answers_before_leaving(kind: Kind) -> u64 {
    if kind.in_input() {
        FOREIGN_LIMIT as u64
    } else {
        ODD_LIMIT as u64
    }
}

/// The longest the voting thread sleeps before it looks at the application's fault flag and
/// reports the odd-one-out decision (`FLAG_CHECK_MS` in impl/layer/src/runtime.rs).
pub const FAULT_FLAG_CHECK_MS: f64 = 100.0;

/// The longest from asking a controller for wrong values (an offset, random) to its
/// `odd_one_out` event: N + 1 camera periods to the decision (and one more per late answer,
/// as for [`wrong_span_bound_ms`]), the voting thread's look at the fault flag, and the slack.
pub fn decision_bound_ms(late: u64) -> f64 {
    decision_bound_of_ms(Kind::WrongPrimary, late)
}

/// As [`decision_bound_ms`], for `kind`: [`answers_before_leaving`] + 1 camera periods.
pub fn decision_bound_of_ms(kind: Kind, late: u64) -> f64 {
    (answers_before_leaving(kind) + 1 + late) as f64 * camera_period_ms()
        + FAULT_FLAG_CHECK_MS
        + GAP_SLACK_MS
}

/// The failures of a wrong-output run against its scenario's promises.
pub fn failures(report: &OutputReport, recorded: &Recorded) -> Vec<String> {
    let mut failed = Vec::new();
    if report.injections.is_empty() {
        failed.push("no wrong output was asked of any controller".into());
        return failed;
    }
    if report.voter.accepted == 0 {
        // Without a working voting reader its other judges would pass on nothing.
        failed.push("the voting reader accepted no command at all".into());
    }
    failed.extend(wrong_accepted(&report.voter.wrong));
    let kind = report.scenario.kind;
    if kind == Kind::TwoWrong {
        failed.extend(two_wrong(report, recorded));
        return failed;
    }
    failed.extend(one_wrong_voter(report));
    for (injection, out) in report.injections.iter().zip(&report.out_and_back) {
        let timed = matches!(
            injection.wrong,
            WrongAnswer::Offset(_) | WrongAnswer::Random | WrongAnswer::ForeignInput
        );
        failed.extend(leaves(out, timed, kind));
    }
    for (reader, delivered, path) in report.exclusive_readers() {
        if kind.primary_alone() {
            failed.extend(primary_left(reader, delivered, path, report));
        } else {
            failed.extend(untouched(reader, delivered, path));
        }
    }
    failed
}

/// The voting reader took none.
pub(super) fn wrong_accepted(wrong: &Delivered) -> Option<String> {
    (wrong.samples > 0).then(|| {
        format!(
            "the voting reader accepted {} wrong commands ({} distinct, from {}, the first at {:.2} s) (expected none: it takes a command only when two controllers agree)",
            wrong.samples,
            wrong.distinct,
            wrong.from.join(", "),
            wrong.first_ms.unwrap_or_default() / 1000.0
        )
    })
}

/// One wrong controller at the voting reader: never without a majority, a dissent alarm
/// about the wrong one only.
fn one_wrong_voter(report: &OutputReport) -> Vec<String> {
    let mut failed = Vec::new();
    if report.voter.no_majority > 0 {
        failed.push(format!(
            "the voting reader had no majority {} times (expected never while at most one controller is wrong: the two right ones agree on every frame)",
            report.voter.no_majority
        ));
    }
    let wrong_ids: Vec<String> = report
        .injections
        .iter()
        .map(|i| format!("C{}", i.id))
        .collect();
    let others: Vec<&String> = report
        .voter
        .dissents_raised
        .iter()
        .filter(|d| !wrong_ids.iter().any(|id| d.starts_with(&format!("{id} "))))
        .collect();
    if !others.is_empty() {
        failed.push(format!(
            "the voting reader raised a dissent alarm about a right controller: {others:?} (expected only about {})",
            wrong_ids.join(", ")
        ));
    }
    failed
}

/// A wrong life reported it was the odd one out, no later than the voting reader's alarm
/// allows and (`timed`: a wrong value at every frame) within [`decision_bound_ms`], exited 75
/// and came back as the Tertiary, and the voting reader named it and cleared it.
fn leaves(out: &OutAndBack, timed: bool, kind: Kind) -> Vec<String> {
    let life = &out.life;
    let late = out.late.unwrap_or(0);
    let answers = answers_before_leaving(kind);
    let bound = decision_bound_of_ms(kind, late);
    let mut failed = Vec::new();
    match out.decided_after_ms {
        None => failed.push(format!(
            "{life} never reported that it was the odd one out (expected: it leaves after {answers} wrong answers)"
        )),
        Some(after) if timed && after > bound => failed.push(format!(
            "{life} reported that it was the odd one out {after:.0} ms after its fault (expected within {bound:.0} ms: {answers} + 1 + {late} late camera periods and the voting thread's look at the fault flag)"
        )),
        Some(_) => {}
    }
    if let Some((on, alarm)) = kind.masked() {
        let raised = if kind.in_input() {
            out.input_alarm_after_ms
        } else {
            out.law_alarm_after_ms
        };
        failed.extend(named_by_itself(
            out,
            (on, alarm),
            raised,
            timed.then_some(bound),
        ));
    }
    if !out.exit.as_deref().is_some_and(|e| e.ends_with(" 75")) {
        failed.push(format!(
            "{life} ended {} (expected exit status 75: FAILED)",
            out.exit.as_deref().unwrap_or("never")
        ));
    }
    if out.back_as.as_deref() != Some("tertiary") {
        failed.push(format!(
            "{life}'s controller came back as {} (expected a new life as the Tertiary)",
            out.back_as.as_deref().unwrap_or("nothing")
        ));
    }
    // The reader hears as many wrong answers as the life had odd inputs after its fault: fewer
    // than it counts to when an earlier glitch of the same life was counted (per life, O2).
    // Answers to inputs the group never had are compared with nothing: the reader cannot name.
    let heard = out.odd_after_fault.unwrap_or(ODD_LIMIT);
    // Nor can it name a controller whose output agrees (a wrong law, masked).
    let named = heard >= VOTER_DISSENT_AFTER as usize && kind.masked().is_none();
    match (out.dissent_raised_after_ms, out.decided_after_ms) {
        (None, _) if named => failed.push(format!(
            "the voting reader never raised a dissent alarm about {life}'s controller (it answered {heard} inputs wrongly; the reader raises at {VOTER_DISSENT_AFTER})"
        )),
        (None, _) => {}
        (Some(raised), Some(decided)) if raised > decided + GAP_SLACK_MS => failed.push(format!(
            "the voting reader raised its dissent alarm about {life}'s controller {raised:.0} ms after the fault, {:.0} ms after {life} decided to leave (expected before: its wrong answers reached the reader before it left)",
            raised - decided
        )),
        _ => {}
    }
    if out.dissent_raised_after_ms.is_some() && out.dissent_cleared_after_ms.is_none() {
        failed.push(format!(
            "the voting reader never cleared its dissent alarm about {life}'s controller (expected once the restarted life agrees)"
        ));
    }
    failed
}

/// A life whose fault the alignment masks said so: its decision was `on` its input or its
/// law, and its alarm about itself (`input_disagrees`, `law_disagrees`), `raised` so many ms
/// after the fault, came within `bound` of the fault (when timed), no later than the decision.
fn named_by_itself(
    out: &OutAndBack,
    (on, alarm): (&str, &str),
    raised: Option<f64>,
    bound: Option<f64>,
) -> Vec<String> {
    let life = &out.life;
    let mut failed = Vec::new();
    if out.decided_after_ms.is_some() && out.odd_on.as_deref() != Some(on) {
        failed.push(format!(
            "{life} left as the odd one out on {} (expected on {on}: its output agreed or was never compared)",
            out.odd_on.as_deref().unwrap_or("an unnamed ground")
        ));
    }
    let within = bound.map_or("before it left".to_string(), |b| {
        format!("within {b:.0} ms of the fault")
    });
    match (raised, out.decided_after_ms) {
        (None, _) => failed.push(format!(
            "{life} raised no {alarm} alarm about itself (expected {within})"
        )),
        (Some(at), _) if bound.is_some_and(|b| at > b) => failed.push(format!(
            "{life} raised its {alarm} alarm {at:.0} ms after the fault (expected {within})"
        )),
        (Some(at), Some(decided)) if at > decided + GAP_SLACK_MS => failed.push(format!(
            "{life} raised its {alarm} alarm {at:.0} ms after the fault, after its decision at {decided:.0} ms (expected with it)"
        )),
        _ => {}
    }
    failed
}

/// At an exclusive reader, a wrong Primary: one owner change away from it, at most N wrong
/// commands over at most N camera periods (for an input the group never had, at most
/// [`FOREIGN_LIMIT`] of each).
fn primary_left(
    reader: &str,
    wrong: &Delivered,
    path: &[String],
    report: &OutputReport,
) -> Vec<String> {
    let mut failed = Vec::new();
    let wrong_life = report.injections.first().map(|i| i.life.as_str());
    // Each of its answers that went out before it could be judged at its next input (the
    // timing assumption broken, counted by the controller) adds one wrong answer.
    let late = report
        .out_and_back
        .first()
        .and_then(|o| o.late)
        .unwrap_or(0);
    let answers = answers_before_leaving(report.scenario.kind);
    let bound = answers + late;
    let span_bound = (answers + late) as f64 * camera_period_ms() + GAP_SLACK_MS;
    let wrong_id = report.injections.first().map(|i| format!("C{}", i.id));
    let away = path.len() == 2
        && path.first().map(String::as_str) == wrong_life
        && wrong_id.is_some_and(|id| !path[1].starts_with(&id));
    if !away {
        failed.push(format!(
            "{reader} owners {} (expected one change, from the wrong Primary to the Secondary, never back)",
            path.join(" -> ")
        ));
    }
    if wrong.distinct as u64 > bound {
        failed.push(format!(
            "{reader} took {} distinct wrong commands (expected at most {answers}, and {late} for its late answers)",
            wrong.distinct
        ));
    }
    if let Some(span) = wrong.span_ms().filter(|span| *span > span_bound) {
        failed.push(format!(
            "{reader} took wrong commands for {span:.0} ms (expected at most {span_bound:.0} ms: {answers} + {late} late camera periods)"
        ));
    }
    failed
}

/// At an exclusive reader, a wrong Secondary: the Primary throughout, nothing wrong.
fn untouched(reader: &str, wrong: &Delivered, path: &[String]) -> Vec<String> {
    let mut failed = Vec::new();
    if path.len() != 1 {
        failed.push(format!(
            "{reader} owners {} (expected the Primary throughout)",
            path.join(" -> ")
        ));
    }
    if wrong.samples > 0 {
        failed.push(format!(
            "{reader} took {} wrong samples (expected none: it follows the Primary)",
            wrong.samples
        ));
    }
    failed
}

/// Two wrong that never agree: the voting reader holds while both are wrong, takes nothing
/// for their frames and accepts again after the heal; and [`nobody_left`].
fn two_wrong(report: &OutputReport, recorded: &Recorded) -> Vec<String> {
    let mut failed = Vec::new();
    let both_from = report
        .injections
        .iter()
        .map(|i| i.from_ms)
        .fold(f64::NEG_INFINITY, f64::max);
    let first_heal = report
        .injections
        .iter()
        .map(|i| i.healed_ms.unwrap_or(recorded.end_ms))
        .fold(f64::INFINITY, f64::min);
    let held = recorded
        .observed
        .outputs
        .no_majority
        .iter()
        .any(|n| n.hold && n.at_ms >= both_from && n.at_ms <= first_heal);
    if !held {
        failed.push(
            "the voting reader never held for want of a majority while both were wrong".into(),
        );
    }
    // Frames taken from a moment after the later asking (the slack: a frame taken just before
    // may be answered before the fault took) until the first heal: every answer to them is
    // wrong but the right controller's, and no wrong one is within the tolerance of the right
    // one or of the other wrong one, so no two agree and nothing may be accepted. A frame
    // taken less than a camera period and the slack before the heal may be answered after it
    // by a healed controller, rightly: accepted, its value must then be the right
    // controller's (it is among the agreeing), never a wrong one's.
    let answered_after_heal_from = first_heal - super::delivered::reference_window_ms();
    let right_one = |a: &&super::readings::Accepted| {
        a.agreeing
            .iter()
            .any(|id| report.injections.iter().all(|i| i.id != *id))
    };
    let while_both: Vec<&super::readings::Accepted> = recorded
        .observed
        .outputs
        .accepted
        .iter()
        .filter(|a| a.input_at_ms >= both_from + GAP_SLACK_MS && a.input_at_ms < first_heal)
        .filter(|a| a.input_at_ms < answered_after_heal_from || !right_one(a))
        .collect();
    if let Some(first) = while_both.first() {
        let agreeing: Vec<String> = first.agreeing.iter().map(|id| format!("C{id}")).collect();
        failed.push(format!(
            "the voting reader accepted {} commands for frames taken while both were wrong, the first at {:.2} s from {} (pan {}) (expected none: no two of the three answers agree)",
            while_both.len(),
            first.at_ms / 1000.0,
            agreeing.join("+"),
            first.pan
        ));
    }
    if report.voter.accepting_again_after_ms.is_none() {
        failed.push("the voting reader accepted nothing after the heal".into());
    }
    failed.extend(nobody_left(report, recorded));
    failed
}

/// Two wrong that never agree: nobody is the odd one out, nobody exits, and the exclusive
/// readers keep the wrong Primary.
fn nobody_left(report: &OutputReport, recorded: &Recorded) -> Vec<String> {
    let mut failed = Vec::new();
    let left: Vec<&str> = recorded
        .observed
        .outputs
        .odd_one_out
        .iter()
        .filter(|o| o.at_ms >= recorded.judged_from_ms)
        .map(|o| o.life.as_str())
        .collect();
    if !left.is_empty() {
        failed.push(format!(
            "{} reported being the odd one out (expected nobody: each sees the two others disagree)",
            left.join(", ")
        ));
    }
    let exited: Vec<String> = recorded
        .lives
        .iter()
        .filter(|l| l.exit.is_some())
        .map(|l| format!("{} ({})", l.label(), l.exit.as_deref().unwrap_or_default()))
        .collect();
    if !exited.is_empty() {
        failed.push(format!(
            "{} exited (expected nobody to leave)",
            exited.join(", ")
        ));
    }
    for (reader, path) in [
        ("rl servo", Some(&report.servo_owner_path)),
        ("Connext", report.connext_owner_path.as_ref()),
    ] {
        if let Some(path) = path.filter(|path| path.len() != 1) {
            failed.push(format!(
                "{reader} owners {} (expected the wrong Primary throughout: nobody leaves)",
                path.join(" -> ")
            ));
        }
    }
    failed
}
