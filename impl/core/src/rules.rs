//! The protocol's rules, applied to one controller's state at its round boundary.
//!
//! Each function is the implementation of the model's rule of the same name
//! (`model/src/protocol/`, default variant); docs/protocol.md states them in prose. Decisions
//! read only what this round's heartbeats carried (finding F5): nothing is decided as
//! messages arrive.

use crate::config::CoreConfig;
use crate::epochs;
use crate::report::Heartbeat;
use crate::state::{ControllerState, Peer};
use crate::strength;
use crate::types::{
    AlarmReason, Arrival, Assignment, ControllerId, Holder, Phase, Role, ROLE_COUNT,
};

/// The end of a round: every heartbeat heard this round (the latest per peer) is taken in,
/// silent peers are counted down, then the controller decides.
pub(crate) fn end_round(config: &CoreConfig, c: &mut ControllerState, heard: &[Heartbeat]) {
    let was_provisional = c.provisional;
    let mut membership_changed = false;
    let mut new_peer = false;
    let mut ids: Vec<ControllerId> = c.peers.keys().copied().collect();
    ids.extend(heard.iter().map(|h| h.id));
    ids.sort_unstable();
    ids.dedup();
    for peer_id in ids {
        if peer_id == c.id {
            continue;
        }
        match heard.iter().rev().find(|h| h.id == peer_id) {
            Some(heartbeat) => {
                let outcome = receive_heartbeat(c, heartbeat);
                membership_changed |= outcome.membership_changed;
                new_peer |= outcome.new_peer;
            }
            None => {
                if c.peers.get(&peer_id).is_some_and(|p| p.alive.is_some()) {
                    membership_changed |= miss_heartbeat(config, c, peer_id);
                }
            }
        }
    }
    match c.phase {
        Phase::Initializing => {
            c.late_joiner = c.peers.values().any(Peer::incumbent);
            if !new_peer {
                c.window_quiet_rounds =
                    (c.window_quiet_rounds + 1).min(config.rounds.window_rounds);
            }
            if c.members_heard() >= ROLE_COUNT && ready_to_vote(c) {
                close_window(config, c);
            }
        }
        Phase::Voting | Phase::Steady => {
            // Re-vote whenever what it knows gives another vote: a peer lost or new, or
            // another incumbent's result, which comes with the heartbeats.
            let knowledge_changed = Some(compute_vote(config, c)) != c.vote;
            if membership_changed || knowledge_changed {
                revote(config, c);
            }
        }
        Phase::Failed => {}
    }
    try_agree(config, c);
    judge_minority(config, c);
    if c.provisional && was_provisional {
        c.provisional_rounds = 1;
    }
    epochs::confirm_provisional(c);
    release_takeover(c);
    if c.is_active() {
        // The strength follows the role: a held Primary (F8) rises once uncontested, a raise
        // waits for the roles above (F13).
        strength::apply_output(c);
    }
}

/// F17: a Secondary whose agreed Primary, commanding at 30, sends commands that arrive late
/// takes over at once at the takeover strength when a command of the agreed Tertiary then
/// arrives on time (`on_time_from`, the input that triggers it): the actuator would otherwise
/// go to it at the Primary's command deadline and back to the Primary with each late sample.
/// Only a Tertiary sample that arrives on time after the Primary's late one shows its own
/// link is not the starved one (measured: with the Secondary's own link starved, the
/// Primary's first delayed sample came before the Tertiary's, whose last verdict was still
/// "on time", `lab run random --seed 5`). Without it, it cannot tell a late Primary from its
/// own starved link, and does nothing. Taken as the measurement comes, not at a round's end:
/// the takeover must come before the actuator's deadline.
pub(crate) fn take_over_from_late(c: &mut ControllerState, on_time_from: ControllerId) {
    if c.took_over_from.is_some()
        || !c.is_active()
        || c.role != Some(Role::Secondary)
        || c.output.is_none()
    {
        return;
    }
    let Some(agreed) = c.agreed else {
        return;
    };
    let (Some(primary), Some(tertiary)) = (
        agreed.0[Role::Primary.rank()],
        agreed.0[Role::Tertiary.rank()],
    ) else {
        return;
    };
    let is = |holder: Holder, arrival: Arrival| {
        c.peers.get(&holder.id).is_some_and(|p| {
            p.alive == Some(holder.incarnation) && !p.failed && p.commands == arrival
        })
    };
    let commanding = c.peers.get(&primary.id).is_some_and(|p| p.claims_primary);
    let fresh = on_time_from == tertiary.id;
    if fresh && commanding && is(primary, Arrival::Late) && is(tertiary, Arrival::OnTime) {
        c.take_over(primary);
    }
}

