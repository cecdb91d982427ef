//! The actuator at DDS-writer granularity: which controller's commands it follows.
//!
//! DDS exclusive ownership (DDS 1.4 §2.2.3.9) gives the instance to the strongest writer the
//! reader knows and hears; when the owner falls silent (crash, pause) the strongest of the
//! rest takes over within the deadline, abstracted here as at once. A raise re-creates the
//! writer: until the actuator discovers the new one, the old one keeps writing
//! (`Controller::set_output`). Equal strengths are broken by GUID, an order no controller
//! chooses: the model keeps the owner or the lowest id and offers `Action::TieBreak` to every
//! other writer tied at the top, so the checker tries each order.
//!
//! The ghost history of owner changes lives here too: each change is counted against the
//! faults, and the controllers it went to are checked when the system next settles.

use crate::properties::settled;
use crate::state::{link_bit, State};
use crate::types::{Id, Role};

/// Every controller whose writer the actuator knows, with its strongest visible strength.
fn visible(state: &State) -> Vec<(Id, u8)> {
    state
        .controllers
        .iter()
        .filter(|c| (state.unplugged | state.lagging) & (1 << (c.id - 1)) == 0)
        .filter_map(|c| c.visible_strength().map(|strength| (c.id, strength)))
        .collect()
}

/// The controllers tied at the top visible strength with the owner whose GUID order against
/// the owner is not known yet: the order may hand the actuator to any of them (once).
pub(super) fn tie_break_targets(state: &State) -> Vec<Id> {
    let writers = visible(state);
    let Some(top) = writers.iter().map(|(_, strength)| *strength).max() else {
        return Vec::new();
    };
    let owner_on_top = writers
        .iter()
        .any(|(id, strength)| Some(*id) == state.owner && *strength == top);
    if !owner_on_top {
        return Vec::new();
    }
    let Some(owner) = state.owner else {
        return Vec::new();
    };
    writers
        .iter()
        .filter(|(id, strength)| *strength == top && *id != owner)
        .filter(|(id, _)| {
            let known = link_bit(*id, owner) | link_bit(owner, *id);
            state.tie_order & known == 0
        })
        .map(|(id, _)| *id)
        .collect()
}

/// Re-evaluates the owner after an action (see [`next_owner`]) and counts a change.
pub(super) fn arbitrate(next: &mut State) {
    if let Some(to) = next_owner(&visible(next), next.owner, next.tie_order) {
        change_owner(next, to);
    }
}

/// DDS exclusive ownership over the writers a reader knows, each `(controller, its strongest
/// visible strength)`: the owner stays while it is among the strongest, unless a tie it is
/// known to lose (`tie_order`, bit `link_bit(a, b)`: `a` beats `b`) gives the actuator to
/// another; otherwise the strongest (the lowest id among equals) takes over. With no writer
/// visible the actuator keeps its last owner (it has nothing else to follow). Returns the
/// owner to change to, if it changes. The conformance suite runs the same rule over the
/// implementation's writers.
pub fn next_owner(writers: &[(Id, u8)], owner: Option<Id>, tie_order: u16) -> Option<Id> {
    let top = writers.iter().map(|(_, strength)| *strength).max()?;
    let owner_on_top = writers
        .iter()
        .any(|(id, strength)| Some(*id) == owner && *strength == top);
    if let (true, Some(owner)) = (owner_on_top, owner) {
        // A tie the owner is known to lose goes to the writer that beats it.
        return writers
            .iter()
            .find(|(id, strength)| *strength == top && tie_order & link_bit(*id, owner) != 0)
            .map(|(id, _)| *id);
    }
    writers
        .iter()
        .filter(|(_, strength)| *strength == top)
        .map(|(id, _)| *id)
        .min()
        .filter(|to| Some(*to) != owner)
}

/// The actuator now follows `to`; a change from another owner is counted.
pub(super) fn change_owner(next: &mut State, to: Id) {
    if next.owner == Some(to) {
        return;
    }
    if next.owner.is_some() {
        let history = &mut next.history;
        // Before the first backed result a loss can split the founders into two systems that
        // each form (F9); the GUID order moves the actuator between their Primaries until
        // they merge, and no rule can know which side the actuator should stay with.
        let formation_split = history.partition_open && !history.formed;
        if !formation_split {
            history.owner_changes = (history.owner_changes + 1).min(history.faults + 1);
        }
        // In a partition a side that believes itself alone steps down and a standby may
        // take the actuator until the sides merge (F11).
        if !history.partition_open {
            history.change_targets |= 1 << (to - 1);
        }
    }
    if next.owner.is_none() && next.history.settled_owner.is_none() {
        // The first owner is the baseline until the system first settles.
        next.history.settled_owner = Some(to);
    }
    next.owner = Some(to);
}

/// At a settled state: every owner change since the last settled state must have gone to the
/// owner of then or to the Primary now settled; the away marks are cleared.
pub(super) fn settle_bookkeeping(next: &mut State) {
    if next.history.partition_open {
        // A partition interrupts the episode: the sides may each command until they merge.
        next.history.change_targets = 0;
    }
    let Some(agreed) = settled(next) else {
        return;
    };
    let mut allowed = 0u8;
    for id in agreed
        .holder(Role::Primary)
        .into_iter()
        .chain(next.history.settled_owner)
    {
        allowed |= 1 << (id - 1);
    }
    let backed = next.up().all(|c| !c.provisional);
    let starved = next.starved != 0;
    let slowed_mask = next.slowed;
    let slowed = slowed_mask != 0;
    let history = &mut next.history;
    history.starvation_open &= starved;
    history.slowdown_open &= slowed;
    history.formed |= backed;
    if history.change_targets & !allowed != 0 {
        history.stray_owner = true;
    }
    // Settled again: the sides of a partition have merged (after the actuator's owner was
    // re-evaluated in this step, so a change the merge causes still counts as partitioned).
    history.partition_open = false;
    history.change_targets = 0;
    history.settled_owner = next.owner;
    if history.away != 0 {
        let back_below = next.controllers.iter().any(|c| {
            history.away & (1 << (c.id - 1)) != 0
                && c.role.is_some_and(|role| role != Role::Primary)
        });
        history.returned_below |= back_below;
        // A slowed controller stays away until it heals: its episode goes on through the
        // settled states it allows.
        history.away &= slowed_mask;
    }
}

/// A Primary that stayed with the system loses the role (between `before` and `next`) while
/// a controller back from a pause or a cut holds Primary: the failback the paper rules out
/// ("once a role is selected, it should be maintained unless the controller with that role
/// fails").
pub(super) fn note_primary_taken_back(before: &State, next: &mut State) {
    let away = next.history.away;
    let returner_holds_primary = next
        .controllers
        .iter()
        .any(|c| away & (1 << (c.id - 1)) != 0 && c.is_up() && c.role == Some(Role::Primary));
    let stayer_lost_primary = before.controllers.iter().any(|b| {
        away & (1 << (b.id - 1)) == 0
            && b.is_active()
            && b.role == Some(Role::Primary)
            && next.controller(b.id).is_active()
            && next.controller(b.id).role != Some(Role::Primary)
    });
    if returner_holds_primary && stayer_lost_primary {
        next.history.primary_taken_back = true;
    }
}
