//! Who is who: each controller id bound to the DDS participant it speaks from.
//!
//! A heartbeat names its sender (`from_id`), and nothing on the wire stops any participant on
//! the LAN from naming another controller: one forged `FAILED` heartbeat for C1 made the others
//! re-vote around it. Every sample also carries its writer's GUID, whose first 12 bytes are the
//! writing participant's, so a reader knows which participant sent it. The book binds an id to
//! the participant its first heartbeat came from, and:
//!
//! - a heartbeat or vote for a live controller (heard within the peer deadline) from another
//!   participant, with **the same incarnation**, is a copy: not believed, counted, alarmed as an
//!   **impostor**;
//! - a heartbeat with **another incarnation** from another participant is taken as a restart
//!   (a new process is a new participant, and a quick restart speaks before the old one's
//!   deadline has run out): the id moves to it. If the participant it replaced then speaks
//!   again within the deadline, two live participants claim the id (a second process started
//!   with the same id, or a forger with an invented incarnation): the id goes back to the one
//!   that held it first, the newcomer is an impostor from then on, and the alarm is raised. So
//!   a forger gets at most one sample believed, and every peer detects a duplicate id;
//! - an id whose participant has been silent for the deadline is free: a forger can take the
//!   id of a controller that is down, as a restart does. Only DDS Security stops that
//!   (docs/protocol.md, "Hostile input").
//!
//! Pure: participants, ids and times in, admissions out. The controller's voting loop, the
//! actuator's trust in command writers and `rl status` use it.

use crate::types::{ControllerId, Incarnation};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The 12-byte GUID prefix that identifies a DDS participant (and prefixes all its
/// entities): who a sample came from, whatever id it names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct ParticipantKey(pub [u8; 12]);

/// What the book says of one sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Admission {
    /// From the participant the id is bound to (or it just bound it).
    Accepted,
    /// Believed, but two live participants claim the id: this one, which held it first, and a
    /// newcomer now refused. Alarm (the impostor alarm about the id).
    Contested,
    /// From an impostor: not believed. `first` for the first sample of this impostor since it
    /// was last silent for the deadline (alarm then).
    Impostor {
        /// `true` for its first sample since it was last silent for the deadline: alarm then.
        first: bool,
    },
}

#[derive(Clone, Copy, Debug)]
struct Bound {
    participant: ParticipantKey,
    incarnation: Incarnation,
    last_heard_ms: u64,
    /// This process's own id: never expires, never moves.
    own: bool,
}

/// The bindings of one reader, with the impostors heard.
#[derive(Clone, Debug)]
pub struct Identities {
    deadline_ms: u64,
    bound: BTreeMap<ControllerId, Bound>,
    /// The binding each id had before it last moved to a new participant.
    superseded: BTreeMap<ControllerId, Bound>,
    /// (id, participant) -> when its samples were last refused.
    impostors: BTreeMap<(ControllerId, ParticipantKey), u64>,
    refused: u64,
}

impl Identities {
    /// A book whose bindings expire after `deadline_ms` of silence (the peer deadline).
    pub fn new(deadline_ms: u64) -> Identities {
        Identities {
            deadline_ms,
            bound: BTreeMap::new(),
            superseded: BTreeMap::new(),
            impostors: BTreeMap::new(),
            refused: 0,
        }
    }

    /// Binds this process's own id to its own participant for good.
    pub fn bind_own(&mut self, id: ControllerId, participant: ParticipantKey) {
        self.bound.insert(
            id,
            Bound {
                participant,
                incarnation: 0,
                last_heard_ms: 0,
                own: true,
            },
        );
    }

    fn alive(&self, bound: &Bound, now_ms: u64) -> bool {
        bound.own || now_ms.saturating_sub(bound.last_heard_ms) <= self.deadline_ms
    }

    /// Marks `participant` an impostor of `id` at `now_ms`; whether it is a new one.
    fn mark(&mut self, id: ControllerId, participant: ParticipantKey, now_ms: u64) -> bool {
        let deadline_ms = self.deadline_ms;
        let previous = self.impostors.insert((id, participant), now_ms);
        previous.is_none_or(|last_ms| now_ms.saturating_sub(last_ms) > deadline_ms)
    }

    fn refuse(&mut self, id: ControllerId, participant: ParticipantKey, now_ms: u64) -> Admission {
        self.refused += 1;
        let first = self.mark(id, participant, now_ms);
        Admission::Impostor { first }
    }

