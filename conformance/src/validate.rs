//! Trace validation: a recorded run of real controllers checked to be a behaviour the model
//! allows.
//!
//! The other direction from the replays: instead of driving the implementation along the
//! model's traces, a run of the implementation (the JSON events of every controller,
//! [`crate::record`]) is explained by stepping the model (`model::protocol::next_state`)
//! round by round. Observations are taken at round boundaries (`t_ms / heartbeat period`):
//! what every controller reported of itself by then, mapped to the model's abstract state by
//! the one abstraction function ([`crate::abstraction`]). Controller lives are numbered per id
//! in start order, the model's incarnation counter.
//!
//! The search keeps every model state consistent with the observations so far. Between two
//! boundaries the environment may do anything the model allows in a round: a controller whose
//! process starts in the round joins (its first life) or restarts (a later one); a controller
//! that printed nothing since may crash (a killed process just stops printing); any heartbeat
//! may be lost (this is also how DDS discovery of a new participant looks to the model); then
//! the round ends (`Tick`) and due initialization windows expire (the model makes them
//! urgent, the implementation fires them at the boundary). Every resulting state is kept if
//! it agrees with what each controller reported at the next boundary.
//!
//! The round's end acts on each controller separately: its next state depends on its own state
//! and on what the others' heartbeats carry (incarnation, phase, role, strength, agreed
//! result, vote), never on the others' hidden counters. So the set of states is kept per
//! controller, as candidate sets that share what heartbeats carry, and the lost heartbeats are
//! chosen per receiver (2^(live senders) choices, not 2^(links)). A test checks this against
//! `next_state` on whole states.
//!
//! What is compared (the abstraction's fields): life, incarnation, phase, role, strength,
//! agreed result, vote and alarms exactly; `sees` and `failed` exactly, except that a peer
//! both seen and FAILED in the last report may since have been lost without a report (the
//! implementation reports membership changes, and losing a FAILED peer is none). A process
//! that printed nothing since round `r` may have crashed in any round from `r` on; a clean
//! stop (`stopped`) ends its life by the next round.
//!
//! Tolerance, exactly: (1) a process may join one round before the round of its `started`
//! event (the core starts before the event is printed); (2) a controller's report may lag the
//! model by one round: where no model state agrees with what a controller reported by
//! boundary `b`, the states that agree with what it reported by boundary `b + 1` are kept
//! instead (a report stamped after the boundary it belongs to, e.g. when the process was not
//! scheduled in time). The summary counts the reports only (2) explains.

use crate::abstraction::{self, IncarnationNumbers, Observed};
use crate::diff::{fields, NAME_WIDTH, VALUE_WIDTH};
use crate::record::{round_of, LifeLog, Recording};
use model::protocol;
use model::state::History;
use model::traces::AbstractController;
use model::{Action, Assignment, Controller, Life, Phase, State, Variant};
use rl::core::ControllerId;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt::{self, Write};

/// Round lengths of the run, from its configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timing {
    pub period_ms: u64,
    pub dead_after_rounds: u8,
    pub window_rounds: u8,
}

impl Timing {
    /// The rounds `rl` derives from its configuration (impl/src/config/timing.rs).
    pub fn from_config(timing: &rl::config::Timing) -> Result<Timing, String> {
        let rounds = |name: &str, value: u32| {
            u8::try_from(value).map_err(|_| format!("{name}: {value} rounds is more than 255"))
        };
        Ok(Timing {
            period_ms: timing.heartbeat_period_ms.max(1),
            dead_after_rounds: rounds("timing.peer_deadline_ms", timing.dead_after_rounds())?,
            window_rounds: rounds("timing.init_window_ms", timing.window_rounds())?,
        })
    }

    /// The model's configuration for a run with ids `1..=controllers`: the default rules,
    /// this timing, and fault budgets that never run out.
    pub fn model_config(&self, controllers: u8) -> model::Config {
        model::Config {
            founders: controllers,
            late_joiners: 0,
            max_crashes: u8::MAX,
            max_restarts: u8::MAX,
            max_lost_heartbeats: u8::MAX,
            dead_after_rounds: self.dead_after_rounds,
            window_rounds: self.window_rounds,
            settle_within_rounds: model::Config::default().settle_within_rounds,
            variant: Variant::Default,
            mutation: None,
        }
    }
}

