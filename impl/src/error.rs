//! The `rl` command's errors: what a command reports before it exits, and with which code.
//! The benchmark's and the demo's own errors live here too, so every command module depends
//! on this one and this one on none of them.

/// A failure of an `rl` command.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// What the RL library reported: a bad configuration (names the field), DDS, a controller
    /// that failed itself and left to be restarted, a bad mutation name.
    #[error(transparent)]
    Layer(#[from] rl_layer::Error),
    /// A bad command-line value (names the flag).
    #[error("{0}")]
    Usage(String),
    /// A benchmark failed, or measured failed kills or formations.
    #[error(transparent)]
    Bench(#[from] BenchError),
    /// The demo stopped early.
    #[error(transparent)]
    Demo(#[from] DemoError),
}

impl Error {
    /// 2 for bad input (configuration, flags), 75 for a controller that failed itself (the
    /// service manager restarts it), 1 for everything else.
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::Layer(error) => error.exit_code(),
            Error::Usage(_) => 2,
            _ => 1,
        }
    }

    /// An operating-system error with what the command was doing (the layer's, so a tool and
    /// the layer report it alike).
    pub fn io(context: impl Into<String>, source: std::io::Error) -> Error {
        Error::Layer(rl_layer::Error::io(context, source))
    }

    /// DDS, used directly by a tool (a simulator's or the status table's own participant),
    /// could not be set up or used.
    pub fn dds(reason: impl std::fmt::Display) -> Error {
        Error::Layer(rl_layer::Error::Dds(reason.to_string()))
    }

    /// Anything else that ends a command.
    pub fn runtime(reason: impl Into<String>) -> Error {
        Error::Layer(rl_layer::Error::Runtime(reason.into()))
    }
}

impl From<rl_layer::config::ConfigError> for Error {
    fn from(error: rl_layer::config::ConfigError) -> Error {
        Error::Layer(error.into())
    }
}

impl From<rl_layer::dds::DdsError> for Error {
    fn from(error: rl_layer::dds::DdsError) -> Error {
        match error {
            rl_layer::dds::DdsError::Keystore(keystore) => Error::Layer(keystore.into()),
            other => Error::dds(other),
        }
    }
}

impl From<rl_layer::security::KeystoreError> for Error {
    fn from(error: rl_layer::security::KeystoreError) -> Error {
        Error::Layer(error.into())
    }
}

/// Why `rl bench` failed.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The controllers of a run did not all become steady in time.
    #[error("bench: no formation of three controllers in the {run} within {timeout_s} s")]
    NoFormation { run: String, timeout_s: u64 },
    /// A child process could not be started or killed, or a file not written.
    #[error("bench: {context}: {source}")]
    Io {
        context: String,
        #[source]
        source: std::io::Error,
    },
    /// A controller's `/proc` entries could not be read or parsed.
    #[error("bench: /proc/{pid}/stat or /proc/{pid}/status unreadable")]
    ProcUnreadable { pid: u32 },
    /// The controller to measure is not running.
    #[error("bench: controller {id} is not running")]
    NotRunning { id: rl_layer::core::ControllerId },
    /// A kill was due, but the servo followed no controller.
    #[error("bench: the servo follows no controller, so there is no owner to kill")]
    NoOwner,
    /// The bench's own DDS reader (formation) could not be set up.
    #[error("bench: {0}")]
    Dds(#[from] rl_layer::dds::DdsError),
    /// The results could not be encoded.
    #[error("bench: encoding the results as JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// Some kills or formations failed; every figure was printed before.
    #[error(
        "bench: {failed_kills} of {kills} kills and {failed_formations} of {formations} formations failed (seed {seed})"
    )]
    Failed {
        failed_kills: u32,
        kills: u32,
        failed_formations: u32,
        formations: u32,
        seed: u64,
    },
    /// `--groups`: some groups did not form or some kills failed; every figure was printed.
    #[error(
        "bench --groups: {failed_formations} of {groups} groups did not form and {failed_kills} of {kills} kills failed"
    )]
    GroupsFailed {
        /// Kills that broke the promise (or found no Primary and Secondary).
        failed_kills: u32,
        /// Kills made, one per formed group and run.
        kills: u32,
        /// Groups that did not form in time.
        failed_formations: u32,
        /// Groups started, over every run.
        groups: u32,
    },
}

impl BenchError {
    pub(crate) fn io(context: impl Into<String>, source: std::io::Error) -> BenchError {
        BenchError::Io {
            context: context.into(),
            source,
        }
    }

    pub(crate) fn spawn(source: std::io::Error) -> BenchError {
        BenchError::io("starting a child process", source)
    }
}

/// Why the demo stopped early.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// A controller the demo did not kill exited (its last stderr line says why).
    #[error("{controller} exited ({status}){}", last_words.as_deref().map(|w| format!(": {w}")).unwrap_or_default())]
    ControllerExited {
        /// `C2`, or with the chain's groups `nav C2`.
        controller: String,
        status: std::process::ExitStatus,
        last_words: Option<String>,
    },
}
