//! The output model's state and actions: each controller's role, fault and command for the
//! current input, the two receivers, and the ghost counts the properties read.
//!
//! Time is counted in inputs (samples of the plant the controllers answer, e.g. camera
//! frames), not in heartbeat rounds: an input opens, every controller with a role answers it
//! in any order, and the next input closes it. Roles are abstracted to their strength order
//! (the role model, `crate::protocol`, specifies how they are voted).

use crate::types::{Id, Phase, Role, ROLE_COUNT};
use serde::{Deserialize, Serialize};
use std::fmt;

/// The controllers of the output model: one group of three, ids 1..=3.
pub const CONTROLLERS: usize = ROLE_COUNT;

/// A command value, abstract: two equal values agree (in the implementation: within the
/// tolerance), two different ones do not.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Value(pub u8);

impl Value {
    /// Every value a command may take.
    pub const ALL: [Value; 3] = [Value(0), Value(1), Value(2)];
    /// The values the plant's right command takes: two, so a frozen output can be right at
    /// one input and wrong at the next; the third value is never right, so two wrong
    /// commands can always differ.
    pub const RIGHT: [Value; 2] = [Value(0), Value(1)];
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "v{}", self.0)
    }
}

/// How a controller's output goes wrong while its heartbeats (and so its role) stay correct.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Fault {
    /// Every command is a wrong value (the checker picks which, input by input).
    WrongValue,
    /// Its output stopped changing: every command is this value, right only while the
    /// plant's right command happens to be it.
    Frozen(Value),
    /// It publishes no command at all.
    Omitted,
    /// Input by input: the right command, a wrong one, or none (an intermittent fault).
    Erratic,
    /// Its input differs from the group's (another camera, a miscalibrated sensor) while its
    /// output, aligned to the group's position, is the right command: masked at every
    /// receiver, and found only by comparing inputs (input congruence).
    WrongInput,
    /// Its law computes wrongly (a wrong gain, a wrong build) by less than the tolerance, from
    /// the right input: aligned to the group's position its output is the right command
    /// (masked at every receiver), and only its raw answer, the law's own step before
    /// alignment, differs from the correct controllers' (found by comparing raw answers).
    WrongLaw,
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::WrongValue => write!(f, "wrong values"),
            Fault::Frozen(value) => write!(f, "frozen at {value}"),
            Fault::Omitted => write!(f, "omits its commands"),
            Fault::Erratic => write!(f, "erratic"),
            Fault::WrongInput => write!(f, "reads a wrong input"),
            Fault::WrongLaw => write!(f, "computes with a wrong law"),
        }
    }
}

/// A controller's command for the current input, as every reader sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Command {
    /// It holds no role: it has no command instance on the bus.
    NoInstance,
    /// It holds a role and has not answered the current input yet.
    Pending,
    /// Its command for the current input.
    Sent(Value),
    /// It holds a role and published nothing for the current input.
    Missing,
}

impl Command {
    pub fn value(self) -> Option<Value> {
        match self {
            Command::Sent(value) => Some(value),
            _ => None,
        }
    }
}

/// One controller as the output model sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Controller {
    pub id: Id,
    /// `Steady` while it holds a role; `Failed` from its local fault until it restarts (its
    /// local-fault alarm is up meanwhile).
    pub phase: Phase,
    pub role: Option<Role>,
    /// How its output is wrong, if it is.
    pub fault: Option<Fault>,
    pub command: Command,
    /// The inputs at which it found itself the odd one out (`CrossCheck` says which count).
    pub odd_count: u8,
    /// It has restarted at least once.
    pub restarted: bool,
    /// Its command for the input before (mutation `CompareAfterNextCommand` only).
    pub previous: Command,
    /// Ghost: its wrong or missing commands in this life (saturating at N + 1).
    pub wrong_in_life: u8,
    /// Ghost: wrong commands the exclusive receiver took from this life (saturating).
    pub exclusive_wrong: u8,
    /// Ghost: inputs for which this life owned the exclusive receiver and sent it nothing.
    pub exclusive_missed: u8,
    /// Ghost: the role it held when it left.
    pub left_as: Option<Role>,
    /// Ghost: this controller (any life) has sent a wrong value at some input.
    pub ever_sent_wrong: bool,
    /// Ghost: inputs it answered from a wrong input in this life (saturating at N + 1).
    pub wrong_input_in_life: u8,
    /// It was the odd one out on input in this life (its input differed from two agreeing
    /// peers').
    pub odd_on_input: bool,
    /// Its `input_disagrees` alarm about itself is up: raised as it leaves odd on input,
    /// gone with the life.
    pub input_alarm: bool,
    /// Ghost: inputs it answered with a wrong law in this life (saturating at N + 1).
    pub wrong_law_in_life: u8,
    /// It was the odd one out on law in this life (its raw answer differed from two agreeing
    /// peers' to the same input).
    pub odd_on_law: bool,
    /// Its `law_disagrees` alarm about itself is up: raised as it leaves odd on law, gone
    /// with the life.
    pub law_alarm: bool,
}

