//! The pair's state and actions: two controllers, each with two implementations of its
//! control law that may carry a bug, what each wrote for the current input, the actuator's
//! samples, and the ghost facts the properties read.
//!
//! Time is counted in inputs, as in the output model: an input opens, every controller in
//! service answers it (computes both implementations, compares, writes or leaves) in any
//! order, the next input closes it. Heartbeats go with the answers: a controller that wrote
//! nothing for an input has missed it, and its partner alarms at the input's close.

use crate::types::{Id, Life, Phase};
use serde::{Deserialize, Serialize};
use std::fmt;

/// The pair's two controllers, ids 1 and 2, neither with a role.
pub const CONTROLLERS: usize = 2;

/// The two diverse implementations of the control law each controller runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Implementation {
    A,
    B,
}

impl Implementation {
    pub const ALL: [Implementation; 2] = [Implementation::A, Implementation::B];

    pub fn index(self) -> usize {
        self as usize
    }
}

/// An output, abstract: the right command for the input, or a wrong one. Two wrong outputs
/// are equal (the worst case: a comparison cannot tell them apart).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Output {
    Right,
    Wrong,
}

impl fmt::Display for Output {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Output::Right => write!(f, "right"),
            Output::Wrong => write!(f, "WRONG"),
        }
    }
}

/// Where a controller is with the current input.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Answer {
    /// In service and not answered yet.
    Pending,
    /// Wrote its output to the actuator (the sample is in `PairState::samples`).
    Wrote,
    /// Found its implementations' outputs differ and left.
    Left,
    /// Out of service at this input (down, or FAILED at an earlier input), or crashed before
    /// it answered.
    Absent,
}

/// One controller of the pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PairController {
    pub id: Id,
    pub life: Life,
    /// `Steady` in service; `Failed` from a mismatch until it restarts (its local-fault
    /// alarm up, its process exiting to be restarted).
    pub phase: Phase,
    /// Which of its implementations carries a bug (wrong at every input that triggers it).
    pub buggy: [bool; 2],
    pub answer: Answer,
    /// Its alarm that the partner was lost (it wrote nothing for an input).
    pub loss_alarm: bool,
    /// Ghost: it has restarted at least once.
    pub restarted: bool,
    /// Ghost: it wrote nothing for the input closed last.
    pub missed_last: bool,
    /// Ghost: it was in service at the last close, and has been since.
    pub judged_last: bool,
}

impl PairController {
    /// A controller in service, correct, about to answer the first input.
    pub fn new(id: Id) -> PairController {
        PairController {
            id,
            life: Life::Up,
            phase: Phase::Steady,
            buggy: [false; 2],
            answer: Answer::Pending,
            loss_alarm: false,
            restarted: false,
            missed_last: false,
            judged_last: true,
        }
    }

    /// Up and not FAILED: it answers inputs.
    pub fn in_service(&self) -> bool {
        self.life == Life::Up && self.phase == Phase::Steady
    }

    pub fn has_bug(&self) -> bool {
        self.buggy.contains(&true)
    }
}

/// The whole state (its `Debug` is the readable lines of [`state_lines`]).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PairState {
    pub controllers: [PairController; CONTROLLERS],
    /// The current input is one at which every buggy implementation is wrong (the same
    /// input gives the same wrong output in every copy of the code).
    pub triggers: bool,
    /// The samples the actuator received for the current input, one per controller at most.
    pub samples: [Option<Output>; CONTROLLERS],
    pub crashes: u8,
    pub bugs: u8,
    /// Ghost: at some point two failures were present at once (a controller down counts
    /// until it restarts, a bug counts for ever).
    pub double_failure: bool,
    /// Ghost: the input closed last left the actuator without a right sample.
    pub closed_without_right: bool,
}

impl PairState {
    pub fn controller(&self, id: Id) -> &PairController {
        &self.controllers[usize::from(id) - 1]
    }

    pub fn controller_mut(&mut self, id: Id) -> &mut PairController {
        &mut self.controllers[usize::from(id) - 1]
    }

    pub fn partner(&self, id: Id) -> &PairController {
        self.controller(3 - id)
    }

    /// Nothing of the current input has happened yet: bugs appear and restarts happen here.
    pub fn input_fresh(&self) -> bool {
        self.controllers
            .iter()
            .all(|c| matches!(c.answer, Answer::Pending | Answer::Absent))
    }

    /// Every controller in service has answered the current input.
    pub fn input_answered(&self) -> bool {
        self.controllers.iter().all(|c| c.answer != Answer::Pending)
    }

    /// Failures present now: controllers down, and every bug that appeared.
    pub fn failures_present(&self) -> u8 {
        let down = self
            .controllers
            .iter()
            .filter(|c| c.life == Life::Down)
            .count();
        u8::try_from(down)
            .unwrap_or(u8::MAX)
            .saturating_add(self.bugs)
    }
}