/// A run the model explains, with the size of the search.
#[derive(Clone, Debug, Default)]
pub struct Accepted {
    pub controllers: u8,
    pub lives: usize,
    /// Round boundaries compared (from the first start to the last event).
    pub rounds_checked: u64,
    /// Model steps taken: one per (candidate state, lost-heartbeat choice) at every round end.
    pub states_explored: u64,
    /// The most candidate states one controller had at one boundary.
    pub candidates_max: usize,
    /// The most alternative histories (crash timing) kept at once.
    pub branches_max: usize,
    /// Reports only the lag tolerance explains: (controller, boundary) pairs at which no
    /// model state agreed with the report but some agreed with the next round's.
    pub lagged_reports: u64,
    /// Where the strict check (no lag) failed, when the tolerance was needed.
    pub strict_rejection_round: Option<u64>,
}

impl fmt::Display for Accepted {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "accepted: {} controller id(s), {} lives, {} round boundaries checked, {} model \
             states explored (at most {} candidates per controller, {} alternative histories); \
             {}",
            self.controllers,
            self.lives,
            self.rounds_checked,
            self.states_explored,
            self.candidates_max,
            self.branches_max,
            match self.strict_rejection_round {
                None => "strictly, without the lag tolerance".to_string(),
                Some(round) => format!(
                    "with the one-round lag tolerance ({} lagged report(s); the strict check \
                     fails at boundary {round})",
                    self.lagged_reports
                ),
            }
        )
    }
}

/// Why a run is not a behaviour of the model (or cannot be checked).
#[derive(Clone, Debug)]
pub struct Rejection {
    /// The boundary at which nothing matched, as a round number and relative to the first.
    pub round: Option<u64>,
    pub message: String,
}

impl fmt::Display for Rejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Rejection {}

fn reject(message: String) -> Box<Rejection> {
    Box::new(Rejection {
        round: None,
        message,
    })
}

/// What the record says of one life, in rounds.
#[derive(Clone, Debug)]
struct LifeRounds {
    log: LifeLog,
    start_round: u64,
    /// The last round in which it printed anything: it was alive until then.
    last_round: u64,
    stopped_round: Option<u64>,
}

/// The search's view of one candidate history: per controller id (index id - 1) the model
/// states it may be in, all with the same heartbeat content.
#[derive(Clone, Debug)]
struct Branch {
    slots: Vec<Vec<Controller>>,
}

/// What one controller's heartbeat carries (and whether it is up): all a receiver's next
/// state depends on.
type Visible = (
    Life,
    u8,
    Phase,
    Option<model::Role>,
    Option<u8>,
    Option<Assignment>,
    Option<Assignment>,
);

fn visible(c: &Controller) -> Visible {
    (
        c.life,
        c.incarnation,
        c.phase,
        c.role,
        c.output,
        c.agreed,
        c.vote,
    )
}

/// An environment choice for one controller in one round.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Lifecycle {
    Keep,
    Crash,
    /// Start life number `n` (a join for 0, a restart otherwise), crashing the current one.
    Start(u8),
}

/// Checks a recorded run against the model: strictly first, then, if that fails, with the
/// one-round lag tolerance (the summary says whether it was needed).
pub fn validate(recording: &Recording, timing: &Timing) -> Result<Accepted, Box<Rejection>> {
    let strict = match Search::new(recording, timing, false)?.run() {
        Ok(accepted) => return Ok(accepted),
        Err(rejection) => rejection,
    };
    match Search::new(recording, timing, true)?.run() {
        Ok(mut accepted) => {
            accepted.strict_rejection_round = strict.round;
            Ok(accepted)
        }
        Err(mut tolerant) => {
            if let Some(round) = strict.round.filter(|r| Some(*r) != tolerant.round) {
                tolerant.message.push_str(&format!(
                    "  (without the lag tolerance the first disagreement is at boundary {round})\n"
                ));
            }
            Err(tolerant)
        }
    }
}

/// Checks a recorded run against the model strictly: without the one-round lag tolerance
/// (the DDS-level replay's recordings, whose boundaries are observed after their reports).
pub fn validate_strict(recording: &Recording, timing: &Timing) -> Result<Accepted, Box<Rejection>> {
    Search::new(recording, timing, false)?.run()
}

