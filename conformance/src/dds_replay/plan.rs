//! The DDS-level replay's plan of one trace: what to do in which round and what to expect at
//! every round boundary, all derived from the model. Pure: no processes here (the driver,
//! [`super`], carries the plan out).
//!
//! Real processes follow the model round for round once DDS discovery is out of the way: every
//! process of the trace is started before round 0 and held until all have found each other
//! ([`super::config`]), and the round clock is the wall clock. So:
//!
//! - round 0's actions happen at start: the trace's initial controllers are let go right
//!   after a boundary (boundary 0), its round-0 crashes, restarts and joins applied at once,
//!   its round-0 heartbeat losses dropped from the start;
//! - from there the replay is in lockstep: the trace's round `k` is real round
//!   `start + k`, its losses are dropped for that round, its crashes are `kill -9` and its
//!   joins and restarts held processes let go at the round's start, and every boundary is
//!   compared;
//! - a pulled cable plugged back in ends the lockstep (the controller is heard once its
//!   neighbours are resolved again); the replay then waits, with a bounded wait, for the next
//!   quiescent boundary (one a round's end leaves unchanged) and re-aligns there if faults
//!   follow, or for the settled end;
//! - after the trace's last step the model adds rounds without faults until nothing changes
//!   any more (the settled end), and the run must reach that state and stay in it.
//!
//! A trace is replayable only if this timing cannot change its outcome, which
//! [`super::checks`] verifies against the model.

use super::checks;
use crate::trace::Trace;
use crate::validate::Timing;
use model::traces::{abstract_state, AbstractState};
use model::{protocol, Action, Life, State};
use rebuild::{lost_links, rebuild, Rebuilt};
use std::collections::BTreeSet;
use std::fmt::Write;

pub use super::refusal::PlanError;

mod rebuild;

/// A cut needs a network namespace per controller: the virtual LAN's three
/// (`crate::lab::lan::CONTROLLER_IDS`).
pub const CUT_CONTROLLERS_MAX: usize = 3;

/// The most rounds the model may take to settle after a trace's last step.
pub const SETTLE_ROUNDS_MAX: usize = 40;

/// What happens during one round of the plan.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RoundPlan {
    /// Crashes, restarts, joins, pauses, resumes, cuts, pulled cables, starved links (and
    /// their commands' missed deadlines and late samples) and heals, in the trace's order.
    pub lifecycle: Vec<Action>,
    /// Heartbeats lost at the round's end, `(from, to)`: `to` drops `from`'s heartbeats for
    /// the round.
    pub lost: BTreeSet<(u8, u8)>,
    /// Starved controllers a peer takes over from in this round (F17): their late commands
    /// must reach the peers before a missed deadline, a late sample or a heal in the same
    /// round changes how they go out.
    pub takeovers: BTreeSet<u8>,
}

impl RoundPlan {
    pub fn is_empty(&self) -> bool {
        self.lifecycle.is_empty() && self.lost.is_empty()
    }

    /// Whether `action` must wait for a takeover in its round: a missed deadline, a late
    /// sample or a heal of the starved link a peer takes over from.
    pub fn waits_for_takeover(&self, action: Action) -> bool {
        matches!(
            action,
            Action::Lag { controller } | Action::CatchUp { controller } | Action::Heal { controller }
                if self.takeovers.contains(&controller)
        )
    }

    /// Whether `action` is a resume in the round of its pause: applied after the round's
    /// other faults, once the stop has lasted a command deadline (see
    /// [`super::config::RunTiming::stop_noticed_ms`]).
    pub fn resumes_within(&self, action: Action) -> bool {
        let Action::Resume { controller } = action else {
            return false;
        };
        let Some(at) = self.lifecycle.iter().position(|a| *a == action) else {
            return false;
        };
        self.lifecycle[..at].contains(&Action::Pause { controller })
    }

    /// A cut or a pulled cable: the replay needs the virtual LAN.
    pub fn cuts(&self) -> bool {
        self.lifecycle
            .iter()
            .any(|a| matches!(a, Action::Isolate { .. } | Action::Unplug { .. }))
    }
}

/// How the replay reaches a boundary of the plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Boundary 0: the processes start.
    Start,
    /// On the model's rounds: the boundary is a known real round, compared exactly there,
    /// and the next round's faults are applied on time.
    Lockstep,
    /// After a pulled cable is plugged back in: not compared (the controller is heard only
    /// once its neighbours are resolved again).
    Free,
    /// A quiescent boundary after such a heal, with faults in its round: waited for
    /// (bounded), then the lockstep resumes from it.
    Realign,
}

