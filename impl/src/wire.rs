//! DDS sample types: what travels on each topic, byte for byte.
//!
//! Every type here is serialized as classic little-endian CDR (RustDDS's
//! `CDRSerializerAdapter`), so field order is wire order. Two topics are shared with the
//! original camera application and match its IDL exactly ([`ShapeTypeExtended`] on `Circle`,
//! [`ServoControl`] on `pixy/servo_control`). The RL's own topics ([`HeartbeatSample`],
//! [`VoteSample`], [`AlarmSample`], [`NetworkAlarmSample`]) are flat structs of integers and
//! booleans: no `Option` on the wire, absence is a `valid` flag or a 0 code, so any DDS tool with
//! the IDL below can read them.
//!
//! Decoding a sample of an RL topic validates it and returns a [`WireError`] naming the bad
//! field; a malformed sample never panics, the reader drops it with a warning. Encoding is
//! infallible, and [`crate::dds`] re-checks every encoded sample with the decoder before
//! writing, so RL never publishes what it would reject.
//!
//! Equivalent IDL of the RL topics (codes in the constants below):
//! ```text
//! struct HolderSlot { octet id; unsigned long long incarnation; };   // id 0 = empty slot
//! struct WireAssignment { HolderSlot slots[3]; };                   // Primary, Secondary, Tertiary
//! struct HeartbeatSample { @key octet from_id; unsigned long long incarnation; octet phase;
//!   octet role; octet strength; boolean agreed_valid; WireAssignment agreed;
//!   boolean vote_valid; WireAssignment vote; };
//! struct VoteSample { @key octet from_id; unsigned long long incarnation; boolean vote_valid;
//!   WireAssignment vote; };
//! struct AlarmSample { octet reporter_id; unsigned long long reporter_incarnation;
//!   octet about_id; boolean about_incarnation_valid; unsigned long long about_incarnation;
//!   octet reason; boolean raised; };
//! struct NetworkAlarmSample { octet reporter_id; octet network; octet peer_id; boolean raised; };
//! ```

use crate::core::types::{
    AlarmReason, Assignment, ControllerId, Holder, Incarnation, Phase, Role, VoteRecord, ROLE_COUNT,
};
use crate::core::Heartbeat;
use rustdds::Keyed;
use serde::{Deserialize, Serialize};

/// A sample that failed validation: which field, and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct WireError {
    /// The field path, e.g. `heartbeat.phase` or `vote.vote`.
    pub field: &'static str,
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
    fn decode(self) -> Result<Self::Value, WireError>;
    fn encode(value: &Self::Value) -> Self;
}

// ---------------------------------------------------------------------------------------------
// Topics shared with the camera application.

/// DDS type name of the camera's `Circle` topic.
pub const SHAPE_TYPE_NAME: &str = "ShapeTypeExtended";
/// DDS type name of the command topic.
pub const SERVO_CONTROL_TYPE_NAME: &str = "ServoControl";

/// `enum ShapeFillKind` of the shapes demo; CDR encodes it as a u32 (declaration order).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ShapeFillKind {
    #[default]
    SolidFill,
    TransparentFill,
    HorizontalHatchFill,
    VerticalHatchFill,
}

/// A shape seen by the camera (`ShapeTypeExtended`, keyed by colour).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeTypeExtended {
    pub color: String,
    pub x: i32,
    pub y: i32,
    pub shapesize: i32,
    pub fill_kind: ShapeFillKind,
    pub angle: f32,
}

impl Keyed for ShapeTypeExtended {
    type K = String;
    fn key(&self) -> String {
        self.color.clone()
    }
}

impl WireSample for ShapeTypeExtended {
    type Value = ShapeTypeExtended;
    const TYPE_NAME: &'static str = SHAPE_TYPE_NAME;
    /// Any shape is acceptable input; the tracker filters by colour.
    fn decode(self) -> Result<ShapeTypeExtended, WireError> {
        Ok(self)
    }
    fn encode(value: &ShapeTypeExtended) -> ShapeTypeExtended {
        value.clone()
    }
}

