//! The voting protocol's rules: what each action does to the controllers.
//!
//! Every rule cites the paper section it comes from; where the default algorithm departs from
//! the paper's literal text, a switch of [`crate::fixes::Rules`] and docs/findings.md say why.
//! This module holds the actions (which are enabled, what each does); the rules they apply
//! are split by what they decide:
//!
//! - `round`: the end of a round, one controller at a time ([`round_step`]): heartbeats
//!   heard and missed, the initialization window, re-votes and the round-boundary decisions;
//! - `vote`: what a controller votes for ([`compute_vote`]) and how votes are published
//!   and delivered;
//! - `agreement`: who counts (the electorate), when a result is agreed, and adopting it;
//! - `minority`: marking minority voters FAILED and failing oneself;
//! - `gray`: a slowed process and a stall that ends unnoticed, and F18's self-doubt;
//! - [`actuator`]: which controller's commands the actuator follows, at DDS-writer granularity.

pub mod actuator;
mod agreement;
mod gray;
mod minority;
mod round;
mod vote;

pub use round::round_step;
pub use vote::compute_vote;

use crate::config::Config;
use crate::fixes::Mutation;
use crate::state::{link_bit, Action, Controller, History, State};
use crate::types::{Id, Life, Phase, Role, ROLE_COUNT};
use round::tick;
use vote::{close_window, deliver_votes, vote_superseded};

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
            isolated: 0,
            unplugged: 0,
            starved: 0,
            slowed: 0,
            lagging: 0,
            owner: None,
            tie_order: 0,
            history: History::default(),
        })
        .collect()
}

/// A vote from `from` that `to` has not received yet. Only without F5 are decisions taken on
/// durable votes; with it votes travel in heartbeats and the durable copy is for late readers
/// and tools, so its delivery is not modelled.
pub fn vote_pending(config: &Config, state: &State, from: Id, to: Id) -> bool {
    if config.rules().f5_decide_on_heartbeats {
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
        lifecycle_actions(config, state, id, out);
    }
    for to in actuator::tie_break_targets(state) {
        out.push(Action::TieBreak { to });
    }
}

/// The faults and process events open to controller `id`: crash, pause, cut, restart, resume,
/// join, heal, and the actuator discovering its newest writer.
fn lifecycle_actions(config: &Config, state: &State, id: Id, out: &mut Vec<Action>) {
    let c = state.controller(id);
    match c.life {
        Life::Up => {
            // A starved link is one fault at a time too, until the system has settled after it: with
            // a second one the Secondary may have no controller on time to compare the
            // Primary with, or the taker may die before the deposed Primary heard it
            // (docs/findings.md, F17).
            let starvation_open = state.history.starvation_open || state.history.slowdown_open;
            if state.history.crashes < config.max_crashes && !starvation_open {
                out.push(Action::Crash { controller: id });
            }
            // One pause, cut or starved link at a time, of a full running system that has
            // settled, its writers established (a split at formation, of a system of two, or
            // in three, has no majority anywhere: F9).
            let running = state.isolated == 0
                && !starvation_open
                && state
                    .controllers
                    .iter()
                    .all(|c| c.life != Life::Paused && !c.fresh_writer)
                && crate::properties::settled(state)
                    .is_some_and(|agreed| agreed.len() == ROLE_COUNT);
            if running && state.history.pauses < config.max_pauses {
                out.push(Action::Pause { controller: id });
            }
            if running && state.history.isolations < config.max_isolations {
                out.push(Action::Isolate { controller: id });
                out.push(Action::Unplug { controller: id });
            }
            if running && state.history.starvations < config.max_starvations {
                out.push(Action::Starve { controller: id });
            }
            gray::actions(config, state, id, running, out);
            if c.phase == Phase::Failed && state.history.restarts < config.max_restarts {
                out.push(Action::Restart { controller: id });
            }
        }
        Life::Down => {
            if state.history.restarts < config.max_restarts {
                out.push(Action::Restart { controller: id });
            }
        }
        Life::Paused => {
            out.push(Action::Resume { controller: id });
            gray::actions(config, state, id, false, out);
        }
        Life::NotStarted => out.push(Action::Join { controller: id }),
    }
    let bit = 1 << (id - 1);
    if (state.starved | state.slowed) & bit != 0 && c.is_up() {
        out.push(if state.lagging & bit == 0 {
            Action::Lag { controller: id }
        } else {
            Action::CatchUp { controller: id }
        });
    }
    let still_late = state.slowed & bit != 0 && gray::late_in_this_round(config, state, id);
    if (state.isolated | state.starved | state.slowed) & bit != 0 && !still_late {
        out.push(Action::Heal { controller: id });
    }
    if c.is_up() && c.undiscovered {
        out.push(Action::DiscoverWriter { controller: id });
    }
}