/// How a trace is replayed on real processes.
#[derive(Clone, Debug)]
pub struct Plan {
    pub file: String,
    pub purpose: String,
    /// The model's configuration with the run's round lengths.
    pub config: model::Config,
    /// Controllers up in the trace's initial state.
    pub initial_up: Vec<u8>,
    /// `rounds[k]`: what happens during round `k` (between boundaries `k` and `k + 1`).
    pub rounds: Vec<RoundPlan>,
    /// `boundaries[k]`: the model's state at boundary `k` (after `k` round ends and the
    /// window expiries right after them); `boundaries.len() == rounds.len() + 1`.
    pub boundaries: Vec<State>,
    /// Boundaries up to this one come from the trace; later ones are the settled end.
    pub trace_boundaries: usize,
    /// `quiescent[k]`: a round's end leaves boundary `k` unchanged (hidden state included).
    pub quiescent: Vec<bool>,
    /// `owners_in_round[k]`: who may own the actuator through round `k`, after the round's
    /// crashes, restarts and joins (a crash at the round's start takes the owner's commands
    /// away within the command deadline); for the last boundary, its own ([`owners`]).
    pub owners_in_round: Vec<Vec<u8>>,
}

impl Plan {
    /// The abstract state expected at boundary `k`.
    pub fn expected(&self, k: usize) -> AbstractState {
        abstract_state(&self.boundaries[k])
    }

    /// Whether the controllers must run on the virtual LAN (a network namespace each), for a
    /// cut or a pulled cable; otherwise they run on loopback.
    pub fn needs_lan(&self) -> bool {
        self.rounds.iter().any(RoundPlan::cuts)
    }

    /// The last boundary: the settled end.
    pub fn last(&self) -> usize {
        self.boundaries.len() - 1
    }

    /// The controllers heard only once they are found again after round `k`: one whose
    /// cables are plugged back in (a heal of a pulled cable: its neighbours must be resolved
    /// again before unicast flows). A join or restart is no newcomer: its process was held,
    /// discovered before it votes.
    pub fn newcomers(&self, k: usize) -> Vec<u8> {
        let Some(round) = self.rounds.get(k) else {
            return Vec::new();
        };
        let mut unplugged = self.boundaries[k].unplugged;
        let mut out = Vec::new();
        for action in &round.lifecycle {
            match *action {
                Action::Unplug { controller } => unplugged |= 1 << (controller - 1),
                Action::Heal { controller } if unplugged & 1 << (controller - 1) != 0 => {
                    unplugged &= !(1 << (controller - 1));
                    out.push(controller);
                }
                _ => {}
            }
        }
        out
    }

    /// How the replay reaches each boundary (index `k`, `0..=last`).
    pub fn modes(&self) -> Vec<Mode> {
        let mut modes = vec![Mode::Start];
        let mut lockstep = true;
        for k in 1..self.boundaries.len() {
            let faults_follow = self.rounds.get(k).is_some_and(|r| !r.is_empty());
            let mode = if lockstep {
                Mode::Lockstep
            } else if self.quiescent[k] && faults_follow {
                lockstep = true;
                Mode::Realign
            } else {
                Mode::Free
            };
            modes.push(mode);
            if !self.newcomers(k).is_empty() {
                lockstep = false;
            }
        }
        modes
    }

    /// A readable summary: what happens in which round.
    pub fn describe(&self) -> String {
        let mut out = String::new();
        for (k, round) in self.rounds.iter().enumerate() {
            if round.is_empty() {
                continue;
            }
            let mut what: Vec<String> = round.lifecycle.iter().map(ToString::to_string).collect();
            what.extend(
                round
                    .lost
                    .iter()
                    .map(|(from, to)| format!("C{to} drops C{from}")),
            );
            let _ = write!(out, "round {k}: {}; ", what.join(", "));
        }
        let _ = write!(
            out,
            "{} boundaries from the trace, {} more to the settled end",
            self.trace_boundaries,
            self.boundaries.len() - self.trace_boundaries
        );
        out
    }
}

