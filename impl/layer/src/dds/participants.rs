//! Who is who on the bus: the participant a GUID belongs to, and which controller each
//! participant speaks for, learned from its heartbeats (a command's writer shares its
//! participant's prefix with that controller's heartbeat writer).

use super::{Received, GUID};
use crate::core::{types::ControllerId, Heartbeat};
use std::collections::HashMap;

pub use crate::core::identity::ParticipantKey;

/// The participant that `guid` (any of its entities, or itself) belongs to.
pub fn participant_key(guid: GUID) -> ParticipantKey {
    let bytes = guid.to_bytes();
    let mut prefix = [0; 12];
    prefix.copy_from_slice(&bytes[..12]);
    ParticipantKey(prefix)
}

/// Which controller each participant belongs to, learned from heartbeats (see the module
/// header): turns a command's writer GUID into a controller id.
#[derive(Clone, Debug, Default)]
pub struct ControllerDirectory {
    by_participant: HashMap<ParticipantKey, ControllerId>,
}

impl ControllerDirectory {
    /// A directory that knows no participant yet.
    pub fn new() -> ControllerDirectory {
        ControllerDirectory::default()
    }

    /// Records the sender of a heartbeat. A restarted controller is a new participant: its
    /// old entry stays, harmless, as nothing writes from that participant any more.
    pub fn note_heartbeat(&mut self, heartbeat: &Received<Heartbeat>) {
        self.by_participant
            .insert(participant_key(heartbeat.writer), heartbeat.value.id);
    }

    /// The controller whose participant wrote through `writer`.
    pub fn controller_of(&self, writer: GUID) -> Option<ControllerId> {
        self.by_participant.get(&participant_key(writer)).copied()
    }

    /// How many participants it has mapped to a controller (restarts included).
    pub fn len(&self) -> usize {
        self.by_participant.len()
    }

    /// Whether no heartbeat has been noted yet.
    pub fn is_empty(&self) -> bool {
        self.by_participant.is_empty()
    }
}
