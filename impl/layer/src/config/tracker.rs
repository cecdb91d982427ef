//! The `[tracker]` section: the application's colour filter, servo frequency and how it keeps
//! an aperiodic command topic within its deadline.

use super::error::{check, quoted, InvalidValue};
use serde::{Deserialize, Serialize};

/// How a controller keeps a lower-strength writer from leaking through on an aperiodic
/// command topic (paper, "Exclusive Ownership on aperiodic topics").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AperiodicPolicy {
    /// Every role holder re-publishes its last command before the deadline (default).
    Republish,
    /// Only the Primary writes commands; nothing is re-published.
    PrimaryOnly,
    /// The application writes at least once per command deadline itself: every role holder
    /// writes what it writes and RL re-publishes nothing.
    Periodic,
}

/// Which implementation of the tracker's control law a controller runs. Both compute the
/// original Pixytracker's law; running different ones on different controllers is the paper's
/// "diverse implementations": a bug in one is outvoted by the others' outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ControlLaw {
    /// The original's fixed-point integer arithmetic (the default).
    #[default]
    Integer,
    /// A second implementation in binary floating point, written apart from the first.
    Float,
}

/// The tracker application.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Tracker {
    /// Only circles of this colour are tracked (the paper: YELLOW).
    pub color: String,
    /// How a lower-strength writer is kept from leaking through on the aperiodic command topic.
    pub aperiodic: AperiodicPolicy,
    /// Servo frequency written in every command (Hz).
    pub servo_frequency_hz: u16,
    /// The implementation of the control law this controller runs.
    pub law: ControlLaw,
    /// N of the cross-check (crate::cross_check): the camera frames of one life at which this
    /// controller may be the odd one out of three before it reports a local fault and leaves;
    /// 0: it only counts them.
    pub odd_limit: u32,
}

impl Default for Tracker {
    fn default() -> Tracker {
        Tracker {
            color: "YELLOW".into(),
            aperiodic: AperiodicPolicy::Republish,
            servo_frequency_hz: 60,
            law: ControlLaw::Integer,
            odd_limit: crate::cross_check::ODD_LIMIT_DEFAULT,
        }
    }
}

/// The largest `tracker.odd_limit`: beyond it an exclusive reader takes that many wrong
/// commands from a wrong Primary (K = N), seconds of camera frames.
pub const ODD_LIMIT_MAX: u32 = 100;

/// Servo frequencies the gimbal can be asked for.
pub const SERVO_FREQUENCY_HZ_RANGE: std::ops::RangeInclusive<u16> = 1..=1000;

impl Tracker {
    /// Checks that the colour is uppercase letters A-Z, the servo frequency is 1..=1000 Hz and
    /// the odd limit at most `ODD_LIMIT_MAX` (100).
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
        )?;
        check(
            self.odd_limit <= ODD_LIMIT_MAX,
            "tracker.odd_limit",
            self.odd_limit,
            || format!("must be at most {ODD_LIMIT_MAX} (0: the cross-check only counts)"),
        )
    }
}
