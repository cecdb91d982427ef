//! Which command writers the actuator obeys: only a controller's, at most at the takeover
//! strength.
//!
//! DDS exclusive ownership gives the actuator to the strongest live writer, whoever it is: a
//! writer announcing strength 100 from anywhere on the LAN would own the servo. So the servo
//! takes a command only from a writer whose participant speaks for a controller (its
//! heartbeats come from that participant and no other has taken the id since,
//! crate::identity) and whose strength is at most the takeover strength (35: a Secondary that
//! took over from a Primary whose commands arrive late, F17, is the only controller above
//! 30). Silence alone does not end the trust: on a lossy link two heartbeats in a row go
//! missing while the commands, ten times as frequent, keep coming, and refusing them would
//! move the actuator where the peers (whose minority grace rides out the same loss) move no
//! role. A writer's liveness is the
//! command deadline's to judge. A forger that also forges heartbeats for a controller
//! that is down, at a role's strength, is stopped only by DDS Security (docs/protocol.md, "Hostile input").
//! `rl servo --any-writer` turns this off (plain DDS semantics, for other tools' writers).

#[cfg(test)]
use crate::core::types::Role;
use crate::core::types::{ControllerId, Strength, TAKEOVER_STRENGTH};
use crate::core::Heartbeat;
use crate::dds::{Received, GUID};
use crate::identity::{Admission, Identities};
use std::collections::BTreeSet;

/// Why a command was not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// Its participant speaks for no controller (never heard, or the id has moved on).
    NotAController,
    /// Above the takeover strength.
    TooStrong {
        /// The writer's announced ownership strength.
        strength: Strength,
    },
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refusal::NotAController => f.write_str(
                "its participant sends no controller heartbeat (or another participant speaks for that id)",
            ),
            Refusal::TooStrong { strength } => write!(
                f,
                "strength {strength} is above the takeover strength {}",
                TAKEOVER_STRENGTH
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
    /// `deadline_ms`: the peer deadline, after which a silent controller's id may be taken by
    /// another participant (a restart).
    pub fn new(deadline_ms: u64, any_writer: bool) -> CommandTrust {
        CommandTrust {
            identities: Identities::new(deadline_ms),
            any_writer,
            warned: BTreeSet::new(),
        }
    }

    /// Takes in a heartbeat; `false` if it came from an impostor (not to be believed).
    pub fn heartbeat(&mut self, heartbeat: &Received<Heartbeat>, now_ms: u64) -> bool {
        let from = crate::dds::participant_key(heartbeat.writer);
        let admission = self.identities.heartbeat(
            heartbeat.value.id,
            heartbeat.value.incarnation,
            from,
            now_ms,
        );
        !matches!(admission, Admission::Impostor { .. })
    }

    /// Whether to take a command from `writer` at `strength`.
    pub fn admit(&self, writer: GUID, strength: Strength) -> Result<ControllerId, Refusal> {
        let controller = self
            .identities
            .speaks_for(crate::dds::participant_key(writer));
        if self.any_writer {
            return Ok(controller.unwrap_or(0));
        }
        let controller = controller.ok_or(Refusal::NotAController)?;
        if strength > TAKEOVER_STRENGTH {
            return Err(Refusal::TooStrong { strength });
        }
        Ok(controller)
    }

    /// True the first time it is asked about `writer` (warn once per writer).
    pub fn first_warning(&mut self, writer: GUID) -> bool {
        self.warned.insert(writer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::types::Phase;

    const PEER_DEADLINE_MS: u64 = 500;

    /// A command writer of participant `n`.
    fn writer(n: u8) -> GUID {
        let mut bytes = [n; 16];
        bytes[12..].copy_from_slice(&[0, 0, 0x0c, 0x03]);
        GUID::from_bytes(bytes)
    }

    fn heartbeat_from(n: u8, id: ControllerId, incarnation: u64) -> Received<Heartbeat> {
        let mut heartbeat_writer = [n; 16];
        heartbeat_writer[12..].copy_from_slice(&[0, 0, 0x0d, 0x03]);
        Received {
            value: Heartbeat {
                id,
                incarnation,
                phase: Phase::Steady,
                role: Some(Role::Primary),
                strength: Some(Role::Primary.strength()),
                agreed: None,
                vote: None,
                epoch: 1,
                provisional: false,
                established_strength: Some(Role::Primary.strength()),
                took_over_from: None,
            },
            writer: GUID::from_bytes(heartbeat_writer),
            source_timestamp: None,
            sent_ms: None,
        }
    }

    #[test]
    fn a_controller_whose_heartbeats_go_missing_keeps_the_actuator() {
        let mut trust = CommandTrust::new(PEER_DEADLINE_MS, false);
        assert!(trust.heartbeat(&heartbeat_from(1, 1, 7), 0));
        // C1's heartbeats lost on a lossy link for twice the peer deadline while C2's arrive:
        // C1's commands are still the Primary's.
        assert!(trust.heartbeat(&heartbeat_from(2, 2, 5), 2 * PEER_DEADLINE_MS));
        assert_eq!(trust.admit(writer(1), Strength(30)), Ok(1));
        assert_eq!(trust.admit(writer(2), Strength(20)), Ok(2));
    }

    #[test]
    fn a_writer_whose_id_moved_on_or_that_never_heartbeated_is_refused() {
        let mut trust = CommandTrust::new(PEER_DEADLINE_MS, false);
        assert_eq!(
            trust.admit(writer(9), Strength(10)),
            Err(Refusal::NotAController)
        );
        trust.heartbeat(&heartbeat_from(1, 1, 7), 0);
        // C1 restarted: a new participant, a new life, after the old one's deadline.
        trust.heartbeat(&heartbeat_from(2, 1, 8), 1_000);
        assert_eq!(
            trust.admit(writer(1), Strength(30)),
            Err(Refusal::NotAController)
        );
        assert_eq!(trust.admit(writer(2), Strength(30)), Ok(1));
    }

    #[test]
    fn a_writer_above_the_takeover_strength_is_refused_unless_any_writer() {
        let mut trust = CommandTrust::new(PEER_DEADLINE_MS, false);
        trust.heartbeat(&heartbeat_from(1, 1, 7), 0);
        assert_eq!(trust.admit(writer(1), Strength(35)), Ok(1));
        assert_eq!(
            trust.admit(writer(1), Strength(36)),
            Err(Refusal::TooStrong {
                strength: Strength(36)
            })
        );
        assert_eq!(
            trust.admit(writer(1), Strength(100)),
            Err(Refusal::TooStrong {
                strength: Strength(100)
            })
        );
        let plain = CommandTrust::new(PEER_DEADLINE_MS, true);
        assert_eq!(plain.admit(writer(9), Strength(100)), Ok(0));
    }
}
