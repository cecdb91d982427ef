//! The controller's configuration: every timing knob, the DDS domain and topic names, the
//! tracker's colour filter and the LED backend, read from TOML (`rl.toml`).
//!
//! Every field has the paper's default, so an empty file is a valid configuration.
//! [`Config::load`] and [`Config::from_toml_str`] parse and then [`Config::validate`], so a
//! `Config` they return is always usable. A bad file is one [`ConfigError`] naming the field:
//!
//! ```text
//! rl.toml: timing.peer_deadline_ms = 300: must be a whole number of heartbeat periods (250 ms) and at least 2 of them
//! rl.toml:1:1: unknown field `timin`, expected one of `timing`, `dds`, `tracker`, `leds`
//! rl.toml:2:20: timing.heartbeat_period_ms: invalid type: string "fast", expected u64
//! ```
//!
//! The CLI prints it and exits 2. `rl.toml.example` lists every field with its default.
//!
//! The protocol counts time in rounds of one heartbeat period (as the model does), so the
//! peer deadline and the initialization window must be whole numbers of periods;
//! [`Timing::dead_after_rounds`], [`Timing::window_rounds`] and
//! [`Timing::minority_grace_rounds`] are those counts.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::Path;
use std::time::Duration;

/// The whole configuration file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    pub timing: Timing,
    pub dds: Dds,
    pub tracker: Tracker,
    pub leds: Leds,
}

/// Protocol and command timing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Timing {
    /// Heartbeat period = one protocol round (paper: 4 Hz).
    pub heartbeat_period_ms: u64,
    /// The dead-man deadline: a peer silent this long is lost (paper: 2 x period). A whole
    /// number of periods, at least two.
    pub peer_deadline_ms: u64,
    /// Initialization window: it closes this long after the last new controller was heard,
    /// or when three controllers are heard (paper: 10 s). A whole number of periods, longer
    /// than the peer deadline.
    pub init_window_ms: u64,
    /// Deadline of the command topic (paper: 100 ms): the actuator switches to the next
    /// writer when the owner is silent this long.
    pub command_deadline_ms: u64,
    /// How often the tracker re-publishes its last command when the camera is quiet, so an
    /// aperiodic command topic never misses its deadline (less than the deadline). The
    /// actuator's gap after the owner dies is at most the deadline plus this period: the
    /// default (a tenth of the deadline) keeps it within 1.1 x the deadline.
    pub command_republish_ms: u64,
}

impl Default for Timing {
    fn default() -> Timing {
        Timing {
            heartbeat_period_ms: 250,
            peer_deadline_ms: 500,
            init_window_ms: 10_000,
            command_deadline_ms: 100,
            command_republish_ms: 10,
        }
    }
}

/// DDS domain and topic names. The camera's two topics default to the original application's
/// names and types (wire-compatible with PixyShapes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Dds {
    pub domain: u16,
    pub heartbeat_topic: String,
    pub vote_topic: String,
    pub controller_alarm_topic: String,
    pub network_alarm_topic: String,
    pub command_topic: String,
    pub camera_topic: String,
    /// ROS 2 node namespace; each controller's node is `rl_controller_<id>` in it.
    pub ros_namespace: String,
}

impl Default for Dds {
    fn default() -> Dds {
        Dds {
            domain: 53,
            heartbeat_topic: "rl/controller_heartbeat".into(),
            vote_topic: "rl/vote".into(),
            controller_alarm_topic: "rl/controller_alarm".into(),
            network_alarm_topic: "rl/network_alarm".into(),
            command_topic: "pixy/servo_control".into(),
            camera_topic: "Circle".into(),
            ros_namespace: "/rl".into(),
        }
    }
}

/// How a controller keeps a lower-strength writer from leaking through on an aperiodic
/// command topic (paper, "Exclusive Ownership on aperiodic topics").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AperiodicPolicy {
    /// Every role holder re-publishes its last command before the deadline (default).
    Republish,
    /// Only the Primary writes commands.
    PrimaryOnly,
}

