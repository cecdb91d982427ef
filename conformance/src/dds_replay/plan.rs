//! The DDS-level replay's plan: which traces it takes (a curated subset, chosen by purpose
//! from `traces/index.json`) and, for each, what to do in which round and what to expect at
//! every round boundary, all derived from the model. Pure: no processes here
//! ([`crate::dds_replay`] runs the plan).
//!
//! Real processes cannot follow the model step for step: DDS discovery takes a round or two,
//! a new process is not heard at once, and the round clock is the wall clock. So a trace is
//! replayed on the model's rounds where it can be and compared at points where timing no
//! longer matters:
//!
//! - round 0's actions happen at start: the trace's initial controllers and its round-0
//!   crashes, restarts and joins are processes started (killed) right after a round
//!   boundary, its round-0 heartbeat losses are dropped from the start;
//! - the first round boundary at which any controller reports a change is the trace's
//!   boundary 1 (before it, discovery: rounds in which every heartbeat is lost). From there
//!   the replay is in lockstep: the trace's round `k` is real round `first + k - 1`, its
//!   losses are dropped for that round, its crashes are `kill -9` at the round's start, and
//!   every boundary is compared;
//! - a restart or join after round 0 ends the lockstep (the new process is heard only after
//!   discovery); the replay then waits, with a bounded wait, for the next quiescent boundary
//!   (one a round's end leaves unchanged) and re-aligns there if faults follow, or for the
//!   settled end;
//! - after the trace's last step the model adds rounds without faults until nothing changes
//!   any more (the settled end), and the run must reach that state and stay in it.
//!
//! A trace is replayable only if this timing cannot change its outcome, which the plan checks
//! against the model: its states are the same under the run's round lengths (the
//! run's window is one round longer than the model's, see `dds_replay::CONFIG_TOML`), a
//! controller heard one
//! round later at start changes nothing, a process started after round 0 ends in the same
//! settled state if discovery takes one or two rounds more, and faults after a late start
//! wait for a quiescent boundary.

use crate::trace::{self, Trace};
use crate::validate::Timing;
use model::state::link_bit;
use model::traces::{abstract_state, AbstractState};
use model::{protocol, Action, Life, Phase, Role, State};
use std::collections::BTreeSet;
use std::fmt::Write;
use std::path::Path;

/// The most rounds the model may take to settle after a trace's last step.
pub const SETTLE_ROUNDS_MAX: usize = 40;

/// A fault kind the curated subset must replay at least once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Need {
    /// A controller holding this role is killed.
    CrashOf(Role),
    /// A controller starts again as a new process (a new incarnation).
    Restart,
    /// A controller comes in after the others formed: still initializing while two others are
    /// steady with roles, and it ends with a role.
    LateJoin,
    /// Controller 4 starts and ends without a role.
    FourthController,
    /// A heartbeat lost one way (the reverse link delivers).
    OneWayLoss,
    /// A controller is marked FAILED for a minority vote.
    MinorityVote,
}

/// Which scope of the trace set a curated entry takes its trace from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scope {
    /// `check`'s default scope (`model::Config::default()`).
    Default,
    /// The persistent link failure (`model::Config::link_failure()`).
    LinkFailure,
}

impl Scope {
    fn config(self) -> model::Config {
        match self {
            Scope::Default => model::Config::default(),
            Scope::LinkFailure => model::Config::link_failure(),
        }
    }
}

/// One entry of the curated subset: the fault it must show, the purposes (in
/// `traces/index.json`) a trace for it may have, in order of preference, and why it is in.
#[derive(Clone, Copy, Debug)]
pub struct Curated {
    pub name: &'static str,
    pub need: Need,
    pub scope: Scope,
    pub purposes: &'static [&'static str],
    /// The DDS domain its test runs on (each test its own, so they never hear each other).
    pub domain: u16,
    pub why: &'static str,
}

