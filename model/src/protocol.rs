//! The voting protocol's rules: what each action does to the controllers.
//!
//! Every rule cites the paper section it comes from; where the default algorithm departs from
//! the paper's literal text, the `Rules` flag and docs/findings.md say why.

use crate::config::Config;
use crate::state::{link_bit, Action, Controller, History, State};
use crate::types::{Assignment, Holder, Id, Life, Mutation, Phase, Role, ROLE_COUNT};

/// The initial states: controllers 1..=k powered on together at system initialization (the
/// timing assumption "they start within the window"), for every k up to the founders.
pub fn init_states(config: &Config) -> Vec<State> {
    let founders = usize::from(config.founders);
    // The first k founders for every k: which ids start matters only through their order,
    // and later ids joining covers the rest.
    (1..=founders)
        .map(|count| (1u32 << count) - 1)
        .map(|started| State {
            controllers: config
                .ids()
                .map(|id| {
                    let index = usize::from(id - 1);
                    let starts = index < founders && started & (1 << index) != 0;
                    let mut controller =
                        Controller::new(id, if starts { Life::Up } else { Life::NotStarted });
                    if starts && config.mutated(Mutation::OutputBeforeRole) {
                        controller.output = Some(Role::Tertiary.strength());
                    }
                    controller
                })
                .collect(),
            lost_links: 0,
            overdue_votes: 0,
            history: History::default(),
        })
        .collect()
}

/// A vote from `from` that `to` has not received yet. Only the paper's rules decide on
/// durable votes; with the default rules votes travel in heartbeats and the durable copy is
/// for late readers and tools, so its delivery is not modelled.
pub fn vote_pending(config: &Config, state: &State, from: Id, to: Id) -> bool {
    if config.rules().decide_on_heartbeats {
        return false;
    }
    let sender = state.controller(from);
    let receiver = state.controller(to);
    if from == to || !sender.is_up() || !receiver.is_up() {
        return false;
    }
    match sender.vote {
        Some(vote) => receiver.peer(from).vote != Some((sender.incarnation, vote)),
        None => false,
    }
}

/// The actions enabled in a state, in a fixed order.
pub fn actions(config: &Config, state: &State, out: &mut Vec<Action>) {
    let ids = config.ids();
    let urgent_before = out.len();
    for id in ids.clone() {
        if window_can_expire(config, state.controller(id)) {
            out.push(Action::ExpireWindow { controller: id });
        }
    }
    for to in ids.clone() {
        if ids
            .clone()
            .any(|from| vote_pending(config, state, from, to))
        {
            out.push(Action::DeliverVotes { to });
        }
    }
    // Timing assumption: a round ends only when its due timers have fired and every vote that
    // was already in flight at the last round's end has arrived.
    let timer_due = out[urgent_before..]
        .iter()
        .any(|a| matches!(a, Action::ExpireWindow { .. }));
    let vote_overdue = out[urgent_before..].iter().any(|a| match *a {
        Action::DeliverVotes { to } => config.ids().any(|from| {
            state.overdue_votes & link_bit(from, to) != 0 && vote_pending(config, state, from, to)
        }),
        _ => false,
    });
    if !timer_due && !vote_overdue && state.up().next().is_some() {
        out.push(Action::Tick);
    }
    if state.history.losses < config.max_lost_heartbeats {
        for from in ids.clone() {
            for to in ids.clone() {
                if from != to
                    && state.controller(from).is_up()
                    && state.controller(to).is_up()
                    && state.lost_links & link_bit(from, to) == 0
                {
                    out.push(Action::LoseHeartbeat { from, to });
                }
            }
        }
    }
    for id in ids {
        let c = state.controller(id);
        match c.life {
            Life::Up => {
                if state.history.crashes < config.max_crashes {
                    out.push(Action::Crash { controller: id });
                }
                if c.phase == Phase::Failed && state.history.restarts < config.max_restarts {
                    out.push(Action::Restart { controller: id });
                }
            }
            Life::Down => {
                if state.history.restarts < config.max_restarts {
                    out.push(Action::Restart { controller: id });
                }
            }
            Life::NotStarted => out.push(Action::Join { controller: id }),
        }
    }
}

