//! Which command writers the actuator obeys: only a controller's, at most at the Primary's
//! strength.
//!
//! DDS exclusive ownership gives the actuator to the strongest live writer, whoever it is: a
//! writer announcing strength 100 from anywhere on the LAN would own the servo. So the servo
//! takes a command only from a writer whose participant speaks for a live controller (its
//! heartbeats come from that participant and no other claims the id, crate::identity) and whose
//! strength is at most the Primary's (30). A forger that also forges heartbeats for a controller
//! that is down, at a role's strength, is stopped only by DDS Security (docs/protocol.md, "Hostile input").
//! `rl servo --any-writer` turns this off (plain DDS semantics, for other tools' writers).

use crate::core::types::{ControllerId, Role};
use crate::core::Heartbeat;
use crate::dds::{ParticipantKey, Received, GUID};
use crate::identity::{Admission, Identities};
use std::collections::BTreeSet;

/// Why a command was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Its participant speaks for no live controller.
    NotAController,
    /// Above the Primary's strength.
    TooStrong { strength: i32 },
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::NotAController => f.write_str(
                "its participant sends no controller heartbeat (or another participant speaks for that id)",
            ),
            Refusal::TooStrong { strength } => write!(
                f,
                "strength {strength} is above the Primary's {}",
                Role::Primary.strength()
            ),
        }
    }
}

/// The servo's trust in command writers.
#[derive(Clone, Debug)]
pub struct CommandTrust {
    identities: Identities,
    /// `--any-writer`: every writer is taken.
    any_writer: bool,
    /// Writers already warned about.
    warned: BTreeSet<GUID>,
}

impl CommandTrust {
    /// `deadline_ms`: how long a controller's participant stays trusted after its last
    /// heartbeat (the peer deadline).
    pub fn new(deadline_ms: u64, any_writer: bool) -> CommandTrust {
        CommandTrust {
            identities: Identities::new(deadline_ms),
            any_writer,
            warned: BTreeSet::new(),
        }
    }

    /// Takes in a heartbeat; `false` if it came from an impostor (not to be believed).
    pub fn heartbeat(&mut self, heartbeat: &Received<Heartbeat>, now_ms: u64) -> bool {
        let from = ParticipantKey::of(heartbeat.writer);
        let admission = self.identities.heartbeat(
            heartbeat.value.id,
            heartbeat.value.incarnation,
            from,
            now_ms,
        );
        !matches!(admission, Admission::Impostor { .. })
    }

    /// Whether to take a command from `writer` at `strength`.
    pub fn admit(&self, writer: GUID, strength: i32, now_ms: u64) -> Result<ControllerId, Refusal> {
        let controller = self
            .identities
            .controller_of(ParticipantKey::of(writer), now_ms);
        if self.any_writer {
            return Ok(controller.unwrap_or(0));
        }
        let controller = controller.ok_or(Refusal::NotAController)?;
        if strength > i32::from(Role::Primary.strength()) {
            return Err(Refusal::TooStrong { strength });
        }
        Ok(controller)
    }

    /// True the first time it is asked about `writer` (warn once per writer).
    pub fn first_warning(&mut self, writer: GUID) -> bool {
        self.warned.insert(writer)
    }
}