struct Search<'a> {
    timing: Timing,
    config: model::Config,
    numbers: IncarnationNumbers,
    /// Per id (index id - 1), its lives in start order.
    lives: Vec<Vec<LifeRounds>>,
    recording: &'a Recording,
    /// Observations already abstracted: (id, life number, boundary round).
    observed: HashMap<(ControllerId, u8, u64), AbstractController>,
    /// (controller, boundary) pairs explained only by the lag tolerance.
    lagged: HashSet<(ControllerId, u64)>,
    /// Whether the one-round lag tolerance applies.
    lag: bool,
    stats: Accepted,
}

impl<'a> Search<'a> {
    fn new(
        recording: &'a Recording,
        timing: &Timing,
        lag: bool,
    ) -> Result<Search<'a>, Box<Rejection>> {
        let controllers = recording.max_id();
        if controllers == 0 {
            return Err(reject("the recording holds no controller events".into()));
        }
        if usize::from(controllers) > model::types::MAX_CONTROLLERS {
            return Err(reject(format!(
                "the recording has controller id {controllers}; the model has at most {} \
                 controllers",
                model::types::MAX_CONTROLLERS
            )));
        }
        let config = timing.model_config(controllers);
        config
            .validate()
            .map_err(|e| reject(format!("model configuration: {e}")))?;
        let period = timing.period_ms;
        let mut lives = vec![Vec::new(); usize::from(controllers)];
        for (id, logs) in &recording.lives {
            if *id == 0 {
                return Err(reject("a controller event names id 0".into()));
            }
            for log in logs {
                let start = log.started_ms().unwrap_or(0);
                lives[usize::from(*id) - 1].push(LifeRounds {
                    log: log.clone(),
                    start_round: round_of(start, period),
                    last_round: round_of(log.last_event_ms().unwrap_or(start), period),
                    stopped_round: log.stopped_ms().map(|t| round_of(t, period)),
                });
            }
        }
        let stats = Accepted {
            controllers,
            lives: lives.iter().map(Vec::len).sum(),
            ..Accepted::default()
        };
        Ok(Search {
            timing: *timing,
            config,
            numbers: recording.incarnation_numbers(),
            lives,
            recording,
            observed: HashMap::new(),
            lagged: HashSet::new(),
            lag,
            stats,
        })
    }

    fn life(&self, id: ControllerId, number: u8) -> Option<&LifeRounds> {
        self.lives
            .get(usize::from(id) - 1)
            .and_then(|lives| lives.get(usize::from(number)))
    }

    /// What life `number` of `id` reported by the boundary of `round`, abstracted.
    fn observation(
        &mut self,
        id: ControllerId,
        number: u8,
        round: u64,
    ) -> Result<AbstractController, Box<Rejection>> {
        if let Some(found) = self.observed.get(&(id, number, round)) {
            return Ok(found.clone());
        }
        let life = self.life(id, number).ok_or_else(|| {
            reject(format!(
                "internal: C{id} life #{number} is not in the recording"
            ))
        })?;
        let status = life.log.status_at_boundary(round, self.timing.period_ms);
        let source = life.log.source.clone();
        let abstracted =
            abstraction::abstract_controller(id, &Observed::Up(Box::new(status)), &self.numbers)
                .map_err(|e| reject(format!("{source}: {e}")))?;
        self.observed
            .insert((id, number, round), abstracted.clone());
        Ok(abstracted)
    }

    fn run(mut self) -> Result<Accepted, Box<Rejection>> {
        let first_start = self
            .lives
            .iter()
            .flatten()
            .map(|l| l.start_round)
            .min()
            .unwrap_or(0);
        let last_round = self
            .lives
            .iter()
            .flatten()
            .map(|l| l.last_round)
            .max()
            .unwrap_or(first_start);
        // One round early: a process may join the round before its `started` event's.
        let begin = first_start.saturating_sub(1);
        let initial = Branch {
            slots: self
                .config
                .ids()
                .map(|id| vec![Controller::new(id, Life::NotStarted)])
                .collect(),
        };
        let mut branches = vec![initial];
        for round in begin..last_round {
            branches = self.step(round, branches, begin)?;
            self.stats.rounds_checked += 1;
            self.stats.branches_max = self.stats.branches_max.max(branches.len());
        }
        Ok(self.stats)
    }

    /// One round: from the branches consistent with boundary `round` to those consistent
    /// with boundary `round + 1`.
    fn step(
        &mut self,
        round: u64,
        branches: Vec<Branch>,
        begin: u64,
    ) -> Result<Vec<Branch>, Box<Rejection>> {
        let mut next: Vec<Branch> = Vec::new();
        let mut first_dead: Option<Dead> = None;
        let considered = branches.len();
        for branch in &branches {
            for prepared in self.lifecycles(round, branch) {
                match self.end_round(round, &prepared)? {
                    Ok(survivors) => {
                        for survivor in survivors {
                            if !next.iter().any(|b| same_branch(b, &survivor)) {
                                next.push(survivor);
                            }
                        }
                    }
                    Err(dead) => {
                        if first_dead.is_none() {
                            first_dead = Some(dead);
                        }
                    }
                }
            }
        }
        if next.is_empty() {
            return Err(self.rejection(round + 1, begin, considered, first_dead));
        }
        if next.len() > BRANCHES_MAX {
            return Err(reject(format!(
                "round {}: {} alternative histories; the search is limited to {BRANCHES_MAX}",
                round + 1,
                next.len()
            )));
        }
        Ok(next)
    }

    /// The environment's choices for round `round` (joins, restarts, crashes), applied.
    fn lifecycles(&self, round: u64, branch: &Branch) -> Vec<Branch> {
        let mut per_id: Vec<Vec<Lifecycle>> = Vec::new();
        for (index, slot) in branch.slots.iter().enumerate() {
            let id = (index + 1) as ControllerId;
            per_id.push(self.lifecycle_options(round, id, &slot[0]));
        }
        let mut out = vec![branch.clone()];
        for (index, options) in per_id.iter().enumerate() {
            let id = (index + 1) as ControllerId;
            let mut expanded = Vec::new();
            for partial in &out {
                for option in options {
                    if let Some(applied) = self.apply_lifecycle(partial, id, *option, round) {
                        expanded.push(applied);
                    }
                }
            }
            out = expanded;
        }
        out
    }

    fn lifecycle_options(&self, round: u64, id: ControllerId, c: &Controller) -> Vec<Lifecycle> {
        let next_number = match c.life {
            Life::NotStarted => 0,
            Life::Up | Life::Down => c.incarnation.saturating_add(1),
        };
        let current = match c.life {
            Life::NotStarted => None,
            Life::Up | Life::Down => self.life(id, c.incarnation),
        };
        // It may crash once it printed its last line; a clean stop ends it by the next round.
        let may_crash =
            c.life == Life::Up && current.as_ref().is_some_and(|l| l.last_round <= round);
        let must_crash = c.life == Life::Up
            && current
                .as_ref()
                .and_then(|l| l.stopped_round)
                .is_some_and(|stopped| round > stopped);
        let mut options = Vec::new();
        if let Some(next) = self.life(id, next_number) {
            let start = next.start_round;
            if round + 1 == start {
                options.push(Lifecycle::Start(next_number));
            } else if round == start {
                // It started this round: the start is not optional.
                return vec![Lifecycle::Start(next_number)];
            } else if round > start {
                return Vec::new();
            }
        }
        if !must_crash {
            options.push(Lifecycle::Keep);
        }
        if may_crash {
            options.push(Lifecycle::Crash);
        }
        options
    }

    /// Applies one lifecycle choice through the model; `None` if the model does not allow it.
    fn apply_lifecycle(
        &self,
        branch: &Branch,
        id: ControllerId,
        choice: Lifecycle,
        round: u64,
    ) -> Option<Branch> {
        let index = usize::from(id) - 1;
        let mut state = representatives(branch);
        let mut actions = Vec::new();
        let current = &state.controllers[index];
        match choice {
            Lifecycle::Keep => return Some(branch.clone()),
            Lifecycle::Crash => actions.push(Action::Crash { controller: id }),
            Lifecycle::Start(number) => {
                if current.life == Life::Up {
                    let may_crash = self
                        .life(id, current.incarnation)
                        .is_some_and(|l| l.last_round <= round);
                    if !may_crash {
                        return None;
                    }
                    actions.push(Action::Crash { controller: id });
                }
                actions.push(if number == 0 {
                    Action::Join { controller: id }
                } else {
                    Action::Restart { controller: id }
                });
            }
        }
        for action in actions {
            state = step_model(&self.config, &state, action)?;
        }
        let mut out = branch.clone();
        out.slots[index] = vec![state.controllers[index].clone()];
        Some(out)
    }

    /// The round ends: every live controller's candidates under every choice of lost
    /// heartbeats towards it, kept if they agree with the next boundary.
    fn end_round(
        &mut self,
        round: u64,
        branch: &Branch,
    ) -> Result<Result<Vec<Branch>, Dead>, Box<Rejection>> {
        let boundary = round + 1;
        let reps = representatives(branch);
        let up: Vec<ControllerId> = reps
            .controllers
            .iter()
            .filter(|c| c.is_up())
            .map(|c| c.id)
            .collect();
        let mut slots: Vec<Vec<Vec<Controller>>> = Vec::new();
        for (index, slot) in branch.slots.iter().enumerate() {
            let id = (index + 1) as ControllerId;
            if !slot[0].is_up() {
                slots.push(vec![slot.clone()]);
                continue;
            }
            let senders: Vec<ControllerId> = up.iter().copied().filter(|s| *s != id).collect();
            let mut outcomes: Vec<(Controller, u16)> = Vec::new();
            let mut seen: HashSet<Controller> = HashSet::new();
            for candidate in slot {
                for (next, lost) in round_end_of(&self.config, &reps, id, candidate, &senders) {
                    self.stats.states_explored += 1;
                    if seen.insert(next.clone()) {
                        outcomes.push((next, lost));
                    }
                }
            }
            let number = slot[0].incarnation;
            let now = self.observation(id, number, boundary)?;
            let later = self.observation(id, number, boundary + 1)?;
            let views: Vec<AbstractController> = outcomes
                .iter()
                .map(|(next, _)| abstract_one(&reps, next))
                .collect();
            let agreeing = |report: &AbstractController| -> Vec<Controller> {
                outcomes
                    .iter()
                    .zip(&views)
                    .filter(|(_, view)| differences(view, report).is_empty())
                    .map(|((next, _), _)| next.clone())
                    .collect()
            };
            let mut kept = agreeing(&now);
            if kept.is_empty() && self.lag && later != now {
                // The lag tolerance, only where no state agrees on time.
                kept = agreeing(&later);
                if !kept.is_empty() && self.lagged.insert((id, boundary)) {
                    self.stats.lagged_reports += 1;
                }
            }
            if kept.is_empty() {
                return Ok(Err(Dead {
                    id,
                    number,
                    observed: now,
                    previous: self.observation(id, number, round)?,
                    candidates: outcomes
                        .iter()
                        .zip(views)
                        .map(|((_, lost), view)| (view, *lost, senders.clone()))
                        .collect(),
                    before: slot[0].clone(),
                }));
            }
            self.stats.candidates_max = self.stats.candidates_max.max(kept.len());
            // Candidates with different heartbeat content belong to different histories.
            let mut groups: Vec<Vec<Controller>> = Vec::new();
            for candidate in kept {
                match groups
                    .iter_mut()
                    .find(|g| visible(&g[0]) == visible(&candidate))
                {
                    Some(group) => group.push(candidate),
                    None => groups.push(vec![candidate]),
                }
            }
            slots.push(groups);
        }
        let mut out = vec![Branch { slots: Vec::new() }];
        for groups in slots {
            let mut expanded = Vec::new();
            for partial in &out {
                for group in &groups {
                    let mut b = partial.clone();
                    b.slots.push(group.clone());
                    expanded.push(b);
                }
            }
            out = expanded;
        }
        Ok(Ok(out))
    }

    fn rejection(
        &mut self,
        boundary: u64,
        begin: u64,
        considered: usize,
        dead: Option<Dead>,
    ) -> Box<Rejection> {
        let period = self.timing.period_ms;
        let mut message = String::new();
        let relative = boundary.saturating_sub(begin);
        let _ = writeln!(
            message,
            "the run is not a behaviour of the model: at round boundary {boundary} \
             (t_ms = {}, round {relative} of the run) no model state agrees with what the \
             controllers reported ({considered} alternative histories were followed)",
            boundary * period
        );
        match &dead {
            Some(dead) => {
                let _ = writeln!(
                    message,
                    "C{} (life #{}) reported at this boundary, against its model state before \
                     the round:",
                    dead.id, dead.number
                );
                let _ = writeln!(
                    message,
                    "    before the round: {}",
                    model::render::controller_line(&dead.before)
                );
                let _ = writeln!(
                    message,
                    "    reported one round earlier: {}",
                    crate::diff::controller_line(&dead.previous)
                );
                let _ = writeln!(
                    message,
                    "    reported now:               {}",
                    crate::diff::controller_line(&dead.observed)
                );
                // Loss choices that end in the same abstract state are shown once.
                let mut distinct: Vec<(&AbstractController, Vec<String>)> = Vec::new();
                for (view, lost, senders) in &dead.candidates {
                    let lost_from: Vec<String> = senders
                        .iter()
                        .enumerate()
                        .filter(|(bit, _)| lost & (1 << bit) != 0)
                        .map(|(_, s)| format!("C{s}"))
                        .collect();
                    let choice = if lost_from.is_empty() {
                        "none lost".to_string()
                    } else {
                        format!("lost from {}", lost_from.join("+"))
                    };
                    match distinct.iter_mut().find(|(v, _)| *v == view) {
                        Some((_, choices)) => choices.push(choice),
                        None => distinct.push((view, vec![choice])),
                    }
                }
                distinct.sort_by_key(|(view, _)| differences(view, &dead.observed).len());
                let _ = writeln!(
                    message,
                    "  the closest of the {} distinct states the round can end in for it \
                     (>> marks a difference):",
                    distinct.len()
                );
                for (view, choices) in distinct.iter().take(3) {
                    let _ = writeln!(
                        message,
                        "  heartbeats to C{}: {}",
                        dead.id,
                        choices.join(" | ")
                    );
                    message.push_str(&field_diff(view, &dead.observed));
                }
            }
            None => {
                let _ = writeln!(
                    message,
                    "  no environment choice (join, restart, crash) of the round is allowed by \
                     the model and the record (e.g. a process printed after a later life of \
                     its id started)"
                );
            }
        }
        let _ = writeln!(message, "  the record around it:");
        let from_ms = boundary.saturating_sub(3) * period;
        let until_ms = (boundary + 2) * period;
        for (source, event) in self.recording.events_by_time() {
            if event.t_ms >= from_ms
                && event.t_ms < until_ms
                && !matches!(event.event, rl::event::Event::Leds { .. })
            {
                let number = self.numbers.number(event.id, event.incarnation);
                let _ = writeln!(
                    message,
                    "    {:>8} ms (round {:+}) {source}: {}",
                    event.t_ms,
                    round_of(event.t_ms, period) as i64 - boundary as i64,
                    crate::record::describe_event(event, number)
                );
            }
        }
        Box::new(Rejection {
            round: Some(boundary),
            message,
        })
    }
}