/// The tracker application.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Tracker {
    /// Only circles of this colour are tracked (the paper: YELLOW).
    pub color: String,
    pub aperiodic: AperiodicPolicy,
    /// Servo frequency written in every command (Hz).
    pub servo_frequency_hz: u16,
}

impl Default for Tracker {
    fn default() -> Tracker {
        Tracker {
            color: "YELLOW".into(),
            aperiodic: AperiodicPolicy::Republish,
            servo_frequency_hz: 60,
        }
    }
}

/// Which LED bank shows the status.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LedBackend {
    /// One console line whenever the LEDs change.
    Console,
    /// Eight GPIO lines (Raspberry Pi).
    Gpio,
}

/// Status LEDs: four two-lead red/green LEDs, each across two BCM GPIO pins.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Leds {
    pub backend: LedBackend,
    /// GPIO character device.
    pub chip: String,
    /// `[green_pin, red_pin]` per LED: LED1 Primary, LED2 Secondary, LED3 Tertiary, LED4 own
    /// status. Driving the first pin high and the second low lights green.
    pub pins: [[u32; 2]; 4],
}

impl Default for Leds {
    fn default() -> Leds {
        Leds {
            backend: LedBackend::Console,
            chip: "/dev/gpiochip0".into(),
            pins: [[20, 21], [7, 8], [24, 23], [15, 14]],
        }
    }
}

/// The highest DDS domain id whose RTPS ports fit in 16 bits: the well-known ports are
/// `7400 + 250 * domain + offset`, and domain 233 already passes 65535.
pub const DOMAIN_MAX: u16 = 232;

/// Heartbeat periods outside this range are either busier than a Pi should be or too slow to
/// notice a failure within a useful time.
pub const HEARTBEAT_PERIOD_MS_RANGE: std::ops::RangeInclusive<u64> = 10..=10_000;

/// Longest duration any timing field may hold (one hour): long enough for any real use, and
/// short enough that `Instant + duration` and round counts never overflow.
pub const DURATION_MS_MAX: u64 = 3_600_000;

/// Servo frequencies the gimbal can be asked for.
pub const SERVO_FREQUENCY_HZ_RANGE: std::ops::RangeInclusive<u16> = 1..=1000;

/// Why a configuration could not be had. Every variant names its source (the file path, or
/// whatever name the caller gave a string), and every variant but `Read` names the field.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{source_name}: cannot read the configuration: {error}")]
    Read {
        source_name: String,
        #[source]
        error: std::io::Error,
    },
    /// Not TOML, an unknown field, or a value of the wrong type.
    #[error("{source_name}{}: {message}", display_line_column(.line_column))]
    Parse {
        source_name: String,
        /// 1-based line and column of the offending text, when the parser knows it.
        line_column: Option<(usize, usize)>,
        /// Dotted path of the field (`timing.peer_deadline_ms`); `None` for syntax errors.
        field: Option<String>,
        /// What is wrong, naming the field: `timing.peer_deadline_ms: invalid type: ...`.
        message: String,
    },
    /// Well-formed, but a value breaks a rule.
    #[error("{source_name}: {invalid}")]
    Invalid {
        source_name: String,
        #[source]
        invalid: InvalidValue,
    },
}

impl ConfigError {
    /// The dotted path of the field at fault, if the error is about one field.
    pub fn field(&self) -> Option<&str> {
        match self {
            ConfigError::Read { .. } => None,
            ConfigError::Parse { field, .. } => field.as_deref(),
            ConfigError::Invalid { invalid, .. } => Some(&invalid.field),
        }
    }
}

fn display_line_column(line_column: &Option<(usize, usize)>) -> String {
    match line_column {
        Some((line, column)) => format!(":{line}:{column}"),
        None => String::new(),
    }
}

/// A value that breaks a validation rule: `timing.peer_deadline_ms = 300: must be ...`.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field} = {value}: {rule}")]
pub struct InvalidValue {
    /// Dotted path of the field (`timing.peer_deadline_ms`).
    pub field: String,
    /// The value as it would be written in TOML.
    pub value: String,
    /// The rule it breaks, phrased as what the value must be.
    pub rule: String,
}

