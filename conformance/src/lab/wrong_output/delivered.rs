//! Which commands a reader took are wrong, and how many of them it took.
//!
//! *Right* is what the right controllers commanded: the commands the voting reader accepted
//! with at least one controller in the agreeing set that was not asked for wrong commands at
//! that moment (the reference). A command is *wrong* when it is farther than the tolerance, on
//! pan or tilt, from every reference command accepted within one camera period (and the
//! slack) of it; with no reference that near (the voting reader holding, say) a command that
//! came from a wrong controller counts as wrong, since nothing shows it right.
//!
//! - At an exclusive reader (`rl servo`, Connext) a sample is judged only when its writer's
//!   participant is a life asked for wrong commands and it arrived after the asking: a right
//!   controller's sample is right by definition, and a frozen controller's is right while the
//!   ball has not moved the tolerance away. A life that lives on past its heal (under the
//!   duplex, or `two-wrong`) answers rightly from the first frame taken after the heal, but
//!   re-publishes its last wrong answer until then: its samples are judged until the voting
//!   reader has accepted an answer to such a frame, and right from then on.
//! - At the voting reader an accepted command is judged only when every agreeing controller
//!   was wrong at that moment: one right controller in the set makes it right by definition.
//!
//! The window is the time between a command and the reference for the same camera frame:
//! both answer the same frame, on the same node, so they arrive within a frame of each other
//! (a command re-published before the next frame, or the reference for the frame after), and
//! the slack covers the readers' timestamps on a loaded machine.

use super::readings::Accepted;
use super::{camera_period_ms, Injection, TOLERANCE};
use crate::lab::expect::GAP_SLACK_MS;
use crate::lab::observe::ActuatorSample;
use crate::lab::procs::Life;
use serde::Serialize;
use std::collections::BTreeSet;

/// Wrong commands one reader took.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Delivered {
    /// Samples (each re-publication counted).
    pub samples: usize,
    /// Distinct commands (pan, tilt) among them: a controller answers a frame once and
    /// re-publishes that answer, so this counts its answers (two frames with the same answer
    /// count once).
    pub distinct: usize,
    /// The first and the last of them (lab ms).
    pub first_ms: Option<f64>,
    pub last_ms: Option<f64>,
    /// The lives (exclusive readers) or agreeing sets (voting reader) they came from.
    pub from: Vec<String>,
}

impl Delivered {
    /// From the first wrong command to the last.
    pub fn span_ms(&self) -> Option<f64> {
        Some(self.last_ms? - self.first_ms?)
    }

    fn add(&mut self, at_ms: f64, from: String) {
        self.samples += 1;
        self.first_ms.get_or_insert(at_ms);
        self.last_ms = Some(at_ms);
        if !self.from.contains(&from) {
            self.from.push(from);
        }
    }
}

/// How far a command and its reference may be apart in time.
pub fn reference_window_ms() -> f64 {
    camera_period_ms() + GAP_SLACK_MS
}

/// Whether two commands agree: each axis within the tolerance.
pub fn agree(a: (u16, u16), b: (u16, u16)) -> bool {
    a.0.abs_diff(b.0) <= TOLERANCE && a.1.abs_diff(b.1) <= TOLERANCE
}

/// The wrong-command judge of one run.
pub struct Judging<'a> {
    injections: &'a [Injection],
    lives: &'a [Life],
    /// The accepted commands a right controller agreed to, in time order.
    reference: Vec<&'a Accepted>,
}

impl<'a> Judging<'a> {
    pub fn new(
        accepted: &'a [Accepted],
        injections: &'a [Injection],
        lives: &'a [Life],
    ) -> Judging<'a> {
        let mut judging = Judging {
            injections,
            lives,
            reference: Vec::new(),
        };
        let mut reference: Vec<&Accepted> = accepted
            .iter()
            .filter(|a| a.agreeing.iter().any(|id| !judging.wrong_at(*id, a.at_ms)))
            .collect();
        reference.sort_by(|a, b| a.at_ms.total_cmp(&b.at_ms));
        judging.reference = reference;
        judging
    }

    /// Whether controller `id` was asked for wrong commands at `at_ms`: from the asking until
    /// `wrong-commands none` or the end of the life asked (a restarted life starts right).
    pub fn wrong_at(&self, id: u8, at_ms: f64) -> bool {
        self.injections.iter().any(|injection| {
            let life_end = self
                .lives
                .iter()
                .find(|l| l.label() == injection.life)
                .and_then(|l| l.ended_ms)
                .unwrap_or(f64::INFINITY);
            let until = injection.healed_ms.unwrap_or(f64::INFINITY).min(life_end);
            injection.id == id && injection.from_ms <= at_ms && at_ms < until
        })
    }

    /// The latest asking of life `life` for wrong commands by `at_ms`, if any.
    fn asked_of(&self, life: &str, at_ms: f64) -> Option<&Injection> {
        self.injections
            .iter()
            .filter(|i| i.life == life && i.from_ms <= at_ms)
            .max_by(|a, b| a.from_ms.total_cmp(&b.from_ms))
    }

    /// When the voting reader first accepted a right answer to a camera frame taken at or
    /// after `from_ms`.
    fn answered_after(&self, from_ms: f64) -> Option<f64> {
        self.reference
            .iter()
            .find(|r| r.input_at_ms >= from_ms)
            .map(|r| r.at_ms)
    }

    /// Whether `command` at `at_ms` agrees with a reference command within the window.
    pub fn near_right(&self, at_ms: f64, command: (u16, u16)) -> bool {
        let window = reference_window_ms();
        let first = self.reference.partition_point(|r| r.at_ms < at_ms - window);
        self.reference[first..]
            .iter()
            .take_while(|r| r.at_ms <= at_ms + window)
            .any(|r| agree(command, (r.pan, r.tilt)))
    }

    /// The wrong samples among an exclusive reader's `samples`; `life_of` names a sample's
    /// writer (its participant, when it arrived) as a controller life.
    pub fn exclusive(
        &self,
        samples: &[ActuatorSample],
        life_of: impl Fn(&str, f64) -> String,
    ) -> Delivered {
        let mut delivered = Delivered::default();
        let mut distinct = BTreeSet::new();
        for sample in samples {
            let life = life_of(&sample.participant, sample.at_ms);
            let Some(asked) = self.asked_of(&life, sample.at_ms) else {
                continue;
            };
            if asked
                .healed_ms
                .and_then(|healed| self.answered_after(healed))
                .is_some_and(|at| sample.at_ms >= at)
            {
                continue;
            }
            let right = sample
                .pan_tilt
                .is_some_and(|command| self.near_right(sample.at_ms, command));
            if !right {
                distinct.insert(sample.pan_tilt);
                delivered.add(sample.at_ms, life);
            }
        }
        delivered.distinct = distinct.len();
        delivered
    }

    /// The wrong commands among the voting reader's `accepted` ones.
    pub fn voter(&self, accepted: &[Accepted]) -> Delivered {
        let mut delivered = Delivered::default();
        let mut distinct = BTreeSet::new();
        for command in accepted {
            let all_wrong = command
                .agreeing
                .iter()
                .all(|id| self.wrong_at(*id, command.at_ms));
            if all_wrong && !self.near_right(command.at_ms, (command.pan, command.tilt)) {
                distinct.insert((command.pan, command.tilt));
                let from: Vec<String> =
                    command.agreeing.iter().map(|id| format!("C{id}")).collect();
                delivered.add(command.at_ms, from.join("+"));
            }
        }
        delivered.distinct = distinct.len();
        delivered
    }
}