/// Histories are limited to this many at once (each is a crash-timing alternative).
const BRANCHES_MAX: usize = 256;

/// Where a history died: the controller none of whose next states agrees with its report.
#[derive(Clone, Debug)]
struct Dead {
    id: ControllerId,
    number: u8,
    observed: AbstractController,
    previous: AbstractController,
    /// Every state the round could end in for it, with the lost-heartbeat choice (a bit per
    /// sender, in `senders` order).
    candidates: Vec<(AbstractController, u16, Vec<ControllerId>)>,
    before: Controller,
}

fn same_branch(a: &Branch, b: &Branch) -> bool {
    a.slots.len() == b.slots.len()
        && a.slots.iter().zip(&b.slots).all(|(x, y)| {
            let x: HashSet<&Controller> = x.iter().collect();
            let y: HashSet<&Controller> = y.iter().collect();
            x == y
        })
}

/// A whole model state from a branch: each controller's first candidate (they all carry the
/// same heartbeat), no lost links, no history.
fn representatives(branch: &Branch) -> State {
    State {
        controllers: branch.slots.iter().map(|slot| slot[0].clone()).collect(),
        lost_links: 0,
        overdue_votes: 0,
        history: History::default(),
    }
}

/// One model step, only if the model offers the action in that state.
fn step_model(config: &model::Config, state: &State, action: Action) -> Option<State> {
    let mut enabled = Vec::new();
    protocol::actions(config, state, &mut enabled);
    if !enabled.contains(&action) {
        return None;
    }
    protocol::next_state(config, state, action)
}

