//! The crate's top-level error: what a command reports before it exits, and with which code.

/// A failure of an `rl` command.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The configuration file is unreadable or invalid (names the field).
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    /// A bad command-line value (names the flag).
    #[error("{0}")]
    Usage(String),
    /// DDS could not be set up or used.
    #[error("DDS: {0}")]
    Dds(String),
    /// An operating-system operation failed.
    #[error("{context}: {source}")]
    Io {
        context: String,
        #[source]
        source: std::io::Error,
    },
    /// `RL_MUTATION` names no mutation (a `mutation` build only).
    #[error("RL_MUTATION={name} is not a mutation; known: {known}")]
    Mutation { name: String, known: String },
    /// A benchmark failed, or measured failed kills or formations.
    #[error(transparent)]
    Bench(#[from] crate::bench::BenchError),
    /// The demo stopped early.
    #[error(transparent)]
    Demo(#[from] crate::demo::DemoError),
    /// The controller failed itself (outvoted, or its application reported a fault) and
    /// left, to be restarted as a new incarnation (crate::failed_exit).
    #[error("{0}; exits with status {status} to be restarted", status = crate::failed_exit::EXIT_STATUS)]
    Failed(Box<crate::failed_exit::Failure>),
    /// Anything else that ends a command.
    #[error("{0}")]
    Runtime(String),
}

impl Error {
    /// 2 for bad input (configuration, flags), 75 for a controller that failed itself (the
    /// service manager restarts it), 1 for everything else.
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::Config(_) | Error::Usage(_) | Error::Mutation { .. } => 2,
            Error::Failed(_) => crate::failed_exit::EXIT_STATUS,
            _ => 1,
        }
    }

    pub fn io(context: impl Into<String>, source: std::io::Error) -> Error {
        Error::Io {
            context: context.into(),
            source,
        }
    }
}

impl From<crate::dds::DdsError> for Error {
    fn from(error: crate::dds::DdsError) -> Error {
        Error::Dds(error.to_string())
    }
}