/// The run's model configuration: the trace's, with the run's round lengths and fault
/// budgets that never run out (real processes are not bounded by the trace's scope; the
/// timing checks add losses).
pub fn run_config(trace: &model::Config, timing: &Timing) -> model::Config {
    model::Config {
        dead_after_rounds: timing.dead_after_rounds,
        window_rounds: timing.window_rounds,
        max_crashes: u8::MAX,
        max_restarts: u8::MAX,
        max_lost_heartbeats: u8::MAX,
        ..trace.clone()
    }
}

/// One model step, if the model offers it in `state`.
pub(super) fn step(
    config: &model::Config,
    state: &State,
    action: Action,
) -> Result<State, PlanError> {
    let mut enabled = Vec::new();
    protocol::actions(config, state, &mut enabled);
    if !enabled.contains(&action) {
        return Err(PlanError::NotAllowed { action });
    }
    protocol::next_state(config, state, action).ok_or(PlanError::NotAllowed { action })
}

/// Expires every due window (they are urgent: the implementation fires them at the boundary).
fn expire_due(config: &model::Config, mut state: State) -> Result<State, PlanError> {
    for id in config.ids() {
        let action = Action::ExpireWindow { controller: id };
        let mut enabled = Vec::new();
        protocol::actions(config, &state, &mut enabled);
        if enabled.contains(&action) {
            state = step(config, &state, action)?;
        }
    }
    Ok(state)
}

/// A round's end: the model's `Tick`, or, with no controller up (the model then has no round
/// ends), the state as it is.
fn end_round(config: &model::Config, state: &State) -> Result<State, PlanError> {
    if state.up().next().is_none() {
        return Ok(state.clone());
    }
    step(config, state, Action::Tick)
}

/// A round's end with nothing lost leaves the state as it is.
pub fn is_quiescent(config: &model::Config, state: &State) -> bool {
    let mut clean = state.clone();
    clean.lost_links = 0;
    let Ok(ended) = end_round(config, &clean).and_then(|s| expire_due(config, s)) else {
        return false;
    };
    ended.controllers == clean.controllers
}

/// Runs the model from `start` through `rounds` (each round's lifecycle actions, losses and
/// end), then on without faults until quiescent; returns the boundary states.
pub(super) fn run_rounds(
    config: &model::Config,
    start: State,
    rounds: &[RoundPlan],
) -> Result<Vec<State>, PlanError> {
    let mut state = expire_due(config, start)?;
    let mut out = vec![state.clone()];
    for round in rounds {
        for action in &round.lifecycle {
            state = step(config, &state, *action)?;
        }
        for (from, to) in &round.lost {
            // A link of a controller that is not up has nothing to lose.
            if state.controller(*from).is_up() && state.controller(*to).is_up() {
                let lose = Action::LoseHeartbeat {
                    from: *from,
                    to: *to,
                };
                state = step(config, &state, lose)?;
            }
        }
        state = expire_due(config, end_round(config, &state)?)?;
        // Ghost history only: it feeds properties and budgets, never a decision.
        state.history = model::state::History::default();
        out.push(state.clone());
    }
    let mut extra = 0;
    while !is_quiescent(config, &state) {
        extra += 1;
        if extra > SETTLE_ROUNDS_MAX {
            return Err(PlanError::NoSettle {
                rounds: SETTLE_ROUNDS_MAX,
            });
        }
        state = expire_due(config, end_round(config, &state)?)?;
        out.push(state.clone());
    }
    Ok(out)
}

/// Who may own the actuator in `state`: the live controllers commanding at the highest
/// strength. The model's owner is the lowest id among them (it takes DDS's tie-break, the
/// lowest writer GUID, for the lowest id); RL's writer GUIDs are not in id order, so with a
/// tie the actuator may follow any of them. Empty when nobody commands.
pub fn owners(state: &State) -> Vec<u8> {
    let top = state.up().filter_map(|c| c.output).max();
    state
        .up()
        .filter(|c| top.is_some() && c.output == top)
        .map(|c| c.id)
        .collect()
}

/// Who may own the actuator through each round: boundary `k`'s state after round `k`'s
/// lifecycle actions (the last boundary's own for the last).
fn owners_in_round(
    config: &model::Config,
    rounds: &[RoundPlan],
    boundaries: &[State],
) -> Result<Vec<Vec<u8>>, PlanError> {
    let mut out = Vec::with_capacity(boundaries.len());
    for (k, boundary) in boundaries.iter().enumerate() {
        let mut state = boundary.clone();
        for action in rounds.get(k).map_or(&[][..], |r| &r.lifecycle[..]) {
            state = step(config, &state, *action)?;
        }
        out.push(owners(&state));
    }
    Ok(out)
}