/// The curated subset: every fault kind at least once. Domains 190-197 (198 is the recorded
/// `rl demo` of trace validation, 199 is free).
pub const CURATED: &[Curated] = &[
    Curated {
        name: "crash of the Primary",
        need: Need::CrashOf(Role::Primary),
        scope: Scope::Default,
        purposes: &[
            "transition: crash by a steady controller (primary) -> down (none)",
            "witness: Primary crash promotes the Secondary",
        ],
        domain: 190,
        why: "kill -9 of the steady Primary: the survivors lose it after the dead-man \
              deadline, re-vote, and the Secondary is promoted",
    },
    Curated {
        name: "crash of the Secondary",
        need: Need::CrashOf(Role::Secondary),
        scope: Scope::Default,
        purposes: &["transition: crash by a steady controller (secondary) -> down (none)"],
        domain: 191,
        why: "kill -9 of the steady Secondary: the Tertiary moves up, the Primary stays",
    },
    Curated {
        name: "crash of the Tertiary",
        need: Need::CrashOf(Role::Tertiary),
        scope: Scope::Default,
        purposes: &["transition: crash by a steady controller (tertiary) -> down (none)"],
        domain: 192,
        why: "kill -9 of the steady Tertiary: Primary and Secondary keep their roles",
    },
    Curated {
        name: "restart",
        need: Need::Restart,
        scope: Scope::Default,
        purposes: &[
            "witness: restarted controller takes the lowest role",
            "transition: restart by a down controller (none) -> initializing (none)",
        ],
        domain: 193,
        why: "a killed controller comes back as a new process, a new incarnation that the \
              others must not confuse with the old one, and takes the lowest role",
    },
    Curated {
        name: "late join",
        need: Need::LateJoin,
        scope: Scope::Default,
        purposes: &["witness: late joiner becomes Tertiary"],
        domain: 194,
        why: "C3 does not hear C1 while C1 and C2 form (its heartbeats dropped), then joins \
              the running system below them",
    },
    Curated {
        name: "fourth controller",
        need: Need::FourthController,
        scope: Scope::Default,
        purposes: &["witness: fourth controller ignored"],
        domain: 195,
        why: "a fourth process joins and stays a spare: it never holds a role or commands",
    },
    Curated {
        name: "one-way heartbeat loss",
        need: Need::OneWayLoss,
        scope: Scope::Default,
        purposes: &["witness: re-vote after heartbeat loss"],
        domain: 196,
        why: "C2 drops C1's heartbeats for two rounds (C1 still hears C2): C2 loses C1, \
              raises an alarm and re-votes, and the two reunite when the heartbeats return",
    },
    Curated {
        name: "minority vote",
        need: Need::MinorityVote,
        scope: Scope::LinkFailure,
        purposes: &["witness: minority voter FAILED"],
        domain: 197,
        why: "the link-failure scope's minority-voter witness: a link broken past the \
              minority grace, the minority voter marked FAILED and then failing itself",
    },
];

/// What happens during one round of the plan.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RoundPlan {
    /// Crashes, restarts and joins, in the trace's order.
    pub lifecycle: Vec<Action>,
    /// Heartbeats lost at the round's end, `(from, to)`: `to` drops `from`'s heartbeats for
    /// the round.
    pub lost: BTreeSet<(u8, u8)>,
}

impl RoundPlan {
    pub fn is_empty(&self) -> bool {
        self.lifecycle.is_empty() && self.lost.is_empty()
    }

    /// A process starts (join or restart) in this round.
    pub fn starts_process(&self) -> bool {
        self.lifecycle
            .iter()
            .any(|a| matches!(a, Action::Join { .. } | Action::Restart { .. }))
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
    /// After a late start: not compared (the new process is heard only once discovered).
    Free,
    /// A quiescent boundary after a late start, with faults in its round: waited for
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
}

impl Plan {
    /// The abstract state expected at boundary `k`.
    pub fn expected(&self, k: usize) -> AbstractState {
        abstract_state(&self.boundaries[k])
    }