/// Every state controller `id` (as `candidate`) can end round in, with the others as in
/// `reps`: one per subset of `senders` whose heartbeat to it is lost (bit i = senders[i]).
/// Due initialization windows expire right after the round ends.
pub fn round_end_of(
    config: &model::Config,
    reps: &State,
    id: ControllerId,
    candidate: &Controller,
    senders: &[ControllerId],
) -> Vec<(Controller, u16)> {
    let index = usize::from(id) - 1;
    let mut base = reps.clone();
    base.controllers[index] = candidate.clone();
    base.lost_links = 0;
    base.history = History::default();
    let mut out = Vec::new();
    for lost in 0u16..(1 << senders.len()) {
        let mut state = base.clone();
        let mut allowed = true;
        for (bit, from) in senders.iter().enumerate() {
            if lost & (1 << bit) != 0 {
                match step_model(
                    config,
                    &state,
                    Action::LoseHeartbeat {
                        from: *from,
                        to: id,
                    },
                ) {
                    Some(next) => state = next,
                    None => allowed = false,
                }
            }
        }
        if !allowed {
            continue;
        }
        let Some(mut ended) = step_model(config, &state, Action::Tick) else {
            continue;
        };
        if let Some(expired) = step_model(config, &ended, Action::ExpireWindow { controller: id }) {
            ended = expired;
        }
        out.push((ended.controllers[index].clone(), lost));
    }
    out
}

