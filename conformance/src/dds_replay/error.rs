//! What can go wrong in a DDS-level replay: the setup (configuration, the `rl` to run, the
//! recording directory), a run that does not conform ([`Problem`], with the run's context in
//! a [`Failure`]), and a recording trace validation rejects.

use crate::record::RecordError;
use crate::validate::Rejection;
use rl_layer::core::ControllerId;
use std::path::PathBuf;
use std::process::ExitStatus;
use std::time::Duration;

/// Why the `rl` the replay runs could not be had. Cloneable: it is looked up once per process
/// and every replay gets the same answer.
#[derive(Clone, Debug, thiserror::Error)]
pub enum BinaryError {
    /// This program's own path is unknown, so the `rl` beside it cannot be found.
    #[error("the path of this program is unknown ({0}), so the rl beside it cannot be found")]
    NoExe(String),
    /// No `rl` beside this program.
    #[error("{} is missing: build it with {}", path.display(), super::binary::BUILD_COMMAND)]
    Missing { path: PathBuf },
    /// The `rl` found could not be run.
    #[error("{} --version could not run: {message}", path.display())]
    Unrunnable { path: PathBuf, message: String },
    /// The `rl` found lacks a feature the replay needs.
    #[error(
        "{} ({version}) lacks the feature(s) {missing}: build it with {}",
        path.display(),
        super::binary::BUILD_COMMAND
    )]
    Features {
        path: PathBuf,
        version: String,
        missing: String,
    },
}

/// Why a replay did not conform, or could not be run.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The replay's own `rl.toml` (`CONFIG_TOML`) is refused, or its timing does not leave
    /// room for the observations.
    #[error("the replay configuration: {0}")]
    Config(String),
    /// No `rl` with the `fault-injection` and `mutation` features beside this program.
    #[error(transparent)]
    Binary(#[from] BinaryError),
    /// The recording directory could not be prepared or written.
    #[error("{what} {}: {source}", path.display())]
    RecordDir {
        what: &'static str,
        path: PathBuf,
        source: std::io::Error,
    },
    /// The virtual LAN a trace with cuts runs on could not be built (it needs root).
    #[error("building the virtual LAN for traces/{file}'s cuts: {error}")]
    Lan { file: String, error: String },
    /// The processes did not do what the model says.
    #[error(transparent)]
    Diverged(Box<Diverged>),
    /// The recording could not be read back for validation.
    #[error("the recording of the replay: {0}")]
    Unreadable(#[from] RecordError),
    /// The recording, validated strictly (no lag tolerance), is not a behaviour of the model.
    #[error(
        "the recording of the replay of traces/{file} ({}) is not a behaviour of the model \
         (strict validation):\n{rejection}",
        record_dir.display()
    )]
    Rejected {
        file: String,
        record_dir: PathBuf,
        rejection: Box<Rejection>,
    },
}

/// A replay that did not do what the model says, with the attempts before it that did not
/// line up with the trace.
#[derive(Debug, thiserror::Error)]
#[error(
    "DDS-level replay of traces/{file} ({purpose}){}, attempt {attempt}:\n{failure}{}\nthe \
     events are kept in {}",
    mutation.as_ref().map_or(String::new(), |m| format!(" with RL_MUTATION={m}")),
    describe_earlier(earlier),
    record_dir.display()
)]
pub struct Diverged {
    pub file: String,
    pub purpose: String,
    /// The broken rule the controllers ran with, if any.
    pub mutation: Option<String>,
    pub attempt: usize,
    pub failure: Failure,
    /// Why each earlier attempt did not line up with the trace.
    pub earlier: Vec<String>,
    pub record_dir: PathBuf,
}

fn describe_earlier(earlier: &[String]) -> String {
    if earlier.is_empty() {
        String::new()
    } else {
        format!(
            "\nearlier attempts did not line up with the trace:\n  {}",
            earlier.join("\n  ")
        )
    }
}

impl ReplayError {
    /// The problem of a run that did not conform, if that is what this is.
    pub fn problem(&self) -> Option<&Problem> {
        match self {
            ReplayError::Diverged(diverged) => Some(&diverged.failure.problem),
            _ => None,
        }
    }
}

/// A run that did not conform: the problem, whether another attempt may line up with the
/// trace, and the run's context (the plan, the processes, their last lines).
#[derive(Debug, thiserror::Error)]
#[error("{problem}{context}")]
pub struct Failure {
    pub problem: Problem,
    /// The processes' timing did not line up with the trace (DDS discovery, a late harness):
    /// not a replay of the trace, try again.
    pub retry: bool,
    pub context: String,
}