    /// The last boundary: the settled end.
    pub fn last(&self) -> usize {
        self.boundaries.len() - 1
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
            if self.rounds.get(k).is_some_and(RoundPlan::starts_process) {
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

fn step(config: &model::Config, state: &State, action: Action) -> Result<State, String> {
    let mut enabled = Vec::new();
    protocol::actions(config, state, &mut enabled);
    if !enabled.contains(&action) {
        return Err(format!("the model does not allow \"{action}\" here"));
    }
    protocol::next_state(config, state, action)
        .ok_or_else(|| format!("the model does not allow \"{action}\" here"))
}

fn lost_links(state: &State) -> BTreeSet<(u8, u8)> {
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

/// Expires every due window (they are urgent: the implementation fires them at the boundary).
fn expire_due(config: &model::Config, mut state: State) -> Result<State, String> {
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

/// A round's end with nothing lost leaves the state as it is.
pub fn is_quiescent(config: &model::Config, state: &State) -> bool {
    let mut clean = state.clone();
    clean.lost_links = 0;
    let Ok(ended) = step(config, &clean, Action::Tick).and_then(|s| expire_due(config, s)) else {
        return false;
    };
    ended.controllers == clean.controllers
}

/// Runs the model from `start` through `rounds` (each round's lifecycle actions, losses and
/// end), then on without faults until quiescent; returns the boundary states.
fn run_rounds(
    config: &model::Config,
    start: State,
    rounds: &[RoundPlan],
) -> Result<Vec<State>, String> {
    let mut state = expire_due(config, start)?;
    let mut out = vec![state.clone()];
    for round in rounds {
        for action in &round.lifecycle {
            state = step(config, &state, *action)?;
        }
        for (from, to) in &round.lost {
            // A link of a controller that is not up has nothing to lose.
            if state.controller(*from).is_up() && state.controller(*to).is_up() {
                state = step(
                    config,
                    &state,
                    Action::LoseHeartbeat {
                        from: *from,
                        to: *to,
                    },
                )?;
            }
        }
        state = expire_due(config, step(config, &state, Action::Tick)?)?;
        // Ghost history only: it feeds properties and budgets, never a decision.
        state.history = model::state::History::default();
        out.push(state.clone());
    }
    let mut extra = 0;
    while !is_quiescent(config, &state) {
        extra += 1;
        if extra > SETTLE_ROUNDS_MAX {
            return Err(format!("does not settle within {SETTLE_ROUNDS_MAX} rounds"));
        }
        state = expire_due(config, step(config, &state, Action::Tick)?)?;
        out.push(state.clone());
    }
    Ok(out)
}

/// The plan of one trace, or why it cannot be replayed on real processes.
pub fn plan(trace: &Trace, timing: &Timing) -> Result<Plan, String> {
    if trace.variant() != model::Variant::Default || trace.config.mutation.is_some() {
        return Err("not a default-variant trace".into());
    }
    let config = run_config(&trace.config, timing);
    let initial = protocol::init_states(&config)
        .get(trace.initial_state_index)
        .cloned()
        .ok_or("its initial state index is not one of the model's")?;
    if abstract_state(&initial) != trace.initial {
        return Err("its initial state differs under the run's round lengths".into());
    }
    // Rebuild the trace under the run's round lengths, round by round.
    let mut rounds = vec![RoundPlan::default()];
    let mut boundaries = vec![initial.clone()];
    let mut state = initial;
    let mut round_has_other_action = false;
    for step_ in &trace.steps {
        let action = step_.action;
        match action {
            Action::Tick => {
                if let Some(round) = rounds.last_mut() {
                    round.lost = lost_links(&state);
                }
                state = step(&config, &state, action)?;
                boundaries.push(state.clone());
                rounds.push(RoundPlan::default());
                round_has_other_action = false;
            }
            Action::ExpireWindow { .. } => {
                if round_has_other_action {
                    return Err(format!(
                        "step {}: a window expires after another action of its round",
                        step_.number
                    ));
                }
                state = step(&config, &state, action)?;
                if let Some(last) = boundaries.last_mut() {
                    *last = state.clone();
                }
            }
            Action::DeliverVotes { .. } => {
                return Err("durable-vote delivery exists only in the paper variant".into())
            }
            Action::LoseHeartbeat { .. } => {
                state = step(&config, &state, action)?;
                round_has_other_action = true;
            }
            Action::Crash { .. } | Action::Restart { .. } | Action::Join { .. } => {
                state = step(&config, &state, action)?;
                if let Some(round) = rounds.last_mut() {
                    round.lifecycle.push(action);
                }
                round_has_other_action = true;
            }
        }
        if abstract_state(&state) != step_.state {
            return Err(format!(
                "step {} ({action}) reaches another state with a {}-round window (the trace \
                 was generated with {} rounds)",
                step_.number, config.window_rounds, trace.config.window_rounds
            ));
        }
    }
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
    };
    check_timing(&plan)?;
    Ok(plan)
}

/// The plan's timing assumptions, checked against the model.
fn check_timing(plan: &Plan) -> Result<(), String> {
    let config = &plan.config;
    if plan.boundaries.len() < 2 {
        return Err("no round ends".into());
    }
    // The replay takes the first round with reports for boundary 1: some controller must
    // report a change there (a new phase or a peer heard), or that round is unknown.
    let reports = |c: &model::Controller| {
        c.is_up()
            && (c.phase != Phase::Initializing
                || c.peers
                    .iter()
                    .any(|p| p.alive.is_some() || p.alarm || p.failed))
    };
    if !plan.boundaries[1].controllers.iter().any(reports) {
        return Err(
            "no controller reports anything at the first round's end, so the replay cannot \
             tell which real round it is"
                .into(),
        );
    }
    // Faults after a late start must wait for a quiescent boundary.
    let modes = plan.modes();
    for (k, round) in plan.rounds.iter().enumerate().skip(1) {
        if !round.is_empty() && modes[k] == Mode::Free {
            return Err(format!(
                "round {k} has faults after a process started late, with no quiescent \
                 boundary to re-align at"
            ));
        }
    }
    // Discovery at start: a controller may be heard one round later than the trace says
    // (it then counts one more quiet round of its window). Every combination must lead to
    // the same states.
    let expected: Vec<AbstractState> = plan.boundaries.iter().map(abstract_state).collect();
    let starters: Vec<u8> = {
        let mut ids = plan.initial_up.clone();
        for action in &plan.rounds[0].lifecycle {
            if let Action::Join { controller } | Action::Restart { controller } = action {
                ids.push(*controller);
            }
        }
        ids.sort_unstable();
        ids.dedup();
        ids
    };
    for mask in 1u32..(1 << starters.len()) {
        let mut start = plan.boundaries[0].clone();
        for action in &plan.rounds[0].lifecycle {
            start = step(config, &start, *action)?;
        }
        for (bit, id) in starters.iter().enumerate() {
            let c = start.controller_mut(*id);
            if mask & (1 << bit) != 0 && c.is_up() && c.phase == Phase::Initializing {
                c.window_quiet_rounds = 1.min(config.window_rounds);
            }
        }
        let mut rest = plan.rounds.clone();
        rest[0].lifecycle.clear();
        let states = run_rounds(config, start, &rest)?;
        let got: Vec<AbstractState> = states.iter().map(abstract_state).collect();
        // Boundary 0 is before round 0's starts and crashes; compare from boundary 1.
        if got.get(1..) != expected.get(1..) {
            let late: Vec<String> = starters
                .iter()
                .enumerate()
                .filter(|(bit, _)| mask & (1 << bit) != 0)
                .map(|(_, id)| format!("C{id}"))
                .collect();
            return Err(format!(
                "its states change if {} is heard one round later at start (DDS discovery)",
                late.join(", ")
            ));
        }
    }
    // A process started after round 0 is heard once discovered: not in the round it starts
    // (as the model's join is), but one or two rounds later; it must settle the same way.
    let last = plan.expected(plan.last());
    for k in 1..plan.rounds.len() {
        let newcomers: Vec<u8> = plan.rounds[k]
            .lifecycle
            .iter()
            .filter_map(|a| match a {
                Action::Join { controller } | Action::Restart { controller } => Some(*controller),
                _ => None,
            })
            .collect();
        if newcomers.is_empty() {
            continue;
        }
        for delay in 0..=1usize {
            let mut rounds: Vec<RoundPlan> = plan.rounds[k..].to_vec();
            let mut muted = RoundPlan::default();
            for newcomer in &newcomers {
                for other in config.ids().filter(|o| o != newcomer) {
                    muted.lost.insert((*newcomer, other));
                    muted.lost.insert((other, *newcomer));
                }
            }
            // The start's own round and `delay` more rounds without the newcomer's links.
            let mut first = rounds.remove(0);
            first.lost.extend(muted.lost.iter().copied());
            let mut delayed = vec![first];
            for _ in 0..delay {
                delayed.push(muted.clone());
            }
            delayed.extend(rounds);
            let states = run_rounds(config, plan.boundaries[k].clone(), &delayed)
                .map_err(|e| format!("with C{newcomers:?} discovered late: {e}"))?;
            let settled = states.last().map(abstract_state);
            if settled.as_ref() != Some(&last) {
                return Err(format!(
                    "its settled end changes if the process started in round {k} is heard \
                     {} round(s) later (DDS discovery)",
                    delay + 1
                ));
            }
        }
    }
    Ok(())
}

/// Whether a plan shows the fault a curated entry needs.
pub fn shows(plan: &Plan, need: Need) -> bool {
    let lifecycle = || {
        plan.rounds
            .iter()
            .enumerate()
            .flat_map(|(k, r)| r.lifecycle.iter().map(move |a| (k, *a)))
    };
    let last = &plan.boundaries[plan.last()];
    match need {
        Need::CrashOf(role) => lifecycle().any(|(k, action)| match action {
            Action::Crash { controller } => {
                plan.boundaries[k].controller(controller).role == Some(role)
            }
            _ => false,
        }),
        Need::Restart => lifecycle().any(|(_, a)| matches!(a, Action::Restart { .. })),
        Need::LateJoin => plan.boundaries.iter().any(|s| {
            s.controllers.iter().any(|late| {
                late.is_up()
                    && late.phase == Phase::Initializing
                    && s.controllers
                        .iter()
                        .filter(|c| c.is_up() && c.phase == Phase::Steady && c.role.is_some())
                        .count()
                        >= 2
                    && last.controller(late.id).role.is_some()
            })
        }),
        Need::FourthController => {
            lifecycle().any(|(_, a)| a == Action::Join { controller: 4 })
                && last
                    .controllers
                    .get(3)
                    .is_some_and(|c| c.is_up() && c.role.is_none())
        }
        Need::OneWayLoss => plan.rounds.iter().any(|r| {
            r.lost
                .iter()
                .any(|(from, to)| !r.lost.contains(&(*to, *from)))
        }),
        Need::MinorityVote => plan.boundaries.iter().any(|s| {
            s.up()
                .any(|c| c.phase == Phase::Failed || c.peers.iter().any(|p| p.failed))
        }),
    }
}

/// A curated entry resolved to a trace.
#[derive(Clone, Debug)]
pub struct Selected {
    pub curated: Curated,
    pub trace: Trace,
    pub plan: Plan,
}

/// Resolves one curated entry: the first trace (in `index.json` order) with one of its
/// purposes, from its scope, that can be replayed and shows its fault.
pub fn select(traces_dir: &Path, curated: &Curated, timing: &Timing) -> Result<Selected, String> {
    let entries =
        trace::read_index_entries(&traces_dir.join("index.json")).map_err(|e| e.to_string())?;
    let mut tried = Vec::new();
    for purpose in curated.purposes {
        for entry in entries.iter().filter(|e| e.purpose == *purpose) {
            let trace =
                trace::read_trace(&traces_dir.join(&entry.file)).map_err(|e| e.to_string())?;
            if trace.config != curated.scope.config() {
                tried.push(format!("{}: from another scope", entry.file));
                continue;
            }
            match plan(&trace, timing) {
                Ok(plan) if shows(&plan, curated.need) => {
                    return Ok(Selected {
                        curated: *curated,
                        trace,
                        plan,
                    })
                }
                Ok(_) => tried.push(format!("{}: does not show {:?}", entry.file, curated.need)),
                Err(reason) => tried.push(format!("{}: not replayable: {reason}", entry.file)),
            }
        }
    }
    Err(format!(
        "the DDS-level replay's \"{}\" needs a trace in {}/index.json with one of the purposes \
         {:?} (scope {:?}) that can be replayed on real processes; {}. If the trace set was \
         regenerated with other purposes, update conformance/src/dds_plan.rs (CURATED).",
        curated.name,
        traces_dir.display(),
        curated.purposes,
        curated.scope,
        if tried.is_empty() {
            "no entry has these purposes".to_string()
        } else {
            format!("tried: {}", tried.join("; "))
        }
    ))
}

/// The run's timing as the DDS-level replay configures `rl` (the model's period and
/// dead-man deadline; a window one round longer, see `dds_replay::CONFIG_TOML`).
pub fn replay_timing() -> Timing {
    Timing {
        period_ms: 250,
        dead_after_rounds: 2,
        window_rounds: 3,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_curated_entry_resolves_to_a_replayable_trace() {
        let dir = trace::default_dir();
        let mut files = BTreeSet::new();
        for curated in CURATED {
            let selected =
                select(&dir, curated, &replay_timing()).unwrap_or_else(|e| panic!("{e}"));
            assert!(shows(&selected.plan, curated.need));
            files.insert(selected.trace.file.clone());
        }
        assert_eq!(files.len(), CURATED.len(), "one trace per entry");
        let domains: BTreeSet<u16> = CURATED.iter().map(|c| c.domain).collect();
        assert_eq!(domains.len(), CURATED.len(), "one domain per entry");
    }
}