/// The plan of one trace, or why it cannot be replayed on real processes.
pub fn plan(trace: &Trace, timing: &Timing) -> Result<Plan, PlanError> {
    if trace.variant() != model::Variant::Default || trace.config.mutation.is_some() {
        return Err(PlanError::NotDefaultVariant);
    }
    let config = run_config(&trace.config, timing);
    let initial = protocol::init_states(&config)
        .get(trace.initial_state_index)
        .cloned()
        .ok_or(PlanError::UnknownInitialState {
            index: trace.initial_state_index,
        })?;
    if abstract_state(&initial) != trace.initial {
        return Err(PlanError::InitialStateDiffers);
    }
    let Rebuilt {
        mut rounds,
        mut boundaries,
        state,
    } = rebuild(trace, &config, initial)?;
    // The round the trace's last steps left open, then rounds without faults until settled.
    let open = rounds.len() - 1;
    rounds[open].lost = lost_links(&state);
    let trace_boundaries = boundaries.len();
    let last_boundary = boundaries[trace_boundaries - 1].clone();
    if rounds[open].is_empty() && is_quiescent(&config, &last_boundary) {
        rounds.pop();
    } else {
        let tail = run_rounds(&config, last_boundary, &rounds[open..])?;
        boundaries.extend(tail.into_iter().skip(1));
        while rounds.len() + 1 < boundaries.len() {
            rounds.push(RoundPlan::default());
        }
    }
    let quiescent = boundaries
        .iter()
        .map(|s| is_quiescent(&config, s))
        .collect();
    let owners_in_round = owners_in_round(&config, &rounds, &boundaries)?;
    let plan = Plan {
        file: trace.file.clone(),
        purpose: trace.purpose.clone(),
        initial_up: trace
            .initial
            .controllers
            .iter()
            .filter(|c| c.life == Life::Up)
            .map(|c| c.id)
            .collect(),
        config,
        rounds,
        boundaries,
        trace_boundaries,
        quiescent,
        owners_in_round,
    };
    checks::check_timing(&plan)?;
    Ok(plan)
}

/// The run's timing as the DDS-level replay configures `rl`: the model's period, dead-man
/// deadline and window ([`super::CONFIG_TOML`]).
pub fn replay_timing() -> Timing {
    Timing {
        period_ms: 250,
        dead_after_rounds: 2,
        window_rounds: 2,
    }
}

#[cfg(test)]
mod tests {
    use super::super::curated::{curated, select};
    use super::*;

    #[test]
    fn the_owner_through_a_crash_round_is_the_survivors() {
        let family = curated("crash of the Primary").expect("a curated family");
        let selected = select(&crate::trace::default_dir(), family, &replay_timing())
            .unwrap_or_else(|e| panic!("{e}"));
        let plan = selected.plan;
        let k = plan
            .rounds
            .iter()
            .position(|r| !r.lifecycle.is_empty())
            .expect("the Primary crashes");
        assert_eq!(owners(&plan.boundaries[k]), vec![1], "at the boundary");
        assert!(
            !plan.owners_in_round[k].contains(&1),
            "through the round: {:?}",
            plan.owners_in_round[k]
        );
        let last = plan.last();
        assert_eq!(owners(&plan.boundaries[last]), plan.owners_in_round[last]);
        assert_eq!(plan.owners_in_round.len(), plan.boundaries.len());
    }

    #[test]
    fn with_a_tie_any_of_the_strongest_may_own_the_actuator() {
        let config = model::Config::default();
        let mut state = protocol::init_states(&config)[0].clone();
        assert!(owners(&state).is_empty(), "nobody commands yet");
        for (id, output) in [(1, Some(30)), (2, Some(30)), (3, Some(10))] {
            let c = state.controller_mut(id);
            c.life = Life::Up;
            c.output = output;
        }
        assert_eq!(owners(&state), vec![1, 2]);
        let writers = [(1, 30), (2, 30), (3, 10)];
        assert_eq!(
            model::protocol::actuator::next_owner(&writers, None, 0),
            Some(1),
            "the model names the lowest id until a tie-break says otherwise"
        );
    }
}
