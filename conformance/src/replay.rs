//! Core-level replay: a model trace driven through real `rl::core::Core` instances.
//!
//! [`CoreNetwork`] is a simulated clock and network around one `Core` per running controller.
//! Time is in milliseconds, one round of the model is one heartbeat period
//! ([`PERIOD_MS`]): round `r` spans `[r * 250, (r + 1) * 250)`, and the cores share these
//! boundaries as controllers with agreeing clocks do (impl/src/core/mod.rs). Each model action
//! becomes core inputs:
//!
//! - `Tick`: every live core fires its timers up to its heartbeat send slot (boundary + 62 ms)
//!   and publishes its heartbeat (a core started this round published one at its start; the
//!   latest one counts); each heartbeat is delivered (boundary + 125 ms) to every other live
//!   core unless the trace lost that link this round; then every live core fires its
//!   round-end timer at the next boundary.
//! - `LoseHeartbeat { from, to }`: that link drops this round's heartbeat.
//! - `ExpireWindow { controller }`: the core fires its window timer, which must be due at the
//!   round boundary.
//! - `Crash { controller }`: the core is dropped.
//! - `Restart` / `Join { controller }`: a new core whose incarnation is the model's number
//!   starts at boundary + 10 ms, before the send slot, so its heartbeat is delivered at this
//!   round's end and it hears this round's heartbeats, as in the model.
//! - `DeliverVotes`: paper variant only; not replayed.
//!
//! A crash, restart or join also forgets the round's lost links of that controller, as the
//! model does. After every step the abstracted core states ([`crate::abstraction`]) must
//! equal the trace's state, and each live core's commands must agree with its change: a
//! `SetOutput` exactly when its role or strength changed, a `PublishVote` exactly when its vote
//! changed, `RaiseAlarm` / `ClearAlarm` exactly for the alarms added / removed. A difference
//! is a [`Failure`], whose `Display` is the readable diff.

use crate::abstraction::{self, IncarnationNumbers, Observed, UnknownIncarnation};
use crate::coverage::{self, CoverageClass};
use crate::trace::Trace;
use crate::transcript;
use model::traces::{AbstractController, AbstractState};
use model::{Action, Life, Variant};
use rl::core::{Command, ControllerId, Core, CoreConfig, Heartbeat, Input, Rounds, Timer};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::{self, Write};

/// One model round: one heartbeat period.
pub const PERIOD_MS: u64 = 250;
/// A started or restarted core starts this long after the round boundary.
pub const START_OFFSET_MS: u64 = 10;
/// Heartbeats of a round arrive this long after its boundary (after every send slot).
pub const DELIVERY_OFFSET_MS: u64 = 125;

/// Why a trace is not replayed at the core level, if it is not.
pub fn skip_reason(trace: &Trace) -> Option<String> {
    if trace.variant() == Variant::Paper {
        return Some(
            "paper variant: a counterexample of the paper's literal rules, which RL corrects \
             (docs/findings.md); the core follows the default rules"
                .to_string(),
        );
    }
    if let Some(mutation) = trace.config.mutation {
        return Some(format!("generated with the model mutation {mutation:?}"));
    }
    None
}

/// A trace that conformed: its transcript and what it covered.
#[derive(Clone, Debug)]
pub struct Replayed {
    pub file: String,
    /// The readable transcript (the snapshot).
    pub transcript: String,
    /// (action kind x stage of the acting controller) pairs its steps exercised.
    pub covered: BTreeSet<CoverageClass>,
    pub steps: usize,
}

/// Replays one default-variant trace against real cores.
pub fn replay(trace: &Trace) -> Result<Replayed, Failure> {
    replay_with(trace, &|config| config)
}

