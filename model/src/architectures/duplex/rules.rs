//! The duplex's rules, action by action: crashes, restarts (preempting or not), lost
//! heartbeats, the round's end with each controller's deadline check, and the actuator that
//! follows the strongest live writer (DDS exclusive ownership).
//!
//! The rules in words are docs/protocol.md, "Other architectures: the spec"; every function
//! here is one of them.

use super::state::{
    partner_of, DuplexAction, DuplexController, DuplexState, PartnerView, Writing, DEADLINE_ROUNDS,
    DWELL_ROUNDS, SICK_GAP_ROUNDS,
};
use super::DuplexConfig;
use crate::architectures::ArchitectureMutation;
use crate::types::{Id, Life, Role};

/// The one initial state: both controllers up and hearing each other, the Primary (C1)
/// writing at 30 and owning the actuator, the Standby (C2) writing at 20.
pub fn init_states(_config: &DuplexConfig) -> Vec<DuplexState> {
    vec![DuplexState {
        controllers: [
            DuplexController::settled(1, Role::Primary),
            DuplexController::settled(2, Role::Secondary),
        ],
        lost: [false; 2],
        lost_before: [false; 2],
        owner: Some(1),
        crashes: 0,
        lost_heartbeats: 0,
        sick_episodes: 0,
        lapses: 0,
        faults: 0,
        owner_changes: 0,
    }]
}

/// Every action enabled in `state`.
pub fn actions(config: &DuplexConfig, state: &DuplexState, actions: &mut Vec<DuplexAction>) {
    for c in &state.controllers {
        if c.is_up() && state.crashes < config.max_crashes {
            actions.push(DuplexAction::Crash { controller: c.id });
        }
        if may_restart(config, state, c.id) {
            actions.push(DuplexAction::Restart { controller: c.id });
        }
        if may_lose_heartbeat(config, state, c.id) {
            actions.push(DuplexAction::LoseHeartbeat { from: c.id });
        }
        if may_sicken(config, state, c.id) {
            actions.push(DuplexAction::Sicken { controller: c.id });
        }
        if may_lapse(config, state, c.id) {
            actions.push(DuplexAction::Lapse { controller: c.id });
        }
        if c.sick {
            actions.push(DuplexAction::Recover { controller: c.id });
        }
    }
    if may_end_round(config, state) {
        actions.push(DuplexAction::Tick);
    }
}

/// The gray faults strike the configured Primary (C1), up and healthy, within budget. A sick
/// Standby is outside the scope (docs/findings.md, A4).
fn may_sicken(config: &DuplexConfig, state: &DuplexState, id: Id) -> bool {
    let c = state.controller(id);
    c.role == Role::Primary
        && c.is_up()
        && !c.sick
        && state.sick_episodes < config.max_sick_episodes
}

/// A sick controller's loop may lapse while the lapse budget lasts.
fn may_lapse(config: &DuplexConfig, state: &DuplexState, id: Id) -> bool {
    let c = state.controller(id);
    c.is_up() && c.sick && state.lapses < config.max_lapses
}

/// The timing assumption on a sick controller: while its episode lasts and lapses remain, it
/// lapses before more than [`SICK_GAP_ROUNDS`] round ends have run on time.
fn may_end_round(config: &DuplexConfig, state: &DuplexState) -> bool {
    state.controllers.iter().all(|c| {
        !(c.is_up()
            && c.sick
            && c.on_time_rounds >= SICK_GAP_ROUNDS
            && may_lapse(config, state, c.id))
    })
}

/// The timing assumption on restarts: a crashed controller starts again only once its
/// partner, if up, has noticed the crash (a restart takes longer than the heartbeat
/// deadline). A faster bounce is a loss the partner never sees.
fn may_restart(config: &DuplexConfig, state: &DuplexState, id: Id) -> bool {
    let partner = state.partner(id);
    let noticed = !partner.is_up()
        || partner.view == PartnerView::Lost
        || config.mutation == Some(ArchitectureMutation::QuickRestart);
    !state.controller(id).is_up() && noticed
}

/// A heartbeat may be lost while both ends are up, once per link per round, within budget.
fn may_lose_heartbeat(config: &DuplexConfig, state: &DuplexState, from: Id) -> bool {
    state.controller(from).is_up()
        && state.partner(from).is_up()
        && !state.lost[usize::from(from) - 1]
        && state.lost_heartbeats < config.max_lost_heartbeats
}