/// The state after an action; `None` if the action is not enabled.
pub fn next_state(config: &Config, state: &State, action: Action) -> Option<State> {
    let mut next = state.clone();
    match action {
        Action::LoseHeartbeat { from, to } => {
            next.lost_links |= link_bit(from, to);
            next.history.losses += 1;
            next.history.quiet_rounds = 0;
            next.history.partition_open = true;
        }
        Action::Tick => tick(config, state, &mut next),
        Action::ExpireWindow { controller } => {
            if !window_can_expire(config, state.controller(controller)) {
                return None;
            }
            close_window(config, &mut next, controller);
        }
        Action::DeliverVotes { to } => {
            let senders: Vec<Id> = config
                .ids()
                .filter(|from| vote_pending(config, state, *from, to))
                .collect();
            if senders.is_empty() {
                return None;
            }
            deliver_votes(config, &mut next, &senders, to);
        }
        Action::Crash { controller } => {
            vote_superseded(config, &mut next, controller);
            let c = next.controller_mut(controller);
            let incarnation = c.incarnation;
            *c = Controller::new(controller, Life::Down);
            c.incarnation = incarnation;
            forget_links(&mut next, controller);
            next.history.crashes += 1;
            next.history.quiet_rounds = 0;
        }
        Action::Restart { controller } | Action::Join { controller } => {
            let c = next.controller_mut(controller);
            let incarnation = match action {
                Action::Restart { .. } => c.incarnation + 1,
                _ => 0,
            };
            *c = Controller::new(controller, Life::Up);
            c.incarnation = incarnation;
            if matches!(action, Action::Restart { .. }) {
                // Ghost: who held a role when it restarted (it must come in below them).
                c.held_roles_at_restart = state
                    .controllers
                    .iter()
                    .filter(|d| d.id != controller && d.is_active() && d.role.is_some())
                    .fold(0u8, |mask, d| mask | 1 << (d.id - 1));
            }
            if config.mutated(Mutation::OutputBeforeRole) {
                c.output = Some(Role::Tertiary.strength());
            }
            forget_links(&mut next, controller);
            if matches!(action, Action::Restart { .. }) {
                next.history.restarts += 1;
            }
            next.history.quiet_rounds = 0;
        }
    }
    Some(next)
}

fn forget_links(state: &mut State, id: Id) {
    for other in 1..=state.controllers.len() as Id {
        let mask = !(link_bit(id, other) | link_bit(other, id));
        state.lost_links &= mask;
        state.overdue_votes &= mask;
    }
}

fn window_can_expire(config: &Config, c: &Controller) -> bool {
    c.is_up()
        && c.phase == Phase::Initializing
        && c.window_quiet_rounds >= config.window_rounds
        && ready_to_vote(c)
}

/// A late joiner votes only once it can learn the running system's result: from a heartbeat
/// (default rules) or a durable vote (the paper's).
fn ready_to_vote(c: &Controller) -> bool {
    !c.late_joiner
        || c.peers
            .iter()
            .any(|p| p.incumbent() || (p.alive.is_some() && p.vote.is_some()))
}

fn window_over(config: &Config, c: &Controller) -> bool {
    c.window_quiet_rounds >= config.window_rounds || c.members_heard() >= ROLE_COUNT
}

impl Controller {
    /// Distinct controllers heard (itself included), FAILED ones too: the window counts heads.
    fn members_heard(&self) -> usize {
        1 + self
            .peers
            .iter()
            .enumerate()
            .filter(|(index, p)| *index + 1 != usize::from(self.id) && p.alive.is_some())
            .count()
    }
}