/// The model's abstract view of one controller (`model::traces::abstract_state`).
fn abstract_one(reps: &State, c: &Controller) -> AbstractController {
    let index = usize::from(c.id) - 1;
    let mut state = reps.clone();
    state.controllers[index] = c.clone();
    model::traces::abstract_state(&state)
        .controllers
        .swap_remove(index)
}

/// The fields in which a model state disagrees with a report. `sees` and `failed` may both
/// lack peers the report has as seen and FAILED (lost since, without a report).
pub fn differences(model: &AbstractController, observed: &AbstractController) -> Vec<&'static str> {
    let mut out = Vec::new();
    let exact = [
        ("life", model.life == observed.life),
        ("incarnation", model.incarnation == observed.incarnation),
        ("phase", model.phase == observed.phase),
        ("role", model.role == observed.role),
        ("strength", model.strength == observed.strength),
        ("alarms", model.alarms == observed.alarms),
        ("agreed", model.agreed == observed.agreed),
        ("vote", model.vote == observed.vote),
    ];
    out.extend(
        exact
            .iter()
            .filter(|(_, same)| !same)
            .map(|(name, _)| *name),
    );
    let dropped: Vec<u8> = observed
        .sees
        .iter()
        .copied()
        .filter(|id| !model.sees.contains(id))
        .collect();
    let sees_ok = model.sees.iter().all(|id| observed.sees.contains(id))
        && dropped.iter().all(|id| observed.failed.contains(id));
    let failed_expected: Vec<u8> = observed
        .failed
        .iter()
        .copied()
        .filter(|id| !dropped.contains(id))
        .collect();
    if !sees_ok {
        out.push("sees");
    }
    if model.failed != failed_expected {
        out.push("failed");
    }
    out
}

