//! Agreement: who counts (the electorate), when a quorum agrees on a result, and what
//! adopting it does (role, command strength, the ghost history of role changes).

use crate::config::Config;
use crate::fixes::{Mutation, Rules};
use crate::state::{Controller, History, Peer, State};
use crate::types::{Assignment, Holder, Id, Phase, Role, PROVISIONAL_PRIMARY_STRENGTH, ROLE_COUNT};

/// Where the votes a decision counts come from.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Source {
    /// The votes carried by this round's heartbeats (F5).
    Heartbeats,
    /// The latest durable votes received (without F5, as the paper decides).
    DurableVotes,
}

impl Source {
    /// A peer's vote as this source has it: the one its heartbeat carried, or its latest
    /// durable vote (with F3, only one of the incarnation believed alive).
    pub(super) fn vote_of(self, rules: &Rules, peer: &Peer) -> Option<Assignment> {
        match self {
            Source::Heartbeats => peer.heard_vote,
            Source::DurableVotes => match (peer.alive, peer.vote) {
                (Some(alive), Some((incarnation, vote)))
                    if !rules.f3_incarnation_aware || alive == incarnation =>
                {
                    Some(vote)
                }
                _ => None,
            },
        }
    }
}

/// Who decides. With F4, while a running system exists only its incumbents' votes count, so
/// a newcomer never completes a quorum; otherwise everyone's.
pub(super) struct Electorate {
    pub votes: Vec<(Id, Assignment)>,
    /// How many controllers the quorum is a majority of.
    pub size: usize,
    /// Whether this controller's own vote counts.
    pub counts_self: bool,
}

pub(super) fn electorate(config: &Config, c: &Controller, source: Source) -> Electorate {
    let rules = config.rules();
    let running_system =
        rules.f4_quorum_of_view && (c.agreed.is_some() || c.peers.iter().any(|p| p.incumbent()));
    let counts_self = !running_system || c.agreed.is_some();
    let mut votes = Vec::new();
    let mut size = usize::from(counts_self);
    if counts_self {
        if let Some(own) = c.vote {
            votes.push((c.id, own));
        }
    }
    for (index, peer) in c.peers.iter().enumerate() {
        let id = (index + 1) as Id;
        if id == c.id || peer.failed || peer.alive.is_none() {
            continue;
        }
        if running_system && !peer.incumbent() {
            continue;
        }
        size += 1;
        if let Some(vote) = source.vote_of(&rules, peer) {
            votes.push((id, vote));
        }
    }
    Electorate {
        votes,
        size,
        counts_self,
    }
}

/// Takes the voted result once a quorum cast the same vote
/// (paper: "using its own vote and achieving two votes in agreement for a role").
pub(super) fn try_agree(config: &Config, next: &mut State, id: Id, source: Source) {
    let c = next.controller(id);
    if c.phase != Phase::Voting {
        return;
    }
    let Some(own) = c.vote else {
        return;
    };
    let electorate = electorate(config, c, source);
    // The quorum is a majority of the electorate (spares included), so two different results
    // can never both reach a quorum among the same controllers. The paper's "two votes in
    // agreement" counts only the result's own members.
    let (counted, size) = if config.rules().f4_quorum_of_view {
        let agreeing = electorate.votes.iter().filter(|(_, v)| *v == own).count();
        (agreeing, electorate.size)
    } else {
        let from_members = electorate
            .votes
            .iter()
            .filter(|(voter, vote)| *vote == own && own.contains(*voter))
            .count();
        (from_members, own.len())
    };
    // F14: a joiner takes the running system's result, not a vote the incumbents may still
    // revise (another joiner it does not hear may be admitted first).
    let joining = c.agreed.is_none() && c.peers.iter().any(|p| p.incumbent());
    if config.rules().f14_join_agreed
        && joining
        && !c
            .peers
            .iter()
            .any(|p| p.incumbent() && p.heard_agreed == Some(own))
    {
        return;
    }
    if size > 0 && counted > size / 2 {
        adopt(config, next, id, own);
    }
}

/// Who stands behind `result` is more than half as many as the last backed result's members
/// (three before there is one): itself and every live peer it has not marked FAILED whose
/// heartbeat carried `result` as its vote or its agreed result. A majority by count: newcomers
/// that vote for it make up for crashed members (two joiners on two sides of a partition are
/// beyond what this rule protects).
pub(super) fn backed(c: &Controller, result: Assignment) -> bool {
    let behind = 1 + c
        .peers
        .iter()
        .enumerate()
        .filter(|(index, p)| *index + 1 != usize::from(c.id) && p.alive.is_some() && !p.failed)
        .filter(|(_, p)| p.heard_vote == Some(result) || p.heard_agreed == Some(result))
        .count() as u32;
    let base = match c.quorum_base.count_ones() {
        0 => ROLE_COUNT as u32,
        members => members,
    };
    behind * 2 > base
}

