//! The controller heartbeat: each controller's phase, role, commanding strength, agreed
//! assignment with its epoch and standing, vote, established strength, and the Primary life it
//! took over from (F17), every round, stamped with when it was written.

use super::assignment::{decode_optional, encode_optional, HolderSlot, WireAssignment};
use super::codes::{
    controller_id, phase_code, phase_from_code, role_code, role_from_code, STRENGTH_NONE,
};
use super::{WireError, WireSample};
use crate::core::types::{
    Holder, Phase, Role, Strength, PROVISIONAL_PRIMARY_STRENGTH, TAKEOVER_STRENGTH,
};
use crate::core::Heartbeat;
use rustdds::Keyed;
use serde::{Deserialize, Serialize};
use std::sync::OnceLock;
use std::time::Instant;

/// DDS type name of the heartbeat topic.
pub const HEARTBEAT_TYPE_NAME: &str = "rl::HeartbeatSample";

/// The controller heartbeat, keyed by the sender's id.
///
/// The sender's DDS identity is not a field: the sample's writer GUID (from the reader's
/// `SampleInfo`) has the sender's participant GUID prefix, which is also the prefix of its
/// command writer (see [`crate::dds`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct HeartbeatSample {
    /// The sender's controller id (0 is refused): the key.
    pub from_id: u8,
    /// The sender's life: a new value at every start (only equality matters).
    pub incarnation: u64,
    /// The sender's phase code (`PHASE_*`: 1 initializing .. 4 failed; 0 is rejected).
    pub phase: u8,
    /// The sender's role code (`ROLE_*`; 0 = no role).
    pub role: u8,
    /// Ownership strength it commands with; 0 = it does not command.
    pub strength: u8,
    /// Whether the sender holds an agreed result; false = none, and `agreed` is all zero.
    pub agreed_valid: bool,
    /// The last result that reached agreement, as the sender knows it.
    pub agreed: WireAssignment,
    /// Whether the sender has a vote published; false = none, and `vote` is all zero.
    pub vote_valid: bool,
    /// The sender's own published vote.
    pub vote: WireAssignment,
    /// The epoch of the agreed result (0 before there is one).
    pub epoch: u32,
    /// The agreed result lacks a majority of the last result's members.
    pub provisional: bool,
    /// The strength of its established command writer (what every reader knows by now);
    /// 0 = none.
    pub established_strength: u8,
    /// The Primary life it took over from, whose commands arrived late (F17); id 0 = none.
    pub took_over_from: HolderSlot,
    /// When it was written, in milliseconds on the sender's monotonic clock
    /// ([`sender_clock_ms`]; any origin: a receiver compares only differences). Not
    /// validated: a receiver learns each sender's offset (`runtime::heartbeat_delay`).
    pub sent_ms: u64,
}

/// Milliseconds since this process first asked, on the monotonic clock: what a heartbeat is
/// stamped with when written, and what a receiver measures its arrival on. Never moved by
/// the round phase, a wall-clock step or a time server.
pub fn sender_clock_ms() -> u64 {
    static ORIGIN: OnceLock<Instant> = OnceLock::new();
    let origin = *ORIGIN.get_or_init(Instant::now);
    u64::try_from(origin.elapsed().as_millis()).unwrap_or(u64::MAX)
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
        let took_over_from = took_over_from(&self.took_over_from, from)?;
        let taking_over = took_over_from.is_some();
        let strength = strength_from_code(
            "heartbeat.strength",
            self.strength,
            role,
            phase,
            taking_over,
        )?;
        // The round after a takeover is released its writer still retires at the takeover
        // strength, above the one it now commands with (F17: the hand-over goes as a raise).
        let handing_over = !taking_over
            && strength.is_some()
            && strength_code(Some(TAKEOVER_STRENGTH)) == self.established_strength;
        let established_strength = strength_from_code(
            "heartbeat.established_strength",
            self.established_strength,
            role,
            phase,
            taking_over || handing_over,
        )?;
        if taking_over && strength != Some(TAKEOVER_STRENGTH) {
            return Err(WireError::new(
                "heartbeat.took_over_from",
                format!(
                    "names a takeover but it commands at {} (a takeover commands at {TAKEOVER_STRENGTH})",
                    self.strength
                ),
            ));
        }
        if established_strength > strength && !handing_over {
            return Err(WireError::new(
                "heartbeat.established_strength",
                format!(
                    "{} is above the strength it commands with ({})",
                    self.established_strength, self.strength
                ),
            ));
        }
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
            epoch: self.epoch,
            provisional: self.provisional,
            established_strength,
            took_over_from,
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
            strength: strength_code(heartbeat.strength),
            agreed_valid,
            agreed,
            vote_valid,
            vote,
            epoch: heartbeat.epoch,
            provisional: heartbeat.provisional,
            established_strength: strength_code(heartbeat.established_strength),
            took_over_from: heartbeat
                .took_over_from
                .map_or(HolderSlot::default(), |holder| HolderSlot {
                    id: holder.id,
                    incarnation: holder.incarnation,
                }),
            sent_ms: sender_clock_ms(),
        }
    }

    fn sent_ms(&self) -> Option<u64> {
        Some(self.sent_ms)
    }

    fn unstamped(self) -> HeartbeatSample {
        HeartbeatSample { sent_ms: 0, ..self }
    }
}