/// The state after `action`, or `None` when the action is not enabled.
pub fn next_state(
    config: &DuplexConfig,
    state: &DuplexState,
    action: DuplexAction,
) -> Option<DuplexState> {
    let mut next = *state;
    match action {
        DuplexAction::Crash { controller } => {
            if !state.controller(controller).is_up() || state.crashes >= config.max_crashes {
                return None;
            }
            crash(&mut next, controller);
        }
        DuplexAction::Restart { controller } => {
            if !may_restart(config, state, controller) {
                return None;
            }
            restart(config, &mut next, controller);
        }
        DuplexAction::LoseHeartbeat { from } => {
            if !may_lose_heartbeat(config, state, from) {
                return None;
            }
            lose_heartbeat(&mut next, from);
        }
        DuplexAction::Tick => {
            if !may_end_round(config, state) {
                return None;
            }
            next = round_end(config, state);
        }
        DuplexAction::Sicken { controller } => {
            if !may_sicken(config, state, controller) {
                return None;
            }
            let c = next.controller_mut(controller);
            c.sick = true;
            c.on_time_rounds = 0;
            next.sick_episodes += 1;
            next.faults += 1;
        }
        DuplexAction::Lapse { controller } => {
            if !may_lapse(config, state, controller) {
                return None;
            }
            lapse(config, &mut next, controller);
        }
        DuplexAction::Recover { controller } => {
            if !state.controller(controller).sick {
                return None;
            }
            next.controller_mut(controller).sick = false;
        }
    }
    follow_strongest_writer(config, &mut next);
    Some(next)
}

/// A crash: the process and everything it knew are gone, its writer with them; a fault.
fn crash(state: &mut DuplexState, id: Id) {
    let c = state.controller_mut(id);
    *c = DuplexController {
        life: Life::Down,
        writing: Writing::Silent,
        view: PartnerView::Unknown,
        missed: 0,
        alarm: false,
        up_rounds: 0,
        down_rounds: 0,
        partner_missed: false,
        dwell: 0,
        sick: false,
        on_time_rounds: 0,
        ..*c
    };
    state.controller_mut(partner_of(id)).partner_missed = true;
    state.crashes += 1;
    state.faults += 1;
}

/// A restart: with preemption the controller writes at its configured strength at once, so a
/// returning Primary takes the actuator back (the paper's rule); without, it yields at 10
/// until it has heard whether its partner commands.
fn restart(config: &DuplexConfig, state: &mut DuplexState, id: Id) {
    let partner_down = !state.partner(id).is_up();
    let writing = if config.preempt {
        Writing::Configured
    } else if config.mutation == Some(ArchitectureMutation::SilentStandby) {
        Writing::Silent
    } else {
        Writing::Yielded
    };
    let c = state.controller_mut(id);
    *c = DuplexController {
        life: Life::Up,
        writing,
        view: PartnerView::Unknown,
        missed: 0,
        alarm: false,
        restarted: true,
        up_rounds: 0,
        down_rounds: 0,
        partner_missed: partner_down,
        ..*c
    };
}

/// A sick controller's loop lapses. Commanding at its configured strength, its writer stops
/// for good (the actuator moves to the partner at the command deadline) and it starts again in
/// place, knowing nothing of its partner, writing below both configured strengths (`rl`'s new
/// life writes nothing before its first round end, which decides at once), and with
/// preemption it dwells: [`DWELL_ROUNDS`]
/// round ends on time before it takes its strength back, whether it hears its partner or not. Yielded or silent, the lapse is a
/// late round end or a stall of its new life: the dwell starts over.
fn lapse(config: &DuplexConfig, state: &mut DuplexState, id: Id) {
    state.lapses += 1;
    let dwell = if config.preempt && config.mutation != Some(ArchitectureMutation::NoDwell) {
        DWELL_ROUNDS
    } else {
        0
    };
    let c = state.controller_mut(id);
    c.on_time_rounds = 0;
    if c.writing == Writing::Configured {
        *c = DuplexController {
            writing: Writing::Yielded,
            view: PartnerView::Unknown,
            missed: 0,
            alarm: false,
            up_rounds: 0,
            lapsed: true,
            dwell,
            ..*c
        };
    } else {
        if c.dwell > 0 {
            c.dwell = dwell;
        }
    }
}