/// F17: the takeover strength is held until the taker has heard the deposed Primary no
/// longer commanding at 30 (its next incarnation, or its life at a lower strength) and holds
/// the Primary role of a backed result itself (a Secondary's or a provisional Primary's
/// strength would hand the actuator to another). Not hearing it is not enough: samples its
/// writer at 30 wrote may still be queued on the starved link, and would tie with the taker's
/// 30 (measured: `lab run tbf-primary --seed 2`); a heartbeat that says otherwise left the
/// same queue after them.
fn release_takeover(c: &mut ControllerState) {
    if let Some(deposed) = c.took_over_from {
        let deposed_below = c.peers.get(&deposed.id).is_some_and(|p| match p.alive {
            Some(heard) if heard == deposed.incarnation => !p.claims_primary,
            Some(_) => true,
            None => false,
        });
        let backed_primary =
            c.phase == Phase::Steady && c.role == Some(Role::Primary) && !c.provisional;
        if deposed_below && backed_primary {
            c.took_over_from = None;
        }
    }
}

/// No heartbeat from a live peer this round; after `dead_after` silent rounds it is lost and
/// an alarm is raised. Returns whether the membership changed.
fn miss_heartbeat(config: &CoreConfig, c: &mut ControllerState, peer_id: ControllerId) -> bool {
    let Some(peer) = c.peers.get_mut(&peer_id) else {
        return false;
    };
    let dead_after_rounds = config.rounds.dead_after_rounds;
    peer.silent_rounds = (peer.silent_rounds + 1).min(dead_after_rounds);
    if peer.silent_rounds < dead_after_rounds {
        #[cfg(feature = "mutation")]
        crate::mutation::promote_without_failure(config, c, peer_id);
        return false;
    }
    let was_member = !peer.failed;
    let alarm = peer.alarm.or(Some(AlarmReason::Lost));
    // How its commands arrive is measured apart from its heartbeats, and outlives them.
    let commands = peer.commands;
    *peer = Peer {
        alarm,
        commands,
        ..Peer::default()
    };
    was_member
}

struct HeartbeatOutcome {
    membership_changed: bool,
    new_peer: bool,
}

/// Takes in a peer's heartbeat. A new incarnation retires the old one at once: its FAILED
/// mark and slot belonged to a process that no longer exists (finding F3).
fn receive_heartbeat(c: &mut ControllerState, heartbeat: &Heartbeat) -> HeartbeatOutcome {
    // F17: a peer took over from this life: its commands arrive late, and what it still sends
    // must not outrank the system it comes back to.
    c.deposed |= heartbeat.took_over_from == Some(c.holder());
    let peer = c.peers.entry(heartbeat.id).or_default();
    let mut outcome = HeartbeatOutcome {
        membership_changed: false,
        new_peer: false,
    };
    if peer.alive == Some(heartbeat.incarnation) {
        peer.silent_rounds = 0;
    } else {
        peer.failed = false;
        peer.dissent_rounds = 0;
        peer.alive = Some(heartbeat.incarnation);
        peer.silent_rounds = 0;
        // The majority clears the alarm of a controller that came back.
        peer.alarm = None;
        outcome.new_peer = true;
        outcome.membership_changed = true;
    }
    if peer.heard_vote != heartbeat.vote {
        // A dissent counts only while the votes it is judged on stay the same.
        peer.dissent_rounds = 0;
    }
    peer.heard_agreed = heartbeat.agreed;
    peer.heard_vote = heartbeat.vote;
    peer.claims_primary = heartbeat.strength == Some(Role::Primary.strength());
    peer.heard_epoch = heartbeat.epoch;
    peer.heard_provisional = heartbeat.provisional;
    peer.heard_strength = heartbeat.established_strength;
    if heartbeat.phase == Phase::Failed && !peer.failed {
        // It announced its own failure: every voter excludes it.
        peer.failed = true;
        peer.alarm = Some(AlarmReason::Failed);
        outcome.membership_changed = true;
    }
    outcome
}

/// A late joiner votes only once it has heard the running system's result.
fn ready_to_vote(c: &ControllerState) -> bool {
    !c.late_joiner || c.peers.values().any(Peer::incumbent)
}

/// The initialization window may time out now (checked right after a round ends).
pub(crate) fn window_can_expire(config: &CoreConfig, c: &ControllerState) -> bool {
    c.phase == Phase::Initializing
        && c.window_quiet_rounds >= config.rounds.window_rounds
        && ready_to_vote(c)
}

/// The initialization window closes: cast the first vote (paper, "Voting Algorithm").
pub(crate) fn close_window(config: &CoreConfig, c: &mut ControllerState) {
    c.phase = Phase::Voting;
    revote(config, c);
}

