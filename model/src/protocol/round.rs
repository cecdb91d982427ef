//! The end of a round, one controller at a time.
//!
//! At `Tick` every heartbeat of the round that was not lost is delivered, each carrying its
//! sender's state as of the round's start; then every live controller runs its dead-man
//! check, its initialization window, its re-vote and (F5) the round-boundary decisions.
//! [`round_step`] is one controller's part of that; `tick` runs it for every controller and
//! then does the bookkeeping that belongs to the whole state.

use super::agreement::{apply_output, confirm_provisional, try_agree, Source};
use super::minority::judge_minority;
use super::vote::{close_window, compute_vote, revote};
use super::{ready_to_vote, vote_pending};
use crate::config::Config;
use crate::fixes::Mutation;
use crate::state::{link_bit, Controller, Peer, State};
use crate::types::{Id, Phase, Role, ROLE_COUNT};

/// The end of a round: every controller's [`round_step`] but the one `asleep` through it
/// (`Action::Oversleep`), then the round's bookkeeping.
pub(super) fn tick(config: &Config, before: &State, next: &mut State, asleep: Option<Id>) {
    let ids: Vec<Id> = config.ids().collect();
    // Votes still undelivered now become overdue: they must arrive within the next round.
    for &from in &ids {
        for &to in &ids {
            if vote_pending(config, before, from, to) {
                next.overdue_votes |= link_bit(from, to);
            }
        }
    }
    for c in next.controllers.iter_mut().filter(|c| Some(c.id) != asleep) {
        c.establish_writers();
    }
    for &id in ids.iter().filter(|id| Some(**id) != asleep) {
        round_step(config, before, next, id);
    }
    // F17: a Primary that heard a peer take over from it starts again as a new incarnation,
    // as after a stall: its commands are late, and what it still sends must not outrank the
    // system it comes back to.
    for &id in &ids {
        if next.controller(id).deposed {
            let old_role = next.controller(id).role;
            super::new_life(config, before, next, id, true);
            super::agreement::note_role_change(&mut next.history, id, old_role, None);
        }
    }
    // A link stays down while it loses a heartbeat, either way, every round; a round that
    // carries its heartbeats ends its failure.
    next.history.links_down = both_ways(before.lost_links);
    next.lost_links = 0;
    next.history.quiet_rounds = (next.history.quiet_rounds + 1).min(config.settle_within_rounds);
}

/// Each link of `links` in both directions.
fn both_ways(links: u16) -> u16 {
    let width = crate::types::MAX_CONTROLLERS;
    (0..width * width)
        .filter(|bit| links & (1 << bit) != 0)
        .fold(links, |all, bit| {
            all | 1 << ((bit % width) * width + bit / width)
        })
}

/// One controller's end of a round: what controller `id` does when the round ends.
///
/// Reads from `before` (the state as the round began) the heartbeat of every other
/// controller: whether it is up, its incarnation, phase, agreed result, vote and command
/// strength, and whether it is lost on the way to `id` (`before.lost_links`, bit
/// `link_bit(from, id)`). Reads and writes `next.controller(id)`, which must still be `id`'s
/// state as the round began (no other controller's step changes it), and records ghost history
/// in `next.history`; the ghost "restart jumped the queue" also reads the other controllers of
/// `next`. A controller that is not up does nothing.
///
/// In order: heartbeats heard (a new peer or incarnation, the content each carries) and
/// missed (after `dead_after_rounds` of silence a peer is lost); then by phase: initializing
/// (late-joiner recognition, the window's quiet rounds, closing it on three heads heard),
/// voting or steady (a re-vote on a membership change or, F6, on new knowledge); then, with
/// F5, the round-boundary decisions: agreement, minority judgement and the Primary's
/// strength. Not included, as they belong to the whole state: overdue durable votes, clearing
/// the round's lost links, the quiet-round count and the partition flag (see `tick`), and a
/// window that expires right after the round (`Action::ExpireWindow`, a separate action).
pub fn round_step(config: &Config, before: &State, next: &mut State, id: Id) {
    if !before.controller(id).is_up() {
        return;
    }
    let heard = hear_round(config, before, next, id);
    match next.controller(id).phase {
        Phase::Initializing => end_initializing_round(config, next, id, heard.new_peer),
        Phase::Voting | Phase::Steady => {
            // Re-vote whenever what it knows gives another vote: a peer lost or new, or
            // (F6) another incumbent's result, which comes with the heartbeats.
            let c = next.controller(id);
            let knowledge_changed =
                config.rules().f6_vote_from_knowledge && Some(compute_vote(config, c)) != c.vote;
            if heard.membership_changed || knowledge_changed {
                revote(config, next, id);
            }
        }
        Phase::Failed => {}
    }
    if config.rules().f5_decide_on_heartbeats {
        try_agree(config, next, id, Source::Heartbeats);
        judge_minority(config, next, id, Source::Heartbeats);
        let c = next.controller_mut(id);
        if c.provisional && before.controller(id).provisional {
            c.provisional_rounds = 1;
        }
        confirm_provisional(config, c);
        release_takeover(c);
        if c.is_active() {
            // The strength follows the role: a held Primary (F8) rises once uncontested, a
            // raise waits for the roles above (F13).
            apply_output(config, c);
        }
    }
}

