//! The gray process faults: a controller that runs, but wrongly slow, and one that stopped
//! and runs again without noticing it (F18, docs/findings.md).
//!
//! A slowed process (starved of CPU, throttled) is one lasting episode: its links are fine,
//! but any of its heartbeats may miss a round's end, in any round, until it heals, and the
//! actuator may miss its commands' deadline. Its samples are stamped when they are written,
//! so its peers see gaps, not late samples, and F17's takeover does not apply. An unnoticed
//! stall is a pause that ends with no signal and no clock jump the controller trusts, within
//! its peers' dead-man deadline (a longer stop is seen by the kernel's account of held time:
//! docs/findings.md).
//!
//! F18's rule is the answer to both: a Primary whose own commands lapsed writes nothing more
//! in that life and starts again as a new incarnation, below the controllers that kept the
//! system running. Only the Primary doubts itself: a loaded host then restarts at most the
//! controller the actuator follows, and a standby's lapse moves nothing.

use super::agreement::note_role_change;
use super::new_life;
use crate::config::Config;
use crate::state::{link_bit, Action, State};
use crate::types::{Id, Life, Role};

/// The gray faults open to controller `id` in `state`: a slowdown of a running system, the
/// late heartbeats of a slowed controller and an unnoticed end of its pause.
pub(super) fn actions(
    config: &Config,
    state: &State,
    id: Id,
    running: bool,
    out: &mut Vec<Action>,
) {
    let c = state.controller(id);
    let bit = 1 << (id - 1);
    if running && state.history.slowdowns < config.max_slowdowns {
        out.push(Action::Slow { controller: id });
    }
    let late_open = state.history.late_heartbeats < config.max_late_heartbeats;
    if state.slowed & bit != 0 && c.is_up() && late_open {
        if !late_this_round(config, state, id) {
            out.push(Action::LateHeartbeat { from: id });
        }
        // A slowed receiver is one the actuator does not follow: a loop a heartbeat's lead on
        // the round's end late (or a round late) has held its process's command sends longer
        // than their gap bound too, so a commanding Primary's writer lapses first (`Lag`, F18).
        let commanding_primary = c.role == Some(Role::Primary) && c.output.is_some();
        let receiver = config.slowed_receivers && !commanding_primary;
        if receiver && !heard_late_this_round(config, state, id) {
            out.push(Action::HearLate { to: id });
        }
        // Pushed before the controllers' own actions: a round may end now.
        // An oversleep is a round late both ways, and a round's lateness either way is
        // already in it.
        let room = state.history.late_heartbeats + 1 < config.max_late_heartbeats;
        if receiver && room && !late_in_this_round(config, state, id) && out.contains(&Action::Tick)
        {
            out.push(Action::Oversleep { controller: id });
        }
    }
    if c.life == Life::Paused && config.unnoticed_stalls && within_peer_deadline(state, id) {
        out.push(Action::Thaw { controller: id });
    }
}

/// No running peer has declared the paused controller lost: the stop was shorter than the
/// dead-man deadline.
fn within_peer_deadline(state: &State, id: Id) -> bool {
    let incarnation = state.controller(id).incarnation;
    state
        .controllers
        .iter()
        .filter(|d| d.id != id && d.is_active())
        .all(|d| d.peer(id).alive == Some(incarnation))
}

/// The slowed controller's heartbeat of this round is already late for every peer.
fn late_this_round(config: &Config, state: &State, from: Id) -> bool {
    config
        .ids()
        .filter(|to| *to != from)
        .all(|to| state.lost_links & link_bit(from, to) != 0)
}

/// A slowdown heals at a round's start: a round with a heartbeat late to or from the slowed
/// controller is still its episode's.
pub(super) fn late_in_this_round(config: &Config, state: &State, id: Id) -> bool {
    config
        .ids()
        .filter(|peer| *peer != id)
        .any(|peer| state.lost_links & (link_bit(id, peer) | link_bit(peer, id)) != 0)
}

/// Every peer's heartbeat of this round is already late for the slowed controller.
fn heard_late_this_round(config: &Config, state: &State, to: Id) -> bool {
    config
        .ids()
        .filter(|from| *from != to)
        .all(|from| state.lost_links & link_bit(from, to) != 0)
}

/// A slowed controller's heartbeat of this round misses every peer's round end: part of its
/// slowdown's episode, not a new fault.
pub(super) fn late_heartbeat(config: &Config, next: &mut State, from: Id) {
    for to in config.ids().filter(|to| *to != from) {
        next.lost_links |= link_bit(from, to);
    }
    count_late(next);
}