    /// Whether `participant` was found impersonating `id` within the deadline.
    fn known_impostor(&self, id: ControllerId, participant: ParticipantKey, now_ms: u64) -> bool {
        self.impostors
            .get(&(id, participant))
            .is_some_and(|last_ms| now_ms.saturating_sub(*last_ms) <= self.deadline_ms)
    }

    /// A heartbeat for `id` (life `incarnation`) from `participant` at `now_ms`.
    pub fn heartbeat(
        &mut self,
        id: ControllerId,
        incarnation: Incarnation,
        participant: ParticipantKey,
        now_ms: u64,
    ) -> Admission {
        if self.known_impostor(id, participant, now_ms) {
            return self.refuse(id, participant, now_ms);
        }
        let heard = Bound {
            participant,
            incarnation,
            last_heard_ms: now_ms,
            own: false,
        };
        let Some(bound) = self.bound.get(&id).copied() else {
            self.bound.insert(id, heard);
            return Admission::Accepted;
        };
        if bound.participant == participant {
            self.bound.insert(
                id,
                Bound {
                    own: bound.own,
                    ..heard
                },
            );
            return Admission::Accepted;
        }
        if bound.own || (self.alive(&bound, now_ms) && incarnation == bound.incarnation) {
            return self.refuse(id, participant, now_ms);
        }
        let replaced_speaks_again = self
            .superseded
            .get(&id)
            .is_some_and(|old| old.participant == participant)
            && self.alive(&bound, now_ms);
        if replaced_speaks_again {
            // Two live claimants: the one that held the id first keeps it.
            self.superseded.remove(&id);
            self.refused += 1;
            self.mark(id, bound.participant, now_ms);
            self.bound.insert(id, heard);
            return Admission::Contested;
        }
        // A restart (or silence for the deadline): the id moves to the new participant.
        self.superseded.insert(id, bound);
        self.bound.insert(id, heard);
        Admission::Accepted
    }

    /// A vote for `id` (life `incarnation`) from `participant`: refused from a known impostor
    /// and as a copy of a live controller's (its incarnation, another participant); never
    /// binds (a vote can come before its sender's first heartbeat).
    pub fn vote(
        &mut self,
        id: ControllerId,
        incarnation: Incarnation,
        participant: ParticipantKey,
        now_ms: u64,
    ) -> Admission {
        if self.known_impostor(id, participant, now_ms) {
            return self.refuse(id, participant, now_ms);
        }
        match self.bound.get(&id).copied() {
            Some(bound)
                if bound.participant != participant
                    && (bound.own
                        || (self.alive(&bound, now_ms) && incarnation == bound.incarnation)) =>
            {
                self.refuse(id, participant, now_ms)
            }
            _ => Admission::Accepted,
        }
    }

    /// The id bound to `participant` (still alive), if any: whom its writers speak for.
    pub fn controller_of(&self, participant: ParticipantKey, now_ms: u64) -> Option<ControllerId> {
        self.speaks_for(participant)
            .filter(|id| self.bound.get(id).is_some_and(|b| self.alive(b, now_ms)))
    }

    /// The id bound to `participant`, however long it has been silent: whom its writers speak
    /// for until another participant takes the id. The actuator's trust uses this, not
    /// [`Identities::controller_of`]: two heartbeats lost on a lossy link must not make it
    /// refuse the Primary's commands, which arrive every republish period and whose liveness
    /// the command deadline judges.
    pub fn speaks_for(&self, participant: ParticipantKey) -> Option<ControllerId> {
        self.bound
            .iter()
            .find(|(_, b)| b.participant == participant)
            .map(|(id, _)| *id)
    }

    /// The incarnation last heard for `id` from its bound participant.
    pub fn incarnation(&self, id: ControllerId) -> Option<Incarnation> {
        self.bound.get(&id).map(|b| b.incarnation)
    }

    /// Ids with an impostor heard within the deadline.
    pub fn impersonated(&self, now_ms: u64) -> Vec<ControllerId> {
        let mut ids: Vec<ControllerId> = self
            .impostors
            .iter()
            .filter(|(_, last_ms)| now_ms.saturating_sub(**last_ms) <= self.deadline_ms)
            .map(|((id, _), _)| *id)
            .collect();
        ids.dedup();
        ids
    }