/// Computes and publishes its vote. Decided at the round boundary; only a controller alone
/// agrees at once.
fn revote(config: &CoreConfig, c: &mut ControllerState) {
    if c.phase == Phase::Failed {
        return;
    }
    let vote = compute_vote(config, c);
    c.phase = Phase::Voting;
    if c.vote != Some(vote) {
        c.vote = Some(vote);
        c.self_dissent_rounds = 0;
    }
    if electorate(c).size == 1 {
        try_agree(config, c);
    }
}

/// The voting algorithm: who should hold which role, as this controller sees it.
///
/// A function of what it knows, never of its own earlier votes (finding F6): every live
/// member is ranked by the best place any known agreed result gives that very incarnation (its
/// own and every incumbent's, from heartbeats), then by lowest id; three at most. A place in a
/// newer epoch comes first, a backed result before a provisional one (F11), then the role, and
/// between two results of one epoch that give one role to two members, the member that holds
/// that result itself. Live holders keep their
/// roles (no oscillation), a lost holder's juniors move up, newcomers come in below, and after
/// a healed partition the side that kept a majority keeps its roles.
// `config` selects a mutation (feature `mutation`); the correct rules need only the state.
#[cfg_attr(not(feature = "mutation"), allow(unused_variables))]
pub(crate) fn compute_vote(config: &CoreConfig, c: &ControllerState) -> Assignment {
    #[cfg_attr(not(feature = "mutation"), allow(unused_mut))]
    let mut known: Vec<KnownResult> = c
        .agreed
        .map(|result| KnownResult {
            result,
            epoch: c.epoch,
            provisional: c.provisional,
            held_by: c.id,
        })
        .into_iter()
        .collect();
    known.extend(
        c.peers
            .iter()
            .filter(|(_, p)| p.incumbent())
            .filter_map(|(&id, p)| {
                p.heard_agreed.map(|result| KnownResult {
                    result,
                    epoch: p.heard_epoch,
                    provisional: p.heard_provisional,
                    held_by: id,
                })
            }),
    );
    #[cfg(feature = "mutation")]
    if crate::mutation::rank_without_epochs(config) {
        for known in &mut known {
            known.epoch = 0;
            known.provisional = false;
        }
    }
    let unranked = (std::cmp::Reverse(0), true, ROLE_COUNT, true);
    let rank = |member: &Holder| -> (std::cmp::Reverse<u32>, bool, usize, bool) {
        #[cfg(feature = "mutation")]
        if crate::mutation::rank_by_id_only(config) {
            return unranked;
        }
        known
            .iter()
            .filter_map(|known| {
                known.result.role_of_holder(*member).map(|role| {
                    (
                        std::cmp::Reverse(known.epoch),
                        known.provisional,
                        role.rank(),
                        known.held_by != member.id,
                    )
                })
            })
            .min()
            .unwrap_or(unranked)
    };
    let mut ranked = c.members();
    ranked.sort_by_key(|member| (rank(member), member.id));
    #[cfg(feature = "mutation")]
    crate::mutation::admit_fourth_vote(config, c, &mut ranked);
    Assignment::from_ranked(ranked)
}

/// An agreed result this controller knows of, with what ranks it against the others.
struct KnownResult {
    result: Assignment,
    epoch: u32,
    provisional: bool,
    /// The controller whose state or heartbeat carried it.
    held_by: ControllerId,
}

/// Who decides: while a running system exists only its incumbents' votes count, so a
/// newcomer never completes a quorum (finding F4); otherwise everyone's.
pub(crate) struct Electorate {
    pub votes: Vec<(ControllerId, Assignment)>,
    /// How many controllers the quorum is a majority of.
    pub size: usize,
    /// Whether this controller's own vote counts.
    pub counts_self: bool,
}

pub(crate) fn electorate(c: &ControllerState) -> Electorate {
    let running_system = c.agreed.is_some() || c.peers.values().any(Peer::incumbent);
    let counts_self = !running_system || c.agreed.is_some();
    let mut votes = Vec::new();
    let mut size = usize::from(counts_self);
    if counts_self {
        if let Some(own) = c.vote {
            votes.push((c.id, own));
        }
    }
    for (&id, peer) in &c.peers {
        if id == c.id || peer.failed || peer.alive.is_none() {
            continue;
        }
        if running_system && !peer.incumbent() {
            continue;
        }
        size += 1;
        if let Some(vote) = peer.heard_vote {
            votes.push((id, vote));
        }
    }
    Electorate {
        votes,
        size,
        counts_self,
    }
}