/// The end of a round. Heartbeats carry the sender's state as it was when the round began:
/// its incarnation, phase, role, agreed result and current vote.
fn tick(config: &Config, before: &State, next: &mut State) {
    let rules = config.rules();
    let ids: Vec<Id> = config.ids().collect();
    // Votes still undelivered now become overdue: they must arrive within the next round.
    for &from in &ids {
        for &to in &ids {
            if vote_pending(config, before, from, to) {
                next.overdue_votes |= link_bit(from, to);
            }
        }
    }
    for &id in &ids {
        if !before.controller(id).is_up() {
            continue;
        }
        let mut membership_changed = false;
        let mut new_peer = false;
        for &peer_id in &ids {
            if peer_id == id {
                continue;
            }
            let sender = before.controller(peer_id);
            let heard = sender.is_up() && before.lost_links & link_bit(peer_id, id) == 0;
            if heard {
                let outcome = receive_heartbeat(config, next, id, sender);
                membership_changed |= outcome.membership_changed;
                new_peer |= outcome.new_peer;
            } else if next.controller(id).peer(peer_id).alive.is_some() {
                membership_changed |= miss_heartbeat(config, before, next, id, peer_id);
            }
        }
        let c = next.controller_mut(id);
        match c.phase {
            Phase::Initializing => {
                // What it knows now: an incumbent heard this round, or a durable vote of a live
                // peer. A running system that vanished (crashed) no longer counts.
                let heard_running =
                    rules.late_join_by_heartbeat && c.peers.iter().any(|p| p.incumbent());
                let holds_vote = c
                    .peers
                    .iter()
                    .any(|p| p.alive.is_some() && p.vote.is_some());
                c.late_joiner = if rules.decide_on_heartbeats {
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
            Phase::Voting | Phase::Steady => {
                // Re-vote whenever what it knows gives another vote: a peer lost or new, or
                // (default rules) another incumbent's result, which comes with the heartbeats.
                let knowledge_changed =
                    rules.decide_on_heartbeats && Some(compute_vote(config, c)) != c.vote;
                if membership_changed || knowledge_changed {
                    revote(config, next, id);
                }
            }
            Phase::Failed => {}
        }
        if rules.decide_on_heartbeats {
            try_agree(config, next, id, Source::Heartbeats);
            judge_minority(config, next, id, Source::Heartbeats);
            let c = next.controller_mut(id);
            if c.role == Some(Role::Primary) && c.is_active() {
                c.output = Some(Role::Primary.strength());
                hold_primary_strength(config, c);
            }
        }
    }
    next.lost_links = 0;
    next.history.quiet_rounds = (next.history.quiet_rounds + 1).min(config.settle_within_rounds);
    if next.history.partition_open && crate::properties::settled(next).is_some() {
        next.history.partition_open = false;
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
        *peer = crate::state::Peer {
            alarm: true,
            ..Default::default()
        };
        if sender.is_up() && Some(sender.incarnation) == old_incarnation {
            next.history.revoted_after_loss = true;
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
        receiver.output = Some(Role::Primary.strength());
    }
    false
}

struct HeartbeatOutcome {
    membership_changed: bool,
    new_peer: bool,
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
    let mut outcome = HeartbeatOutcome {
        membership_changed: false,
        new_peer: false,
    };
    let known_as = c.peer(sender.id).alive;
    let known = match known_as {
        Some(incarnation) => !rules.incarnation_aware || incarnation == sender.incarnation,
        None => false,
    };
    if !known && rules.incarnation_aware && known_as.is_some() {
        // A new incarnation retires the old one at once: its vote, FAILED mark and slot
        // belonged to a process that no longer exists.
        c.peer_mut(sender.id).vote = None;
    }
    let peer = c.peer_mut(sender.id);
    if known {
        peer.silent_rounds = 0;
    } else {
        if rules.incarnation_aware || peer.alive.is_none() {
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
    if rules.decide_on_heartbeats {
        if peer.heard_vote != sender.vote {
            // A dissent counts only while the votes it is judged on stay the same.
            peer.dissent_rounds = 0;
        }
        peer.heard_agreed = sender.agreed;
        peer.heard_vote = sender.vote;
        peer.claims_primary = sender.output == Some(Role::Primary.strength());
    }
    if sender.phase == Phase::Failed && !peer.failed {
        // It announced its own failure: every voter excludes it.
        peer.failed = true;
        peer.alarm = true;
        outcome.membership_changed = true;
    }
    outcome
}

/// The initialization window closes: cast the first vote (paper, "Voting Algorithm").
fn close_window(config: &Config, next: &mut State, id: Id) {
    next.controller_mut(id).phase = Phase::Voting;
    revote(config, next, id);
}

/// Computes and publishes its vote. With the paper's rules, a lone voter (or a matching
/// quorum already held) agrees at once.
fn revote(config: &Config, next: &mut State, id: Id) {
    let vote = compute_vote(config, next.controller(id));
    let c = next.controller_mut(id);
    if c.phase == Phase::Failed {
        return;
    }
    c.phase = Phase::Voting;
    if c.vote != Some(vote) {
        c.vote = Some(vote);
        c.self_dissent_rounds = 0;
        vote_superseded(config, next, id);
    }
    if config.rules().decide_on_heartbeats {
        // Decided at the round boundary; only a controller alone decides at once.
        if electorate(config, next.controller(id), Source::Heartbeats).size == 1 {
            try_agree(config, next, id, Source::Heartbeats);
        }
    } else {
        try_agree(config, next, id, Source::DurableVotes);
    }
}

/// The voting algorithm: who should hold which role, as this controller sees it.
///
/// A function of what the controller knows, never of its own earlier votes, so controllers
/// that know the same vote the same: every live member is ranked by the best role any known
/// agreed result gives that very incarnation (its own result and, with the default rules,
/// every incumbent's as this round's heartbeats carry it), then by lowest id; three at most.
/// Keeping known roles is what avoids oscillation; losing a holder promotes those below it;
/// newcomers come in below by id; two results from a healed partition merge with the
/// lower id first.
pub fn compute_vote(config: &Config, c: &Controller) -> Assignment {
    let rules = config.rules();
    let members: Vec<Holder> = c
        .members()
        .map(|id| Holder {
            id,
            incarnation: if id == c.id {
                c.incarnation
            } else {
                c.peer(id).alive.unwrap_or_default()
            },
        })
        .collect();
    let mut known: Vec<Assignment> = c.agreed.into_iter().collect();
    if rules.decide_on_heartbeats {
        known.extend(
            c.peers
                .iter()
                .filter(|p| p.incumbent())
                .filter_map(|p| p.heard_agreed),
        );
    } else if c.agreed.is_none() && c.late_joiner {
        // Paper: a late joiner "assesses the existing system priority" from durable votes.
        known.extend(durable_result(config, c));
    }
    let rank = |member: &Holder| -> usize {
        if config.mutated(Mutation::Failback) {
            return ROLE_COUNT;
        }
        known
            .iter()
            .filter_map(|result| {
                let role = if rules.incarnation_aware {
                    result.role_of_holder(*member)
                } else {
                    result.role_of(member.id)
                };
                // Paper: "Precedence should be given to any currently Active Controller";
                // the other roles are ranked by id again.
                role.filter(|r| rules.keep_standby_order || *r == Role::Primary)
            })
            .map(Role::rank)
            .min()
            .unwrap_or(ROLE_COUNT)
    };
    let mut ranked = members.clone();
    ranked.sort_by_key(|member| (rank(member), member.id));
    let mut vote = Assignment::from_ranked(ranked);
    if config.mutated(Mutation::AdmitFourth) && !vote.contains(c.id) && vote.len() == ROLE_COUNT {
        vote.0[ROLE_COUNT - 1] = Some(Holder {
            id: c.id,
            incarnation: c.incarnation,
        });
    }
    vote
}

/// The running system's result from the durable votes of live peers: the assignment most of
/// them voted for (paper: a late joiner "assesses the existing system priority" from votes).
fn durable_result(config: &Config, c: &Controller) -> Option<Assignment> {
    let rules = config.rules();
    let votes = c
        .peers
        .iter()
        .filter_map(|peer| match (peer.alive, peer.vote) {
            (Some(alive), Some((incarnation, vote)))
                if !peer.failed && (!rules.incarnation_aware || alive == incarnation) =>
            {
                Some(vote)
            }
            _ => None,
        });
    most_common(votes)
}

/// The most frequent assignment; ties go to the smallest, so every controller picks the same.
fn most_common(items: impl Iterator<Item = Assignment>) -> Option<Assignment> {
    let mut counts: Vec<(Assignment, usize)> = Vec::new();
    for item in items {
        match counts.iter_mut().find(|(a, _)| *a == item) {
            Some((_, count)) => *count += 1,
            None => counts.push((item, 1)),
        }
    }
    counts
        .into_iter()
        .max_by(|(a, x), (b, y)| x.cmp(y).then(b.cmp(a)))
        .map(|(a, _)| a)
}

/// Where the votes a decision counts come from.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Source {
    /// The votes carried by this round's heartbeats (default rules).
    Heartbeats,
    /// The latest durable votes received (the paper's rules).
    DurableVotes,
}

/// Who decides. With the default rules, while a running system exists only its incumbents'
/// votes count, so a newcomer never completes a quorum; otherwise everyone's.
struct Electorate {
    votes: Vec<(Id, Assignment)>,
    /// How many controllers the quorum is a majority of.
    size: usize,
    /// Whether this controller's own vote counts.
    counts_self: bool,
}

fn electorate(config: &Config, c: &Controller, source: Source) -> Electorate {
    let rules = config.rules();
    let running_system = source == Source::Heartbeats
        && (c.agreed.is_some() || c.peers.iter().any(|p| p.incumbent()));
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
        let vote = match source {
            Source::Heartbeats => peer.heard_vote,
            Source::DurableVotes => match (peer.alive, peer.vote) {
                (Some(alive), Some((incarnation, vote)))
                    if !rules.incarnation_aware || alive == incarnation =>
                {
                    Some(vote)
                }
                _ => None,
            },
        };
        if let Some(vote) = vote {
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
fn try_agree(config: &Config, next: &mut State, id: Id, source: Source) {
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
    let (counted, size) = if config.rules().quorum_of_view {
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
    let mut new_role = if config.rules().incarnation_aware {
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
fn hold_primary_strength(config: &Config, c: &mut Controller) {
    if !config.rules().decide_on_heartbeats || c.role != Some(Role::Primary) {
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
fn note_role_change(history: &mut History, old: Option<Role>, new: Option<Role>) {
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

/// `id` published a new vote (or withdrew it). With the default rules no decision reads a
/// durable copy, so superseded copies are dropped: the state stays canonical. The paper's
/// rules decide on the copies, which stay until replaced.
fn vote_superseded(config: &Config, next: &mut State, id: Id) {
    if !config.rules().decide_on_heartbeats {
        return;
    }
    for c in next.controllers.iter_mut() {
        if c.id != id {
            c.peer_mut(id).vote = None;
        }
    }
}

/// The latest durable votes of `senders` reach `to` together (one reader's batch).
fn deliver_votes(config: &Config, next: &mut State, senders: &[Id], to: Id) {
    for &from in senders {
        let sender = next.controller(from);
        let vote = (sender.incarnation, sender.vote.unwrap_or_default());
        next.overdue_votes &= !link_bit(from, to);
        let receiver = next.controller_mut(to);
        receiver.peer_mut(from).vote = Some(vote);
        if !config.rules().decide_on_heartbeats {
            // A dissent counts only while the votes it is judged on stay the same.
            receiver.peer_mut(from).dissent_rounds = 0;
            receiver.self_dissent_rounds = 0;
        }
    }
    let c = next.controller_mut(to);
    match c.phase {
        Phase::Initializing if !config.rules().decide_on_heartbeats => {
            // Paper: a vote before our own voting means a running system ("Late Joiner").
            c.late_joiner = true;
            if window_over(config, c) {
                close_window(config, next, to);
            }
        }
        Phase::Initializing => {}
        Phase::Voting if !config.rules().decide_on_heartbeats => {
            try_agree(config, next, to, Source::DurableVotes)
        }
        Phase::Voting | Phase::Steady | Phase::Failed => {}
    }
    if !config.rules().minority_grace && !config.rules().decide_on_heartbeats {
        // Paper: "any minority vote from a controller indicates the controller is faulted".
        judge_minority(config, next, to, Source::DurableVotes);
    }
}

/// Marks minority voters FAILED; a controller that is itself the minority fails itself
/// (paper: "Any unit that does not agree with the two votes of the other controllers will
/// take itself offline").
fn judge_minority(config: &Config, next: &mut State, id: Id, source: Source) {
    let c = next.controller(id);
    if !matches!(c.phase, Phase::Voting | Phase::Steady) {
        return;
    }
    let grace = config.minority_grace_rounds();
    let ignore = config.mutated(Mutation::IgnoreMinorityVote);
    let Electorate {
        votes, counts_self, ..
    } = electorate(config, c, source);
    // Judging itself, it counts every live peer's vote, FAILED marks notwithstanding: two
    // sides that marked each other FAILED would otherwise each ignore being outvoted.
    let own_outvoted = counts_self && c.vote.is_some_and(|own| outvoted(config, c, own, source));
    if judge_self(config, next, id, own_outvoted, grace, ignore) {
        return;
    }
    let mut majority: Option<(Assignment, usize)> = None;
    for (_, vote) in &votes {
        let count = votes.iter().filter(|(_, v)| v == vote).count();
        if majority.is_none_or(|(_, best)| count > best) {
            majority = Some((*vote, count));
        }
    }
    let c = next.controller_mut(id);
    let winner = majority
        .filter(|(_, count)| *count >= 2 && count * 2 > votes.len())
        .map(|(vote, _)| vote);
    let mut marked = false;
    for (voter, vote) in &votes {
        if *voter == id {
            continue;
        }
        let peer = c.peer_mut(*voter);
        if winner.is_none_or(|winner| *vote == winner) {
            peer.dissent_rounds = 0;
            continue;
        }
        peer.dissent_rounds = peer.dissent_rounds.saturating_add(1);
        if peer.dissent_rounds > grace && !ignore {
            peer.failed = true;
            peer.alarm = true;
            marked = true;
        }
    }
    if marked {
        revote(config, next, id);
    }
}

/// Two or more other live voters agree on a result other than `own`, and they are a majority
/// of the others (paper: "does not agree with the two votes of the other controllers").
fn outvoted(config: &Config, c: &Controller, own: Assignment, source: Source) -> bool {
    let rules = config.rules();
    let others: Vec<Assignment> = c
        .peers
        .iter()
        .enumerate()
        .filter(|(index, peer)| *index + 1 != usize::from(c.id) && peer.alive.is_some())
        .filter_map(|(_, peer)| match source {
            // Newcomers' votes never count (see `electorate`).
            Source::Heartbeats => peer.heard_agreed.and(peer.heard_vote),
            Source::DurableVotes => match (peer.alive, peer.vote) {
                (Some(alive), Some((incarnation, vote)))
                    if !rules.incarnation_aware || alive == incarnation =>
                {
                    Some(vote)
                }
                _ => None,
            },
        })
        .collect();
    others.iter().any(|vote| {
        let count = others.iter().filter(|v| *v == vote).count();
        *vote != own && count >= 2 && count * 2 > others.len()
    })
}

/// Counts the rounds this controller has been outvoted; past the grace it fails itself.
/// Returns whether it did.
fn judge_self(
    config: &Config,
    next: &mut State,
    id: Id,
    outvoted: bool,
    grace: u8,
    ignore: bool,
) -> bool {
    let c = next.controller_mut(id);
    if !outvoted {
        c.self_dissent_rounds = 0;
        return false;
    }
    c.self_dissent_rounds = c.self_dissent_rounds.saturating_add(1);
    if c.self_dissent_rounds > grace && !ignore {
        fail_self(config, next, id);
        return true;
    }
    false
}

fn fail_self(config: &Config, next: &mut State, id: Id) {
    vote_superseded(config, next, id);
    let c = next.controller_mut(id);
    let old_role = c.role;
    c.phase = Phase::Failed;
    c.role = None;
    c.output = None;
    c.vote = None;
    c.agreed = None;
    note_role_change(&mut next.history, old_role, None);
}