/// What departed from the model in one attempt.
#[derive(Debug, thiserror::Error)]
pub enum Problem {
    /// The held processes did not all find each other before the start.
    #[error(
        "the held processes did not all discover each other within {timeout:?} \
         (participants with a heartbeat writer / reader, as each reported last: {counts}; \
         each needs {writers} / {readers})"
    )]
    NotDiscovered {
        timeout: Duration,
        counts: String,
        writers: usize,
        readers: usize,
    },
    /// The harness reached a round after its heartbeats went out.
    #[error("the harness reached round {real} {late_ms} ms late, after its heartbeats")]
    HarnessLate { real: u64, late_ms: u64 },
    /// At a compared boundary the processes' state (the servo's owner included) differs.
    #[error(
        "at boundary {boundary} of {last} ({how}; real round {real}, {since_first} after \
         boundary 1):\n{diff}"
    )]
    StateDiffers {
        boundary: usize,
        last: usize,
        how: &'static str,
        real: u64,
        since_first: u64,
        diff: String,
    },
    /// A quiescent or settled boundary was not reached within the bounded wait.
    #[error(
        "boundary {boundary} of {last} ({what}) was not reached within {timeout:?}; at round \
         {real}:\n{diff}"
    )]
    NotReached {
        boundary: usize,
        last: usize,
        what: &'static str,
        timeout: Duration,
        real: u64,
        diff: String,
    },
    /// The servo took commands from more than one controller, or from a writer it cannot name,
    /// where the owner must be settled.
    #[error(
        "at boundary {boundary} (real round {real}) the servo has no single owner between \
         {from_ms} and {until_ms} ms into the round, where the model allows {}: it accepted \
         commands from {commands}",
        owners_allowed(expected)
    )]
    OwnerUnsettled {
        boundary: usize,
        real: u64,
        from_ms: u64,
        until_ms: u64,
        /// Who the model allows (the strongest; several with a tie).
        expected: Vec<ControllerId>,
        commands: String,
    },
    /// A process the plan did not kill exited.
    #[error(
        "{source_name} exited ({status}) in real round {real} while the plan has it running; \
         its last lines:\n{}",
        tail.join("\n")
    )]
    ProcessExited {
        source_name: String,
        status: ExitStatus,
        real: u64,
        tail: Vec<String>,
    },
    /// A heartbeat the plan loses was not dropped by its receiver in its round: it did not
    /// arrive (a real loss), or the fault-injection control came too late.
    #[error(
        "round {round} (real round {real}) loses C{from}'s heartbeat to C{to}, but C{to} \
         logged no drop of it in that round (the heartbeat did not arrive, or the control came \
         late)"
    )]
    DropMissing {
        round: usize,
        real: u64,
        from: ControllerId,
        to: ControllerId,
    },
    /// A receiver dropped a heartbeat the plan does not lose at that time.
    #[error(
        "{source_name} dropped C{from}'s heartbeat at {t_ms} ms (real round {real}), where the \
         plan loses none from C{from} to it"
    )]
    DropUnplanned {
        source_name: String,
        from: ControllerId,
        t_ms: u64,
        real: u64,
    },
    /// A process could not be started.
    #[error("starting {what}: {source}")]
    Spawn {
        what: String,
        source: std::io::Error,
    },
    /// A controller could not be killed.
    #[error("kill -9 C{id}: {source}")]
    Kill {
        id: ControllerId,
        source: std::io::Error,
    },
    /// A controller could not be stopped or continued.
    #[error("signal {signal} to C{id}: {source}")]
    Signal {
        id: ControllerId,
        signal: i32,
        source: std::io::Error,
    },
    /// A cut, a pulled cable or a heal could not be applied on the virtual LAN.
    #[error("{action}: {why}")]
    Cut { action: model::Action, why: String },
    /// The fault-injection control (the controller's stdin) could not be written.
    #[error("{source_name}'s fault-injection control (stdin): {source}")]
    Control {
        source_name: String,
        source: std::io::Error,
    },
    /// A reported state names a life that was never started.
    #[error("abstraction: {0}")]
    Abstraction(#[from] crate::abstraction::UnknownIncarnation),
}

/// `C2`, or `none`.
pub fn owner_name(owner: Option<ControllerId>) -> String {
    owner.map_or("none".to_string(), |id| format!("C{id}"))
}

/// `C2`, `C1 or C2` (a tie), or `none`.
pub fn owners_allowed(owners: &[ControllerId]) -> String {
    if owners.is_empty() {
        return "none".to_string();
    }
    let names: Vec<String> = owners.iter().map(|id| format!("C{id}")).collect();
    names.join(" or ")
}