/// Where a bug appears: what `--bug-in` allows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(tag = "in", rename_all = "snake_case")]
pub enum BugSite {
    /// One implementation of one controller.
    One {
        controller: Id,
        implementation: Implementation,
    },
    /// Both implementations of one controller, alike (a bug of the specification both follow).
    BothImplementations { controller: Id },
    /// One implementation, in both controllers (they run the same two implementations).
    BothControllers { implementation: Implementation },
}

/// One event of the pair.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum PairAction {
    BugAppears {
        site: BugSite,
    },
    /// A controller computes both implementations, compares them and writes (or leaves).
    Answer {
        controller: Id,
    },
    Crash {
        controller: Id,
    },
    /// A crashed or FAILED controller starts again, in service, its bugs with it.
    Restart {
        controller: Id,
    },
    /// The next input arrives (triggering the bugs or not); the current one closes.
    NextInput {
        triggers: bool,
    },
}

impl fmt::Display for PairAction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            PairAction::BugAppears { site } => match site {
                BugSite::One {
                    controller,
                    implementation,
                } => write!(
                    f,
                    "a bug appears in C{controller}'s implementation {implementation:?}"
                ),
                BugSite::BothImplementations { controller } => {
                    write!(
                        f,
                        "a bug appears in both of C{controller}'s implementations, alike"
                    )
                }
                BugSite::BothControllers { implementation } => write!(
                    f,
                    "a bug appears in implementation {implementation:?}, in both controllers"
                ),
            },
            PairAction::Answer { controller } => write!(
                f,
                "C{controller} answers: computes A and B, compares, writes if they agree"
            ),
            PairAction::Crash { controller } => write!(f, "C{controller} crashes"),
            PairAction::Restart { controller } => write!(f, "C{controller} restarts"),
            PairAction::NextInput { triggers: true } => {
                write!(
                    f,
                    "next input (it triggers every bug); the input before closes"
                )
            }
            PairAction::NextInput { triggers: false } => {
                write!(
                    f,
                    "next input (it triggers no bug); the input before closes"
                )
            }
        }
    }
}

/// `C1 in service, bug in A, wrote right, alarm: C2 lost`, `C2 FAILED (mismatch, alarm)`.
pub fn controller_line(state: &PairState, c: &PairController) -> String {
    let mut line = format!("C{}", c.id);
    match (c.life, c.phase) {
        (Life::Up, Phase::Failed) => line.push_str(" FAILED (mismatch: local alarm, exits)"),
        (Life::Up, _) => line.push_str(" in service"),
        _ => line.push_str(" down"),
    }
    let bugs: Vec<String> = Implementation::ALL
        .iter()
        .filter(|i| c.buggy[i.index()])
        .map(|i| format!("{i:?}"))
        .collect();
    if !bugs.is_empty() {
        line.push_str(&format!(", bug in {}", bugs.join("+")));
    }
    match (c.answer, state.samples[usize::from(c.id) - 1]) {
        (Answer::Pending, _) => line.push_str(", answering"),
        (_, Some(output)) => line.push_str(&format!(", wrote {output}")),
        (Answer::Left, None) => line.push_str(", left without writing"),
        _ => {}
    }
    if c.loss_alarm {
        line.push_str(&format!(", alarm: C{} lost", 3 - c.id));
    }
    if c.restarted {
        line.push_str(" (restarted)");
    }
    line
}

/// Every line of a state: the input, the controllers, the actuator, the faults.
pub fn state_lines(state: &PairState) -> Vec<String> {
    let mut lines = vec![format!(
        "input: {}",
        if state.triggers {
            "triggers every bug"
        } else {
            "triggers no bug"
        }
    )];
    lines.extend(state.controllers.iter().map(|c| controller_line(state, c)));
    let samples: Vec<String> = state
        .controllers
        .iter()
        .zip(state.samples)
        .filter_map(|(c, sample)| sample.map(|output| format!("C{} {output}", c.id)))
        .collect();
    lines.push(if samples.is_empty() {
        "actuator: no sample yet".to_string()
    } else {
        format!("actuator samples: {}", samples.join(", "))
    });
    let mut faults = format!("faults: crashes {}, bugs {}", state.crashes, state.bugs);
    if state.double_failure {
        faults.push_str("; two failures were present at once");
    }
    if state.closed_without_right {
        faults.push_str("; the input before closed WITHOUT A RIGHT SAMPLE");
    }
    lines.push(faults);
    lines
}

impl fmt::Debug for PairState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for line in state_lines(self) {
            writeln!(f, "{line}")?;
        }
        Ok(())
    }
}