/// A slowed controller takes this round's heartbeats in after its round's end: a slowed
/// receiver, part of its slowdown's episode.
pub(super) fn hear_late(config: &Config, next: &mut State, to: Id) {
    for from in config.ids().filter(|from| *from != to) {
        next.lost_links |= link_bit(from, to);
    }
    count_late(next);
}

/// The round ends while the slowed controller's loop sleeps: its heartbeat of the round was
/// never sent, and it ends no round of its own (the implementation's loop, once it runs,
/// ends one round for all it missed: `rl_core::Core`'s round end).
pub(super) fn oversleep(config: &Config, next: &mut State, controller: Id) {
    late_heartbeat(config, next, controller);
    // What it would have heard is late too: two of the slowdown's late heartbeats.
    count_late(next);
    let before = next.clone();
    super::round::tick(config, &before, next, Some(controller));
}

/// One more late heartbeat of the slowdown's budget.
fn count_late(next: &mut State) {
    let history = &mut next.history;
    history.late_heartbeats += 1;
    history.quiet_rounds = 0;
    if !history.formed {
        history.partition_open = true;
    }
}

/// A controller's process is slowed: a new fault episode.
pub(super) fn slow(next: &mut State, controller: Id) {
    next.slowed |= 1 << (controller - 1);
    let history = &mut next.history;
    history.slowdowns += 1;
    history.slowdown_open = true;
    history.faults += 1;
    history.quiet_rounds = 0;
    history.away |= 1 << (controller - 1);
}

/// The actuator misses a controller's command deadline. A slowed Primary's writer has seen
/// its own commands lapse by then (its bound, half the deadline, is below the actuator's):
/// with F18 it starts again before it writes anything more.
pub(super) fn lag(config: &Config, state: &State, next: &mut State, controller: Id) {
    next.lagging |= 1 << (controller - 1);
    if next.slowed & (1 << (controller - 1)) != 0 && doubts_itself(config, next, controller) {
        start_again(config, state, next, controller);
    }
}

/// A paused controller runs again without noticing that it stopped. With F18 a Primary's
/// writer finds its commands lapsed (the actuator has left it) and it starts again; any other
/// controller goes on with what it knew, its peers never having declared it lost.
pub(super) fn thaw(config: &Config, state: &State, next: &mut State, controller: Id) {
    next.history.quiet_rounds = 0;
    next.controller_mut(controller).life = Life::Up;
    if doubts_itself(config, next, controller) {
        start_again(config, state, next, controller);
    }
}

/// F18: the Primary, commanding, doubts itself when its commands lapse.
fn doubts_itself(config: &Config, state: &State, controller: Id) -> bool {
    let c = state.controller(controller);
    config.rules().f18_self_doubt && c.role == Some(Role::Primary) && c.output.is_some()
}

/// A new incarnation, as after a stall (F12): silent until it has heard a round, below the
/// controllers that kept the system running. The actuator has nothing of the old life to
/// miss any more.
fn start_again(config: &Config, state: &State, next: &mut State, controller: Id) {
    let old_role = next.controller(controller).role;
    new_life(config, state, next, controller, true);
    note_role_change(&mut next.history, controller, old_role, None);
    next.lagging &= !(1 << (controller - 1));
    next.history.doubted = true;
}

/// Ghost bookkeeping after a step: a slowed controller that lost the Primary role must not
/// hold it again while it is slowed ("a sick controller is not made Primary again"). A
/// provisional Primary is not made Primary by anyone: it is a slowed receiver that heard
/// nobody, alone, below the live Primary's strength (F11).
pub(super) fn note_sick(before: &State, next: &mut State) {
    for b in &before.controllers {
        let bit = 1 << (b.id - 1);
        let sick = before.slowed & bit != 0;
        if sick
            && b.role == Some(Role::Primary)
            && next.controller(b.id).role != Some(Role::Primary)
        {
            next.history.sick_lost_primary |= bit;
        }
    }
    let still_sick = next.slowed;
    next.history.sick_lost_primary &= still_sick;
    let repromoted = next.controllers.iter().any(|c| {
        next.history.sick_lost_primary & (1 << (c.id - 1)) != 0
            && c.is_up()
            && c.role == Some(Role::Primary)
            && !c.provisional
    });
    next.history.sick_repromoted |= repromoted;
}
