//! The search for model states consistent with a recorded run: candidate histories
//! ("branches"), one model state set per controller, stepped round by round through the
//! environment's choices (join, restart, crash) and the round's end.

use super::{reject, Accepted, Rejection, Timing};
use crate::abstraction::{self, IncarnationNumbers, Observed};
use crate::record::{round_of, LifeLog, Recording};
use model::protocol;
use model::state::History;
use model::traces::AbstractController;
use model::{Action, Assignment, Controller, Life, Phase, State};
use rl_layer::core::ControllerId;
use std::collections::{HashMap, HashSet};

/// What the record says of one life, in rounds.
#[derive(Clone, Debug)]
pub(super) struct LifeRounds {
    pub(super) log: LifeLog,
    pub(super) start_round: u64,
    /// The last round in which it printed anything: it was alive until then.
    pub(super) last_round: u64,
    pub(super) stopped_round: Option<u64>,
    /// Boundaries its loop slept through (its `round_ends_missed` lines: the model's
    /// `Oversleep`): no round end of its own there.
    pub(super) missed_boundaries: HashSet<u64>,
}

/// The boundaries a life's loop slept through: a `round_ends_missed` line of `n` printed in
/// round `r` (its late round end, boundary `r`) stands for boundaries `r - n` to `r - 1`.
fn missed_boundaries(log: &LifeLog, period_ms: u64) -> HashSet<u64> {
    log.events
        .iter()
        .filter_map(|e| match e.event {
            rl_layer::event::Event::RoundEndsMissed { rounds } => Some((e.t_ms, rounds)),
            _ => None,
        })
        .flat_map(|(t_ms, rounds)| {
            let late = round_of(t_ms, period_ms);
            late.saturating_sub(rounds)..late
        })
        .collect()
}

/// The search's view of one candidate history: per controller id (index id - 1) the model
/// states it may be in, all with the same heartbeat content.
#[derive(Clone, Debug)]
pub(super) struct Branch {
    pub(super) slots: Vec<Vec<Controller>>,
    /// Each controller's representative state at the previous boundary: what a heartbeat
    /// that waited a round on a starved link carries (tolerance 4).
    pub(super) previous: Vec<Controller>,
}

/// What one controller's heartbeat carries (and whether it is up): all a receiver's next
/// state depends on: life, incarnation, phase, role, strength; agreed result and vote; the
/// result's epoch and standing, the established strength and the life it took over from.
pub(super) type Visible = (
    (Life, u8, Phase, Option<model::Role>, Option<u8>),
    (Option<Assignment>, Option<Assignment>),
    (u32, bool, Option<u8>, Option<(ControllerId, u8)>),
);

pub(super) fn visible(c: &Controller) -> Visible {
    (
        (c.life, c.incarnation, c.phase, c.role, c.output),
        (c.agreed, c.vote),
        (
            c.epoch,
            c.provisional,
            c.established_strength(),
            c.took_over_from,
        ),
    )
}

/// An environment choice for one controller in one round.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Lifecycle {
    Keep,
    Crash,
    /// Start life number `n` (a join for 0, a restart otherwise), crashing the current one.
    Start(u8),
}

pub(super) struct Search<'a> {
    pub(super) timing: Timing,
    pub(super) config: model::Config,
    pub(super) numbers: IncarnationNumbers,
    /// Per id (index id - 1), its lives in start order.
    pub(super) lives: Vec<Vec<LifeRounds>>,
    pub(super) recording: &'a Recording,
    /// Observations already abstracted: (id, life number, boundary round).
    pub(super) observed: HashMap<(ControllerId, u8, u64), AbstractController>,
    /// (controller, boundary) pairs explained only by the lag tolerance.
    pub(super) lagged: HashSet<(ControllerId, u64)>,
    /// Whether the one-round lag tolerance applies.
    pub(super) lag: bool,
    /// A boundary's reports are those printed this long into its round (its decisions),
    /// not the whole round's; `None`: the whole round's.
    pub(super) decided_within_ms: Option<u64>,
    pub(super) stats: Accepted,
}