impl Controller {
    /// A correct controller holding `role`, about to answer the current input.
    pub fn new(id: Id, role: Role) -> Controller {
        Controller {
            id,
            phase: Phase::Steady,
            role: Some(role),
            fault: None,
            command: Command::Pending,
            odd_count: 0,
            restarted: false,
            previous: Command::NoInstance,
            wrong_in_life: 0,
            exclusive_wrong: 0,
            exclusive_missed: 0,
            left_as: None,
            ever_sent_wrong: false,
            wrong_input_in_life: 0,
            odd_on_input: false,
            input_alarm: false,
            wrong_law_in_life: 0,
            odd_on_law: false,
            law_alarm: false,
        }
    }

    pub fn has_role(&self) -> bool {
        self.role.is_some()
    }
}

/// The receiver that votes (the paper's hyper-critical extension): it reads every
/// controller's command instance.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct VotingReceiver {
    /// The value accepted for the current input, once two sources agree on it.
    pub accepted: Option<Value>,
    /// The dissent alarm per source (index id - 1): raised when the source's command differs
    /// from the value accepted for the same input, cleared when it sends the accepted value
    /// again (a source that left keeps it meanwhile).
    pub dissent: [bool; CONTROLLERS],
    /// Raised when an input closed without two agreeing sources (nothing was accepted),
    /// cleared at the next accepted input.
    pub hold_alarm: bool,
}

/// The paper's receiver: DDS exclusive ownership, the strongest live writer's commands.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct ExclusiveReceiver {
    /// The controller whose writer is strongest (the Primary's strength wins).
    pub owner: Option<Id>,
    /// The owner's command for the current input, once it arrived.
    pub taken: Option<Value>,
}

/// The whole state (its `Debug` is the readable lines of `super::render`).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct OutputState {
    /// The plant's right command for the current input (what correct controllers send).
    pub right: Value,
    pub controllers: [Controller; CONTROLLERS],
    pub voting: VotingReceiver,
    pub exclusive: ExclusiveReceiver,
    /// Faults begun so far (the budget is `OutputConfig::max_wrong`).
    pub faults_begun: u8,
    /// Ghost: two controllers were wrong at the same time at some point of the run.
    pub two_wrong_at_once: bool,
    /// Ghost: the input closed last had no two commands agreeing (read from the commands,
    /// not from the receiver).
    pub closed_without_pair: bool,
}

impl OutputState {
    pub fn controller(&self, id: Id) -> &Controller {
        &self.controllers[usize::from(id) - 1]
    }

    pub fn controller_mut(&mut self, id: Id) -> &mut Controller {
        &mut self.controllers[usize::from(id) - 1]
    }

    /// No command of the current input has been published yet: faults begin and restarts
    /// happen here, between inputs.
    pub fn input_fresh(&self) -> bool {
        self.controllers
            .iter()
            .all(|c| matches!(c.command, Command::Pending | Command::NoInstance))
    }

    /// Every controller with a role has answered the current input (sent or missed it).
    pub fn input_answered(&self) -> bool {
        self.controllers
            .iter()
            .all(|c| c.command != Command::Pending)
    }

    /// Controllers whose output is wrong now (a FAILED one keeps its fault until it restarts).
    pub fn wrong_now(&self) -> usize {
        self.controllers
            .iter()
            .filter(|c| c.fault.is_some())
            .count()
    }

    /// How many sources sent `value` for the current input.
    pub fn senders_of(&self, value: Value) -> usize {
        self.controllers
            .iter()
            .filter(|c| c.command == Command::Sent(value))
            .count()
    }

    /// A value at least two sources sent for the current input (at most one exists).
    pub fn agreed_value(&self) -> Option<Value> {
        Value::ALL
            .into_iter()
            .find(|value| self.senders_of(*value) >= 2)
    }
}

/// One event of the output model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum OutputAction {
    /// A controller's output goes wrong; its heartbeats, and so its role, stay correct.
    GoWrong { controller: Id, fault: Fault },
    /// A controller publishes its command for the current input; both receivers and its
    /// peers get it.
    Publish { controller: Id, value: Value },
    /// A controller with a role publishes nothing for the current input.
    Omit { controller: Id },
    /// The next input arrives with its right command; every controller closes the current
    /// input's comparison first (and the odd one out may leave), the voting receiver holds
    /// the current input if nothing was accepted.
    NextInput { right: Value },
    /// A FAILED controller restarts in the lowest free role, its output correct again or
    /// still wrong.
    Restart { controller: Id, still_wrong: bool },
}

impl OutputAction {
    /// The controller the action is about, if one.
    pub fn actor(&self) -> Option<Id> {
        match *self {
            OutputAction::GoWrong { controller, .. }
            | OutputAction::Publish { controller, .. }
            | OutputAction::Omit { controller }
            | OutputAction::Restart { controller, .. } => Some(controller),
            OutputAction::NextInput { .. } => None,
        }
    }
}

impl fmt::Display for OutputAction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            OutputAction::GoWrong { controller, fault } => {
                write!(f, "C{controller}'s output goes wrong: {fault}")
            }
            OutputAction::Publish { controller, value } => {
                write!(f, "C{controller} publishes {value}")
            }
            OutputAction::Omit { controller } => write!(f, "C{controller} publishes nothing"),
            OutputAction::NextInput { right } => write!(
                f,
                "next input (right command {right}); the input before closes"
            ),
            OutputAction::Restart {
                controller,
                still_wrong: false,
            } => write!(f, "C{controller} restarts, correct again"),
            OutputAction::Restart {
                controller,
                still_wrong: true,
            } => write!(f, "C{controller} restarts, still wrong"),
        }
    }
}