/// Takes the voted result once a majority of the electorate cast the same vote (paper:
/// "using its own vote and achieving two votes in agreement for a role").
fn try_agree(config: &CoreConfig, c: &mut ControllerState) {
    if c.phase != Phase::Voting {
        return;
    }
    let Some(own) = c.vote else {
        return;
    };
    let electorate = electorate(c);
    let agreeing = electorate.votes.iter().filter(|(_, v)| *v == own).count();
    // A joiner takes the running system's result, not a vote the incumbents may still revise
    // (another joiner it does not hear may be admitted first; finding F14).
    let joining = c.agreed.is_none() && c.peers.values().any(Peer::incumbent);
    if joining
        && !c
            .peers
            .values()
            .any(|p| p.incumbent() && p.heard_agreed == Some(own))
    {
        return;
    }
    if electorate.size > 0 && agreeing > electorate.size / 2 {
        adopt(config, c, own);
    }
}

// `config` selects a mutation (feature `mutation`); the correct rules need only the state.
#[cfg_attr(not(feature = "mutation"), allow(unused_variables))]
fn adopt(config: &CoreConfig, c: &mut ControllerState, agreed: Assignment) {
    let role = agreed.role_of_holder(c.holder());
    #[cfg(feature = "mutation")]
    let role = crate::mutation::admit_fourth_role(config, role);
    let old_role = c.role;
    epochs::take_epoch(c, agreed);
    c.agreed = Some(agreed);
    c.phase = Phase::Steady;
    c.role = role;
    let moved_down = old_role.is_some_and(|old| role.is_none_or(|new| new > old));
    if moved_down && c.output != role.map(Role::strength) {
        // A lower role (a merge) starts from silence unless it already commands at the new
        // role's strength: its old writer's strength belongs to the role it left, and could
        // tie with the roles now above it (finding F13).
        c.set_output(None);
    }
    strength::apply_output(c);
}

/// Marks minority voters FAILED; a controller that is itself the minority fails itself (paper:
/// "Any unit that does not agree with the two votes of the other controllers will take itself
/// offline").
fn judge_minority(config: &CoreConfig, c: &mut ControllerState) {
    if !matches!(c.phase, Phase::Voting | Phase::Steady) {
        return;
    }
    let grace = config.rounds.minority_grace_rounds();
    #[cfg(feature = "mutation")]
    let grace = crate::mutation::minority_grace_rounds(config, grace);
    let Electorate {
        votes, counts_self, ..
    } = electorate(c);
    // Judging itself it counts every live peer's vote, FAILED marks notwithstanding
    // (finding F7).
    let own_outvoted = counts_self && c.vote.is_some_and(|own| outvoted(c, own));
    if judge_self(c, own_outvoted, grace) {
        return;
    }
    let mut majority: Option<(Assignment, usize)> = None;
    for (_, vote) in &votes {
        let count = votes.iter().filter(|(_, v)| v == vote).count();
        if majority.is_none_or(|(_, best)| count > best) {
            majority = Some((*vote, count));
        }
    }
    let winner = majority
        .filter(|(_, count)| *count >= 2 && count * 2 > votes.len())
        .map(|(vote, _)| vote);
    let mut marked = false;
    for (voter, vote) in &votes {
        if *voter == c.id {
            continue;
        }
        let Some(peer) = c.peers.get_mut(voter) else {
            continue;
        };
        if winner.is_none_or(|winner| *vote == winner) {
            peer.dissent_rounds = 0;
            continue;
        }
        if peer.silent_rounds > 0 {
            // Its heartbeat was lost this round: the vote judged is last round's, which it
            // may have changed since. A dissent counts only in rounds it was heard.
            continue;
        }
        peer.dissent_rounds = peer.dissent_rounds.saturating_add(1);
        if peer.dissent_rounds > grace {
            peer.failed = true;
            peer.alarm = Some(AlarmReason::Failed);
            marked = true;
        }
    }
    if marked {
        revote(config, c);
    }
}

/// Two or more other live voters agree on a result other than `own`, and they are a majority
/// of the others.
fn outvoted(c: &ControllerState, own: Assignment) -> bool {
    let others: Vec<Assignment> = c
        .live_peers()
        .filter(|(id, _)| *id != c.id)
        // Newcomers' votes never count (see `electorate`).
        .filter_map(|(_, peer)| peer.heard_agreed.and(peer.heard_vote))
        .collect();
    others.iter().any(|vote| {
        let count = others.iter().filter(|v| *v == vote).count();
        *vote != own && count >= 2 && count * 2 > others.len()
    })
}

/// Counts the rounds this controller has been outvoted; past the grace it fails itself.
fn judge_self(c: &mut ControllerState, outvoted: bool, grace: u32) -> bool {
    if !outvoted {
        c.self_dissent_rounds = 0;
        return false;
    }
    c.self_dissent_rounds = c.self_dissent_rounds.saturating_add(1);
    if c.self_dissent_rounds > grace {
        fail_self(c);
        return true;
    }
    false
}

/// Stops commanding and voting until restarted.
pub(crate) fn fail_self(c: &mut ControllerState) {
    c.phase = Phase::Failed;
    c.role = None;
    c.set_output(None);
    c.vote = None;
    c.agreed = None;
}
