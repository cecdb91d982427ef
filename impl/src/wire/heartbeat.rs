//! The controller heartbeat: each controller's phase, role, commanding strength, agreed
//! assignment and vote, every round.

use super::assignment::{decode_optional, encode_optional, WireAssignment};
use super::codes::{
    controller_id, phase_code, phase_from_code, role_code, role_from_code, STRENGTH_NONE,
};
use super::{WireError, WireSample};
use crate::core::types::{Phase, Role};
use crate::core::Heartbeat;
use rustdds::Keyed;
use serde::{Deserialize, Serialize};

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

    fn decode(self) -> Result<Heartbeat, WireError> {
        let from = controller_id("heartbeat.from_id", self.from_id)?;
        let phase = phase_from_code("heartbeat.phase", self.phase)?;
        let role = role_from_code("heartbeat.role", self.role)?;
        let strength = strength_from_code(self.strength, role, phase)?;
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

/// The strength a heartbeat commands with. Rules beyond the code: a strength needs a role, is
/// one of the role strengths and never above the role's own (a new Primary commands at 20
/// during a hand-over), and only a voting or steady controller commands.
fn strength_from_code(code: u8, role: Option<Role>, phase: Phase) -> Result<Option<u8>, WireError> {
    const FIELD: &str = "heartbeat.strength";
    if code == STRENGTH_NONE {
        return Ok(None);
    }
    if Role::from_strength(code).is_none() {
        return Err(WireError::new(
            FIELD,
            format!("{code} is not a role strength"),
        ));
    }
    let Some(role) = role else {
        return Err(WireError::new(
            FIELD,
            format!("commands at {code} without a role"),
        ));
    };
    if code > role.strength() {
        return Err(WireError::new(
            FIELD,
            format!("{code} is above the {role} strength {}", role.strength()),
        ));
    }
    if !matches!(phase, Phase::Voting | Phase::Steady) {
        return Err(WireError::new(
            FIELD,
            format!("commands at {code} while {phase}"),
        ));
    }
    Ok(Some(code))
}