impl InvalidValue {
    fn new(field: &str, value: impl fmt::Display, rule: impl Into<String>) -> InvalidValue {
        InvalidValue {
            field: field.to_string(),
            value: value.to_string(),
            rule: rule.into(),
        }
    }
}

/// Fails with `rule` unless `holds`.
fn check(
    holds: bool,
    field: &str,
    value: impl fmt::Display,
    rule: impl FnOnce() -> String,
) -> Result<(), InvalidValue> {
    if holds {
        Ok(())
    } else {
        Err(InvalidValue::new(field, value, rule()))
    }
}

/// A string value as TOML writes it (`"YELLOW"`).
fn quoted(text: &str) -> String {
    format!("{text:?}")
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
            .map_err(|error| parse_error(text, source_name, error))?;
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
        self.leds.validate()
    }
}

/// Turns a deserialization error into one message naming the field and where it is.
fn parse_error(
    text: &str,
    source_name: &str,
    error: serde_path_to_error::Error<toml::de::Error>,
) -> ConfigError {
    let path = error.path().to_string();
    // serde_path_to_error writes "." for the top level (syntax errors).
    let field = (path != ".").then_some(path);
    let inner = error.into_inner();
    let line_column = inner.span().map(|span| line_column_at(text, span.start));
    // Syntax errors come as several lines; the CLI prints one.
    let detail = inner.message().trim_end().replace('\n', "; ");
    let message = match &field {
        None => detail,
        Some(field) => match unknown_field_rest(&detail, field) {
            // The path ends with the unknown key itself: say it once, in full.
            Some(rest) => format!("unknown field `{field}`{rest}"),
            None => format!("{field}: {detail}"),
        },
    };
    ConfigError::Parse {
        source_name: source_name.to_string(),
        line_column,
        field,
        message,
    }
}

/// For serde's "unknown field `key`, expected ..." about the last key of `field`, the text
/// after the key.
fn unknown_field_rest<'m>(detail: &'m str, field: &str) -> Option<&'m str> {
    let rest = detail.strip_prefix("unknown field `")?;
    let (key, rest) = rest.split_once('`')?;
    let last_key = field.rsplit('.').next()?;
    (key == last_key).then_some(rest)
}

/// 1-based line and column (in characters) of a byte offset.
fn line_column_at(text: &str, offset: usize) -> (usize, usize) {
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |newline| newline + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}

