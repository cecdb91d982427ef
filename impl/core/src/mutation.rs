//! Deliberately broken rules, compiled only with the `mutation` feature: the voting rules, and
//! the lockstep pair's compare-before-write, which the controller application applies.
//!
//! The conformance suite replays the model's traces against the core, and the DDS-level
//! replay runs real controllers; a suite that cannot fail proves nothing, so its mutation
//! checks configure one of these rule breaks ([`crate::CoreConfig::mutation`]) and assert that
//! the replay then fails. They mirror the model's own mutations (`model/src/fixes.rs`,
//! `Mutation`) where the core has the same rule. With no mutation configured every hook is the
//! identity, so enabling the feature changes no behaviour by itself.

use crate::config::CoreConfig;
use crate::state::ControllerState;
use crate::types::{ControllerId, Holder, Role, ROLE_COUNT};

/// One deliberate break of a voting rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
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
    /// A controller whose links all lose their carrier goes on as it was (the model's F16
    /// reverted): [`CoreConfig::restarts_when_unplugged`] says no.
    StayWhenUnplugged,
    /// A lockstep pair's member writes each output before comparing it with its second
    /// implementation's (the pair model's `write_before_compare`): a mismatch still takes it
    /// off the bus, but after the wrong output went out. No rule of this crate changes: the
    /// application that compares reads it (`rl controller`).
    WriteBeforeCompare,
    /// A controller whose voting loop stood still for a peer deadline (a SIGSTOP, a stall)
    /// goes on as the incarnation it was (the model's F12 reverted): it speaks at once with
    /// what it knew before the stall.
    KeepIncarnationOnResume,
    /// Agreed results are ranked without their epochs and standing (the model's F11
    /// reverted): after a healed cut, a result agreed alone ranks with the majority's newer
    /// one, by role and holder only.
    NoEpochRanking,
}

impl Mutation {
    /// Every mutation.
    pub const ALL: [Mutation; 8] = [
        Mutation::PromoteWithoutFailure,
        Mutation::IgnoreMinorityVote,
        Mutation::Failback,
        Mutation::AdmitFourth,
        Mutation::StayWhenUnplugged,
        Mutation::WriteBeforeCompare,
        Mutation::KeepIncarnationOnResume,
        Mutation::NoEpochRanking,
    ];

    /// Its name on a command line or in an environment variable (`promote-without-failure`).
    pub fn name(self) -> &'static str {
        match self {
            Mutation::PromoteWithoutFailure => "promote-without-failure",
            Mutation::IgnoreMinorityVote => "ignore-minority-vote",
            Mutation::Failback => "failback",
            Mutation::AdmitFourth => "admit-fourth",
            Mutation::StayWhenUnplugged => "stay-when-unplugged",
            Mutation::WriteBeforeCompare => "write-before-compare",
            Mutation::KeepIncarnationOnResume => "keep-incarnation-on-resume",
            Mutation::NoEpochRanking => "no-epoch-ranking",
        }
    }

    /// The mutation with this [`Mutation::name`].
    pub fn from_name(name: &str) -> Option<Mutation> {
        Mutation::ALL.into_iter().find(|m| m.name() == name)
    }
}

fn active(config: &CoreConfig, mutation: Mutation) -> bool {
    config.mutation == Some(mutation)
}

/// `StayWhenUnplugged`: whether a controller so configured goes on when its links all lose
/// their carrier, instead of starting again as a new incarnation.
pub(crate) fn stays_when_unplugged(config: &CoreConfig) -> bool {
    active(config, Mutation::StayWhenUnplugged)
}

/// `KeepIncarnationOnResume`: whether a controller so configured goes on after a stall,
/// instead of starting again as a new incarnation.
pub(crate) fn keeps_incarnation_on_resume(config: &CoreConfig) -> bool {
    active(config, Mutation::KeepIncarnationOnResume)
}

/// `NoEpochRanking`: whether the ranking leaves out the epoch and standing of each result.
pub(crate) fn rank_without_epochs(config: &CoreConfig) -> bool {
    active(config, Mutation::NoEpochRanking)
}

/// `PromoteWithoutFailure`: called when `silent_peer` missed this round's heartbeat but is not
/// lost yet.
pub(crate) fn promote_without_failure(
    config: &CoreConfig,
    c: &mut ControllerState,
    silent_peer: ControllerId,
) {
    if active(config, Mutation::PromoteWithoutFailure)
        && c.role == Some(Role::Secondary)
        && c.agreed
            .is_some_and(|agreed| agreed.holder(Role::Primary) == Some(silent_peer))
    {
        c.role = Some(Role::Primary);
        c.output = Some(Role::Primary.strength());
    }
}

/// `IgnoreMinorityVote`: the grace a dissent must outlast before it is marked FAILED.
pub(crate) fn minority_grace_rounds(config: &CoreConfig, grace_rounds: u32) -> u32 {
    if active(config, Mutation::IgnoreMinorityVote) {
        u32::MAX
    } else {
        grace_rounds
    }
}

/// `Failback`: whether the ranking ignores the known results.
pub(crate) fn rank_by_id_only(config: &CoreConfig) -> bool {
    active(config, Mutation::Failback)
}

/// `AdmitFourth`: a controller ranked beyond the three roles (`ranked` is the vote's order of
/// precedence) puts itself in as Tertiary.
pub(crate) fn admit_fourth_vote(config: &CoreConfig, c: &ControllerState, ranked: &mut [Holder]) {
    if !active(config, Mutation::AdmitFourth) {
        return;
    }
    if let Some(position) = ranked.iter().position(|h| h.id == c.id) {
        if position >= ROLE_COUNT {
            ranked.swap(ROLE_COUNT - 1, position);
        }
    }
}

/// `AdmitFourth`: a controller the agreed result leaves out takes the Tertiary role anyway.
pub(crate) fn admit_fourth_role(config: &CoreConfig, role: Option<Role>) -> Option<Role> {
    if active(config, Mutation::AdmitFourth) && role.is_none() {
        Some(Role::Tertiary)
    } else {
        role
    }
}