/// A gimbal command (`ServoControl`, unkeyed): servo positions 0..1000 and the servo frequency.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ServoControl {
    pub pan: u16,
    pub tilt: u16,
    pub frequency: u16,
}

impl WireSample for ServoControl {
    type Value = ServoControl;
    const TYPE_NAME: &'static str = SERVO_CONTROL_TYPE_NAME;
    /// The camera accepts any value (it clamps), so neither does RL reject one.
    fn decode(self) -> Result<ServoControl, WireError> {
        Ok(self)
    }
    fn encode(value: &ServoControl) -> ServoControl {
        *value
    }
}

// ---------------------------------------------------------------------------------------------
// Codes of the RL topics. 0 never means a valid phase or reason, so an all-zero sample is
// rejected rather than read as "initializing".

pub const PHASE_INITIALIZING: u8 = 1;
pub const PHASE_VOTING: u8 = 2;
pub const PHASE_STEADY: u8 = 3;
pub const PHASE_FAILED: u8 = 4;

/// Role codes: 0 = no role.
pub const ROLE_NONE: u8 = 0;
pub const ROLE_PRIMARY: u8 = 1;
pub const ROLE_SECONDARY: u8 = 2;
pub const ROLE_TERTIARY: u8 = 3;

pub const REASON_LOST: u8 = 1;
pub const REASON_FAILED: u8 = 2;

/// Strength 0 on the wire: the controller does not command.
pub const STRENGTH_NONE: u8 = 0;

pub fn phase_code(phase: Phase) -> u8 {
    match phase {
        Phase::Initializing => PHASE_INITIALIZING,
        Phase::Voting => PHASE_VOTING,
        Phase::Steady => PHASE_STEADY,
        Phase::Failed => PHASE_FAILED,
    }
}

fn phase_from_code(field: &'static str, code: u8) -> Result<Phase, WireError> {
    match code {
        PHASE_INITIALIZING => Ok(Phase::Initializing),
        PHASE_VOTING => Ok(Phase::Voting),
        PHASE_STEADY => Ok(Phase::Steady),
        PHASE_FAILED => Ok(Phase::Failed),
        other => Err(WireError::new(field, format!("unknown phase code {other}"))),
    }
}

pub fn role_code(role: Option<Role>) -> u8 {
    match role {
        None => ROLE_NONE,
        Some(Role::Primary) => ROLE_PRIMARY,
        Some(Role::Secondary) => ROLE_SECONDARY,
        Some(Role::Tertiary) => ROLE_TERTIARY,
    }
}

fn role_from_code(field: &'static str, code: u8) -> Result<Option<Role>, WireError> {
    match code {
        ROLE_NONE => Ok(None),
        ROLE_PRIMARY => Ok(Some(Role::Primary)),
        ROLE_SECONDARY => Ok(Some(Role::Secondary)),
        ROLE_TERTIARY => Ok(Some(Role::Tertiary)),
        other => Err(WireError::new(field, format!("unknown role code {other}"))),
    }
}

pub fn reason_code(reason: AlarmReason) -> u8 {
    match reason {
        AlarmReason::Lost => REASON_LOST,
        AlarmReason::Failed => REASON_FAILED,
    }
}

fn reason_from_code(field: &'static str, code: u8) -> Result<AlarmReason, WireError> {
    match code {
        REASON_LOST => Ok(AlarmReason::Lost),
        REASON_FAILED => Ok(AlarmReason::Failed),
        other => Err(WireError::new(
            field,
            format!("unknown alarm reason code {other}"),
        )),
    }
}

fn controller_id(field: &'static str, id: u8) -> Result<ControllerId, WireError> {
    if id == 0 {
        Err(WireError::new(field, "0 is not a controller id"))
    } else {
        Ok(id)
    }
}

// ---------------------------------------------------------------------------------------------
// Assignments.