/// Replays one default-variant trace against cores whose configuration `configure` adjusts
/// (the mutation check configures a deliberately broken rule).
pub fn replay_with(trace: &Trace, configure: &Configure) -> Result<Replayed, Failure> {
    let fail = |step: usize, problem: Problem| Failure::new(trace, step, problem);
    if let Some(reason) = skip_reason(trace) {
        return Err(fail(0, Problem::Unsupported(reason)));
    }
    let mut network =
        CoreNetwork::start(&trace.config, &trace.initial, configure).map_err(|p| fail(0, p))?;
    let observed = network.observe().map_err(|p| fail(0, p))?;
    if observed != trace.initial {
        return Err(fail(
            0,
            Problem::State {
                expected: trace.initial.clone(),
                observed,
            },
        ));
    }
    let mut text = transcript::header(trace);
    transcript::push_state(&mut text, "initial", &observed);
    let mut covered = BTreeSet::new();
    for (index, step) in trace.steps.iter().enumerate() {
        let before = trace.state_before(index);
        covered.extend(coverage::classes(before, &step.action));
        let commands = network
            .apply(step.action)
            .map_err(|p| fail(step.number, p))?;
        let observed = network.observe().map_err(|p| fail(step.number, p))?;
        if observed != step.state {
            return Err(fail(
                step.number,
                Problem::State {
                    expected: step.state.clone(),
                    observed,
                },
            ));
        }
        let problems = command_problems(before, &step.state, &commands, &network.numbers)
            .map_err(|e| fail(step.number, Problem::Abstraction(e)))?;
        if !problems.is_empty() {
            return Err(fail(step.number, Problem::Commands(problems)));
        }
        transcript::push_state(
            &mut text,
            &format!("step {}: {}", step.number, step.action),
            &observed,
        );
    }
    Ok(Replayed {
        file: trace.file.clone(),
        transcript: text,
        covered,
        steps: trace.steps.len(),
    })
}

/// One controller id's slot in the simulated system.
#[derive(Clone, Debug)]
struct Slot {
    id: ControllerId,
    life: Life,
    /// The model's incarnation number of its current or last life.
    incarnation: u8,
    /// The running core, while `life` is up.
    core: Option<Core>,
}

/// Real cores on a simulated clock and network, stepped by model actions.
pub struct CoreNetwork<'a> {
    rounds: Rounds,
    configure: &'a Configure,
    /// The current round: the model's rounds ended so far.
    round: u64,
    slots: Vec<Slot>,
    /// Links whose heartbeat is lost this round, as (from, to).
    lost: BTreeSet<(ControllerId, ControllerId)>,
    numbers: IncarnationNumbers,
}

/// Commands each core returned during one step, by controller id.
pub type StepCommands = BTreeMap<ControllerId, Vec<Command>>;

/// Adjusts each core's configuration before it starts.
pub type Configure = dyn Fn(CoreConfig) -> CoreConfig;

