//! The `[security]` section: DDS Security for RL's control plane (docs/security.md).
//!
//! `keystore` is the directory `rl keys add` made for this participant (its certificate, key,
//! permissions, the CA certificate and the governance document). Empty: security off, and
//! anyone on the network can publish RL's topics. Whether the files are present, current and
//! belong together is checked when a command starts (crate::security), not here: the
//! configuration is often checked on another machine than the one holding the keys.

use super::error::{check, quoted, InvalidValue};
use serde::{Deserialize, Serialize};

/// DDS Security for RL's control plane: the keystore, and whether the device topics stay open.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Security {
    /// The participant's keystore directory. Empty: DDS Security off.
    pub keystore: String,
    /// Leave the device topics (`dds.command_topic`, `dds.camera_topic`) unprotected, so a
    /// camera or actuator without DDS Security still works: they go on a second, unsecured
    /// participant; RL's own topics stay protected.
    pub open_device_topics: bool,
}

impl Security {
    /// Whether DDS Security is configured.
    pub fn enabled(&self) -> bool {
        !self.keystore.is_empty()
    }

    /// Checks that a keystore is only set in an rl built with the `security` feature, is a
    /// path, and that `open_device_topics` comes with one.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        check(
            !self.enabled() || cfg!(feature = "security"),
            "security.keystore",
            quoted(&self.keystore),
            || "needs an rl built with the `security` feature (this one is not)".into(),
        )?;
        check(
            !self.keystore.contains('\0'),
            "security.keystore",
            quoted(&self.keystore),
            || "must be a directory path".into(),
        )?;
        check(
            self.enabled() || !self.open_device_topics,
            "security.open_device_topics",
            self.open_device_topics,
            || "only means something with security.keystore set".into(),
        )
    }
}
