//! Checking the output model: stateright's checker for the verdicts and state counts (as
//! `check` does for the role model), and our own breadth-first search with parent links for
//! the shortest path to each discovery (stateright 0.31's are not the shortest, docs/model.md).

use super::properties::{catalogue, OutputPropertyInfo};
use super::state::{OutputAction, OutputState};
use super::{render, OutputConfig, OutputModel};
use stateright::{Checker, Expectation, HasDiscoveries, Model};
use std::collections::{BTreeSet, HashMap, VecDeque};
use std::fmt::Write;
use std::time::{Duration, Instant};

/// What a check found about one property.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    Holds,
    Violated,
    Witnessed,
    NeverWitnessed,
    /// A witness the scope lacks the faults for (the reason).
    NotApplicable(&'static str),
}

impl Outcome {
    /// Whether the outcome is as the property expects.
    pub fn as_expected(self) -> bool {
        !matches!(self, Outcome::Violated | Outcome::NeverWitnessed)
    }

    pub fn label(self) -> &'static str {
        match self {
            Outcome::Holds => "holds",
            Outcome::Violated => "VIOLATED",
            Outcome::Witnessed => "witnessed",
            Outcome::NeverWitnessed => "NEVER WITNESSED",
            Outcome::NotApplicable(_) => "not applicable",
        }
    }

    fn of(info: &OutputPropertyInfo, config: &OutputConfig, discovered: bool) -> Outcome {
        match (info.expectation.clone(), discovered) {
            (Expectation::Sometimes, false) if !info.applies(config) => {
                Outcome::NotApplicable(info.needs())
            }
            (Expectation::Sometimes, true) => Outcome::Witnessed,
            (Expectation::Sometimes, false) => Outcome::NeverWitnessed,
            (_, true) => Outcome::Violated,
            (_, false) => Outcome::Holds,
        }
    }
}

/// One property's verdict.
#[derive(Clone, Debug)]
pub struct Verdict {
    pub name: &'static str,
    pub always: bool,
    pub meaning: &'static str,
    pub outcome: Outcome,
}

/// A path: the initial state and the steps from it.
#[derive(Clone, Debug)]
pub struct OutputPath {
    pub init: OutputState,
    pub steps: Vec<(OutputAction, OutputState)>,
}

impl OutputPath {
    pub fn render(&self) -> String {
        render::numbered_steps(&self.init, &self.steps)
    }

    pub fn actions(&self) -> Vec<OutputAction> {
        self.steps.iter().map(|(action, _)| *action).collect()
    }

    /// The path as stateright's explorer addresses it: `#/steps/0/<action index>/...`.
    pub fn explorer_fragment(&self, model: &OutputModel) -> String {
        let mut fragment = String::from("#/steps/0");
        let mut state = &self.init;
        for (action, next) in &self.steps {
            let mut enabled = Vec::new();
            model.actions(state, &mut enabled);
            let index = enabled
                .iter()
                .position(|a| a == action)
                .unwrap_or(usize::MAX);
            let _ = write!(fragment, "/{index}");
            state = next;
        }
        fragment
    }
}

/// Every reachable state, in level order, with its parent link and the first state at which
/// each property was discovered (violated or witnessed).
pub struct Explored {
    model: OutputModel,
    states: Vec<OutputState>,
    parents: Vec<Option<(usize, OutputAction)>>,
    hits: Vec<Option<usize>>,
    pub edges: usize,
}

impl Explored {
    pub fn unique_states(&self) -> usize {
        self.states.len()
    }

    /// Every reachable state, in level order.
    pub fn states(&self) -> &[OutputState] {
        &self.states
    }

    /// The verdict of every property of the catalogue.
    pub fn verdicts(&self) -> Vec<Verdict> {
        catalogue()
            .iter()
            .zip(&self.hits)
            .map(|(info, hit)| verdict(info, &self.model.config, hit.is_some()))
            .collect()
    }

    /// The names of the properties not as expected.
    pub fn failed(&self) -> Vec<&'static str> {
        self.verdicts()
            .into_iter()
            .filter(|v| !v.outcome.as_expected())
            .map(|v| v.name)
            .collect()
    }

    /// The shortest path to the property's discovery, if it has one.
    pub fn discovery(&self, property: &str) -> Option<OutputPath> {
        let index = catalogue().iter().position(|p| p.name == property)?;
        let mut cursor = self.hits[index]?;
        let mut steps = Vec::new();
        while let Some((parent, action)) = self.parents[cursor] {
            steps.push((action, self.states[cursor]));
            cursor = parent;
        }
        steps.reverse();
        Some(OutputPath {
            init: self.states[cursor],
            steps,
        })
    }
}

fn verdict(info: &OutputPropertyInfo, config: &OutputConfig, discovered: bool) -> Verdict {
    Verdict {
        name: info.name,
        always: info.expectation == Expectation::Always,
        meaning: info.meaning,
        outcome: Outcome::of(info, config, discovered),
    }
}