impl<'a> CoreNetwork<'a> {
    /// The cores of a trace's initial state, started together inside round 0.
    pub fn start(
        config: &model::Config,
        initial: &AbstractState,
        configure: &'a Configure,
    ) -> Result<CoreNetwork<'a>, Problem> {
        let mut network = CoreNetwork {
            rounds: Rounds {
                dead_after_rounds: u32::from(config.dead_after_rounds),
                window_rounds: u32::from(config.window_rounds),
            },
            configure,
            round: 0,
            slots: Vec::new(),
            lost: BTreeSet::new(),
            numbers: IncarnationNumbers::new(),
        };
        for (index, c) in initial.controllers.iter().enumerate() {
            if usize::from(c.id) != index + 1 {
                return Err(Problem::Unsupported(format!(
                    "controller {} listed at position {}",
                    c.id,
                    index + 1
                )));
            }
            network.slots.push(Slot {
                id: c.id,
                life: Life::NotStarted,
                incarnation: c.incarnation,
                core: None,
            });
            match c.life {
                Life::Up => network.start_core(c.id, c.incarnation)?,
                Life::Down => network.slots[index].life = Life::Down,
                Life::NotStarted => {}
            }
        }
        Ok(network)
    }

    /// The current round's boundary (its start).
    fn boundary_ms(&self) -> u64 {
        self.round * PERIOD_MS
    }

    fn slot_mut(&mut self, id: ControllerId) -> Result<&mut Slot, Problem> {
        let index = usize::from(id).wrapping_sub(1);
        self.slots.get_mut(index).ok_or_else(|| {
            Problem::Unsupported(format!(
                "the action names C{id}, which the trace does not have"
            ))
        })
    }

    fn live_core(&mut self, id: ControllerId) -> Result<&mut Core, Problem> {
        self.slot_mut(id)?
            .core
            .as_mut()
            .ok_or_else(|| Problem::Timing(format!("C{id} is not running")))
    }

    fn start_core(&mut self, id: ControllerId, incarnation: u8) -> Result<(), Problem> {
        let rounds = self.rounds;
        let start_ms = self.boundary_ms() + START_OFFSET_MS;
        // The implementation's incarnation is the model's number, so holders map one to one.
        let stamp = u64::from(incarnation);
        let number = self.numbers.started(id, stamp);
        if number != incarnation {
            return Err(Problem::Timing(format!(
                "C{id} starts its life #{incarnation}, but it is its start number {number}"
            )));
        }
        let config = (self.configure)(CoreConfig::new(id, stamp, PERIOD_MS, rounds));
        let slot = self.slot_mut(id)?;
        slot.life = Life::Up;
        slot.incarnation = incarnation;
        slot.core = Some(Core::new(config, start_ms));
        self.lost.retain(|&(from, to)| from != id && to != id);
        Ok(())
    }

    /// What an observer sees of every controller, in id order.
    pub fn observed(&self) -> Vec<Observed> {
        self.slots
            .iter()
            .map(|slot| match (&slot.core, slot.life) {
                (Some(core), _) => Observed::Up(Box::new(core.status())),
                (None, Life::Down) => Observed::Down {
                    incarnation: u64::from(slot.incarnation),
                },
                (None, _) => Observed::NotStarted,
            })
            .collect()
    }

    /// The abstract state of the cores.
    pub fn observe(&self) -> Result<AbstractState, Problem> {
        abstraction::abstract_state(&self.observed(), &self.numbers).map_err(Problem::Abstraction)
    }

    /// Performs one model action; returns the commands each core emitted.
    pub fn apply(&mut self, action: Action) -> Result<StepCommands, Problem> {
        let mut commands = StepCommands::new();
        match action {
            Action::Tick => self.tick(&mut commands)?,
            Action::LoseHeartbeat { from, to } => {
                self.lost.insert((from, to));
            }
            Action::ExpireWindow { controller } => {
                let boundary = self.boundary_ms();
                let core = self.live_core(controller)?;
                let due = core.next_deadline();
                if due.timer != Timer::WindowExpiry || due.at_ms > boundary {
                    return Err(Problem::Timing(format!(
                        "C{controller}'s initialization window is not due at the round \
                         boundary ({boundary} ms; its next timer is {:?} at {} ms)",
                        due.timer, due.at_ms
                    )));
                }
                commands.insert(controller, core.step(Input::Timer(due.timer), due.at_ms));
            }
            Action::Crash { controller } => {
                let slot = self.slot_mut(controller)?;
                slot.core = None;
                slot.life = Life::Down;
                self.lost
                    .retain(|&(from, to)| from != controller && to != controller);
            }
            Action::Restart { controller } => {
                let next = self.slot_mut(controller)?.incarnation.saturating_add(1);
                self.start_core(controller, next)?;
                commands.insert(controller, Vec::new());
            }
            Action::Join { controller } => {
                self.start_core(controller, 0)?;
                commands.insert(controller, Vec::new());
            }
            Action::DeliverVotes { to } => {
                return Err(Problem::Unsupported(format!(
                    "votes delivered to C{to}: durable-vote delivery exists only in the paper \
                     variant"
                )));
            }
        }
        Ok(commands)
    }

    /// The end of a round: heartbeats out at the send slot, delivered, then the round ends.
    fn tick(&mut self, commands: &mut StepCommands) -> Result<(), Problem> {
        let boundary = self.boundary_ms();
        let round_end = boundary + PERIOD_MS;
        let mut heartbeats: BTreeMap<ControllerId, Heartbeat> = BTreeMap::new();
        for slot in &mut self.slots {
            let Some(core) = slot.core.as_mut() else {
                continue;
            };
            let id = slot.id;
            if core.next_deadline().timer == Timer::WindowExpiry {
                return Err(Problem::Timing(format!(
                    "C{id}'s initialization window is due, but the model ends the round \
                     without it expiring"
                )));
            }
            let send_slot = boundary + core.config().heartbeat_offset_ms();
            let emitted = commands.entry(id).or_default();
            while core.next_deadline().at_ms <= send_slot {
                let due = core.next_deadline();
                for command in core.step(Input::Timer(due.timer), due.at_ms) {
                    if let Command::PublishHeartbeat(heartbeat) = &command {
                        heartbeats.insert(id, *heartbeat);
                    }
                    emitted.push(command);
                }
            }
            if !heartbeats.contains_key(&id) {
                return Err(Problem::Timing(format!(
                    "C{id} published no heartbeat by its send slot ({send_slot} ms)"
                )));
            }
        }
        let lost = &self.lost;
        for slot in &mut self.slots {
            let Some(core) = slot.core.as_mut() else {
                continue;
            };
            let to = slot.id;
            let emitted = commands.entry(to).or_default();
            for (&from, heartbeat) in &heartbeats {
                if from != to && !lost.contains(&(from, to)) {
                    emitted.extend(
                        core.step(Input::Heartbeat(*heartbeat), boundary + DELIVERY_OFFSET_MS),
                    );
                }
            }
        }
        for slot in &mut self.slots {
            let Some(core) = slot.core.as_mut() else {
                continue;
            };
            let due = core.next_deadline();
            if due.at_ms != round_end || due.timer != Timer::RoundEnd {
                return Err(Problem::Timing(format!(
                    "C{}'s next timer is {:?} at {} ms, but the round ends at {round_end} ms",
                    slot.id, due.timer, due.at_ms
                )));
            }
            commands
                .entry(slot.id)
                .or_default()
                .extend(core.step(Input::Timer(Timer::RoundEnd), round_end));
        }
        self.lost.clear();
        self.round += 1;
        Ok(())
    }
}

