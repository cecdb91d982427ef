//! The trace rebuilt under the run's round lengths, round by round ([`rebuild`]): each step
//! taken on the model again, its faults sorted into rounds, the boundaries between them, and
//! the refusals a step meets on the way (a fault real processes cannot take, a window the
//! implementation would fire elsewhere, a state that differs). Kept apart from the plan's
//! types and the settled end ([`super`]).

use super::{expire_due, step, PlanError, RoundPlan, CUT_CONTROLLERS_MAX};
use crate::trace::{Trace, TraceStep};
use model::state::link_bit;
use model::traces::abstract_state;
use model::{protocol, Action, State};
use std::collections::BTreeSet;

pub(super) fn lost_links(state: &State) -> BTreeSet<(u8, u8)> {
    let n = state.controllers.len() as u8;
    let mut out = BTreeSet::new();
    for from in 1..=n {
        for to in 1..=n {
            if from != to && state.lost_links & link_bit(from, to) != 0 {
                out.insert((from, to));
            }
        }
    }
    out
}

/// Whether real processes can take `action`, a process or network fault: a cut needs a
/// namespace per controller. (Any pause can be resumed: SIGCONT waits until the runtime
/// surely starts again, run/faults.rs.)
fn admit_process_fault(state: &State, action: Action) -> Result<(), PlanError> {
    match action {
        Action::Isolate { .. } | Action::Unplug { .. }
            if state.controllers.len() > CUT_CONTROLLERS_MAX =>
        {
            Err(PlanError::CutBeyondTheLan {
                controllers: state.controllers.len(),
            })
        }
        _ => Ok(()),
    }
}

/// The trace rebuilt under the run's round lengths, round by round: its rounds and the
/// boundaries between them.
pub(super) struct Rebuilt {
    pub(super) rounds: Vec<RoundPlan>,
    pub(super) boundaries: Vec<State>,
    pub(super) state: State,
}

pub(super) fn rebuild(
    trace: &Trace,
    config: &model::Config,
    initial: State,
) -> Result<Rebuilt, PlanError> {
    let mut rounds = vec![RoundPlan::default()];
    let mut boundaries = vec![initial.clone()];
    let mut state = initial;
    // The round's actions so far, other than window expiries.
    let mut round_actions: Vec<Action> = Vec::new();
    for trace_step in &trace.steps {
        let action = trace_step.action;
        match action {
            Action::Tick => {
                left_open(config, boundaries.last(), trace_step.number)?;
                if let Some(round) = rounds.last_mut() {
                    round.lost = lost_links(&state);
                }
                state = step(config, &state, action)?;
                boundaries.push(state.clone());
                rounds.push(RoundPlan::default());
                round_actions.clear();
            }
            Action::ExpireWindow { .. } if !round_actions.is_empty() => {
                let (at_boundary, in_order) =
                    expire_late(config, &boundaries, &state, &round_actions, trace_step)?;
                if let Some(last) = boundaries.last_mut() {
                    *last = at_boundary;
                }
                state = in_order;
            }
            Action::ExpireWindow { .. } => {
                state = step(config, &state, action)?;
                if let Some(last) = boundaries.last_mut() {
                    *last = state.clone();
                }
            }
            Action::DeliverVotes { .. } => return Err(PlanError::PaperVariantAction),
            Action::Slow { .. }
            | Action::LateHeartbeat { .. }
            | Action::HearLate { .. }
            | Action::Oversleep { .. }
            | Action::Thaw { .. } => {
                return Err(PlanError::GrayFault { action });
            }
            // The actuator's own events: DDS does them; the model keeps its owner.
            Action::DiscoverWriter { .. } | Action::TieBreak { .. } => {
                state = step(config, &state, action)?;
            }
            Action::LoseHeartbeat { .. } => {
                state = step(config, &state, action)?;
                round_actions.push(action);
            }
            Action::Crash { .. }
            | Action::Restart { .. }
            | Action::Join { .. }
            | Action::Pause { .. }
            | Action::Resume { .. }
            | Action::Isolate { .. }
            | Action::Unplug { .. }
            | Action::Starve { .. }
            | Action::Lag { .. }
            | Action::CatchUp { .. }
            | Action::Heal { .. } => {
                admit_process_fault(&state, action)?;
                state = step(config, &state, action)?;
                if let Some(round) = rounds.last_mut() {
                    round.lifecycle.push(action);
                    note_takeover(round, &state, action);
                }
                round_actions.push(action);
            }
        }
        if abstract_state(&state) != trace_step.state {
            return Err(PlanError::StateDiffers {
                step: trace_step.number,
                action,
                run_window_rounds: config.window_rounds,
                trace_window_rounds: trace.config.window_rounds,
            });
        }
    }
    let state = close(config, trace, &mut boundaries, state, &round_actions)?;
    Ok(Rebuilt {
        rounds,
        boundaries,
        state,
    })
}

