//! The controller's configuration: every timing knob, the DDS domain and topic names, the
//! tracker's colour filter and the LED backend, read from TOML (`rl.toml`).
//!
//! Every field has the paper's default, so an empty file is a valid configuration.
//! [`Config::load`] and [`Config::from_toml_str`] parse and then [`Config::validate`], so a
//! `Config` they return is always usable. A bad file is one [`ConfigError`] naming the field:
//!
//! ```text
//! rl.toml: timing.peer_deadline_ms = 300: must be a whole number of heartbeat periods (250 ms) and at least 2 of them
//! rl.toml:1:1: unknown field `timin`, expected one of `architecture`, `timing`, `dds`, `tracker`, `leds`, `networks`, `security`, `duplex`, `pair`
//! rl.toml:2:20: timing.heartbeat_period_ms: invalid type: string "fast", expected u64
//! ```
//!
//! The CLI prints it and exits 2. `rl.toml.example` lists every field with its default.
//!
//! The protocol counts time in rounds of one heartbeat period (as the model does), so the
//! peer deadline and the initialization window must be whole numbers of periods;
//! [`Timing::dead_after_rounds`] and [`Timing::window_rounds`] are those counts
//! ([`Timing::rounds`] hands them to the core, which derives the rest).
//!
//! One file per section (`timing`, `dds`, `tracker`, `leds`, `networks`, `security`, and
//! `architecture` with `[duplex]` and `[pair]`) with its defaults and rules;
//! `error` says what goes wrong, `parse` turns TOML errors into one line naming the field.

mod architecture;
mod dds;
mod error;
mod leds;
mod networks;
mod parse;
mod security;
#[cfg(test)]
mod tests;
mod timing;
mod tracker;

pub use self::architecture::{ArchitectureName, DuplexSection, PairSection};
pub use self::dds::{Dds, DOMAIN_MAX};
pub use self::error::{ConfigError, InvalidValue};
pub use self::leds::{LedBackend, Leds};
pub use self::networks::{NetworkName, Networks};
pub use self::security::Security;
pub use self::timing::{Timing, DURATION_MS_MAX, HEARTBEAT_PERIOD_MS_RANGE};
pub use self::tracker::{AperiodicPolicy, ControlLaw, Tracker, SERVO_FREQUENCY_HZ_RANGE};

use serde::{Deserialize, Serialize};
use std::path::Path;

/// The whole configuration file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// `architecture`: which redundancy architecture the controllers run: `voting` (the
    /// default), `duplex` or `pair`. First, as TOML wants plain values before sections.
    pub architecture: ArchitectureName,
    /// `[timing]`: the heartbeat period (one round), peer deadline, initialization window and
    /// command topic timing.
    pub timing: Timing,
    /// `[dds]`: the DDS domain, topic names and ROS 2 namespace.
    pub dds: Dds,
    /// `[tracker]`: the application's colour filter, servo frequency and aperiodic policy.
    pub tracker: Tracker,
    /// `[leds]`: which bank shows the four status LEDs, and their GPIO chip and pins.
    pub leds: Leds,
    /// `[networks]`: the two redundant networks and the network monitor's timing.
    pub networks: Networks,
    /// `[security]`: the DDS Security keystore (empty: security off).
    pub security: Security,
    /// `[duplex]`: the simple duplex's Primary, Standby and preemption.
    pub duplex: DuplexSection,
    /// `[pair]`: the lockstep pair's two members.
    pub pair: PairSection,
}

impl Config {
    /// Reads, parses and validates a configuration file. Errors name the file as given.
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let source_name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|error| ConfigError::Read {
            source_name: source_name.clone(),
            error,
        })?;
        Config::from_toml_str(&text, &source_name)
    }

    /// Parses and validates TOML text; `source_name` prefixes every error (a path, or
    /// something like `<command line>`).
    pub fn from_toml_str(text: &str, source_name: &str) -> Result<Config, ConfigError> {
        let deserializer = toml::Deserializer::new(text);
        let config: Config = serde_path_to_error::deserialize(deserializer)
            .map_err(|error| parse::parse_error(text, source_name, error))?;
        config.validate().map_err(|invalid| ConfigError::Invalid {
            source_name: source_name.to_string(),
            invalid,
        })?;
        Ok(config)
    }

    /// The configuration as TOML, every field written out; `from_toml_str` reads it back equal.
    pub fn to_toml_string(&self) -> Result<String, toml::ser::Error> {
        toml::to_string(self)
    }

    /// Checks every rule, section by section; the first broken rule is the error.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        self.timing.validate()?;
        self.dds.validate()?;
        self.tracker.validate()?;
        self.leds.validate()?;
        self.networks.validate(self.dds.domain)?;
        self.security.validate()?;
        self.duplex.validate()?;
        self.pair.validate()
    }

    /// The architecture the core runs under this configuration.
    pub fn core_architecture(&self) -> rl_core::Architecture {
        architecture::core_architecture(self.architecture, &self.duplex, &self.pair)
    }

    /// Whether controller `id` belongs to the configured architecture (a duplex or a pair has
    /// exactly two members); the error names the field listing them.
    pub fn check_member(&self, id: rl_core::ControllerId) -> Result<(), InvalidValue> {
        architecture::check_member(self.architecture, &self.duplex, &self.pair, id)
    }
}