/// The commands' disagreements with the trace's state change, one line each.
fn command_problems(
    before: &AbstractState,
    after: &AbstractState,
    commands: &StepCommands,
    numbers: &IncarnationNumbers,
) -> Result<Vec<String>, UnknownIncarnation> {
    let mut problems = Vec::new();
    for (&id, emitted) in commands {
        let Some(now) = after.controllers.iter().find(|c| c.id == id) else {
            continue;
        };
        if now.life != Life::Up {
            continue;
        }
        let blank = fresh_life(now);
        // A new life starts from nothing: the commands of the old one are not its own.
        let was = before
            .controllers
            .iter()
            .find(|c| c.id == id && c.life == Life::Up && c.incarnation == now.incarnation)
            .unwrap_or(&blank);
        check_output(id, was, now, emitted, &mut problems);
        check_vote(id, was, now, emitted, numbers, &mut problems)?;
        check_alarms(id, was, now, emitted, &mut problems);
    }
    Ok(problems)
}

fn fresh_life(now: &AbstractController) -> AbstractController {
    AbstractController {
        id: now.id,
        life: Life::Up,
        incarnation: now.incarnation,
        phase: Some(model::Phase::Initializing),
        role: None,
        strength: None,
        sees: vec![],
        failed: vec![],
        alarms: vec![],
        agreed: None,
        vote: None,
    }
}

fn role_name(role: Option<model::Role>) -> String {
    role.map_or("no role".to_string(), |r| r.name().to_lowercase())
}

fn strength_text(strength: Option<u8>) -> String {
    strength.map_or("silent".to_string(), |s| s.to_string())
}

fn check_output(
    id: ControllerId,
    was: &AbstractController,
    now: &AbstractController,
    emitted: &[Command],
    problems: &mut Vec<String>,
) {
    let last = emitted.iter().rev().find_map(|c| match c {
        Command::SetOutput { role, strength } => Some((role.map(abstraction::role), *strength)),
        _ => None,
    });
    let changed = (was.role, was.strength) != (now.role, now.strength);
    match (changed, last) {
        (true, None) => problems.push(format!(
            "C{id}: role/strength changed ({} {} -> {} {}) but no SetOutput was emitted",
            role_name(was.role),
            strength_text(was.strength),
            role_name(now.role),
            strength_text(now.strength)
        )),
        (false, Some((role, strength))) => problems.push(format!(
            "C{id}: SetOutput {{ {}, {} }} emitted but role/strength did not change",
            role_name(role),
            strength_text(strength)
        )),
        (true, Some((role, strength))) if (role, strength) != (now.role, now.strength) => problems
            .push(format!(
                "C{id}: SetOutput {{ {}, {} }} emitted, the state says {} {}",
                role_name(role),
                strength_text(strength),
                role_name(now.role),
                strength_text(now.strength)
            )),
        _ => {}
    }
}

