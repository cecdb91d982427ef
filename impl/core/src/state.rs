//! What one controller knows: its own phase, role, vote and agreed result, and one entry per
//! peer (the paper's RedundancyInfo). Field for field the model's `Controller` and `Peer`
//! (`model/src/state.rs`), so the conformance abstraction is a plain mapping.

use crate::types::{
    AlarmReason, Arrival, Assignment, ControllerId, Holder, Incarnation, Phase, Role, Strength,
    TAKEOVER_STRENGTH,
};
use std::collections::{BTreeMap, BTreeSet};

/// What a controller knows of one peer.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Peer {
    /// `Some(incarnation)` while the peer is believed alive.
    pub alive: Option<Incarnation>,
    /// Rounds since its last heartbeat (the paper's dead-man count, inverted).
    pub silent_rounds: u32,
    /// Marked FAILED: it cast a minority vote past the grace, or announced its own failure.
    pub failed: bool,
    /// Consecutive rounds its vote has disagreed with a majority.
    pub dissent_rounds: u32,
    /// A controller-failed alarm is raised for it and not yet cleared.
    pub alarm: Option<AlarmReason>,
    /// The agreed result its last heartbeat carried (`Some` = it is an incumbent of a
    /// running system).
    pub heard_agreed: Option<Assignment>,
    /// The vote its last heartbeat carried.
    pub heard_vote: Option<Assignment>,
    /// Its last heartbeat said it commands at Primary strength.
    pub claims_primary: bool,
    /// The epoch of the agreed result its last heartbeat carried.
    pub heard_epoch: u32,
    /// Its last heartbeat's result was provisional (agreed without a majority).
    pub heard_provisional: bool,
    /// The strength of its established command writer, as its last heartbeat reported it.
    pub heard_strength: Option<Strength>,
    /// How its commands arrive (F17), as the adapter last measured them: measured by id,
    /// apart from its heartbeats, so kept when it is lost or starts a new life.
    pub commands: Arrival,
}

impl Peer {
    /// Alive, not FAILED, and holding an agreed result.
    pub fn incumbent(&self) -> bool {
        self.alive.is_some() && !self.failed && self.heard_agreed.is_some()
    }
}

/// One controller's protocol state.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ControllerState {
    /// The controller's id.
    pub id: ControllerId,
    /// Its process life.
    pub incarnation: Incarnation,
    /// Where it is in the protocol.
    pub phase: Phase,
    /// The role it holds.
    pub role: Option<Role>,
    /// The ownership strength it commands with; `None` = silent.
    pub output: Option<Strength>,
    /// It heard an incumbent before voting: it joins a running system.
    pub late_joiner: bool,
    /// Rounds since the last new peer was heard, while initializing.
    pub window_quiet_rounds: u32,
    /// The last result that reached agreement.
    pub agreed: Option<Assignment>,
    /// Its own published vote.
    pub vote: Option<Assignment>,
    /// Consecutive rounds in which two peers agreed on a result other than its vote.
    pub self_dissent_rounds: u32,
    /// Every peer ever heard, by id.
    pub peers: BTreeMap<ControllerId, Peer>,
    /// The epoch of its agreed result: results agreed with a majority count up from 1.
    pub epoch: u32,
    /// The members of the last result agreed with a majority: the base the next majority is
    /// counted against.
    pub quorum_base: BTreeSet<ControllerId>,
    /// Its agreed result lacks a majority of `quorum_base` (a side cut off from the rest).
    pub provisional: bool,
    /// Rounds since it became provisional (saturates at 1).
    pub provisional_rounds: u32,
    /// Its command writers, as the DDS adapter runs them.
    pub writer: Writer,
    /// F17: it took over from this Primary, whose commands arrived late, and commands at
    /// [`TAKEOVER_STRENGTH`] until it no longer hears that life and holds a backed Primary
    /// role itself.
    pub took_over_from: Option<Holder>,
    /// F17: it heard a peer that took over from it; it starts again as a new incarnation.
    pub deposed: bool,
    /// Duplex with preemption (A4): round ends it must still run on time, hearing its
    /// partner, before it takes its configured strength back; set when it started again
    /// after a stall, 0 otherwise.
    pub dwell_rounds_left: u8,
}