impl<'a> Search<'a> {
    pub(super) fn new(
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
                    missed_boundaries: missed_boundaries(log, period),
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
            decided_within_ms: None,
            stats,
        })
    }

    /// Takes a boundary's reports as those printed within `ms` of it (see
    /// [`Search::decided_within_ms`]).
    pub(super) fn decided_within(mut self, ms: u64) -> Search<'a> {
        self.decided_within_ms = Some(ms);
        self
    }

    /// What `log` reported by the boundary of `round`.
    pub(super) fn reported(&self, log: &LifeLog, round: u64) -> rl_layer::core::Status {
        let period_ms = self.timing.period_ms;
        match self.decided_within_ms {
            Some(ms) => log.status_before(round * period_ms + ms),
            None => log.status_at_boundary(round, period_ms),
        }
    }

    pub(super) fn life(&self, id: ControllerId, number: u8) -> Option<&LifeRounds> {
        self.lives
            .get(usize::from(id) - 1)
            .and_then(|lives| lives.get(usize::from(number)))
    }

    /// What life `number` of `id` reported by the boundary of `round`, abstracted.
    pub(super) fn observation(
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
        let status = self.reported(&life.log, round);
        let source = life.log.source.clone();
        let abstracted =
            abstraction::abstract_controller(id, &Observed::Up(Box::new(status)), &self.numbers)
                .map_err(|e| reject(format!("{source}: {e}")))?;
        self.observed
            .insert((id, number, round), abstracted.clone());
        Ok(abstracted)
    }

    pub(super) fn run(mut self) -> Result<Accepted, Box<Rejection>> {
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
            previous: Vec::new(),
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
    pub(super) fn step(
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
                    super::round::RoundEnd::Survivors(survivors) => {
                        for survivor in survivors {
                            if !next.iter().any(|b| same_branch(b, &survivor)) {
                                next.push(survivor);
                            }
                        }
                    }
                    super::round::RoundEnd::Dead(dead) => {
                        if first_dead.is_none() {
                            first_dead = Some(*dead);
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

    /// The environment's choices for round `round` (joins, restarts, crashes, and a starved
    /// Primary where a takeover is reported at its end), applied.
    pub(super) fn lifecycles(&self, round: u64, branch: &Branch) -> Vec<Branch> {
        let mut out = self.process_lifecycles(round, branch);
        if self.reports_takeover(round + 1) {
            let starved: Vec<Branch> = out.iter().flat_map(|b| self.starvations(b)).collect();
            out.extend(starved);
        }
        out
    }

    /// Whether some life reports the takeover strength at boundary `boundary` (F17).
    fn reports_takeover(&self, boundary: u64) -> bool {
        self.lives.iter().flatten().any(|life| {
            life.start_round < boundary
                && life.last_round + 1 >= boundary
                && self.reported(&life.log, boundary).report.strength
                    == Some(rl_layer::core::types::TAKEOVER_STRENGTH)
        })
    }

    /// `branch` with each Primary that commands at 30 starved in turn, where the model allows
    /// it: its Secondary takes over (F17) in every candidate state it may be in.
    fn starvations(&self, branch: &Branch) -> Vec<Branch> {
        let state = representatives(branch);
        if state.controllers.iter().any(|c| c.took_over_from.is_some()) {
            return Vec::new();
        }
        let primaries = state
            .controllers
            .iter()
            .filter(|c| c.is_up() && c.role == Some(model::Role::Primary))
            .map(|c| c.id);
        let mut out = Vec::new();
        for primary in primaries {
            let action = Action::Starve {
                controller: primary,
            };
            let Some(starved) = step_model(&self.config, &state, action) else {
                continue;
            };
            let mut next = branch.clone();
            for (index, slot) in next.slots.iter_mut().enumerate() {
                if starved.controllers[index] == state.controllers[index] {
                    continue;
                }
                // The takeover changes the taker alone; apply it to each of its candidates.
                *slot = slot
                    .iter()
                    .filter_map(|candidate| {
                        let mut with = state.clone();
                        with.controllers[index] = candidate.clone();
                        step_model(&self.config, &with, action)
                            .map(|s| s.controllers[index].clone())
                    })
                    .collect();
            }
            if next.slots.iter().all(|slot| !slot.is_empty()) {
                out.push(next);
            }
        }
        out
    }

    /// The process events of round `round` (joins, restarts, crashes), applied.
    fn process_lifecycles(&self, round: u64, branch: &Branch) -> Vec<Branch> {
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

    pub(super) fn lifecycle_options(
        &self,
        round: u64,
        id: ControllerId,
        c: &Controller,
    ) -> Vec<Lifecycle> {
        let next_number = match c.life {
            Life::NotStarted => 0,
            Life::Up | Life::Down | Life::Paused => c.incarnation.saturating_add(1),
        };
        let current = match c.life {
            Life::NotStarted => None,
            Life::Up | Life::Down | Life::Paused => self.life(id, c.incarnation),
        };
        // It may crash once it printed its last line; a clean stop ends it by the next round.
        let may_crash =
            c.life == Life::Up && current.as_ref().is_some_and(|l| l.last_round <= round);
        let must_crash = c.life == Life::Up
            && current
                .as_ref()
                .and_then(|l| l.stopped_round)
                .is_some_and(|stopped| round > stopped);
        // The life this one replaces stopped in the round the next one started: it may have
        // spoken in that round before it stopped (its heartbeat timer fires at any point of
        // the round), which the model shows as the old life lasting the round and the new
        // one starting with the next.
        let replaced_mid_round = |start: u64| {
            c.life == Life::Up
                && current
                    .as_ref()
                    .is_some_and(|l| l.stopped_round == Some(start))
        };
        let mut options = Vec::new();
        if let Some(next) = self.life(id, next_number) {
            let start = next.start_round;
            if round + 1 == start {
                options.push(Lifecycle::Start(next_number));
            } else if round == start {
                if !replaced_mid_round(start) {
                    // It started this round: the start is not optional.
                    return vec![Lifecycle::Start(next_number)];
                }
                return vec![Lifecycle::Start(next_number), Lifecycle::Keep];
            } else if round == start + 1 && replaced_mid_round(start) {
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
    pub(super) fn apply_lifecycle(
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
}

/// Histories are limited to this many at once (each is a crash-timing alternative).
pub(super) const BRANCHES_MAX: usize = 256;

/// Where a history died: the controller none of whose next states agrees with its report.
#[derive(Clone, Debug)]
pub(super) struct Dead {
    pub(super) id: ControllerId,
    pub(super) number: u8,
    pub(super) observed: AbstractController,
    pub(super) previous: AbstractController,
    /// Every state the round could end in for it, with the lost-heartbeat choice (a bit per
    /// sender, in `senders` order).
    pub(super) candidates: Vec<(AbstractController, u16, Vec<ControllerId>)>,
    pub(super) before: Controller,
}

pub(super) fn same_branch(a: &Branch, b: &Branch) -> bool {
    a.slots.len() == b.slots.len()
        && a.slots.iter().zip(&b.slots).all(|(x, y)| {
            let x: HashSet<&Controller> = x.iter().collect();
            let y: HashSet<&Controller> = y.iter().collect();
            x == y
        })
}

/// A whole model state from a branch: each controller's first candidate (they all carry the
/// same heartbeat), no lost links, no history.
pub(super) fn representatives(branch: &Branch) -> State {
    State {
        controllers: branch.slots.iter().map(|slot| slot[0].clone()).collect(),
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
    }
}

/// One model step, only if the model offers the action in that state.
pub(super) fn step_model(config: &model::Config, state: &State, action: Action) -> Option<State> {
    let mut enabled = Vec::new();
    protocol::actions(config, state, &mut enabled);
    if !enabled.contains(&action) {
        return None;
    }
    protocol::next_state(config, state, action)
}