/// The state after an action; `None` if the action is not enabled.
pub fn next_state(config: &Config, state: &State, action: Action) -> Option<State> {
    let mut next = state.clone();
    match action {
        Action::LateHeartbeat { from } => gray::late_heartbeat(config, &mut next, from),
        Action::HearLate { to } => gray::hear_late(config, &mut next, to),
        Action::Oversleep { controller } => gray::oversleep(config, &mut next, controller),
        Action::LoseHeartbeat { from, to } => {
            let link = link_bit(from, to) | link_bit(to, from);
            if (state.lost_links | state.history.links_down) & link == 0 {
                // The link goes down: a new fault episode (losses on it in this round, either
                // way, or in the rounds right after, continue the same one).
                next.history.faults += 1;
            }
            next.lost_links |= link_bit(from, to);
            next.history.losses += 1;
            next.history.quiet_rounds = 0;
            // Before the first settled state there is no agreed system to protect: a loss
            // can split the founders into two groups that each agree (F9).
            if !next.history.formed {
                next.history.partition_open = true;
            }
        }
        Action::Tick => tick(config, state, &mut next, None),
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
            next.history.faults += 1;
            next.history.quiet_rounds = 0;
        }
        Action::Restart { controller } | Action::Join { controller } => {
            let restarted = matches!(action, Action::Restart { .. });
            new_life(config, state, &mut next, controller, restarted);
            if restarted {
                next.history.restarts += 1;
            }
        }
        Action::Pause { .. }
        | Action::Resume { .. }
        | Action::Isolate { .. }
        | Action::Unplug { .. }
        | Action::Starve { .. }
        | Action::Slow { .. }
        | Action::Thaw { .. }
        | Action::Lag { .. }
        | Action::CatchUp { .. }
        | Action::Heal { .. }
        | Action::DiscoverWriter { .. }
        | Action::TieBreak { .. } => interrupt(config, state, &mut next, action),
    }
    gray::note_sick(state, &mut next);
    actuator::arbitrate(&mut next);
    actuator::note_primary_taken_back(state, &mut next);
    if next.isolated == 0 && next.controllers.iter().all(|c| c.life != Life::Paused) {
        actuator::settle_bookkeeping(&mut next);
    }
    Some(next)
}