/// A lost heartbeat; the first of an episode on its link (not lost the round before) is a
/// fault.
fn lose_heartbeat(state: &mut DuplexState, from: Id) {
    let link = usize::from(from) - 1;
    state.lost[link] = true;
    state.lost_heartbeats += 1;
    if !state.lost_before[link] {
        state.faults += 1;
    }
    state.controller_mut(partner_of(from)).partner_missed = true;
}

/// The round ends: each live controller hears its partner's heartbeat unless the partner is
/// down or the heartbeat was lost, and otherwise counts a missed round. Every controller
/// decides on the state as the round ended (`before`).
fn round_end(config: &DuplexConfig, before: &DuplexState) -> DuplexState {
    let mut next = *before;
    for c in next.controllers.iter_mut() {
        if !c.is_up() {
            c.down_rounds = (c.down_rounds + 1).min(DEADLINE_ROUNDS);
            continue;
        }
        c.up_rounds = (c.up_rounds + 1).min(DEADLINE_ROUNDS);
        if c.sick {
            c.on_time_rounds = (c.on_time_rounds + 1).min(SICK_GAP_ROUNDS);
        }
        let partner = before.partner(c.id);
        if partner.is_up() && !before.lost[usize::from(partner.id) - 1] {
            hear(config, c, partner);
        } else {
            miss(c);
        }
    }
    next.lost_before = before.lost;
    next.lost = [false; 2];
    next
}

/// A heartbeat from the partner: it is alive (its alarm clears). A controller that does not
/// command yet decides: it stays yielded only without preemption, when the partner commands
/// at its configured strength and that strength is below its own (a returned Primary beside
/// a commanding Standby); otherwise it takes its configured strength.
fn hear(config: &DuplexConfig, c: &mut DuplexController, partner: &DuplexController) {
    c.missed = 0;
    c.view = PartnerView::Heard;
    c.alarm = false;
    c.partner_missed = false;
    if c.writing == Writing::Configured {
        return;
    }
    // The dwell: a round end on time, hearing the partner, counts down; the last one takes
    // the configured strength back (with no dwell left, preemption takes it at once).
    if c.dwell > 0 {
        c.dwell -= 1;
        if c.dwell > 0 {
            c.writing = Writing::Yielded;
            return;
        }
    }
    let yields = !config.preempt
        && partner.writing == Writing::Configured
        && c.role.strength() > partner.role.strength();
    if !yields {
        c.writing = Writing::Configured;
    }
}

/// A round without the partner's heartbeat; at the deadline the partner is taken for failed:
/// the alarm is raised, and a controller that did not command takes its configured strength.
///
/// A dwelling controller counts the round down all the same (its loop ran on time; a lapse is
/// its own action) and keeps 10 until the dwell ends, lost partner or not: at 10 it is the
/// actuator's writer at once if the partner is gone, and a starved loop that hears its
/// partner late must not take the actuator back for it (`rl` measured just that).
fn miss(c: &mut DuplexController) {
    c.missed = (c.missed + 1).min(DEADLINE_ROUNDS);
    let dwelling = c.dwell > 0;
    if dwelling {
        c.dwell -= 1;
        if c.dwell == 0 {
            c.writing = Writing::Configured;
        }
    }
    if c.missed < DEADLINE_ROUNDS || c.view == PartnerView::Lost {
        return;
    }
    c.view = PartnerView::Lost;
    c.alarm = true;
    if !dwelling {
        c.writing = Writing::Configured;
    }
}

/// The actuator after any event: DDS exclusive ownership gives it to the strongest live
/// writer at once (the command deadline is not modelled: a dead writer's ownership moves in
/// the same step). Every move from one controller to the other is counted.
fn follow_strongest_writer(config: &DuplexConfig, state: &mut DuplexState) {
    let owner = match config.mutation {
        Some(ArchitectureMutation::OwnerByLowestId) => state
            .controllers
            .iter()
            .find(|c| c.strength().is_some())
            .map(|c| c.id),
        _ => state.strongest_writer(),
    };
    if let (Some(before), Some(after)) = (state.owner, owner) {
        if before != after {
            state.owner_changes += 1;
        }
    }
    state.owner = owner;
}