/// One role slot of an assignment: `id` 0 = empty (then `incarnation` must be 0 too).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct HolderSlot {
    pub id: u8,
    pub incarnation: u64,
}

/// Primary, Secondary, Tertiary holders, in that order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct WireAssignment {
    pub slots: [HolderSlot; ROLE_COUNT],
}

impl WireAssignment {
    pub fn encode(assignment: &Assignment) -> WireAssignment {
        let mut slots = [HolderSlot::default(); ROLE_COUNT];
        for (slot, holder) in slots.iter_mut().zip(assignment.0.iter()) {
            if let Some(holder) = holder {
                *slot = HolderSlot {
                    id: holder.id,
                    incarnation: holder.incarnation,
                };
            }
        }
        WireAssignment { slots }
    }

    fn is_blank(&self) -> bool {
        *self == WireAssignment::default()
    }

    /// Validates: empty slots are all zero, holes only at the end, no controller twice.
    pub fn decode(&self, field: &'static str) -> Result<Assignment, WireError> {
        let mut holders = [None; ROLE_COUNT];
        let mut hole_seen = false;
        for (rank, slot) in self.slots.iter().enumerate() {
            if slot.id == 0 {
                if slot.incarnation != 0 {
                    return Err(WireError::new(
                        field,
                        format!(
                            "slot {rank} is empty but carries incarnation {}",
                            slot.incarnation
                        ),
                    ));
                }
                hole_seen = true;
                continue;
            }
            if hole_seen {
                return Err(WireError::new(
                    field,
                    format!("slot {rank} is filled after an empty slot (holes only at the end)"),
                ));
            }
            if holders.iter().flatten().any(|h: &Holder| h.id == slot.id) {
                return Err(WireError::new(
                    field,
                    format!("controller {} holds two roles", slot.id),
                ));
            }
            holders[rank] = Some(Holder {
                id: slot.id,
                incarnation: slot.incarnation,
            });
        }
        Ok(Assignment(holders))
    }
}

fn encode_optional(assignment: &Option<Assignment>) -> (bool, WireAssignment) {
    match assignment {
        Some(a) => (true, WireAssignment::encode(a)),
        None => (false, WireAssignment::default()),
    }
}

fn decode_optional(
    field: &'static str,
    valid: bool,
    assignment: &WireAssignment,
) -> Result<Option<Assignment>, WireError> {
    if valid {
        assignment.decode(field).map(Some)
    } else if assignment.is_blank() {
        Ok(None)
    } else {
        Err(WireError::new(
            field,
            "marked not valid but has filled slots",
        ))
    }
}

// ---------------------------------------------------------------------------------------------
// Controller heartbeat.

/// DDS type name of the heartbeat topic.
pub const HEARTBEAT_TYPE_NAME: &str = "rl::HeartbeatSample";

/// The controller heartbeat, keyed by the sender's id.
///
/// The sender's DDS identity is not a field: the sample's writer GUID (from the reader's
/// `SampleInfo`) has the sender's participant GUID prefix, which is also the prefix of its
/// command writer (see [`crate::dds`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct HeartbeatSample {
    pub from_id: u8,
    pub incarnation: u64,
    pub phase: u8,
    pub role: u8,
    /// Ownership strength it commands with; 0 = it does not command.
    pub strength: u8,
    pub agreed_valid: bool,
    pub agreed: WireAssignment,
    pub vote_valid: bool,
    pub vote: WireAssignment,
}

impl Keyed for HeartbeatSample {
    type K = u8;
    fn key(&self) -> u8 {
        self.from_id
    }
}

impl WireSample for HeartbeatSample {
    type Value = Heartbeat;
    const TYPE_NAME: &'static str = HEARTBEAT_TYPE_NAME;