/// Level-order search of every reachable state (the output model is small: states are kept
/// whole).
pub fn explore(model: &OutputModel) -> Explored {
    let infos = catalogue();
    let mut explored = Explored {
        model: model.clone(),
        states: Vec::new(),
        parents: Vec::new(),
        hits: vec![None; infos.len()],
        edges: 0,
    };
    let mut index_of: HashMap<OutputState, usize> = HashMap::new();
    let mut queue = VecDeque::new();
    for state in model.init_states() {
        if !index_of.contains_key(&state) {
            let index = explored.add(&mut index_of, &infos, state, None);
            queue.push_back(index);
        }
    }
    let mut actions = Vec::new();
    while let Some(index) = queue.pop_front() {
        let state = explored.states[index];
        actions.clear();
        model.actions(&state, &mut actions);
        for action in actions.iter().copied() {
            let Some(next) = model.next_state(&state, action) else {
                continue;
            };
            explored.edges += 1;
            if !index_of.contains_key(&next) {
                let child = explored.add(&mut index_of, &infos, next, Some((index, action)));
                queue.push_back(child);
            }
        }
    }
    explored
}

impl Explored {
    fn add(
        &mut self,
        index_of: &mut HashMap<OutputState, usize>,
        infos: &[OutputPropertyInfo],
        state: OutputState,
        parent: Option<(usize, OutputAction)>,
    ) -> usize {
        let index = self.states.len();
        for (hit, info) in self.hits.iter_mut().zip(infos) {
            let holds = (info.condition)(&self.model, &state);
            let discovered = match info.expectation {
                Expectation::Always => !holds,
                Expectation::Sometimes => holds,
                Expectation::Eventually => false,
            };
            if hit.is_none() && discovered {
                *hit = Some(index);
            }
        }
        self.states.push(state);
        self.parents.push(parent);
        index_of.insert(state, index);
        index
    }
}

/// The result of `check --outputs`.
pub struct OutputReport {
    pub config: OutputConfig,
    pub verdicts: Vec<Verdict>,
    pub unique_states: usize,
    pub total_states: usize,
    pub max_depth: usize,
    pub elapsed: Duration,
    pub threads: usize,
}

impl OutputReport {
    pub fn failures(&self) -> Vec<&Verdict> {
        self.verdicts
            .iter()
            .filter(|v| !v.outcome.as_expected())
            .collect()
    }

    /// The verdict lines and the state counts, as `check` prints them for the role model.
    pub fn render(&self) -> String {
        let mut out = String::new();
        for v in &self.verdicts {
            let kind = if v.always { "always" } else { "sometimes" };
            let _ = write!(out, "  {:>15}  {kind:<9} {}", v.outcome.label(), v.name);
            if let Outcome::NotApplicable(reason) = v.outcome {
                let _ = write!(out, " ({reason})");
            }
            out.push('\n');
        }
        let secs = self.elapsed.as_secs_f64().max(1e-9);
        let _ = writeln!(
            out,
            "\n{} unique states, {} total, max depth {}, {:.0} states/s, {:.2} s wall ({} threads, BFS)",
            self.unique_states,
            self.total_states,
            self.max_depth,
            self.total_states as f64 / secs,
            secs,
            self.threads
        );
        out
    }
}

/// Runs stateright's checker exhaustively over the output model with `threads` threads.
pub fn check(config: &OutputConfig, threads: usize) -> OutputReport {
    let model = OutputModel::new(config.clone());
    let start = Instant::now();
    let checker = model
        .clone()
        .checker()
        .threads(threads)
        // Run exhaustively: stateright stops early once every property has a discovery.
        .finish_when(HasDiscoveries::AnyOf(BTreeSet::new()))
        .spawn_bfs()
        .join();
    let elapsed = start.elapsed();
    let discoveries = checker.discoveries();
    let verdicts = catalogue()
        .iter()
        .map(|info| verdict(info, config, discoveries.contains_key(info.name)))
        .collect();
    OutputReport {
        config: config.clone(),
        verdicts,
        unique_states: checker.unique_state_count(),
        total_states: checker.state_count(),
        max_depth: checker.max_depth(),
        elapsed,
        threads,
    }
}

/// The shortest counterexample (or, for a witness never found, the reason) of every failure
/// in `report`, with the command that opens it in the explorer.
pub fn render_failures(report: &OutputReport) -> String {
    let model = OutputModel::new(report.config.clone());
    let explored = explore(&model);
    let mut out = String::new();
    for failure in report.failures() {
        out.push('\n');
        match explored.discovery(failure.name) {
            Some(path) if failure.always => {
                let _ = writeln!(
                    out,
                    "counterexample to \"{}\" ({} steps): {}",
                    failure.name,
                    path.steps.len(),
                    failure.meaning
                );
                out.push_str(&path.render());
                let addr = "127.0.0.1:3000";
                let _ = writeln!(
                    out,
                    "  explore it: cargo run --release -p model -- explore {} --addr {addr}\n  \
                     then open http://{addr}/{}",
                    report.config.flags(),
                    path.explorer_fragment(&model)
                );
            }
            _ => {
                let _ = writeln!(
                    out,
                    "\"{}\" was never witnessed: {} (a rule is unreachable or vacuous)",
                    failure.name, failure.meaning
                );
            }
        }
    }
    out
}