fn check_vote(
    id: ControllerId,
    was: &AbstractController,
    now: &AbstractController,
    emitted: &[Command],
    numbers: &IncarnationNumbers,
    problems: &mut Vec<String>,
) -> Result<(), UnknownIncarnation> {
    let last = emitted.iter().rev().find_map(|c| match c {
        Command::PublishVote(record) => Some(record.vote),
        _ => None,
    });
    let show = |v: &Option<String>| v.clone().unwrap_or_else(|| "none".to_string());
    let changed = was.vote != now.vote;
    match (changed, last) {
        (true, None) => problems.push(format!(
            "C{id}: vote changed ({} -> {}) but no PublishVote was emitted",
            show(&was.vote),
            show(&now.vote)
        )),
        (false, Some(vote)) => problems.push(format!(
            "C{id}: PublishVote [{}] emitted but the vote did not change",
            show(&abstraction::render_assignment(id, vote, numbers)?)
        )),
        (true, Some(vote)) => {
            let published = abstraction::render_assignment(id, vote, numbers)?;
            if published != now.vote {
                problems.push(format!(
                    "C{id}: PublishVote [{}] emitted, the state's vote is [{}]",
                    show(&published),
                    show(&now.vote)
                ));
            }
        }
        (false, None) => {}
    }
    Ok(())
}

fn check_alarms(
    id: ControllerId,
    was: &AbstractController,
    now: &AbstractController,
    emitted: &[Command],
    problems: &mut Vec<String>,
) {
    let before: BTreeSet<u8> = was.alarms.iter().copied().collect();
    let after: BTreeSet<u8> = now.alarms.iter().copied().collect();
    let expected_raised: BTreeSet<u8> = after.difference(&before).copied().collect();
    let expected_cleared: BTreeSet<u8> = before.difference(&after).copied().collect();
    let raised: BTreeSet<u8> = emitted
        .iter()
        .filter_map(|c| match c {
            Command::RaiseAlarm { about, .. } => Some(*about),
            _ => None,
        })
        .collect();
    let cleared: BTreeSet<u8> = emitted
        .iter()
        .filter_map(|c| match c {
            Command::ClearAlarm { about, .. } => Some(*about),
            _ => None,
        })
        .collect();
    if raised != expected_raised {
        problems.push(format!(
            "C{id}: alarms raised for {} but the alarms added are {}",
            coverage::id_set(&raised),
            coverage::id_set(&expected_raised)
        ));
    }
    if cleared != expected_cleared {
        problems.push(format!(
            "C{id}: alarms cleared for {} but the alarms removed are {}",
            coverage::id_set(&cleared),
            coverage::id_set(&expected_cleared)
        ));
    }
}

/// What went wrong at a step.
#[derive(Clone, Debug)]
pub enum Problem {
    /// The abstracted cores differ from the trace's state.
    State {
        expected: AbstractState,
        observed: AbstractState,
    },
    /// The commands disagree with the state change (one line per disagreement).
    Commands(Vec<String>),
    /// A timer was not due when the model's action says it fires (or was due when the model
    /// says it is not).
    Timing(String),
    /// The abstraction could not map the cores' state.
    Abstraction(UnknownIncarnation),
    /// The trace uses something the core-level replay does not map.
    Unsupported(String),
}

/// A trace that does not conform: where, and the readable difference.
#[derive(Clone, Debug)]
pub struct Failure {
    pub file: String,
    pub purpose: String,
    /// The step (1-based); 0 = the initial state.
    pub step: usize,
    pub steps_total: usize,
    pub action: Option<Action>,
    /// The actions before it, for reproducing by hand.
    pub earlier_actions: Vec<Action>,
    pub problem: Box<Problem>,
}

