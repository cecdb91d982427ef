//! Deliberately broken voting rules, compiled only with the `mutation` feature.
//!
//! The conformance suite (`conformance/`) replays the model's traces against the core; a suite
//! that cannot fail proves nothing, so its mutation check selects one of these rule breaks and
//! asserts that the replay then fails with a readable difference. They mirror the model's own
//! mutations (`model/src/types.rs`, `Mutation`) where the core has the same rule.
//!
//! The selection is per thread: the replay drives its cores on the test's thread, and tests
//! running in parallel on other threads keep the correct rules. With nothing selected (the
//! default) every hook is the identity, so enabling the feature changes no behaviour by itself.

use super::state::ControllerState;
use super::types::{ControllerId, Holder, Role};
use super::ROLE_COUNT;
use std::cell::Cell;

/// One deliberate break of a voting rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mutation {
    /// A Secondary takes Primary as soon as the Primary misses one heartbeat, without a vote.
    PromoteWithoutFailure,
    /// Dissenting votes are never marked FAILED, and an outvoted controller never fails itself.
    IgnoreMinorityVote,
    /// Known results are ignored when ranking: roles go by id, so a restarted low id takes
    /// Primary back from a live Primary.
    Failback,
    /// A fourth controller puts itself in as Tertiary and takes the Tertiary role.
    AdmitFourth,
}

impl Mutation {
    pub const ALL: [Mutation; 4] = [
        Mutation::PromoteWithoutFailure,
        Mutation::IgnoreMinorityVote,
        Mutation::Failback,
        Mutation::AdmitFourth,
    ];
}

thread_local! {
    static SELECTED: Cell<Option<Mutation>> = const { Cell::new(None) };
}

/// Selects the mutation the cores on this thread run with (`None` = the correct rules).
pub fn select(mutation: Option<Mutation>) {
    SELECTED.with(|selected| selected.set(mutation));
}

/// The mutation selected on this thread.
pub fn selected() -> Option<Mutation> {
    SELECTED.with(Cell::get)
}

/// Selects `mutation` on this thread until the returned guard is dropped.
pub fn select_scoped(mutation: Mutation) -> Selection {
    select(Some(mutation));
    Selection { _private: () }
}

/// Restores the correct rules when dropped (also when a test panics).
pub struct Selection {
    _private: (),
}

impl Drop for Selection {
    fn drop(&mut self) {
        select(None);
    }
}

fn active(mutation: Mutation) -> bool {
    selected() == Some(mutation)
}

/// `PromoteWithoutFailure`: called when `silent_peer` missed this round's heartbeat but is not
/// lost yet.
pub(super) fn promote_without_failure(c: &mut ControllerState, silent_peer: ControllerId) {
    if active(Mutation::PromoteWithoutFailure)
        && c.role == Some(Role::Secondary)
        && c.agreed
            .is_some_and(|agreed| agreed.holder(Role::Primary) == Some(silent_peer))
    {
        c.role = Some(Role::Primary);
        c.output = Some(Role::Primary.strength());
    }
}

/// `IgnoreMinorityVote`: the grace a dissent must outlast before it is marked FAILED.
pub(super) fn minority_grace(grace: u32) -> u32 {
    if active(Mutation::IgnoreMinorityVote) {
        u32::MAX
    } else {
        grace
    }
}

/// `Failback`: whether the ranking ignores the known results.
pub(super) fn rank_by_id_only() -> bool {
    active(Mutation::Failback)
}

/// `AdmitFourth`: a controller ranked beyond the three roles (`ranked` is the vote's order of
/// precedence) puts itself in as Tertiary.
pub(super) fn admit_fourth_vote(c: &ControllerState, ranked: &mut [Holder]) {
    if !active(Mutation::AdmitFourth) {
        return;
    }
    if let Some(position) = ranked.iter().position(|h| h.id == c.id) {
        if position >= ROLE_COUNT {
            ranked.swap(ROLE_COUNT - 1, position);
        }
    }
}

/// `AdmitFourth`: a controller the agreed result leaves out takes the Tertiary role anyway.
pub(super) fn admit_fourth_role(role: Option<Role>) -> Option<Role> {
    if active(Mutation::AdmitFourth) && role.is_none() {
        Some(Role::Tertiary)
    } else {
        role
    }
}