/// Model against report, one row per field, `>>` where they differ.
fn field_diff(model: &AbstractController, observed: &AbstractController) -> String {
    let differing = differences(model, observed);
    let mut out = format!(
        "      {:<NAME_WIDTH$}{:<VALUE_WIDTH$}reported\n",
        "", "model"
    );
    for ((name, model_value), (_, observed_value)) in
        fields(model).into_iter().zip(fields(observed))
    {
        let mark = if differing.contains(&name) {
            ">>"
        } else {
            "  "
        };
        let _ = writeln!(
            out,
            "   {mark} {name:<NAME_WIDTH$}{model_value:<VALUE_WIDTH$}{observed_value}"
        );
    }
    out
}

/// Reads a run's configuration: `path` if given, else `<dir>/rl.toml` if it exists, else
/// `rl`'s defaults.
pub fn run_timing(
    dir: &std::path::Path,
    path: Option<&std::path::Path>,
) -> Result<(Timing, String), String> {
    let candidate = path
        .map(std::path::Path::to_path_buf)
        .or_else(|| Some(dir.join("rl.toml")).filter(|p| p.is_file()));
    let (config, source) = match candidate {
        Some(path) => (
            rl::config::Config::load(&path).map_err(|e| e.to_string())?,
            path.display().to_string(),
        ),
        None => (rl::config::Config::default(), "rl's defaults".to_string()),
    };
    Ok((Timing::from_config(&config.timing)?, source))
}