impl Failure {
    fn new(trace: &Trace, step: usize, problem: Problem) -> Failure {
        let index = step.checked_sub(1);
        Failure {
            file: trace.file.clone(),
            purpose: trace.purpose.clone(),
            step,
            steps_total: trace.steps.len(),
            action: index.and_then(|i| trace.steps.get(i)).map(|s| s.action),
            earlier_actions: trace
                .steps
                .iter()
                .take(index.unwrap_or(0))
                .map(|s| s.action)
                .collect(),
            problem: Box::new(problem),
        }
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.action {
            Some(action) => writeln!(
                f,
                "traces/{}, step {} of {}: {action}",
                self.file, self.step, self.steps_total
            )?,
            None => writeln!(f, "traces/{}, initial state", self.file)?,
        }
        writeln!(f, "  trace purpose: {}", self.purpose)?;
        if !self.earlier_actions.is_empty() {
            let list: Vec<String> = self
                .earlier_actions
                .iter()
                .enumerate()
                .map(|(i, a)| format!("{}. {a}", i + 1))
                .collect();
            writeln!(f, "  after: {}", list.join("; "))?;
        }
        match self.problem.as_ref() {
            Problem::State { expected, observed } => f.write_str(&state_diff(expected, observed)),
            Problem::Commands(lines) => {
                writeln!(f, "  the commands disagree with the state change:")?;
                for line in lines {
                    writeln!(f, "    {line}")?;
                }
                Ok(())
            }
            Problem::Timing(message) => writeln!(f, "  timing: {message}"),
            Problem::Abstraction(error) => writeln!(f, "  abstraction: {error}"),
            Problem::Unsupported(message) => writeln!(f, "  not replayable: {message}"),
        }
    }
}

/// The fields of an abstract controller, named and rendered for a diff.
pub fn fields(c: &AbstractController) -> Vec<(&'static str, String)> {
    let opt = |s: Option<String>| s.unwrap_or_else(|| "-".to_string());
    vec![
        ("life", format!("{:?}", c.life).to_lowercase()),
        ("incarnation", c.incarnation.to_string()),
        ("phase", opt(c.phase.map(|p| p.name().to_string()))),
        ("role", opt(c.role.map(|r| r.name().to_lowercase()))),
        ("strength", opt(c.strength.map(|s| s.to_string()))),
        ("sees", coverage::id_set(&c.sees)),
        ("failed", coverage::id_set(&c.failed)),
        ("alarms", coverage::id_set(&c.alarms)),
        ("agreed", opt(c.agreed.clone())),
        ("vote", opt(c.vote.clone())),
    ]
}

/// Width of the field-name column of a state diff.
pub const NAME_WIDTH: usize = 13;
/// Width of the model's column of a state diff (an assignment is at most 17 characters).
pub const VALUE_WIDTH: usize = 24;

/// Expected (model) against observed (core), per controller; differing rows marked `>>`:
///
/// ```text
///   C2               model                   core
///   >> role          secondary               primary
///      strength      20                      20
/// ```
pub fn state_diff(expected: &AbstractState, observed: &AbstractState) -> String {
    state_diff_of("core", "the core's", expected, observed)
}