/// It hears more than half as many live controllers as the last backed result had members:
/// not cut off, whatever its result's standing.
fn hears_majority(c: &Controller) -> bool {
    let base = match c.quorum_base.count_ones() {
        0 => ROLE_COUNT as u32,
        members => members,
    };
    c.members().count() as u32 * 2 > base
}

fn members_mask(agreed: Assignment) -> u8 {
    agreed.members().fold(0, |mask, id| mask | 1 << (id - 1))
}

/// F11: the epoch and standing of a newly agreed result. It advances the epoch only when it
/// is backed (see [`backed`]); otherwise it is provisional (a side that lost its majority),
/// and a merge ranks it below the majority's result.
fn take_epoch(c: &mut Controller, agreed: Assignment) {
    // A result an incumbent already holds (a joiner taking the system's result) keeps the
    // epoch it was agreed in: one result, one epoch.
    let held = c
        .peers
        .iter()
        .filter(|p| p.incumbent() && p.heard_agreed == Some(agreed) && !p.heard_provisional)
        .map(|p| p.heard_epoch)
        .max();
    if let Some(epoch) = held {
        c.epoch = epoch;
        c.quorum_base = members_mask(agreed);
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
fn known_epoch(c: &Controller) -> u32 {
    c.peers
        .iter()
        .filter(|p| p.incumbent())
        .map(|p| p.heard_epoch)
        .chain(std::iter::once(c.epoch))
        .max()
        .unwrap_or(0)
}

fn back(c: &mut Controller, agreed: Assignment) {
    c.epoch = known_epoch(c).saturating_add(1);
    c.quorum_base = members_mask(agreed);
    c.provisional = false;
}

/// F11: a provisional result that a majority now stands behind (a joiner agreed to it, the
/// peers heard it) becomes backed, with a new epoch.
pub(super) fn confirm_provisional(config: &Config, c: &mut Controller) {
    if !config.rules().f11_epochs || !c.provisional || c.phase != Phase::Steady {
        return;
    }
    if let Some(agreed) = c.agreed.filter(|agreed| backed(c, *agreed)) {
        back(c, agreed);
    }
}

fn adopt(config: &Config, next: &mut State, id: Id, agreed: Assignment) {
    // Ghost: a restarted controller's first role lands above a live controller that held a
    // role when it restarted (failback).
    let first = next.controller(id);
    let jumped_queue = first.role.is_none()
        && agreed.role_of(id).is_some_and(|own| {
            next.controllers.iter().any(|d| {
                first.held_roles_at_restart & (1 << (d.id - 1)) != 0
                    && d.is_active()
                    && agreed.role_of(d.id).is_some_and(|theirs| theirs > own)
            })
        });
    let c = next.controller_mut(id);
    let old_role = c.role;
    // A provisional result never had a majority: leaving its role for the majority's is the
    // merge working, not a demotion.
    let was_provisional = c.provisional;
    let mut new_role = if config.rules().f3_incarnation_aware {
        agreed.role_of_holder(Holder {
            id,
            incarnation: c.incarnation,
        })
    } else {
        agreed.role_of(id)
    };
    if config.mutated(Mutation::AdmitFourth) && new_role.is_none() {
        new_role = Some(Role::Tertiary);
    }
    if config.rules().f11_epochs {
        take_epoch(c, agreed);
    }
    c.agreed = Some(agreed);
    c.phase = Phase::Steady;
    c.role = new_role;
    let moved_down = old_role.is_some_and(|old| new_role.is_none_or(|new| new > old));
    if moved_down && config.rules().f13_ordered_raise && c.output != new_role.map(Role::strength) {
        // A lower role (a merge) starts from silence unless it already commands at the new
        // role's strength: its old writer's strength belongs to the role it left, and could
        // tie with the roles now above it.
        c.set_output(None);
    }
    apply_output(config, c);
    if !was_provisional {
        note_role_change(&mut next.history, id, old_role, new_role);
    }
    if jumped_queue && !next.history.partition_open {
        next.history.restart_jumped_queue = true;
    }
}

/// The strength a controller's role and result entitle it to now. None before a Primary
/// exists or without a role. F11: a provisional result's Primary
/// commands at 15 from its second round on and its standbys are silent. F8: a new Primary commands at 20 while another live controller still claims Primary in its heartbeats (a
/// Primary the majority voted out has not yet noticed): two writers at Primary strength would
/// let DDS, not the vote, pick the commander.
pub(super) fn entitled_strength(config: &Config, c: &Controller) -> Option<u8> {
    let rules = config.rules();
    if rules.f17_starved_takeover && c.took_over_from.is_some() {
        // F17: a takeover holds until the deposed Primary is heard again as a new life.
        return Some(crate::types::TAKEOVER_STRENGTH);
    }
    let role = c.role?;
    if !matches!(c.phase, Phase::Voting | Phase::Steady) {
        return None;
    }
    c.agreed?.holder(Role::Primary)?;
    if rules.f11_epochs && c.provisional {
        if role != Role::Primary {
            return None;
        }
        // Newly provisional, the majority side elects its Primary in this round: dropping
        // before it raises would hand the actuator to a standby first. While it hears a
        // majority (a healed cut, a result not yet confirmed) it keeps its strength until
        // the merge or the confirmation is agreed.
        // F15: a Primary at full strength whose lost peers cannot form a majority of the
        // last backed result keeps it: no side can elect a Primary above it, and dropping
        // would only hand the actuator to a standby that may still hear it (a link down one
        // way). A promoted standby has no such claim and drops.
        let unoutranked = rules.f15_hold_unoutranked
            && c.output == Some(Role::Primary.strength())
            && !c.lost_could_outvote();
        if c.output.is_some() && (c.provisional_rounds == 0 || hears_majority(c) || unoutranked) {
            // A takeover released meanwhile (F17) comes down to the Primary's strength.
            return c.output.map(|kept| kept.min(Role::Primary.strength()));
        }
        return Some(PROVISIONAL_PRIMARY_STRENGTH);
    }
    let contested = c
        .peers
        .iter()
        .any(|p| p.alive.is_some() && p.claims_primary);
    if role == Role::Primary && rules.f8_hold_primary_strength && contested {
        // F13: a Primary already at full strength keeps it (dropping to 20 would tie with
        // its Secondary); a new one waits at the Secondary's strength.
        let primary = Role::Primary.strength();
        let keeps_full = rules.f13_ordered_raise && c.output == Some(primary);
        return Some(if keeps_full {
            primary
        } else {
            Role::Secondary.strength()
        });
    }
    Some(role.strength())
}

/// Moves the command output to the entitled strength. F13: a raise waits until every
/// controller above it in the agreed result reports an established strength above the new
/// one, so a tie can never hand the actuator to a lower role; lowering is immediate.
pub(super) fn apply_output(config: &Config, c: &mut Controller) {
    let target = entitled_strength(config, c);
    let raise = match (c.output, target) {
        (old, Some(new)) => old.is_none_or(|old| new > old),
        _ => false,
    };
    if raise && config.rules().f13_ordered_raise {
        let new = target.unwrap_or_default();
        if !above_established(c, new) {
            return;
        }
    }
    c.set_output(target);
}

/// Every live holder of a role above `c`'s in its agreed result reported, in its last
/// heartbeat, an established strength of at least its own role's (and so above `strength`).
fn above_established(c: &Controller, strength: u8) -> bool {
    let (Some(agreed), Some(role)) = (c.agreed, c.role) else {
        return true;
    };
    Role::ALL[..role.rank()].iter().all(|above| {
        agreed.holder(*above).is_none_or(|holder| {
            holder == c.id
                || c.peer(holder)
                    .heard_strength
                    .is_some_and(|reported| reported > strength && reported >= above.strength())
        })
    })
}

/// Records the history the properties read. A demotion outside a partition (see
/// `properties::partitioned`) of a controller that was not away (paused or cut off) is a
/// violation: roles then only ever move up.
pub(super) fn note_role_change(
    history: &mut History,
    id: Id,
    old: Option<Role>,
    new: Option<Role>,
) {
    let partitioned = history.partition_open || history.away & (1 << (id - 1)) != 0;
    let Some(old) = old else {
        return;
    };
    let demoted = new.is_none_or(|new| new > old);
    if demoted && !partitioned && history.demoted_outside_partition.is_none() {
        history.demoted_outside_partition = Some(old);
    }
    if old == Role::Secondary && new == Some(Role::Primary) {
        history.secondary_promoted = true;
    }
}