/// Per controller id, the lives of a recording and their rounds: a summary line per life.
pub fn describe_lives(recording: &Recording, period_ms: u64) -> String {
    let numbers = recording.incarnation_numbers();
    let mut out = String::new();
    let lives: BTreeMap<_, _> = recording.lives.iter().collect();
    for (id, logs) in lives {
        for log in logs {
            let number = numbers.number(*id, log.incarnation).unwrap_or(0);
            let start = log.started_ms().map_or(0, |t| round_of(t, period_ms));
            let last = log.last_event_ms().map_or(0, |t| round_of(t, period_ms));
            let end = if log.stopped_ms().is_some() {
                "stopped"
            } else {
                "then silent (killed or still running)"
            };
            let _ = writeln!(
                out,
                "  C{id}#{number} ({}): rounds {start}..={last}, {} events, {end}",
                log.source,
                log.events.len()
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use model::RlModel;

    /// The round's end acts on each controller separately: a receiver's next state under a
    /// choice of lost heartbeats is the same whether the others' losses are chosen with it or
    /// not, and whatever the others' hidden counters are.
    #[test]
    fn a_round_end_decomposes_per_receiver() {
        let rl_model = RlModel::new(model::Config::default());
        // The walks stay in the default scope; the round ends are checked without budgets.
        let config = model::Config {
            max_lost_heartbeats: u8::MAX,
            ..model::Config::default()
        };
        let mut checked = 0;
        for seed in 0..40 {
            let path = model::simulate::walk(&rl_model, seed, 30);
            for state in std::iter::once(&path.init).chain(path.steps.iter().map(|(_, s)| s)) {
                let mut state = state.clone();
                state.lost_links = 0;
                state.history = History::default();
                let up: Vec<u8> = state.up().map(|c| c.id).collect();
                let mut enabled = Vec::new();
                protocol::actions(&config, &state, &mut enabled);
                if !enabled.contains(&Action::Tick) {
                    continue;
                }
                // Every link lost with probability 1/2, from the seed.
                let mut bits = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ checked;
                let mut joint = state.clone();
                let mut lost_to: BTreeMap<u8, u16> = BTreeMap::new();
                for &to in &up {
                    let senders: Vec<u8> = up.iter().copied().filter(|s| *s != to).collect();
                    for (bit, &from) in senders.iter().enumerate() {
                        bits = bits.rotate_left(7) ^ 0x5555;
                        if bits & 1 == 1 {
                            joint = protocol::next_state(
                                &config,
                                &joint,
                                Action::LoseHeartbeat { from, to },
                            )
                            .expect("a loss is always a step");
                            *lost_to.entry(to).or_default() |= 1 << bit;
                        }
                    }
                }
                let together = protocol::next_state(&config, &joint, Action::Tick).expect("tick");
                // The others' hidden counters replaced: the receiver must not notice.
                let mut others_hidden = state.clone();
                for c in others_hidden.controllers.iter_mut() {
                    c.self_dissent_rounds = 3;
                    c.window_quiet_rounds = 0;
                    for p in c.peers.iter_mut() {
                        p.silent_rounds = 1;
                        p.dissent_rounds = 2;
                    }
                }
                for &to in &up {
                    let index = usize::from(to) - 1;
                    let senders: Vec<u8> = up.iter().copied().filter(|s| *s != to).collect();
                    let lost = lost_to.get(&to).copied().unwrap_or(0);
                    let alone = round_end_of(
                        &config,
                        &others_hidden,
                        to,
                        &state.controllers[index],
                        &senders,
                    );
                    let (mine, _) = alone
                        .iter()
                        .find(|(_, mask)| *mask == lost)
                        .expect("every loss choice is explored");
                    let mut expected = together.controllers[index].clone();
                    if let Some(expired) =
                        step_model(&config, &together, Action::ExpireWindow { controller: to })
                    {
                        expected = expired.controllers[index].clone();
                    }
                    assert_eq!(mine, &expected, "C{to} in {state:?}");
                    checked += 1;
                }
            }
        }
        assert!(checked > 500, "only {checked} receivers checked");
    }

    #[test]
    fn a_lost_failed_peer_may_be_missing_from_sees_and_failed() {
        let observed = AbstractController {
            id: 1,
            life: Life::Up,
            incarnation: 0,
            phase: Some(Phase::Steady),
            role: Some(model::Role::Primary),
            strength: Some(30),
            sees: vec![2, 3],
            failed: vec![2],
            alarms: vec![2],
            agreed: None,
            vote: None,
        };
        let lost = AbstractController {
            sees: vec![3],
            failed: vec![],
            ..observed.clone()
        };
        assert!(differences(&lost, &observed).is_empty());
        let lost_unfailed = AbstractController {
            sees: vec![2],
            ..observed.clone()
        };
        assert_eq!(differences(&lost_unfailed, &observed), vec!["sees"]);
    }
}
