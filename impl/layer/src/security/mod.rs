//! DDS Security for RL's control plane (docs/security.md): keystores, their start-up check,
//! and `rl keys`, which makes them.
//!
//! With `[security] keystore` set, every RL participant (controller, `rl status`, `rl servo`,
//! `rl shapes`) authenticates with a certificate from the RL CA, and the governance and
//! permissions documents (signed by the same CA) decide who may write which topic. Before the
//! participant is created, [`keystore_of`] checks the files (the command exits with status 2
//! naming the one at fault); the participant itself is created by
//! [`crate::dds::Session::with_keystore`]. The network monitor's participants stay
//! unsecured: they carry only network heartbeats on their own domains (docs/security.md).
//!
//! The cryptography (RustDDS's builtin plugins, rcgen, ring) is behind the `security`
//! feature; without it a keystore in the configuration is refused and `rl keys` says so.

#[cfg(feature = "security")]
mod certificate;
#[cfg(feature = "security")]
mod check;
pub mod documents;
#[cfg(feature = "security")]
pub mod keys;
#[cfg(feature = "security")]
mod pem;
#[cfg(feature = "security")]
mod smime;

use crate::config::Config;
use std::path::{Path, PathBuf};

/// The CA's private key (only in the directory `rl keys init` made).
pub const CA_KEY: &str = "ca.key.pem";
/// The CA certificate: identity CA and permissions CA both.
pub const CA_CERT: &str = "ca.cert.pem";
/// The governance document: how each topic is protected.
pub const GOVERNANCE: &str = "governance.p7s";
/// The participant's identity certificate.
pub const CERT: &str = "cert.pem";
/// The participant's private key (PKCS#8).
pub const KEY: &str = "key.pem";
/// The participant's permissions document.
pub const PERMISSIONS: &str = "permissions.p7s";

/// A keystore file that is missing, unreadable, expired or does not belong with the others.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("security keystore: {}: {problem}", file.display())]
pub struct KeystoreError {
    /// The file at fault (or the keystore directory itself).
    pub file: PathBuf,
    /// What is wrong with it, for the operator.
    pub problem: String,
}

impl KeystoreError {
    /// The error for `file` with `problem`.
    pub fn new(file: &Path, problem: impl Into<String>) -> KeystoreError {
        KeystoreError {
            file: file.to_path_buf(),
            problem: problem.into(),
        }
    }
}

/// A checked keystore: one participant's files. With `open_device_topics` the device topics
/// go on a second, unsecured participant (crate::dds::Session).
#[derive(Clone, Debug)]
pub struct Keystore {
    /// The keystore directory (`$CREDENTIALS_DIRECTORY` already expanded).
    pub dir: PathBuf,
    /// The device topics go on a second, unsecured participant (`security.open_device_topics`).
    pub open_device_topics: bool,
}

impl Keystore {
    /// The path of one of its files, such as [`CERT`].
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Checks the keystore at `dir` (every file, see `check.rs`).
    #[cfg(feature = "security")]
    pub fn open(dir: &Path, open_device_topics: bool) -> Result<Keystore, KeystoreError> {
        let keystore = Keystore {
            dir: dir.to_path_buf(),
            open_device_topics,
        };
        check::check(&keystore)?;
        Ok(keystore)
    }

    /// Without the `security` feature there is nothing to open a keystore with.
    #[cfg(not(feature = "security"))]
    pub fn open(dir: &Path, _open_device_topics: bool) -> Result<Keystore, KeystoreError> {
        Err(KeystoreError::new(
            dir,
            "this rl was built without the `security` feature",
        ))
    }

    /// RustDDS's view of the files.
    #[cfg(feature = "security")]
    pub fn participant_files(&self) -> rustdds::DomainParticipantSecurityConfigFiles {
        use rustdds::DomainParticipantSecurityConfigFiles as Files;
        let mut files = Files::with_ros_default_names(&self.dir, String::new());
        files.identity_ca_certificate = self.path(CA_CERT);
        files.permissions_ca_certificate = self.path(CA_CERT);
        files.domain_governance_document = self.path(GOVERNANCE);
        files
    }
}

/// The checked keystore `config` names (`None`: security off). A problem names the file; a
/// command reports it as a usage error (exit status 2).
pub fn keystore_of(config: &Config) -> Result<Option<Keystore>, KeystoreError> {
    if !config.security.enabled() {
        return Ok(None);
    }
    let dir = keystore_dir(&config.security.keystore)?;
    Keystore::open(&dir, config.security.open_device_topics).map(Some)
}

/// Where systemd's `LoadCredential=` puts a service's files (docs/deploy-pi.md, "Security"):
/// `keystore = "$CREDENTIALS_DIRECTORY"` lets one rl.toml serve every Pi's `rl@<id>`.
const CREDENTIALS_DIRECTORY: &str = "$CREDENTIALS_DIRECTORY";

/// The keystore directory `keystore` names, `$CREDENTIALS_DIRECTORY` expanded.
fn keystore_dir(keystore: &str) -> Result<PathBuf, KeystoreError> {
    let Some(rest) = keystore.strip_prefix(CREDENTIALS_DIRECTORY) else {
        return Ok(PathBuf::from(keystore));
    };
    let base = std::env::var_os("CREDENTIALS_DIRECTORY").ok_or_else(|| {
        KeystoreError::new(
            Path::new(keystore),
            "security.keystore names $CREDENTIALS_DIRECTORY, which is not set (only a systemd service with LoadCredential= has it)",
        )
    })?;
    Ok(PathBuf::from(base).join(rest.trim_start_matches('/')))
}
