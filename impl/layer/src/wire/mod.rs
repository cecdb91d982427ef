//! DDS sample types: what travels on each topic, byte for byte.
//!
//! Every type here is serialized as classic little-endian CDR (RustDDS's
//! `CDRSerializerAdapter`), so field order is wire order. Two topics are shared with the
//! original camera application and match its IDL exactly ([`ShapeTypeExtended`] on `Circle`,
//! [`ServoControl`] on `pixy/servo_control`). The RL's own topics ([`HeartbeatSample`],
//! [`VoteSample`], [`AlarmSample`], [`NetworkHeartbeatSample`], [`NetworkAlarmSample`]) are
//! flat structs of integers and booleans (and the alarm's cause, a bounded string): no `Option` on the wire, absence is a `valid` flag or a 0 code, so any DDS tool with
//! the IDL below can read them.
//!
//! Decoding a sample of an RL topic validates it and returns a [`WireError`] naming the bad
//! field; a malformed sample never panics, the reader drops it with a warning. Encoding is
//! infallible, and [`crate::dds`] re-checks every encoded sample with the decoder before
//! writing, so RL never publishes what it would reject.
//!
//! One file per sample family (`camera`, `heartbeat`, `vote`, `alarm`, `network`, `voted`: one
//! controller's answer on a voted topic, [`VotedSample`]), with `codes` (the enumerations' wire
//! codes) and `assignment` (role slots) shared between them.
//!
//! The IDL of every topic type, with the codes and the topics' QoS, is `docs/rl.idl`: what a
//! second implementation compiles against. `impl/tests/interop.rs` reads RL's heartbeats,
//! votes and controller alarms with Cyclone DDS through types written from it: a member the
//! IDL misplaces or mistypes shifts the ones after it, and that test fails. Change both
//! together.

mod alarm;
mod assignment;
mod camera;
mod codes;
mod heartbeat;
mod network;
mod plain;
#[cfg(test)]
mod proptests;
#[cfg(test)]
mod tests;
mod vote;
mod voted;

pub use self::alarm::{AlarmSample, ControllerAlarm, ALARM_TYPE_NAME};
pub use self::assignment::{HolderSlot, WireAssignment};
pub use self::camera::{
    ServoControl, ShapeFillKind, ShapeTypeExtended, SERVO_CONTROL_TYPE_NAME, SHAPE_TYPE_NAME,
};
pub use self::codes::{
    phase_code, reason_code, role_code, PHASE_FAILED, PHASE_INITIALIZING, PHASE_STEADY,
    PHASE_VOTING, REASON_FAILED, REASON_IMPOSTOR, REASON_INPUT_DISAGREES, REASON_LAW_DISAGREES,
    REASON_LOST, REASON_STALLED, ROLE_NONE, ROLE_PRIMARY, ROLE_SECONDARY, ROLE_TERTIARY,
    STRENGTH_NONE,
};
pub use self::heartbeat::{sender_clock_ms, HeartbeatSample, HEARTBEAT_TYPE_NAME};
pub use self::network::{
    fit_cause, Certainty, NetworkAlarm, NetworkAlarmKey, NetworkAlarmSample,
    NetworkHeartbeatSample, CAUSE_MAX_BYTES, LINK_FAIL, LINK_GOOD, LINK_UNKNOWN,
    NETWORK_ALARM_TYPE_NAME, NETWORK_COUNT, NETWORK_HEARTBEAT_TYPE_NAME,
};
pub use self::plain::Plain;
pub use self::vote::{VoteSample, VOTE_TYPE_NAME};
pub use self::voted::{
    input_digest, RawAnswer, Voted, VotedSample, VotedServoControl, VOTED_SERVO_CONTROL_TYPE_NAME,
};

use serde::{Deserialize, Serialize};

/// A sample that failed validation: which field, and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct WireError {
    /// The field path, e.g. `heartbeat.phase` or `vote.vote`.
    pub field: &'static str,
    /// What is wrong with its value, in words (e.g. `unknown phase code 9`).
    pub reason: String,
}

impl WireError {
    fn new(field: &'static str, reason: impl Into<String>) -> WireError {
        WireError {
            field,
            reason: reason.into(),
        }
    }
}

/// A sample type of an RL topic: how it is validated into the value the program uses, and how
/// that value is encoded.
pub trait WireSample: Sized {
    /// The validated value.
    type Value;
    /// DDS type name registered for the topic.
    const TYPE_NAME: &'static str;
    /// Validates the sample into its value, or names the bad field (the reader drops it).
    fn decode(self) -> Result<Self::Value, WireError>;
    /// The sample carrying `value`; never fails (a heartbeat's `sent_ms` is stamped here).
    fn encode(value: &Self::Value) -> Self;
    /// When the sender wrote the sample, on the sender's own monotonic clock, for the types
    /// that carry it (the heartbeat: a receiver tells a late one by it).
    fn sent_ms(&self) -> Option<u64> {
        None
    }
    /// The sample without what encoding stamps and decoding does not read (the heartbeat's
    /// `sent_ms`): two encodings of one value are equal unstamped.
    fn unstamped(self) -> Self {
        self
    }
}

/// `std_msgs/msg/String`: the controller's status line on the ROS 2 topic `status`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RosString {
    /// The controller's status, as one line of JSON.
    pub data: String,
}