impl Timing {
    /// Checks the timing rules. The heartbeat period comes first: the others are measured in it.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        let period_ms = self.heartbeat_period_ms;
        check(
            HEARTBEAT_PERIOD_MS_RANGE.contains(&period_ms),
            "timing.heartbeat_period_ms",
            period_ms,
            || {
                format!(
                    "must be between {} and {} ms",
                    HEARTBEAT_PERIOD_MS_RANGE.start(),
                    HEARTBEAT_PERIOD_MS_RANGE.end()
                )
            },
        )?;
        for (field, value_ms) in [
            ("timing.peer_deadline_ms", self.peer_deadline_ms),
            ("timing.init_window_ms", self.init_window_ms),
            ("timing.command_deadline_ms", self.command_deadline_ms),
            ("timing.command_republish_ms", self.command_republish_ms),
        ] {
            check(value_ms <= DURATION_MS_MAX, field, value_ms, || {
                format!("must be at most {DURATION_MS_MAX} ms (one hour)")
            })?;
        }
        // Fewer than two periods would declare a peer lost after a single late heartbeat.
        check(
            whole_periods(self.peer_deadline_ms, period_ms)
                && self.peer_deadline_ms >= 2 * period_ms,
            "timing.peer_deadline_ms",
            self.peer_deadline_ms,
            || {
                format!(
                    "must be a whole number of heartbeat periods ({period_ms} ms) and at least 2 of them"
                )
            },
        )?;
        // A window shorter than the deadline could close before a slow peer is even missed;
        // the checked model uses a window as long as the deadline (2 rounds each).
        check(
            whole_periods(self.init_window_ms, period_ms)
                && self.init_window_ms >= self.peer_deadline_ms,
            "timing.init_window_ms",
            self.init_window_ms,
            || {
                format!(
                    "must be a whole number of heartbeat periods ({period_ms} ms) and at least \
                     timing.peer_deadline_ms ({} ms)",
                    self.peer_deadline_ms
                )
            },
        )?;
        check(
            self.command_deadline_ms >= 1,
            "timing.command_deadline_ms",
            self.command_deadline_ms,
            || "must be at least 1 ms".to_string(),
        )?;
        // Republishing no faster than the deadline would let the command topic miss it.
        check(
            self.command_republish_ms >= 1 && self.command_republish_ms < self.command_deadline_ms,
            "timing.command_republish_ms",
            self.command_republish_ms,
            || {
                format!(
                    "must be at least 1 ms and less than timing.command_deadline_ms ({} ms)",
                    self.command_deadline_ms
                )
            },
        )
    }

    /// Rounds without a heartbeat after which a peer is lost (`peer_deadline / period`).
    pub fn dead_after_rounds(&self) -> u32 {
        rounds(self.peer_deadline_ms, self.heartbeat_period_ms)
    }

    /// Rounds without a new controller after which the initialization window closes
    /// (`init_window / period`).
    pub fn window_rounds(&self) -> u32 {
        rounds(self.init_window_ms, self.heartbeat_period_ms)
    }

    /// Rounds a minority vote is tolerated before its voter is marked FAILED: one more than
    /// `dead_after_rounds`, so every voter has noticed the same loss first (the model's rule).
    pub fn minority_grace_rounds(&self) -> u32 {
        self.dead_after_rounds().saturating_add(1)
    }

    pub fn heartbeat_period(&self) -> Duration {
        Duration::from_millis(self.heartbeat_period_ms)
    }

    pub fn peer_deadline(&self) -> Duration {
        Duration::from_millis(self.peer_deadline_ms)
    }

    pub fn init_window(&self) -> Duration {
        Duration::from_millis(self.init_window_ms)
    }

    pub fn command_deadline(&self) -> Duration {
        Duration::from_millis(self.command_deadline_ms)
    }

    pub fn command_republish(&self) -> Duration {
        Duration::from_millis(self.command_republish_ms)
    }
}

/// Whether a duration is a whole number of periods (`period_ms` > 0).
fn whole_periods(duration_ms: u64, period_ms: u64) -> bool {
    duration_ms.checked_rem(period_ms) == Some(0)
}

/// Whole periods in a duration; validation keeps both in range, so the fallbacks never apply.
fn rounds(duration_ms: u64, period_ms: u64) -> u32 {
    let count = duration_ms.checked_div(period_ms).unwrap_or(0);
    u32::try_from(count).unwrap_or(u32::MAX)
}