/// The command writers of one controller, as the DDS adapter keeps them. A raise creates a
/// new writer (RustDDS cannot change a writer's strength) and keeps the old one writing for
/// the round in which readers discover the new one; a lowering or silence drops the old
/// writer at once. Heartbeats report the strength of the established writer only.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Writer {
    /// The previous, weaker writer that still writes during this round.
    pub retiring: Option<Strength>,
    /// The newest writer was created in this round.
    pub fresh: bool,
}

impl ControllerState {
    /// A controller that has just started: initializing, heard nobody.
    pub fn new(id: ControllerId, incarnation: Incarnation) -> ControllerState {
        ControllerState {
            id,
            incarnation,
            phase: Phase::Initializing,
            role: None,
            output: None,
            late_joiner: false,
            window_quiet_rounds: 0,
            agreed: None,
            vote: None,
            self_dissent_rounds: 0,
            peers: BTreeMap::new(),
            epoch: 0,
            quorum_base: BTreeSet::new(),
            provisional: false,
            provisional_rounds: 0,
            writer: Writer::default(),
            took_over_from: None,
            deposed: false,
            dwell_rounds_left: 0,
        }
    }

    /// The strength its heartbeat reports: a writer created in this round is not yet known
    /// to every reader, so the previous one's strength is reported.
    pub fn established_strength(&self) -> Option<Strength> {
        if self.writer.fresh {
            self.writer.retiring
        } else {
            self.output
        }
    }

    /// Changes the command strength as the DDS adapter does (see [`Writer`]). Leaving the
    /// takeover strength for another hands over like a raise (F17): the takeover writer owns
    /// the actuator, and nobody else commands above 30 meanwhile.
    pub fn set_output(&mut self, strength: Option<Strength>) {
        if strength == self.output {
            return;
        }
        let raise = matches!((self.output, strength), (Some(old), Some(new)) if new > old);
        let from_takeover = self.output == Some(TAKEOVER_STRENGTH) && strength.is_some();
        self.writer.retiring = if raise || from_takeover {
            self.output.max(self.writer.retiring)
        } else {
            None
        };
        self.output = strength;
        self.writer.fresh = strength.is_some();
    }

    /// F17: takes over from the Primary `from` at [`TAKEOVER_STRENGTH`], on the writer the
    /// adapter keeps ready for this (the actuator already knows it).
    pub fn take_over(&mut self, from: Holder) {
        self.took_over_from = Some(from);
        self.set_output(Some(TAKEOVER_STRENGTH));
    }

    /// A new round: the writers created in the last one are established and the retired
    /// ones are gone (discovery within a round, the model's timing assumption).
    pub fn establish_writers(&mut self) {
        self.writer = Writer::default();
    }

    /// Not FAILED: it takes part in voting.
    pub fn is_active(&self) -> bool {
        self.phase != Phase::Failed
    }

    /// This incarnation as a vote names it.
    pub fn holder(&self) -> Holder {
        Holder {
            id: self.id,
            incarnation: self.incarnation,
        }
    }

    /// Its membership view: itself and every peer believed alive and not FAILED, by id.
    pub fn members(&self) -> Vec<Holder> {
        let mut members: Vec<Holder> = self
            .peers
            .iter()
            .filter(|(_, peer)| !peer.failed)
            .filter_map(|(&id, peer)| peer.alive.map(|incarnation| Holder { id, incarnation }))
            .collect();
        members.push(self.holder());
        members.sort();
        members
    }

    /// Distinct controllers heard (itself included), FAILED ones too: the window counts heads.
    pub fn members_heard(&self) -> usize {
        1 + self.peers.values().filter(|p| p.alive.is_some()).count()
    }

    /// Peers believed alive.
    pub fn live_peers(&self) -> impl Iterator<Item = (ControllerId, &Peer)> {
        self.peers
            .iter()
            .filter(|(_, p)| p.alive.is_some())
            .map(|(&id, p)| (id, p))
    }
}
