//! The layer's error: what starting or running RL reports, and the exit code a command that
//! ends on it should use.

/// A failure of the redundancy layer.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The configuration file is unreadable or invalid (names the field).
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    /// The configuration's DDS Security keystore is missing, unreadable or wrong (names the
    /// file).
    #[error(transparent)]
    Keystore(#[from] crate::security::KeystoreError),
    /// DDS could not be set up or used.
    #[error("DDS: {0}")]
    Dds(String),
    /// An operating-system operation failed.
    #[error("{context}: {source}")]
    Io {
        /// What was being done (`creating the event poll`).
        context: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// `RL_MUTATION` names no mutation (a `mutation` build only).
    #[error("RL_MUTATION={name} is not a mutation; known: {known}")]
    Mutation {
        /// The value `RL_MUTATION` was set to.
        name: String,
        /// The known mutation names, comma-separated.
        known: String,
    },
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
            Error::Config(_) | Error::Keystore(_) | Error::Mutation { .. } => 2,
            Error::Failed(_) => crate::failed_exit::EXIT_STATUS,
            _ => 1,
        }
    }

    /// An operating-system failure, `source`, while doing `context` (`creating the event poll`).
    pub fn io(context: impl Into<String>, source: std::io::Error) -> Error {
        Error::Io {
            context: context.into(),
            source,
        }
    }
}

impl From<crate::dds::DdsError> for Error {
    fn from(error: crate::dds::DdsError) -> Error {
        match error {
            crate::dds::DdsError::Keystore(keystore) => Error::Keystore(keystore),
            other => Error::Dds(other.to_string()),
        }
    }
}