    /// Samples refused so far.
    pub fn refused(&self) -> u64 {
        self.refused
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEADLINE_MS: u64 = 500;

    fn participant(n: u8) -> ParticipantKey {
        ParticipantKey([n; 12])
    }

    #[test]
    fn a_copy_of_a_live_controller_is_refused() {
        let mut book = Identities::new(DEADLINE_MS);
        assert_eq!(
            book.heartbeat(1, 10, participant(1), 0),
            Admission::Accepted
        );
        assert_eq!(
            book.heartbeat(1, 10, participant(9), 100),
            Admission::Impostor { first: true },
            "the same id and incarnation from another participant"
        );
        assert_eq!(
            book.heartbeat(1, 10, participant(9), 200),
            Admission::Impostor { first: false }
        );
        assert_eq!(
            book.vote(1, 10, participant(9), 250),
            Admission::Impostor { first: false }
        );
        assert_eq!(book.vote(1, 10, participant(1), 250), Admission::Accepted);
        assert_eq!(
            book.heartbeat(1, 10, participant(1), 300),
            Admission::Accepted
        );
        assert_eq!(book.controller_of(participant(1), 300), Some(1));
        assert_eq!(book.controller_of(participant(9), 300), None);
        assert_eq!(book.impersonated(300), vec![1]);
        assert_eq!(book.impersonated(800), Vec::<ControllerId>::new());
        assert_eq!(book.refused(), 3);
    }

    #[test]
    fn a_quick_restart_takes_the_id_at_once() {
        let mut book = Identities::new(DEADLINE_MS);
        book.heartbeat(2, 10, participant(2), 0);
        assert_eq!(
            book.heartbeat(2, 11, participant(7), 100),
            Admission::Accepted,
            "a new incarnation from a new participant, 100 ms after the old one's last word"
        );
        assert_eq!(book.incarnation(2), Some(11));
        assert_eq!(book.controller_of(participant(7), 100), Some(2));
        assert_eq!(
            book.heartbeat(2, 11, participant(7), 350),
            Admission::Accepted
        );
        assert_eq!(book.refused(), 0);
    }

    #[test]
    fn two_live_claimants_leave_the_id_with_the_first_and_alarm() {
        let mut book = Identities::new(DEADLINE_MS);
        book.heartbeat(3, 10, participant(3), 0);
        // A second process (or a forger with an invented incarnation) speaks: taken as a
        // restart, once.
        assert_eq!(
            book.heartbeat(3, 99, participant(8), 100),
            Admission::Accepted
        );
        // The first speaks again: two live claimants.
        assert_eq!(
            book.heartbeat(3, 10, participant(3), 250),
            Admission::Contested
        );
        assert_eq!(book.controller_of(participant(3), 250), Some(3));
        assert_eq!(
            book.heartbeat(3, 99, participant(8), 350),
            Admission::Impostor { first: false },
            "already alarmed by the contest"
        );
        assert_eq!(
            book.heartbeat(3, 10, participant(3), 500),
            Admission::Accepted
        );
        assert_eq!(book.impersonated(500), vec![3]);
    }

    #[test]
    fn a_silent_participant_frees_its_id() {
        let mut book = Identities::new(DEADLINE_MS);
        book.heartbeat(2, 10, participant(2), 0);
        assert_eq!(
            book.heartbeat(2, 10, participant(7), 500),
            Admission::Impostor { first: true },
            "a copy at the deadline: the old one still counts"
        );
        assert_eq!(
            book.heartbeat(2, 10, participant(6), 501),
            Admission::Accepted,
            "after the deadline anyone may take the id"
        );
    }

    #[test]
    fn a_silent_participant_speaks_for_its_id_until_another_takes_it() {
        let mut book = Identities::new(DEADLINE_MS);
        book.heartbeat(1, 10, participant(1), 0);
        assert_eq!(book.controller_of(participant(1), 10_000), None);
        assert_eq!(
            book.speaks_for(participant(1)),
            Some(1),
            "silence alone keeps the id"
        );
        book.heartbeat(1, 11, participant(9), 10_000);
        assert_eq!(book.speaks_for(participant(1)), None, "the restart took it");
        assert_eq!(book.speaks_for(participant(9)), Some(1));
        assert_eq!(book.speaks_for(participant(4)), None, "never heard");
    }

    #[test]
    fn the_own_id_never_moves_and_votes_bind_nothing() {
        let mut book = Identities::new(DEADLINE_MS);
        book.bind_own(3, participant(3));
        assert_eq!(
            book.heartbeat(3, 5, participant(8), 1_000_000),
            Admission::Impostor { first: true }
        );
        assert_eq!(book.vote(2, 1, participant(8), 0), Admission::Accepted);
        assert_eq!(
            book.controller_of(participant(8), 0),
            None,
            "a vote binds nothing"
        );
    }
}
