//! Who is who: each controller id bound to the DDS participant it speaks from.
//!
//! A heartbeat names its sender (`from_id`), and nothing on the wire stops any participant on
//! the LAN from naming another controller: one forged `FAILED` heartbeat for C1 made the others
//! re-vote around it. Every sample also carries its writer's GUID, whose first 12 bytes are the
//! writing participant's, so a reader knows which participant sent it. The book binds an id to
//! the participant its first heartbeat came from and believes samples in that id's name only
//! from there, while that participant lives (was heard within the peer deadline):
//!
//! - a heartbeat or vote for a bound id from another participant is an **impostor**'s: not
//!   believed, counted, alarmed (a second process configured with the same id is caught the
//!   same way, by every peer);
//! - once the bound participant has been silent for the deadline, the id is free again: a
//!   restarted controller is a new participant, and binds the id at its first heartbeat;
//! - an id not yet bound is bound by whoever speaks first. So while a controller is down, a
//!   forger can take its id; only DDS Security stops that (docs/protocol.md, "Hostile input").
//!
//! Pure: participants, ids and times in, admissions out. The voting thread, `rl servo` and
//! `rl status` use it.

use crate::core::types::{ControllerId, Incarnation};
use crate::dds::ParticipantKey;
use std::collections::BTreeMap;

/// What the book says of one sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Admission {
    /// From the participant the id is bound to (or it just bound it).
    Accepted,
    /// From another participant while the bound one lives. `first` for the first sample of
    /// this impostor since it was last silent for the deadline (alarm then).
    Impostor { first: bool },
}

#[derive(Clone, Copy, Debug)]
struct Bound {
    participant: ParticipantKey,
    incarnation: Incarnation,
    last_heard_ms: u64,
    /// This process's own id: never expires.
    own: bool,
}

/// The bindings of one reader, with the impostors heard.
#[derive(Clone, Debug)]
pub struct Identities {
    deadline_ms: u64,
    bound: BTreeMap<ControllerId, Bound>,
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

    fn refuse(&mut self, id: ControllerId, participant: ParticipantKey, now_ms: u64) -> Admission {
        self.refused += 1;
        let deadline_ms = self.deadline_ms;
        let previous = self.impostors.insert((id, participant), now_ms);
        let first = previous.is_none_or(|last_ms| now_ms.saturating_sub(last_ms) > deadline_ms);
        Admission::Impostor { first }
    }

    /// A heartbeat for `id` (life `incarnation`) from `participant` at `now_ms`.
    pub fn heartbeat(
        &mut self,
        id: ControllerId,
        incarnation: Incarnation,
        participant: ParticipantKey,
        now_ms: u64,
    ) -> Admission {
        match self.bound.get(&id) {
            Some(bound) if bound.participant == participant => {}
            Some(bound) if self.alive(bound, now_ms) => {
                return self.refuse(id, participant, now_ms);
            }
            // Unbound, or its participant silent for the deadline: a (re)start binds it.
            _ => {}
        }
        let own = self.bound.get(&id).is_some_and(|b| b.own);
        self.bound.insert(
            id,
            Bound {
                participant,
                incarnation,
                last_heard_ms: now_ms,
                own,
            },
        );
        Admission::Accepted
    }

    /// A vote for `id` from `participant`: believed from the bound participant, or for an id
    /// not bound (a vote can arrive before its sender's first heartbeat); never binds.
    pub fn vote(
        &mut self,
        id: ControllerId,
        participant: ParticipantKey,
        now_ms: u64,
    ) -> Admission {
        match self.bound.get(&id) {
            Some(bound) if bound.participant != participant && self.alive(bound, now_ms) => {
                self.refuse(id, participant, now_ms)
            }
            _ => Admission::Accepted,
        }
    }

    /// The id bound to `participant` (still alive), if any: whom its writers speak for.
    pub fn controller_of(&self, participant: ParticipantKey, now_ms: u64) -> Option<ControllerId> {
        self.bound
            .iter()
            .find(|(_, b)| b.participant == participant && self.alive(b, now_ms))
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
    fn an_id_is_believed_only_from_the_participant_that_announced_it() {
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
            book.heartbeat(1, 99, participant(9), 200),
            Admission::Impostor { first: false },
            "another incarnation changes nothing while the real one lives"
        );
        assert_eq!(
            book.vote(1, participant(9), 250),
            Admission::Impostor { first: false }
        );
        assert_eq!(book.vote(1, participant(1), 250), Admission::Accepted);
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
    fn a_silent_participant_frees_its_id_for_a_restart() {
        let mut book = Identities::new(DEADLINE_MS);
        book.heartbeat(2, 10, participant(2), 0);
        assert_eq!(
            book.heartbeat(2, 11, participant(7), 500),
            Admission::Impostor { first: true },
            "at the deadline the old one still counts"
        );
        assert_eq!(
            book.heartbeat(2, 11, participant(7), 501),
            Admission::Accepted
        );
        assert_eq!(book.incarnation(2), Some(11));
        assert_eq!(
            book.heartbeat(2, 10, participant(2), 600),
            Admission::Impostor { first: true },
            "the old participant back is now the stranger"
        );
    }

    #[test]
    fn the_own_id_never_expires_and_votes_for_unbound_ids_pass() {
        let mut book = Identities::new(DEADLINE_MS);
        book.bind_own(3, participant(3));
        assert_eq!(
            book.heartbeat(3, 5, participant(8), 1_000_000),
            Admission::Impostor { first: true }
        );
        assert_eq!(book.vote(2, participant(8), 0), Admission::Accepted);
        assert_eq!(
            book.controller_of(participant(8), 0),
            None,
            "a vote binds nothing"
        );
    }

    #[test]
    fn an_impostor_silent_for_the_deadline_is_new_again() {
        let mut book = Identities::new(DEADLINE_MS);
        book.heartbeat(1, 1, participant(1), 0);
        for t in [100, 200, 300] {
            book.heartbeat(1, 1, participant(1), t);
        }
        assert_eq!(
            book.heartbeat(1, 1, participant(5), 300),
            Admission::Impostor { first: true }
        );
        book.heartbeat(1, 1, participant(1), 700);
        assert_eq!(
            book.heartbeat(1, 1, participant(5), 900),
            Admission::Impostor { first: true }
        );
    }
}