/// [`state_diff`] with another name for the observed side (`processes` for the DDS-level
/// replay): `column` heads its column, `whose` opens the first line.
pub fn state_diff_of(
    column: &str,
    whose: &str,
    expected: &AbstractState,
    observed: &AbstractState,
) -> String {
    let mut out = format!("  {whose} state differs from the model's (>> marks a difference):\n");
    let mut matching = Vec::new();
    let count = expected.controllers.len().max(observed.controllers.len());
    for index in 0..count {
        let model_side = expected.controllers.get(index);
        let core_side = observed.controllers.get(index);
        if model_side == core_side {
            if let Some(c) = model_side {
                matching.push(format!("C{}", c.id));
            }
            continue;
        }
        let id = model_side.or(core_side).map_or(0, |c| c.id);
        let _ = writeln!(
            out,
            "  {:<width$}{:<VALUE_WIDTH$}{column}",
            format!("C{id}"),
            "model",
            width = 3 + NAME_WIDTH
        );
        let rows_model = model_side.map(fields).unwrap_or_default();
        let rows_core = core_side.map(fields).unwrap_or_default();
        for row in 0..rows_model.len().max(rows_core.len()) {
            let name = rows_model
                .get(row)
                .or(rows_core.get(row))
                .map_or("", |(name, _)| name);
            let model_value = rows_model.get(row).map_or("(absent)", |(_, v)| v.as_str());
            let core_value = rows_core.get(row).map_or("(absent)", |(_, v)| v.as_str());
            let mark = if model_value == core_value {
                "  "
            } else {
                ">>"
            };
            let _ = writeln!(
                out,
                "  {mark} {name:<NAME_WIDTH$}{model_value:<VALUE_WIDTH$}{core_value}"
            );
        }
    }
    if !matching.is_empty() {
        let _ = writeln!(out, "  {}: as the model says", matching.join(", "));
    }
    let owner = |o: Option<u8>| o.map_or("none".to_string(), |id| format!("C{id}"));
    let mark = if expected.actuator_owner == observed.actuator_owner {
        "  "
    } else {
        ">>"
    };
    let _ = writeln!(
        out,
        "  {mark} actuator owner: model {}, {column} {}",
        owner(expected.actuator_owner),
        owner(observed.actuator_owner)
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::traces::AbstractController;
    use rl::core::{AlarmReason, Role};

    fn controller(id: u8) -> AbstractController {
        AbstractController {
            id,
            life: Life::Up,
            incarnation: 0,
            phase: Some(model::Phase::Steady),
            role: Some(model::Role::Secondary),
            strength: Some(20),
            sees: vec![1, 3],
            failed: vec![],
            alarms: vec![],
            agreed: None,
            vote: None,
        }
    }

    fn state(c: AbstractController) -> AbstractState {
        AbstractState {
            controllers: vec![controller(1), c],
            actuator_owner: Some(1),
        }
    }

    fn problems(
        before: AbstractController,
        after: AbstractController,
        emitted: Vec<Command>,
    ) -> Vec<String> {
        let commands: StepCommands = [(2, emitted)].into_iter().collect();
        command_problems(
            &state(before),
            &state(after),
            &commands,
            &IncarnationNumbers::new(),
        )
        .expect("no holders to number")
    }

    #[test]
    fn a_role_change_needs_its_set_output_and_nothing_else_does() {
        let before = controller(2);
        let promoted = AbstractController {
            role: Some(model::Role::Primary),
            strength: Some(30),
            ..controller(2)
        };
        let set_output = Command::SetOutput {
            role: Some(Role::Primary),
            strength: Some(30),
        };
        assert_eq!(
            problems(before.clone(), promoted.clone(), vec![set_output.clone()]),
            Vec::<String>::new()
        );
        assert_eq!(
            problems(before.clone(), promoted, vec![]),
            vec!["C2: role/strength changed (secondary 20 -> primary 30) but no SetOutput was emitted"]
        );
        assert_eq!(
            problems(before.clone(), before, vec![set_output]),
            vec!["C2: SetOutput { primary, 30 } emitted but role/strength did not change"]
        );
    }

    #[test]
    fn alarms_raised_and_cleared_must_match_the_alarm_set() {
        let before = AbstractController {
            alarms: vec![3],
            ..controller(2)
        };
        let after = AbstractController {
            alarms: vec![1],
            ..controller(2)
        };
        let raise = Command::RaiseAlarm {
            about: 1,
            reason: AlarmReason::Lost,
        };
        let clear = Command::ClearAlarm {
            about: 3,
            reason: AlarmReason::Lost,
        };
        assert!(problems(before.clone(), after.clone(), vec![raise.clone(), clear]).is_empty());
        assert_eq!(
            problems(before, after, vec![raise]),
            vec!["C2: alarms cleared for {} but the alarms removed are {3}"]
        );
    }

    #[test]
    fn a_window_that_is_not_due_cannot_expire() {
        let config = model::Config::default();
        let initial = AbstractState {
            controllers: vec![AbstractController {
                phase: Some(model::Phase::Initializing),
                role: None,
                strength: None,
                sees: vec![],
                ..controller(1)
            }],
            actuator_owner: None,
        };
        let mut network = CoreNetwork::start(&config, &initial, &|c| c).expect("one controller");
        assert_eq!(network.observe().expect("known lives"), initial);
        match network.apply(Action::ExpireWindow { controller: 1 }) {
            Err(Problem::Timing(message)) => {
                assert!(message.contains("window is not due"), "{message}")
            }
            other => panic!("expected a timing failure, got {other:?}"),
        }
    }
}