/// F17: the takeover strength is held until the taker has heard the deposed Primary no
/// longer commanding at 30 (its next incarnation, or its life at a lower strength) and holds
/// the Primary role of a backed result itself (a Secondary's or a provisional Primary's
/// strength would hand the actuator to another). Not hearing it is not enough: samples its
/// writer at 30 wrote may still be queued on the starved link, and would tie with the taker's
/// 30; a heartbeat that says otherwise left the same queue after them.
fn release_takeover(c: &mut Controller) {
    if let Some((deposed, incarnation)) = c.took_over_from {
        let peer = c.peer(deposed);
        let deposed_below = match peer.alive {
            Some(heard) if heard == incarnation => !peer.claims_primary,
            Some(_) => true,
            None => false,
        };
        let backed_primary =
            c.phase == Phase::Steady && c.role == Some(Role::Primary) && !c.provisional;
        if deposed_below && backed_primary {
            c.took_over_from = None;
        }
    }
}

/// What one round's heartbeats changed for a receiver.
#[derive(Default)]
struct HeartbeatOutcome {
    membership_changed: bool,
    new_peer: bool,
}

/// Every other controller's heartbeat of the round, heard or missed by `id`.
fn hear_round(config: &Config, before: &State, next: &mut State, id: Id) -> HeartbeatOutcome {
    let mut round = HeartbeatOutcome::default();
    for peer_id in config.ids().filter(|peer_id| *peer_id != id) {
        let sender = before.controller(peer_id);
        let heard = sender.is_up() && !before.link_lost(peer_id, id);
        if heard {
            let outcome = receive_heartbeat(config, next, id, sender);
            round.membership_changed |= outcome.membership_changed;
            round.new_peer |= outcome.new_peer;
        } else if next.controller(id).peer(peer_id).alive.is_some() {
            round.membership_changed |= miss_heartbeat(config, before, next, id, peer_id);
        }
    }
    round
}

/// The window's part of the round: who it now knows to be running, one more quiet round
/// unless a new peer was heard, and the window closes once three controllers are heard.
fn end_initializing_round(config: &Config, next: &mut State, id: Id, new_peer: bool) {
    let rules = config.rules();
    let c = next.controller_mut(id);
    // What it knows now: an incumbent heard this round, or a durable vote of a live peer. A
    // running system that vanished (crashed) no longer counts.
    let heard_running = rules.f1_late_join_by_heartbeat && c.peers.iter().any(|p| p.incumbent());
    let holds_vote = c
        .peers
        .iter()
        .any(|p| p.alive.is_some() && p.vote.is_some());
    c.late_joiner = if rules.f5_decide_on_heartbeats {
        heard_running
    } else {
        heard_running || holds_vote
    };
    if !new_peer {
        c.window_quiet_rounds = (c.window_quiet_rounds + 1).min(config.window_rounds);
    }
    if c.members_heard() >= ROLE_COUNT && ready_to_vote(c) {
        close_window(config, next, id);
    }
}

