//! Epochs and provisional results (finding F11): which of two agreed results wins a merge.
//!
//! A result agreed while a majority of the last result's members stands behind it is backed
//! and gets a new epoch; one agreed without that majority (a side cut off from the rest, or a
//! controller alone) is provisional and keeps the newest epoch it knew. When the sides meet
//! again the newer epoch wins, and a backed result wins over a provisional one of the same
//! epoch (`rules::compute_vote`), so the side that kept the majority keeps its roles. The
//! model's rules of the same names are in `model/src/protocol/agreement.rs`.

use crate::state::ControllerState;
use crate::types::{Assignment, ControllerId, Phase, ROLE_COUNT};
use std::collections::BTreeSet;

/// The number the next majority is counted against: the last backed result's members, or
/// three before there is one.
fn quorum_base_size(c: &ControllerState) -> usize {
    match c.quorum_base.len() {
        0 => ROLE_COUNT,
        members => members,
    }
}

/// More than half as many controllers as the last backed result had members stand behind
/// `result`: itself and every live peer it has not marked FAILED whose heartbeat carried
/// `result` as its vote or its agreed result. A majority by count: newcomers that vote for it
/// make up for crashed members.
pub(crate) fn backed(c: &ControllerState, result: Assignment) -> bool {
    let behind = 1 + c
        .peers
        .values()
        .filter(|p| p.alive.is_some() && !p.failed)
        .filter(|p| p.heard_vote == Some(result) || p.heard_agreed == Some(result))
        .count();
    behind * 2 > quorum_base_size(c)
}

/// It hears more than half as many live controllers as the last backed result had members:
/// not cut off, whatever its result's standing.
pub(crate) fn hears_majority(c: &ControllerState) -> bool {
    c.members().len() * 2 > quorum_base_size(c)
}

/// F15: the members of its last backed result that it no longer hears are more than half of
/// that result: they could back a result (and elect a Primary) of their own.
pub(crate) fn lost_could_outvote(c: &ControllerState) -> bool {
    let heard: BTreeSet<ControllerId> = c.members().iter().map(|holder| holder.id).collect();
    let lost = c.quorum_base.difference(&heard).count();
    lost * 2 > c.quorum_base.len()
}

fn members_of(agreed: Assignment) -> BTreeSet<ControllerId> {
    agreed.holders().map(|holder| holder.id).collect()
}

/// The epoch and standing of a newly agreed result.
pub(crate) fn take_epoch(c: &mut ControllerState, agreed: Assignment) {
    // A result an incumbent already holds (a joiner taking the system's result) keeps the
    // epoch it was agreed in: one result, one epoch.
    let held = c
        .peers
        .values()
        .filter(|p| p.incumbent() && p.heard_agreed == Some(agreed) && !p.heard_provisional)
        .map(|p| p.heard_epoch)
        .max();
    if let Some(epoch) = held {
        c.epoch = epoch;
        c.quorum_base = members_of(agreed);
        c.provisional = false;
        return;
    }
    let is_backed = backed(c, agreed);
    if !is_backed && !c.provisional {
        c.provisional_rounds = 0;
    }
    c.provisional = !is_backed;
    if is_backed {
        back(c, agreed);
    } else {
        c.epoch = known_epoch(c);
    }
}

/// The newest epoch it knows: its own and every incumbent's.
fn known_epoch(c: &ControllerState) -> u32 {
    c.peers
        .values()
        .filter(|p| p.incumbent())
        .map(|p| p.heard_epoch)
        .chain(std::iter::once(c.epoch))
        .max()
        .unwrap_or(0)
}

fn back(c: &mut ControllerState, agreed: Assignment) {
    c.epoch = known_epoch(c).saturating_add(1);
    c.quorum_base = members_of(agreed);
    c.provisional = false;
}

/// A provisional result that a majority now stands behind (a joiner agreed to it, the peers
/// heard it) becomes backed, with a new epoch.
pub(crate) fn confirm_provisional(c: &mut ControllerState) {
    if !c.provisional || c.phase != Phase::Steady {
        return;
    }
    if let Some(agreed) = c.agreed.filter(|agreed| backed(c, *agreed)) {
        back(c, agreed);
    }
}
