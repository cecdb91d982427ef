//! The wrong-output scenarios under the paper's two other architectures (`lab run
//! wrong-primary --architecture duplex|pair`), judged on what each promises, argued from its
//! rules as [`super::verdict`] argues voting's. Neither has three answers to compare, so the
//! voting reader (here two controllers' answers: a command only when both agree) is the
//! judges' reference for the right commands ([`super::delivered`]), not a reader they judge;
//! it must still take no wrong command, as any voting reader.
//!
//! - **The duplex** compares nothing (the paper's conclusion table: it does not catch a
//!   software bug). A wrong controller keeps its role and its writers: nobody leaves, no
//!   owner moves. A wrong Primary's commands reach both exclusive readers for as long as it is
//!   wrong (at least one wrong sample: a run where none arrived tested nothing), and what they
//!   did to the camera is the tracking error; a wrong Standby's reach no reader.
//! - **The pair** compares every output with its second implementation's before writing it
//!   (`Outputs::write`, impl/src/controller.rs), and the fault corrupts the first
//!   implementation's, as a bug in it would. The wrong member logs the mismatch at its first
//!   wrong frame: within a camera period of the asking for a value wrong at every frame (the
//!   fault takes effect at the next frame), once the ball has moved the tolerance away for a
//!   frozen one. It writes nothing more, exits 75 and comes back; its partner stays. No wrong
//!   command reaches any reader; the actuator moves once, to the partner, when the wrong
//!   member owned it, and not at all when it did not.

use super::delivered::Delivered;
use super::{camera_period_ms, Kind, OutputReport, Recorded};
use crate::lab::architecture::Architecture;
use crate::lab::expect::GAP_SLACK_MS;
use crate::lab::faults::WrongAnswer;
use crate::lab::procs::Life;

/// The longest from asking a pair member for a value wrong at every frame to its logged
/// mismatch: the next camera frame, compared before it is written, and the slack.
pub fn mismatch_bound_ms() -> f64 {
    camera_period_ms() + GAP_SLACK_MS
}

/// The failures of a wrong-output run under `architecture` (the duplex or the pair).
pub fn failures(
    architecture: Architecture,
    report: &OutputReport,
    recorded: &Recorded,
) -> Vec<String> {
    let mut failed = Vec::new();
    if report.injections.is_empty() {
        failed.push("no wrong output was asked of any controller".into());
        return failed;
    }
    if report.voter.accepted == 0 {
        // Without it there is no reference, and every command of a wrong life counts wrong.
        failed.push("the voting reader (the judges' reference) accepted no command at all".into());
    }
    failed.extend(super::verdict::wrong_accepted(&report.voter.wrong));
    match architecture {
        Architecture::Duplex => failed.extend(duplex(report, recorded)),
        Architecture::Pair => failed.extend(pair(report, recorded)),
        Architecture::Voting => {}
    }
    failed
}

/// The duplex: nobody leaves, the actuators follow the Primary throughout, and take its wrong
/// commands when it is the wrong one (none of a wrong Standby's).
fn duplex(report: &OutputReport, recorded: &Recorded) -> Vec<String> {
    let mut failed = Vec::new();
    failed.extend(exited(
        recorded,
        |_| true,
        "nobody to leave: the duplex compares nothing",
    ));
    let primary_wrong = report.scenario.kind != Kind::WrongSecondary;
    for (reader, delivered, path) in report.exclusive_readers() {
        if path.len() != 1 {
            failed.push(format!(
                "{reader} owners {} (expected the Primary throughout: nothing in the duplex moves a wrong controller)",
                path.join(" -> ")
            ));
        }
        if primary_wrong && delivered.samples == 0 {
            failed.push(format!(
                "{reader} took no wrong command (expected the wrong Primary's: the duplex compares nothing, so none means the fault never took)"
            ));
        }
        if !primary_wrong && delivered.samples > 0 {
            failed.push(format!(
                "{reader} took {} wrong samples (expected none: it follows the Primary)",
                delivered.samples
            ));
        }
    }
    failed
}

/// The pair: the wrong member leaves at its mismatch and comes back, its partner stays, no
/// reader takes a wrong command, and the actuator moves once if the wrong member owned it.
fn pair(report: &OutputReport, recorded: &Recorded) -> Vec<String> {
    let mut failed = Vec::new();
    for (injection, out) in report.injections.iter().zip(&report.out_and_back) {
        let life = &out.life;
        let timed = matches!(
            injection.wrong,
            WrongAnswer::Offset(_) | WrongAnswer::Random
        );
        match out.mismatch_after_ms {
            None => failed.push(format!(
                "{life} never logged a lockstep mismatch (expected at its first wrong frame: its second implementation disagrees)"
            )),
            Some(after) if timed && after > mismatch_bound_ms() => failed.push(format!(
                "{life} logged its lockstep mismatch {after:.0} ms after its fault (expected within {:.0} ms: the next camera frame, compared before it is written)",
                mismatch_bound_ms()
            )),
            Some(_) => {}
        }
        if !out.exit.as_deref().is_some_and(|e| e.ends_with(" 75")) {
            failed.push(format!(
                "{life} ended {} (expected exit status 75: FAILED)",
                out.exit.as_deref().unwrap_or("never")
            ));
        }
        if out.back_after_ms.is_none() {
            failed.push(format!(
                "{life}'s controller never came back (expected a new life beside its partner)"
            ));
        }
    }
    let wrong_ids: Vec<u8> = report.injections.iter().map(|i| i.id).collect();
    failed.extend(exited(
        recorded,
        |l| !wrong_ids.contains(&l.id),
        "the right member to stay",
    ));
    let wrong_life = report.injections.first().map(|i| i.life.as_str());
    for (reader, delivered, path) in report.exclusive_readers() {
        failed.extend(nothing_wrong_taken(reader, delivered));
        let owned = path.first().map(String::as_str) == wrong_life;
        let expected_changes = usize::from(owned);
        if path.len() != 1 + expected_changes {
            let expected = if owned {
                "one change, from the wrong member to its partner, never back"
            } else {
                "its owner throughout: the wrong member did not own it"
            };
            failed.push(format!(
                "{reader} owners {} (expected {expected})",
                path.join(" -> ")
            ));
        }
    }
    failed
}

/// The lives `judged` that exited, if any did: a failure that says what was `expected`.
fn exited(recorded: &Recorded, judged: impl Fn(&Life) -> bool, expected: &str) -> Option<String> {
    let left: Vec<String> = recorded
        .lives
        .iter()
        .filter(|l| judged(l))
        .filter_map(|l| Some(format!("{} ({})", l.label(), l.exit.as_deref()?)))
        .collect();
    (!left.is_empty()).then(|| format!("{} exited (expected {expected})", left.join(", ")))
}

/// A pair's reader that took any wrong sample: the compare before the write let one through.
fn nothing_wrong_taken(reader: &str, delivered: &Delivered) -> Option<String> {
    (delivered.samples > 0).then(|| {
        format!(
            "{reader} took {} wrong samples ({} distinct) from {} (expected none: a pair member compares each output before it writes it)",
            delivered.samples,
            delivered.distinct,
            delivered.from.join(", ")
        )
    })
}

#[cfg(test)]
mod tests;