/// No heartbeat from a peer this round; after `dead_after_rounds` of silence it is lost
/// (paper: the dead-man count, "nulled out of the RedundancyInfo struct"). Returns whether
/// the membership changed.
fn miss_heartbeat(config: &Config, before: &State, next: &mut State, id: Id, peer_id: Id) -> bool {
    let dead_after = config.dead_after_rounds;
    let sender = before.controller(peer_id);
    let receiver = next.controller_mut(id);
    let peer = receiver.peer_mut(peer_id);
    let old_incarnation = peer.alive;
    peer.silent_rounds = (peer.silent_rounds + 1).min(dead_after);
    if peer.silent_rounds >= dead_after {
        let was_member = !peer.failed;
        *peer = Peer {
            alarm: true,
            ..Default::default()
        };
        if sender.is_up() && Some(sender.incarnation) == old_incarnation {
            // A live peer declared lost: the two sides may now act apart.
            next.history.revoted_after_loss = true;
            next.history.partition_open = true;
        }
        return was_member;
    }
    if config.mutated(Mutation::PromoteWithoutFailure)
        && receiver.role == Some(Role::Secondary)
        && receiver
            .agreed
            .is_some_and(|a| a.holder(Role::Primary) == Some(peer_id))
    {
        receiver.role = Some(Role::Primary);
        receiver.set_output(Some(Role::Primary.strength()));
    }
    false
}

/// `receiver` hears `sender`'s heartbeat.
fn receive_heartbeat(
    config: &Config,
    next: &mut State,
    receiver: Id,
    sender: &Controller,
) -> HeartbeatOutcome {
    let rules = config.rules();
    let c = next.controller_mut(receiver);
    let c_incarnation = c.incarnation;
    let mut deposed = false;
    let mut outcome = HeartbeatOutcome::default();
    let known_as = c.peer(sender.id).alive;
    let known = match known_as {
        Some(incarnation) => !rules.f3_incarnation_aware || incarnation == sender.incarnation,
        None => false,
    };
    if !known && rules.f3_incarnation_aware && known_as.is_some() {
        // A new incarnation retires the old one at once: its vote, FAILED mark and slot
        // belonged to a process that no longer exists.
        c.peer_mut(sender.id).vote = None;
    }
    let peer = c.peer_mut(sender.id);
    if known {
        peer.silent_rounds = 0;
    } else {
        if rules.f3_incarnation_aware || peer.alive.is_none() {
            peer.failed = false;
            peer.dissent_rounds = 0;
        }
        peer.alive = Some(sender.incarnation);
        peer.silent_rounds = 0;
        // The majority clears the alarm of a controller that came back.
        peer.alarm = false;
        outcome.new_peer = true;
        outcome.membership_changed = !peer.failed;
    }
    // A heartbeat carries what some rule reads: the result (incumbency), the vote (F5) and
    // whether the sender commands at Primary strength (F8).
    if rules.heartbeats_carry_results() {
        peer.heard_agreed = sender.agreed;
    }
    if rules.f5_decide_on_heartbeats {
        if peer.heard_vote != sender.vote {
            // A dissent counts only while the votes it is judged on stay the same.
            peer.dissent_rounds = 0;
        }
        peer.heard_vote = sender.vote;
    }
    if rules.f8_hold_primary_strength {
        peer.claims_primary = sender.output == Some(Role::Primary.strength());
    }
    if rules.f11_epochs {
        peer.heard_epoch = sender.epoch;
        peer.heard_provisional = sender.provisional;
    }
    if rules.f13_ordered_raise {
        peer.heard_strength = sender.established_strength();
    }
    if rules.f17_starved_takeover && sender.took_over_from == Some((receiver, c_incarnation)) {
        deposed = true;
    }
    if sender.phase == Phase::Failed && !peer.failed {
        // It announced its own failure: every voter excludes it.
        peer.failed = true;
        peer.alarm = true;
        outcome.membership_changed = true;
    }
    c.deposed |= deposed;
    outcome
}