    /// Rules beyond the codes: a strength needs a role, is one of the role strengths and never
    /// above the role's own (a new Primary commands at 20 during a hand-over), and only a
    /// voting or steady controller commands.
    fn decode(self) -> Result<Heartbeat, WireError> {
        let from = controller_id("heartbeat.from_id", self.from_id)?;
        let phase = phase_from_code("heartbeat.phase", self.phase)?;
        let role = role_from_code("heartbeat.role", self.role)?;
        let strength = match self.strength {
            STRENGTH_NONE => None,
            s => {
                if Role::from_strength(s).is_none() {
                    return Err(WireError::new(
                        "heartbeat.strength",
                        format!("{s} is not a role strength"),
                    ));
                }
                let Some(role) = role else {
                    return Err(WireError::new(
                        "heartbeat.strength",
                        format!("commands at {s} without a role"),
                    ));
                };
                if s > role.strength() {
                    return Err(WireError::new(
                        "heartbeat.strength",
                        format!("{s} is above the {role} strength {}", role.strength()),
                    ));
                }
                if !matches!(phase, Phase::Voting | Phase::Steady) {
                    return Err(WireError::new(
                        "heartbeat.strength",
                        format!("commands at {s} while {phase}"),
                    ));
                }
                Some(s)
            }
        };
        let agreed = decode_optional("heartbeat.agreed", self.agreed_valid, &self.agreed)?;
        let vote = decode_optional("heartbeat.vote", self.vote_valid, &self.vote)?;
        Ok(Heartbeat {
            id: from,
            incarnation: self.incarnation,
            phase,
            role,
            strength,
            agreed,
            vote,
        })
    }

