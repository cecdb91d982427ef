//! The voting loop's guard against samples in another controller's name (crate::identity):
//! a copy of a live controller's heartbeat or vote from another participant, and anything from
//! a participant that lost a contest for an id, is not believed; the first raises an impostor
//! alarm about that id, which clears once no impostor has been heard for the peer deadline.
//!
//! Heartbeats with this controller's own id are let through: the core ignores them and counts
//! those of another incarnation (another process configured with its id, a console warning),
//! and its own participant never expires, so they are refused here only in name.

use super::Voting;
use crate::core::{AlarmReason, ControllerId};
use crate::dds::{ParticipantKey, Received};
use crate::identity::Admission;
use tracing::warn;

impl Voting {
    /// Whether to believe a heartbeat, by the participant that wrote it.
    pub(super) fn admit_heartbeat(&mut self, heartbeat: &Received<crate::core::Heartbeat>) -> bool {
        let id = heartbeat.value.id;
        if id == self.core.config().id {
            return true;
        }
        let now_ms = self.clock.now_ms();
        let from = crate::dds::participant_key(heartbeat.writer);
        let admission = self
            .identities
            .heartbeat(id, heartbeat.value.incarnation, from, now_ms);
        self.on_admission(id, "heartbeat", from, admission)
    }

    /// Whether to believe a vote record, by the participant that wrote it.
    pub(super) fn admit_vote(&mut self, vote: &Received<crate::core::VoteRecord>) -> bool {
        let (id, writer) = (vote.value.from, vote.writer);
        if id == self.core.config().id {
            return true;
        }
        let now_ms = self.clock.now_ms();
        let from = crate::dds::participant_key(writer);
        let admission = self
            .identities
            .vote(id, vote.value.incarnation, from, now_ms);
        self.on_admission(id, "vote", from, admission)
    }

    fn on_admission(
        &mut self,
        id: ControllerId,
        what: &str,
        from: ParticipantKey,
        admission: Admission,
    ) -> bool {
        match admission {
            Admission::Accepted => true,
            Admission::Contested => {
                warn!(
                    "C{}: two participants speak as C{id} (another process with id {id}, or a \
                     forgery): believing the one that spoke first, {}",
                    self.core.config().id,
                    hex(from)
                );
                self.raise_impostor_alarm(id);
                true
            }
            Admission::Impostor { first } => {
                if first {
                    warn!(
                        "C{}: a {what} in the name of C{id} came from participant {} while C{id} \
                         speaks from another: not believed (another process with id {id}, or a \
                         forgery)",
                        self.core.config().id,
                        hex(from)
                    );
                    self.raise_impostor_alarm(id);
                }
                false
            }
        }
    }

    fn raise_impostor_alarm(&mut self, id: ControllerId) {
        if !self.impostor_alarms.contains(&id) {
            self.impostor_alarms.push(id);
            self.alarm(id, AlarmReason::Impostor, true);
        }
    }

    /// Clears the impostor alarms of ids no impostor has spoken for within the deadline.
    pub(super) fn clear_silent_impostors(&mut self) {
        if self.impostor_alarms.is_empty() {
            return;
        }
        let active = self.identities.impersonated(self.clock.now_ms());
        let silent: Vec<ControllerId> = self
            .impostor_alarms
            .iter()
            .copied()
            .filter(|id| !active.contains(id))
            .collect();
        for id in silent {
            self.impostor_alarms.retain(|other| *other != id);
            self.alarm(id, AlarmReason::Impostor, false);
        }
    }
}

fn hex(participant: ParticipantKey) -> String {
    participant.0.iter().map(|b| format!("{b:02x}")).collect()
}