impl Dds {
    /// The topic fields with their dotted paths, in file order.
    fn topics(&self) -> [(&'static str, &str); 6] {
        [
            ("dds.heartbeat_topic", &self.heartbeat_topic),
            ("dds.vote_topic", &self.vote_topic),
            ("dds.controller_alarm_topic", &self.controller_alarm_topic),
            ("dds.network_alarm_topic", &self.network_alarm_topic),
            ("dds.command_topic", &self.command_topic),
            ("dds.camera_topic", &self.camera_topic),
        ]
    }

    pub fn validate(&self) -> Result<(), InvalidValue> {
        check(self.domain <= DOMAIN_MAX, "dds.domain", self.domain, || {
            format!("must be at most {DOMAIN_MAX} (higher domains' RTPS ports pass 65535)")
        })?;
        let topics = self.topics();
        for (field, name) in topics {
            check(
                !name.is_empty() && !name.chars().any(char::is_whitespace),
                field,
                quoted(name),
                || "must be a non-empty topic name without whitespace".to_string(),
            )?;
        }
        // Two kinds of sample on one topic name would not match in DDS.
        for (index, (field, name)) in topics.iter().enumerate() {
            if let Some((other_field, _)) = topics[..index].iter().find(|(_, other)| other == name)
            {
                return Err(InvalidValue::new(
                    field,
                    quoted(name),
                    format!("must differ from {other_field}"),
                ));
            }
        }
        check(
            is_ros_namespace(&self.ros_namespace),
            "dds.ros_namespace",
            quoted(&self.ros_namespace),
            || {
                "must be an absolute ROS 2 namespace: `/` or `/`-separated names of letters, \
                 digits and `_`, each not starting with a digit"
                    .to_string()
            },
        )
    }
}

/// ROS 2's rule for a fully qualified namespace (`/`, `/rl`, `/robots/rl_1`).
fn is_ros_namespace(namespace: &str) -> bool {
    let Some(rest) = namespace.strip_prefix('/') else {
        return false;
    };
    rest.is_empty()
        || rest.split('/').all(|token| {
            token
                .chars()
                .next()
                .is_some_and(|first| first.is_ascii_alphabetic() || first == '_')
                && token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        })
}

impl Tracker {
    pub fn validate(&self) -> Result<(), InvalidValue> {
        // The colour goes into a content filter expression: letters only keeps it a literal.
        check(
            !self.color.is_empty() && self.color.chars().all(|c| c.is_ascii_uppercase()),
            "tracker.color",
            quoted(&self.color),
            || "must be a colour name in uppercase letters (A-Z), like \"YELLOW\"".to_string(),
        )?;
        check(
            SERVO_FREQUENCY_HZ_RANGE.contains(&self.servo_frequency_hz),
            "tracker.servo_frequency_hz",
            self.servo_frequency_hz,
            || {
                format!(
                    "must be between {} and {} Hz",
                    SERVO_FREQUENCY_HZ_RANGE.start(),
                    SERVO_FREQUENCY_HZ_RANGE.end()
                )
            },
        )
    }
}

impl Leds {
    pub fn validate(&self) -> Result<(), InvalidValue> {
        check(
            !self.chip.is_empty(),
            "leds.chip",
            quoted(&self.chip),
            || "must name a GPIO character device, like \"/dev/gpiochip0\"".to_string(),
        )?;
        // One line driven by two LEDs would light neither correctly.
        let pins: Vec<(usize, u32)> = self
            .pins
            .iter()
            .enumerate()
            .flat_map(|(led, pair)| pair.iter().map(move |pin| (led, *pin)))
            .collect();
        for (index, (led, pin)) in pins.iter().enumerate() {
            if let Some((other_led, _)) = pins[..index].iter().find(|(_, other)| other == pin) {
                let place = if other_led == led {
                    format!("twice by LED{}", led + 1)
                } else {
                    format!("by LED{} and LED{}", other_led + 1, led + 1)
                };
                return Err(InvalidValue::new(
                    "leds.pins",
                    format!("{:?}", self.pins),
                    format!("pins must be distinct, but pin {pin} is used {place}"),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Config, ConfigError> {
        Config::from_toml_str(text, "rl.toml")
    }

    /// The error for `text`, which must fail, as the CLI would print it.
    fn error_of(text: &str) -> (Option<String>, String) {
        let error = parse(text).unwrap_err();
        (error.field().map(str::to_string), error.to_string())
    }

    #[test]
    fn defaults_are_valid_and_match_the_paper() {
        let config = Config::default();
        config.validate().unwrap();
        assert_eq!(config.timing.heartbeat_period_ms, 250);
        assert_eq!(config.timing.dead_after_rounds(), 2);
        assert_eq!(config.timing.window_rounds(), 40);
        assert_eq!(config.timing.minority_grace_rounds(), 3);
        assert_eq!(config.timing.command_deadline(), Duration::from_millis(100));
        assert_eq!(config.dds.domain, 53);
    }

    #[test]
    fn empty_file_is_the_default() {
        assert_eq!(parse("").unwrap(), Config::default());
        assert_eq!(parse("# nothing\n\n").unwrap(), Config::default());
        assert_eq!(parse("[timing]\n[leds]\n").unwrap(), Config::default());
    }

    #[test]
    fn partial_file_keeps_other_defaults() {
        let config =
            parse("[timing]\nheartbeat_period_ms = 100\npeer_deadline_ms = 300\n").unwrap();
        assert_eq!(config.timing.heartbeat_period_ms, 100);
        assert_eq!(config.timing.peer_deadline_ms, 300);
        assert_eq!(config.timing.init_window_ms, 10_000);
        assert_eq!(config.timing.dead_after_rounds(), 3);
        assert_eq!(config.timing.window_rounds(), 100);
        assert_eq!(config.timing.minority_grace_rounds(), 4);
        assert_eq!(config.tracker, Tracker::default());
    }

    #[test]
    fn round_trip_through_toml() {
        let mut config = Config::default();
        config.timing.heartbeat_period_ms = 100;
        config.timing.peer_deadline_ms = 400;
        config.dds.domain = 7;
        config.dds.camera_topic = "Square".into();
        config.tracker.color = "RED".into();
        config.tracker.aperiodic = AperiodicPolicy::PrimaryOnly;
        config.leds.backend = LedBackend::Gpio;
        config.leds.pins = [[1, 2], [3, 4], [5, 6], [7, 8]];
        let text = config.to_toml_string().unwrap();
        assert_eq!(parse(&text).unwrap(), config);
        let defaults = Config::default().to_toml_string().unwrap();
        assert_eq!(parse(&defaults).unwrap(), Config::default());
    }

    #[test]
    fn example_file_is_the_defaults() {
        let text = include_str!("../rl.toml.example");
        assert_eq!(parse(text).unwrap(), Config::default());
        // Uncommenting every field must still give the defaults: the example says them all.
        let uncommented: String = text
            .lines()
            .map(|line| {
                line.strip_prefix("# ")
                    .filter(|setting| {
                        setting.split_once(" = ").is_some_and(|(key, _)| {
                            key.chars().all(|c| c.is_ascii_lowercase() || c == '_')
                        })
                    })
                    .unwrap_or(line)
            })
            .collect::<Vec<_>>()
            .join("\n");
        assert_eq!(parse(&uncommented).unwrap(), Config::default());
        let default_text = Config::default().to_toml_string().unwrap();
        for line in default_text.lines().filter(|l| l.contains(" = ")) {
            let key = line.split(" = ").next().unwrap();
            assert!(
                uncommented
                    .lines()
                    .any(|l| l.starts_with(&format!("{key} = "))),
                "rl.toml.example lacks {key}"
            );
        }
    }

    #[test]
    fn load_reads_a_file_and_names_it() {
        let dir = std::env::temp_dir().join(format!("rl-config-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rl.toml");
        std::fs::write(&path, "[dds]\ndomain = 9\n").unwrap();
        assert_eq!(Config::load(&path).unwrap().dds.domain, 9);
        std::fs::write(&path, "[dds]\ndomain = 999\n").unwrap();
        let message = Config::load(&path).unwrap_err().to_string();
        assert!(message.starts_with(&format!("{}: dds.domain = 999: ", path.display())));
        let missing = dir.join("missing.toml");
        let error = Config::load(&missing).unwrap_err();
        assert!(matches!(error, ConfigError::Read { .. }));
        assert!(error
            .to_string()
            .starts_with(&format!("{}: cannot read", missing.display())));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_brief_example_message() {
        let (field, message) = error_of("[timing]\npeer_deadline_ms = 300\n");
        assert_eq!(field.as_deref(), Some("timing.peer_deadline_ms"));
        assert_eq!(
            message,
            "rl.toml: timing.peer_deadline_ms = 300: must be a whole number of heartbeat \
             periods (250 ms) and at least 2 of them"
        );
    }

    #[test]
    fn parse_errors_name_the_field_and_place() {
        let (field, message) = error_of("timin = 3\n");
        assert_eq!(field.as_deref(), Some("timin"));
        assert_eq!(
            message,
            "rl.toml:1:1: unknown field `timin`, expected one of `timing`, `dds`, `tracker`, `leds`"
        );

        let (field, message) = error_of("[timing]\nheartbeat = 250\n");
        assert_eq!(field.as_deref(), Some("timing.heartbeat"));
        assert!(
            message.starts_with("rl.toml:2:1: unknown field `timing.heartbeat`, expected one of"),
            "{message}"
        );

        let (field, message) = error_of("[timin]\nheartbeat_period_ms = 250\n");
        assert_eq!(field.as_deref(), Some("timin"));
        assert!(
            message.starts_with("rl.toml:1:2: unknown field `timin`"),
            "{message}"
        );

        let (field, message) = error_of("[timing]\nheartbeat_period_ms = \"fast\"\n");
        assert_eq!(field.as_deref(), Some("timing.heartbeat_period_ms"));
        assert!(
            message.starts_with("rl.toml:2:23: timing.heartbeat_period_ms: invalid type: string"),
            "{message}"
        );

        let (field, message) = error_of("[dds]\ndomain = -1\n");
        assert_eq!(field.as_deref(), Some("dds.domain"));
        assert!(
            message.starts_with("rl.toml:2:10: dds.domain: "),
            "{message}"
        );

        let (field, message) = error_of("[tracker]\naperiodic = \"sometimes\"\n");
        assert_eq!(field.as_deref(), Some("tracker.aperiodic"));
        assert!(message.contains("unknown variant `sometimes`"), "{message}");

        let (field, message) = error_of("[leds]\npins = [[1, 2], [3, 4], [5, 6]]\n");
        assert_eq!(field.as_deref(), Some("leds.pins"));
        assert!(message.starts_with("rl.toml:2:8: leds.pins: "), "{message}");

        let (field, message) = error_of("[timing\n");
        assert_eq!(field, None);
        assert_eq!(
            message,
            "rl.toml:1:8: invalid table header; expected `.`, `]`"
        );
    }

    /// Each rule, broken once: (file text, field named, words the message must contain).
    const RULE_BREAKS: &[(&str, &str, &str)] = &[
        (
            "[timing]\nheartbeat_period_ms = 9",
            "timing.heartbeat_period_ms",
            "between 10 and 10000",
        ),
        (
            "[timing]\nheartbeat_period_ms = 10001",
            "timing.heartbeat_period_ms",
            "between 10 and 10000",
        ),
        (
            "[timing]\npeer_deadline_ms = 250",
            "timing.peer_deadline_ms",
            "at least 2 of them",
        ),
        (
            "[timing]\npeer_deadline_ms = 600",
            "timing.peer_deadline_ms",
            "whole number",
        ),
        (
            "[timing]\npeer_deadline_ms = 0",
            "timing.peer_deadline_ms",
            "at least 2",
        ),
        (
            "[timing]\npeer_deadline_ms = 3600250",
            "timing.peer_deadline_ms",
            "at most 3600000",
        ),
        (
            "[timing]\ninit_window_ms = 10100",
            "timing.init_window_ms",
            "whole number",
        ),
        (
            "[timing]\ninit_window_ms = 250",
            "timing.init_window_ms",
            "at least timing.peer_deadline_ms (500 ms)",
        ),
        (
            "[timing]\ncommand_deadline_ms = 0\ncommand_republish_ms = 0",
            "timing.command_deadline_ms",
            "at least 1",
        ),
        (
            "[timing]\ncommand_republish_ms = 0",
            "timing.command_republish_ms",
            "at least 1 ms",
        ),
        (
            "[timing]\ncommand_republish_ms = 100",
            "timing.command_republish_ms",
            "less than timing.command_deadline_ms (100 ms)",
        ),
        (
            "[timing]\ncommand_deadline_ms = 10",
            "timing.command_republish_ms",
            "less than timing.command_deadline_ms (10 ms)",
        ),
        ("[dds]\ndomain = 233", "dds.domain", "at most 232"),
        (
            "[dds]\nheartbeat_topic = \"\"",
            "dds.heartbeat_topic",
            "non-empty",
        ),
        (
            "[dds]\nvote_topic = \"rl vote\"",
            "dds.vote_topic",
            "without whitespace",
        ),
        (
            "[dds]\ncontroller_alarm_topic = \"a\\tb\"",
            "dds.controller_alarm_topic",
            "without whitespace",
        ),
        (
            "[dds]\nnetwork_alarm_topic = \" \"",
            "dds.network_alarm_topic",
            "non-empty",
        ),
        (
            "[dds]\ncommand_topic = \"\"",
            "dds.command_topic",
            "non-empty",
        ),
        (
            "[dds]\ncamera_topic = \"Circle \"",
            "dds.camera_topic",
            "without whitespace",
        ),
        (
            "[dds]\ncamera_topic = \"rl/vote\"",
            "dds.camera_topic",
            "must differ from dds.vote_topic",
        ),
        (
            "[dds]\nros_namespace = \"rl\"",
            "dds.ros_namespace",
            "absolute ROS 2 namespace",
        ),
        (
            "[dds]\nros_namespace = \"/rl/\"",
            "dds.ros_namespace",
            "ROS 2 namespace",
        ),
        (
            "[dds]\nros_namespace = \"/1rl\"",
            "dds.ros_namespace",
            "ROS 2 namespace",
        ),
        (
            "[tracker]\ncolor = \"\"",
            "tracker.color",
            "uppercase letters",
        ),
        (
            "[tracker]\ncolor = \"yellow\"",
            "tracker.color",
            "uppercase letters",
        ),
        (
            "[tracker]\ncolor = \"RED' OR 1=1\"",
            "tracker.color",
            "uppercase letters",
        ),
        (
            "[tracker]\nservo_frequency_hz = 0",
            "tracker.servo_frequency_hz",
            "between 1 and 1000",
        ),
        (
            "[tracker]\nservo_frequency_hz = 1001",
            "tracker.servo_frequency_hz",
            "between 1 and 1000",
        ),
        ("[leds]\nchip = \"\"", "leds.chip", "GPIO character device"),
        (
            "[leds]\npins = [[1, 2], [3, 4], [5, 6], [7, 1]]",
            "leds.pins",
            "pin 1 is used by LED1 and LED4",
        ),
        (
            "[leds]\npins = [[1, 2], [3, 3], [5, 6], [7, 8]]",
            "leds.pins",
            "pin 3 is used twice by LED2",
        ),
    ];

    #[test]
    fn every_rule_is_enforced_with_the_field_named() {
        for (text, field, words) in RULE_BREAKS {
            let error = parse(text).unwrap_err();
            assert!(
                matches!(error, ConfigError::Invalid { .. }),
                "{text}: {error}"
            );
            assert_eq!(error.field(), Some(*field), "{text}");
            let message = error.to_string();
            assert!(
                message.starts_with(&format!("rl.toml: {field} = ")),
                "{message}"
            );
            assert!(message.contains(words), "{text}: {message} lacks {words:?}");
        }
    }

    #[test]
    fn boundary_values_are_accepted() {
        for text in [
            "[timing]\nheartbeat_period_ms = 10\npeer_deadline_ms = 20\ninit_window_ms = 30\n\
             command_deadline_ms = 2\ncommand_republish_ms = 1",
            "[timing]\nheartbeat_period_ms = 10000\npeer_deadline_ms = 20000\ninit_window_ms = 30000",
            "[timing]\npeer_deadline_ms = 3599750\ninit_window_ms = 3600000",
            "[dds]\ndomain = 232",
            "[dds]\ndomain = 0\nros_namespace = \"/\"",
            "[dds]\nros_namespace = \"/robots/_rl_1\"",
            "[tracker]\ncolor = \"Y\"\nservo_frequency_hz = 1",
            "[tracker]\nservo_frequency_hz = 1000",
        ] {
            if let Err(error) = parse(text) {
                panic!("{text:?} rejected: {error}");
            }
        }
        let config =
            parse("[timing]\npeer_deadline_ms = 3500000\ninit_window_ms = 3600000").unwrap();
        assert_eq!(config.timing.dead_after_rounds(), 14_000);
        assert_eq!(config.timing.window_rounds(), 14_400);
    }
}