/// The life a takeover names (F17): empty (id 0, incarnation 0), or a controller other than
/// the sender.
fn took_over_from(slot: &HolderSlot, from: u8) -> Result<Option<Holder>, WireError> {
    const FIELD: &str = "heartbeat.took_over_from";
    if slot.id == 0 {
        if slot.incarnation != 0 {
            return Err(WireError::new(
                FIELD,
                format!(
                    "names no controller but carries incarnation {}",
                    slot.incarnation
                ),
            ));
        }
        return Ok(None);
    }
    let id = controller_id(FIELD, slot.id)?;
    if id == from {
        return Err(WireError::new(FIELD, "names the sender itself"));
    }
    Ok(Some(Holder {
        id,
        incarnation: slot.incarnation,
    }))
}

/// A strength a heartbeat reports (`FIELD` names which). Rules beyond the code: a strength
/// needs a role, is one of the role strengths or the provisional Primary's, never above the
/// role's own (a new Primary commands at 20 during a hand-over, a standby keeps its lower
/// strength until the roles above have raised theirs), and only a voting or steady controller
/// commands. The takeover strength goes with a takeover (`taking_over`, F17) and needs only
/// a voting or steady controller.
fn strength_from_code(
    field: &'static str,
    code: u8,
    role: Option<Role>,
    phase: Phase,
    taking_over: bool,
) -> Result<Option<Strength>, WireError> {
    if code == STRENGTH_NONE {
        return Ok(None);
    }
    let strength = Strength(i32::from(code));
    if strength == TAKEOVER_STRENGTH {
        if !taking_over {
            return Err(WireError::new(
                field,
                format!("{code} is the takeover strength, but it names no takeover"),
            ));
        }
        if !matches!(phase, Phase::Voting | Phase::Steady) {
            return Err(WireError::new(
                field,
                format!("commands at {code} while {phase}"),
            ));
        }
        return Ok(Some(strength));
    }
    if Role::from_strength(strength).is_none() && strength != PROVISIONAL_PRIMARY_STRENGTH {
        return Err(WireError::new(
            field,
            format!("{code} is not a role strength"),
        ));
    }
    let Some(role) = role else {
        return Err(WireError::new(
            field,
            format!("commands at {code} without a role"),
        ));
    };
    if strength > role.strength() {
        return Err(WireError::new(
            field,
            format!("{code} is above the {role} strength {}", role.strength()),
        ));
    }
    if !matches!(phase, Phase::Voting | Phase::Steady) {
        return Err(WireError::new(
            field,
            format!("commands at {code} while {phase}"),
        ));
    }
    Ok(Some(strength))
}

/// A strength as the heartbeat's octet carries it (RL's strengths are 10 to 35); none is 0.
fn strength_code(strength: Option<Strength>) -> u8 {
    strength
        .and_then(|strength| u8::try_from(strength.value()).ok())
        .unwrap_or(STRENGTH_NONE)
}
