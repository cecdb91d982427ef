//! Agreement: who counts (the electorate), when a quorum agrees on a result, and what
//! adopting it does (role, command strength, the ghost history of role changes).

use crate::config::Config;
use crate::fixes::{Mutation, Rules};
use crate::state::{Controller, History, Peer, State};
use crate::types::{Assignment, Holder, Id, Phase, Role};

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
    if size > 0 && counted > size / 2 {
        adopt(config, next, id, own);
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
    c.agreed = Some(agreed);
    c.phase = Phase::Steady;
    c.role = new_role;
    // No command output before a Primary exists and the controller holds a role.
    c.output = match (new_role, agreed.holder(Role::Primary)) {
        (Some(role), Some(_)) => Some(role.strength()),
        _ => None,
    };
    hold_primary_strength(config, c);
    note_role_change(&mut next.history, old_role, new_role);
    if jumped_queue && !next.history.partition_open {
        next.history.restart_jumped_queue = true;
    }
}

/// A new Primary keeps its previous strength while another live controller still claims
/// Primary in its heartbeats (a Primary the majority voted out has not yet noticed): two
/// writers at Primary strength would let DDS, not the vote, pick the commander.
pub(super) fn hold_primary_strength(config: &Config, c: &mut Controller) {
    if !config.rules().f8_hold_primary_strength || c.role != Some(Role::Primary) {
        return;
    }
    let contested = c
        .peers
        .iter()
        .any(|p| p.alive.is_some() && p.claims_primary);
    if contested {
        c.output = c
            .output
            .filter(|strength| *strength < Role::Primary.strength())
            .or(Some(Role::Secondary.strength()));
    }
}

/// Records the history the properties read. A demotion outside a partition (see
/// `properties::partitioned`) is a violation: roles then only ever move up.
pub(super) fn note_role_change(history: &mut History, old: Option<Role>, new: Option<Role>) {
    let partitioned = history.partition_open;
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