/// The trace's end: it may stop at a boundary before every window due there has expired,
/// and the implementation expires them all at once, which the model allows next; a window
/// due at the boundary and left open into a round the trace leaves open is refused.
fn close(
    config: &model::Config,
    trace: &Trace,
    boundaries: &mut [State],
    state: State,
    round_actions: &[Action],
) -> Result<State, PlanError> {
    if !round_actions.is_empty() {
        let after = trace.steps.last().map_or(0, |s| s.number);
        left_open(config, boundaries.last(), after)?;
        return Ok(state);
    }
    let state = expire_due(config, state)?;
    if let Some(last) = boundaries.last_mut() {
        *last = state.clone();
    }
    Ok(state)
}

/// A window the trace expires after other actions of its round (`round_actions`): the
/// implementation's timer fires at the boundary, before the round's faults, so it is
/// replayable if expiring it there and taking the round's actions after reaches the same
/// state. Returns the boundary's state with it expired, and the state after it in the trace's
/// order.
fn expire_late(
    config: &model::Config,
    boundaries: &[State],
    state: &State,
    round_actions: &[Action],
    trace_step: &TraceStep,
) -> Result<(State, State), PlanError> {
    let action = trace_step.action;
    let at_boundary = boundaries.last().unwrap_or(state);
    let expired = step(config, at_boundary, action)?;
    let moved = expire_at_boundary(config, &expired, round_actions);
    let in_order = step(config, state, action)?;
    if moved.as_ref().map(without_history) != Some(without_history(&in_order)) {
        return Err(PlanError::WindowAfterOtherAction {
            step: trace_step.number,
        });
    }
    Ok((expired, in_order))
}

/// A starved link a peer takes over from at once (F17), in the model's `state` after it.
fn note_takeover(round: &mut RoundPlan, state: &State, action: Action) {
    if let Action::Starve { controller } = action {
        let taken_over = state
            .controllers
            .iter()
            .any(|c| c.took_over_from.is_some_and(|(from, _)| from == controller));
        if taken_over {
            round.takeovers.insert(controller);
        }
    }
}

/// A window due at `boundary` that the trace leaves open into the round (expiring it later,
/// or never): the implementation fires every due window at the boundary itself.
fn left_open(
    config: &model::Config,
    boundary: Option<&State>,
    step_number: usize,
) -> Result<(), PlanError> {
    let Some(boundary) = boundary else {
        return Ok(());
    };
    let mut enabled = Vec::new();
    protocol::actions(config, boundary, &mut enabled);
    match enabled
        .iter()
        .find(|a| matches!(a, Action::ExpireWindow { .. }))
    {
        Some(&Action::ExpireWindow { controller }) => Err(PlanError::WindowLeftOpen {
            step: step_number,
            controller,
        }),
        _ => Ok(()),
    }
}

/// The round's `actions` taken again after its boundary's state `expired` (with a window
/// expired there); `None` if the model does not allow one of them then.
fn expire_at_boundary(
    config: &model::Config,
    expired: &State,
    actions: &[Action],
) -> Option<State> {
    let mut state = expired.clone();
    for action in actions {
        state = step(config, &state, *action).ok()?;
    }
    Some(state)
}

/// `state` without its ghost history, which feeds properties and budgets, never a decision.
fn without_history(state: &State) -> State {
    State {
        history: model::state::History::default(),
        ..state.clone()
    }
}