    fn encode(heartbeat: &Heartbeat) -> HeartbeatSample {
        let (agreed_valid, agreed) = encode_optional(&heartbeat.agreed);
        let (vote_valid, vote) = encode_optional(&heartbeat.vote);
        HeartbeatSample {
            from_id: heartbeat.id,
            incarnation: heartbeat.incarnation,
            phase: phase_code(heartbeat.phase),
            role: role_code(heartbeat.role),
            strength: heartbeat.strength.unwrap_or(STRENGTH_NONE),
            agreed_valid,
            agreed,
            vote_valid,
            vote,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Durable vote record.

/// DDS type name of the vote topic.
pub const VOTE_TYPE_NAME: &str = "rl::VoteSample";

/// The durable vote record, keyed by the voter's id (a restarted controller replaces its
/// earlier life's record).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct VoteSample {
    pub from_id: u8,
    pub incarnation: u64,
    /// false = the vote is withdrawn.
    pub vote_valid: bool,
    pub vote: WireAssignment,
}

impl Keyed for VoteSample {
    type K = u8;
    fn key(&self) -> u8 {
        self.from_id
    }
}

impl WireSample for VoteSample {
    type Value = VoteRecord;
    const TYPE_NAME: &'static str = VOTE_TYPE_NAME;

    fn decode(self) -> Result<VoteRecord, WireError> {
        Ok(VoteRecord {
            from: controller_id("vote.from_id", self.from_id)?,
            incarnation: self.incarnation,
            vote: decode_optional("vote.vote", self.vote_valid, &self.vote)?,
        })
    }

    fn encode(record: &VoteRecord) -> VoteSample {
        let (vote_valid, vote) = encode_optional(&record.vote);
        VoteSample {
            from_id: record.from,
            incarnation: record.incarnation,
            vote_valid,
            vote,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Alarms.

/// DDS type name of the controller alarm topic.
pub const ALARM_TYPE_NAME: &str = "rl::AlarmSample";
/// DDS type name of the network alarm topic.
pub const NETWORK_ALARM_TYPE_NAME: &str = "rl::NetworkAlarmSample";

/// A controller alarm raised or cleared by a controller about another (or itself).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ControllerAlarm {
    pub reporter: ControllerId,
    pub reporter_incarnation: Incarnation,
    pub about: ControllerId,
    /// The life of the controller the alarm is about, when the reporter knows it.
    pub about_incarnation: Option<Incarnation>,
    pub reason: AlarmReason,
    /// true = raised, false = cleared.
    pub raised: bool,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AlarmSample {
    pub reporter_id: u8,
    pub reporter_incarnation: u64,
    pub about_id: u8,
    pub about_incarnation_valid: bool,
    pub about_incarnation: u64,
    pub reason: u8,
    pub raised: bool,
}

impl WireSample for AlarmSample {
    type Value = ControllerAlarm;
    const TYPE_NAME: &'static str = ALARM_TYPE_NAME;

    fn decode(self) -> Result<ControllerAlarm, WireError> {
        let about_incarnation = if self.about_incarnation_valid {
            Some(self.about_incarnation)
        } else if self.about_incarnation == 0 {
            None
        } else {
            return Err(WireError::new(
                "alarm.about_incarnation",
                "marked not valid but not 0",
            ));
        };
        Ok(ControllerAlarm {
            reporter: controller_id("alarm.reporter_id", self.reporter_id)?,
            reporter_incarnation: self.reporter_incarnation,
            about: controller_id("alarm.about_id", self.about_id)?,
            about_incarnation,
            reason: reason_from_code("alarm.reason", self.reason)?,
            raised: self.raised,
        })
    }

    fn encode(alarm: &ControllerAlarm) -> AlarmSample {
        AlarmSample {
            reporter_id: alarm.reporter,
            reporter_incarnation: alarm.reporter_incarnation,
            about_id: alarm.about,
            about_incarnation_valid: alarm.about_incarnation.is_some(),
            about_incarnation: alarm.about_incarnation.unwrap_or(0),
            reason: reason_code(alarm.reason),
            raised: alarm.raised,
        }
    }
}

/// A network alarm: the reporter stopped (or resumed) hearing a peer on one network.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetworkAlarm {
    pub reporter: ControllerId,
    /// Network index (0 = bus A, 1 = bus B).
    pub network: u8,
    pub peer: ControllerId,
    pub raised: bool,
}

/// The number of redundant networks a network alarm can name.
pub const NETWORK_COUNT: u8 = 2;

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetworkAlarmSample {
    pub reporter_id: u8,
    pub network: u8,
    pub peer_id: u8,
    pub raised: bool,
}

impl WireSample for NetworkAlarmSample {
    type Value = NetworkAlarm;
    const TYPE_NAME: &'static str = NETWORK_ALARM_TYPE_NAME;

    fn decode(self) -> Result<NetworkAlarm, WireError> {
        if self.network >= NETWORK_COUNT {
            return Err(WireError::new(
                "network_alarm.network",
                format!("network {} (there are {NETWORK_COUNT})", self.network),
            ));
        }
        Ok(NetworkAlarm {
            reporter: controller_id("network_alarm.reporter_id", self.reporter_id)?,
            network: self.network,
            peer: controller_id("network_alarm.peer_id", self.peer_id)?,
            raised: self.raised,
        })
    }

    fn encode(alarm: &NetworkAlarm) -> NetworkAlarmSample {
        NetworkAlarmSample {
            reporter_id: alarm.reporter,
            network: alarm.network,
            peer_id: alarm.peer,
            raised: alarm.raised,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// ROS 2.

/// `std_msgs/msg/String`: the controller's status line on the ROS 2 topic `status`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RosString {
    pub data: String,
}

#[cfg(test)]
mod tests {
    use super::*;
    use rustdds::{
        no_key::{DeserializerAdapter, SerializerAdapter},
        CDRDeserializerAdapter, CDRSerializerAdapter, RepresentationIdentifier,
    };
    use serde::de::DeserializeOwned;

    fn to_cdr<T: Serialize>(value: &T) -> Vec<u8> {
        <CDRSerializerAdapter<T> as SerializerAdapter<T>>::to_bytes(value)
            .unwrap()
            .to_vec()
    }

    fn from_cdr<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, String> {
        <CDRDeserializerAdapter<T> as DeserializerAdapter<T>>::from_bytes(
            bytes,
            RepresentationIdentifier::CDR_LE,
        )
        .map_err(|e| e.to_string())
    }

    /// Encode, go through CDR bytes, decode.
    fn round_trip<S>(value: &S::Value) -> Result<S::Value, WireError>
    where
        S: WireSample + Serialize + DeserializeOwned,
    {
        let bytes = to_cdr(&S::encode(value));
        from_cdr::<S>(&bytes).unwrap().decode()
    }

    fn holder(id: u8, incarnation: u64) -> Holder {
        Holder { id, incarnation }
    }

    fn full_assignment() -> Assignment {
        Assignment::from_ranked([holder(2, 77), holder(1, 5), holder(3, u64::MAX)])
    }

    fn heartbeat() -> Heartbeat {
        Heartbeat {
            id: 2,
            incarnation: 1_723_000_000_123,
            phase: Phase::Steady,
            role: Some(Role::Primary),
            strength: Some(30),
            agreed: Some(full_assignment()),
            vote: Some(Assignment::from_ranked([holder(2, 77), holder(1, 5)])),
        }
    }

    /// A valid heartbeat sample to break one field at a time.
    fn heartbeat_sample() -> HeartbeatSample {
        HeartbeatSample::encode(&heartbeat())
    }

    fn rejected_field<S: WireSample>(sample: S) -> &'static str
    where
        S::Value: std::fmt::Debug,
    {
        sample.decode().unwrap_err().field
    }

    #[test]
    fn shape_matches_the_idl_layout() {
        let shape = ShapeTypeExtended {
            color: "YELLOW".into(),
            x: 1,
            y: -2,
            shapesize: 30,
            fill_kind: ShapeFillKind::HorizontalHatchFill,
            angle: 1.5,
        };
        let bytes = to_cdr(&shape);
        // string: length 7 incl. NUL, "YELLOW\0", 1 byte padding to 4, then 5 x 4-byte fields.
        let mut expected = vec![7, 0, 0, 0];
        expected.extend_from_slice(b"YELLOW\0\0");
        for field in [1i32, -2, 30, 2] {
            expected.extend_from_slice(&field.to_le_bytes());
        }
        expected.extend_from_slice(&1.5f32.to_le_bytes());
        assert_eq!(bytes, expected);
        assert_eq!(from_cdr::<ShapeTypeExtended>(&bytes).unwrap(), shape);
        assert_eq!(shape.key(), "YELLOW");
    }

    #[test]
    fn unknown_fill_kind_is_a_decode_error_not_a_panic() {
        let mut bytes = to_cdr(&ShapeTypeExtended {
            color: "RED".into(),
            x: 0,
            y: 0,
            shapesize: 0,
            fill_kind: ShapeFillKind::SolidFill,
            angle: 0.0,
        });
        // fill_kind sits after the 8-byte string and three i32.
        bytes[20..24].copy_from_slice(&9u32.to_le_bytes());
        assert!(from_cdr::<ShapeTypeExtended>(&bytes).is_err());
    }

    #[test]
    fn servo_control_is_three_u16() {
        let command = ServoControl {
            pan: 500,
            tilt: 1000,
            frequency: 60,
        };
        let bytes = to_cdr(&command);
        assert_eq!(bytes, [244, 1, 232, 3, 60, 0]);
        assert_eq!(round_trip::<ServoControl>(&command).unwrap(), command);
    }

    #[test]
    fn heartbeat_round_trips_through_cdr() {
        assert_eq!(
            round_trip::<HeartbeatSample>(&heartbeat()).unwrap(),
            heartbeat()
        );
        let quiet = Heartbeat {
            id: 1,
            incarnation: 0,
            phase: Phase::Initializing,
            role: None,
            strength: None,
            agreed: None,
            vote: None,
        };
        assert_eq!(round_trip::<HeartbeatSample>(&quiet).unwrap(), quiet);
        let handover = Heartbeat {
            phase: Phase::Voting,
            strength: Some(20),
            agreed: Some(Assignment::default()),
            ..heartbeat()
        };
        assert_eq!(round_trip::<HeartbeatSample>(&handover).unwrap(), handover);
        for phase in Phase::ALL {
            let h = Heartbeat {
                phase,
                strength: None,
                ..heartbeat()
            };
            assert_eq!(round_trip::<HeartbeatSample>(&h).unwrap(), h);
        }
    }

    #[test]
    fn heartbeat_key_is_the_sender() {
        assert_eq!(heartbeat_sample().key(), 2);
    }

    #[test]
    fn malformed_heartbeat_fields_are_named() {
        let cases: Vec<(HeartbeatSample, &str)> = vec![
            (
                HeartbeatSample {
                    from_id: 0,
                    ..heartbeat_sample()
                },
                "heartbeat.from_id",
            ),
            (
                HeartbeatSample {
                    phase: 0,
                    ..heartbeat_sample()
                },
                "heartbeat.phase",
            ),
            (
                HeartbeatSample {
                    phase: 5,
                    ..heartbeat_sample()
                },
                "heartbeat.phase",
            ),
            (
                HeartbeatSample {
                    role: 4,
                    ..heartbeat_sample()
                },
                "heartbeat.role",
            ),
            // A strength that is no role's.
            (
                HeartbeatSample {
                    strength: 25,
                    ..heartbeat_sample()
                },
                "heartbeat.strength",
            ),
            // Commanding without a role.
            (
                HeartbeatSample {
                    role: ROLE_NONE,
                    ..heartbeat_sample()
                },
                "heartbeat.strength",
            ),
            // A Tertiary commanding at the Primary's strength.
            (
                HeartbeatSample {
                    role: ROLE_TERTIARY,
                    ..heartbeat_sample()
                },
                "heartbeat.strength",
            ),
            // A failed controller commanding.
            (
                HeartbeatSample {
                    phase: PHASE_FAILED,
                    ..heartbeat_sample()
                },
                "heartbeat.strength",
            ),
            (
                HeartbeatSample {
                    phase: PHASE_INITIALIZING,
                    ..heartbeat_sample()
                },
                "heartbeat.strength",
            ),
        ];
        for (sample, field) in cases {
            assert_eq!(rejected_field(sample), field, "{sample:?}");
        }
    }

    #[test]
    fn malformed_assignments_are_named() {
        let slot = |id, incarnation| HolderSlot { id, incarnation };
        let broken = [
            // Hole before a filled slot.
            WireAssignment {
                slots: [slot(1, 1), slot(0, 0), slot(3, 3)],
            },
            WireAssignment {
                slots: [slot(0, 0), slot(2, 2), slot(0, 0)],
            },
            // Empty slot with an incarnation.
            WireAssignment {
                slots: [slot(1, 1), slot(0, 9), slot(0, 0)],
            },
            // One controller in two roles.
            WireAssignment {
                slots: [slot(1, 1), slot(1, 2), slot(0, 0)],
            },
        ];
        for assignment in broken {
            let agreed = HeartbeatSample {
                agreed: assignment,
                ..heartbeat_sample()
            };
            assert_eq!(rejected_field(agreed), "heartbeat.agreed", "{assignment:?}");
            let vote = HeartbeatSample {
                vote: assignment,
                ..heartbeat_sample()
            };
            assert_eq!(rejected_field(vote), "heartbeat.vote", "{assignment:?}");
            let record = VoteSample {
                from_id: 1,
                incarnation: 1,
                vote_valid: true,
                vote: assignment,
            };
            assert_eq!(rejected_field(record), "vote.vote", "{assignment:?}");
        }
        // Slots filled but marked not valid.
        let stale = HeartbeatSample {
            agreed_valid: false,
            ..heartbeat_sample()
        };
        assert_eq!(rejected_field(stale), "heartbeat.agreed");
    }

    #[test]
    fn vote_round_trips_and_rejects_id_zero() {
        let record = VoteRecord {
            from: 3,
            incarnation: 42,
            vote: Some(full_assignment()),
        };
        assert_eq!(round_trip::<VoteSample>(&record).unwrap(), record);
        let withdrawn = VoteRecord {
            vote: None,
            ..record
        };
        assert_eq!(round_trip::<VoteSample>(&withdrawn).unwrap(), withdrawn);
        assert_eq!(VoteSample::encode(&record).key(), 3);
        let anonymous = VoteSample {
            from_id: 0,
            ..VoteSample::encode(&record)
        };
        assert_eq!(rejected_field(anonymous), "vote.from_id");
    }

    #[test]
    fn alarm_round_trips_and_rejects_bad_fields() {
        let alarm = ControllerAlarm {
            reporter: 1,
            reporter_incarnation: 10,
            about: 3,
            about_incarnation: Some(30),
            reason: AlarmReason::Lost,
            raised: true,
        };
        assert_eq!(round_trip::<AlarmSample>(&alarm).unwrap(), alarm);
        let cleared = ControllerAlarm {
            about_incarnation: None,
            reason: AlarmReason::Failed,
            raised: false,
            ..alarm
        };
        assert_eq!(round_trip::<AlarmSample>(&cleared).unwrap(), cleared);

        let good = AlarmSample::encode(&alarm);
        let cases = [
            (
                AlarmSample {
                    reporter_id: 0,
                    ..good
                },
                "alarm.reporter_id",
            ),
            (
                AlarmSample {
                    about_id: 0,
                    ..good
                },
                "alarm.about_id",
            ),
            (AlarmSample { reason: 0, ..good }, "alarm.reason"),
            (AlarmSample { reason: 3, ..good }, "alarm.reason"),
            (
                AlarmSample {
                    about_incarnation_valid: false,
                    ..good
                },
                "alarm.about_incarnation",
            ),
        ];
        for (sample, field) in cases {
            assert_eq!(rejected_field(sample), field, "{sample:?}");
        }
    }

    #[test]
    fn network_alarm_round_trips_and_rejects_bad_fields() {
        let alarm = NetworkAlarm {
            reporter: 2,
            network: 1,
            peer: 3,
            raised: true,
        };
        assert_eq!(round_trip::<NetworkAlarmSample>(&alarm).unwrap(), alarm);
        let good = NetworkAlarmSample::encode(&alarm);
        let cases = [
            (
                NetworkAlarmSample {
                    reporter_id: 0,
                    ..good
                },
                "network_alarm.reporter_id",
            ),
            (
                NetworkAlarmSample { peer_id: 0, ..good },
                "network_alarm.peer_id",
            ),
            (
                NetworkAlarmSample { network: 2, ..good },
                "network_alarm.network",
            ),
        ];
        for (sample, field) in cases {
            assert_eq!(rejected_field(sample), field, "{sample:?}");
        }
    }

    #[test]
    fn truncated_or_garbage_bytes_are_errors_not_panics() {
        let bytes = to_cdr(&heartbeat_sample());
        for len in 0..bytes.len() {
            assert!(from_cdr::<HeartbeatSample>(&bytes[..len]).is_err(), "{len}");
        }
        // A boolean flag that is neither 0 nor 1.
        let mut flipped = bytes.clone();
        let agreed_valid_offset = 1 + 7 + 8 + 3; // from_id, pad, incarnation, phase/role/strength
        assert_eq!(flipped[agreed_valid_offset], 1);
        flipped[agreed_valid_offset] = 7;
        assert!(from_cdr::<HeartbeatSample>(&flipped).is_err());
        // Random bytes never panic (they may decode; then validation judges them).
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        for _ in 0..2000 {
            let noise: Vec<u8> = (0..bytes.len())
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state & 0xff) as u8
                })
                .collect();
            if let Ok(sample) = from_cdr::<HeartbeatSample>(&noise) {
                let _ = sample.decode();
            }
        }
    }
}