/// A controller starts (a join) or starts again as its next incarnation (a restart).
fn new_life(config: &Config, state: &State, next: &mut State, controller: Id, restarted: bool) {
    let c = next.controller_mut(controller);
    let incarnation = if restarted { c.incarnation + 1 } else { 0 };
    *c = Controller::new(controller, Life::Up);
    c.incarnation = incarnation;
    if restarted {
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
    forget_links(next, controller);
    next.tie_order &= !links_of(controller);
    next.history.quiet_rounds = 0;
}

/// Every link bit to or from `id`.
fn links_of(id: Id) -> u16 {
    (1..=crate::types::MAX_CONTROLLERS as Id).fold(0, |mask, other| {
        mask | link_bit(id, other) | link_bit(other, id)
    })
}

/// Pauses, cuts and the actuator's own events.
fn interrupt(config: &Config, state: &State, next: &mut State, action: Action) {
    match action {
        Action::Pause { controller } => {
            next.controller_mut(controller).life = Life::Paused;
            next.history.pauses += 1;
            next.history.faults += 1;
            next.history.quiet_rounds = 0;
            next.history.away |= 1 << (controller - 1);
        }
        Action::Resume { controller } => {
            next.history.quiet_rounds = 0;
            if config.rules().f12_self_fence {
                // Its round clock jumped: what it knew is stale. It starts again as a new
                // incarnation, silent until it has heard a round and joined below the
                // controllers that kept the system running.
                let old_role = next.controller(controller).role;
                new_life(config, state, next, controller, true);
                agreement::note_role_change(&mut next.history, controller, old_role, None);
            } else {
                next.controller_mut(controller).life = Life::Up;
            }
        }
        Action::Isolate { controller } => {
            next.isolated |= 1 << (controller - 1);
            next.history.isolations += 1;
            next.history.faults += 1;
            next.history.quiet_rounds = 0;
            next.history.away |= 1 << (controller - 1);
        }
        Action::Unplug { controller } => {
            next.isolated |= 1 << (controller - 1);
            next.unplugged |= 1 << (controller - 1);
            next.history.isolations += 1;
            next.history.faults += 1;
            next.history.quiet_rounds = 0;
            next.history.away |= 1 << (controller - 1);
            if config.rules().f16_unplugged_restart {
                // It sees its carrier go: whatever it knew may be stale by the time the cable
                // is back, so it starts again as a new incarnation now, as after a stall.
                let old_role = next.controller(controller).role;
                new_life(config, state, next, controller, true);
                agreement::note_role_change(&mut next.history, controller, old_role, None);
            }
        }
        Action::Starve { controller } => {
            next.starved |= 1 << (controller - 1);
            next.history.starvations += 1;
            next.history.starvation_open = true;
            next.history.faults += 1;
            next.history.quiet_rounds = 0;
            next.history.away |= 1 << (controller - 1);
            if config.rules().f17_starved_takeover {
                take_over_from_starved(next, controller);
            }
        }
        Action::Slow { controller } => gray::slow(next, controller),
        Action::Thaw { controller } => gray::thaw(config, state, next, controller),
        Action::Lag { controller } => gray::lag(config, state, next, controller),
        Action::CatchUp { controller } => next.lagging &= !(1 << (controller - 1)),
        Action::Heal { controller } => {
            let bit = 1 << (controller - 1);
            next.isolated &= !bit;
            next.unplugged &= !bit;
            next.starved &= !bit;
            next.slowed &= !bit;
            next.lagging &= !bit;
            next.history.quiet_rounds = 0;
        }
        Action::DiscoverWriter { controller } => {
            next.controller_mut(controller).undiscovered = false;
        }
        Action::TieBreak { to } => {
            if let Some(owner) = next.owner {
                next.tie_order |= link_bit(to, owner);
            }
            actuator::change_owner(next, to);
        }
        _ => {}
    }
}

/// F17: the starved controller's commands reach its peers late. If it is the Primary, its
/// Secondary compares them with the Tertiary's, which arrive on time, and takes over at once
/// at the takeover strength (timing assumption: two late samples, well within the actuator's
/// command deadline). Without a Tertiary on time to compare with, a Secondary cannot tell a
/// late Primary from its own starved link, and does nothing.
fn take_over_from_starved(next: &mut State, starved: Id) {
    let primary = next.controller(starved);
    if !primary.is_active()
        || primary.role != Some(Role::Primary)
        || primary.output != Some(Role::Primary.strength())
    {
        return;
    }
    let incarnation = primary.incarnation;
    let Some(agreed) = primary.agreed else {
        return;
    };
    let on_time = |id: Option<Id>| {
        id.filter(|id| next.starved & (1 << (id - 1)) == 0)
            .map(|id| next.controller(id))
            .filter(|c| c.is_active() && c.output.is_some())
    };
    let (Some(secondary), Some(_tertiary)) = (
        on_time(agreed.holder(Role::Secondary)),
        on_time(agreed.holder(Role::Tertiary)),
    ) else {
        return;
    };
    if secondary.role != Some(Role::Secondary) {
        return;
    }
    let id = secondary.id;
    next.controller_mut(id).take_over(starved, incarnation);
    next.history.took_over = true;
}

fn forget_links(state: &mut State, id: Id) {
    // Ghost: the life that ended no longer holds a role a restarted controller must come in
    // below (a next life of it has no such claim).
    for c in state.controllers.iter_mut() {
        c.held_roles_at_restart &= !(1 << (id - 1));
    }
    for other in 1..=state.controllers.len() as Id {
        let mask = !(link_bit(id, other) | link_bit(other, id));
        state.lost_links &= mask;
        state.overdue_votes &= mask;
        // A new life's lost heartbeat is a new link failure.
        state.history.links_down &= mask;
    }
}

fn window_can_expire(config: &Config, c: &Controller) -> bool {
    c.is_up()
        && c.phase == Phase::Initializing
        && c.window_quiet_rounds >= config.window_rounds
        && ready_to_vote(c)
}

/// A late joiner votes only once it can learn the running system's result: from a heartbeat
/// (F1) or a durable vote (the paper's).
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
    pub(crate) fn members_heard(&self) -> usize {
        1 + self
            .peers
            .iter()
            .enumerate()
            .filter(|(index, p)| *index + 1 != usize::from(self.id) && p.alive.is_some())
            .count()
    }
}
