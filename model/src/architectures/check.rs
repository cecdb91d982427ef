//! Checking the duplex and the pair: what both models provide ([`Spec`]), the property
//! catalogue's shape, stateright's checker for the verdicts and state counts (as
//! `check --outputs` does), our own breadth-first search with parent links for the shortest
//! path to each discovery (stateright 0.31's are not the shortest, docs/model.md), and the
//! readable report and paths.

use stateright::{Checker, Expectation, HasDiscoveries, Model, Property};
use std::collections::{BTreeSet, HashMap, VecDeque};
use std::fmt::{self, Debug, Write};
use std::hash::Hash;
use std::time::{Duration, Instant};

/// One property: name, expectation, one-line meaning, condition, and (for a witness) what the
/// scope must allow for it to be reachable.
pub struct PropertyInfo<M: Model> {
    pub name: &'static str,
    pub expectation: Expectation,
    pub meaning: &'static str,
    pub condition: fn(&M, &M::State) -> bool,
    /// Why the scope cannot reach this witness (the fault it lacks), or `None`.
    pub lacking: fn(&M) -> Option<&'static str>,
}

/// For the properties every scope applies to.
pub fn always_applies<M>(_: &M) -> Option<&'static str> {
    None
}

/// What the duplex and the pair models provide to be checked, explored and reported.
pub trait Spec:
    Model<State = Self::SpecState, Action = Self::SpecAction> + Clone + Send + Sync + 'static
{
    type SpecState: Clone + Debug + Eq + Hash + Send + Sync + 'static;
    type SpecAction: Clone + Copy + Debug + Eq + fmt::Display + Send + Sync + 'static;

    /// Every property, in the report's order.
    fn catalogue() -> Vec<PropertyInfo<Self>>;
    /// One line describing the scope.
    fn summary(&self) -> String;
    /// The flags that give this scope (for the `explore` command of a counterexample).
    fn flags(&self) -> String;
    /// The readable lines of a state.
    fn state_lines(state: &Self::SpecState) -> Vec<String>;
    /// The explorer's name of an initial state.
    fn initial_state_name(&self, state: &Self::SpecState) -> String;
}

/// stateright's properties of a model, from its catalogue.
pub fn properties<M: Spec>() -> Vec<Property<M>> {
    M::catalogue()
        .into_iter()
        .map(|info| match info.expectation {
            Expectation::Always => Property::always(info.name, info.condition),
            Expectation::Sometimes => Property::sometimes(info.name, info.condition),
            Expectation::Eventually => Property::eventually(info.name, info.condition),
        })
        .collect()
}

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
}

/// One property's verdict.
#[derive(Clone, Debug)]
pub struct Verdict {
    pub name: &'static str,
    pub always: bool,
    pub meaning: &'static str,
    pub outcome: Outcome,
}

fn verdict<M: Spec>(info: &PropertyInfo<M>, model: &M, discovered: bool) -> Verdict {
    let outcome = match (info.expectation.clone(), discovered) {
        (Expectation::Sometimes, false) => match (info.lacking)(model) {
            Some(reason) => Outcome::NotApplicable(reason),
            None => Outcome::NeverWitnessed,
        },
        (Expectation::Sometimes, true) => Outcome::Witnessed,
        (_, true) => Outcome::Violated,
        (_, false) => Outcome::Holds,
    };
    Verdict {
        name: info.name,
        always: info.expectation == Expectation::Always,
        meaning: info.meaning,
        outcome,
    }
}

/// A path: the initial state and the steps from it.
#[derive(Clone, Debug)]
pub struct SpecPath<M: Spec> {
    pub init: M::SpecState,
    pub steps: Vec<(M::SpecAction, M::SpecState)>,
}

impl<M: Spec> SpecPath<M> {
    pub fn actions(&self) -> Vec<M::SpecAction> {
        self.steps.iter().map(|(action, _)| *action).collect()
    }

    /// The state the path ends in.
    pub fn last(&self) -> &M::SpecState {
        self.steps.last().map_or(&self.init, |(_, state)| state)
    }

    /// Numbered steps: the initial state, then each action and what it changed.
    pub fn render(&self) -> String {
        let mut out = String::from("  0. initial state\n");
        for line in M::state_lines(&self.init) {
            let _ = writeln!(out, "       {line}");
        }
        let mut before = &self.init;
        for (index, (action, after)) in self.steps.iter().enumerate() {
            let _ = writeln!(out, "{:>3}. {action}", index + 1);
            for line in diff::<M>(before, after).lines() {
                let _ = writeln!(out, "       {line}");
            }
            before = after;
        }
        out
    }

    /// The path as stateright's explorer addresses it: `#/steps/<init>/<action index>/...`.
    pub fn explorer_fragment(&self, model: &M) -> String {
        let init = model
            .init_states()
            .iter()
            .position(|state| *state == self.init)
            .unwrap_or(usize::MAX);
        let mut fragment = format!("#/steps/{init}");
        let mut state = &self.init;
        for (action, next) in &self.steps {
            let mut enabled = Vec::new();
            model.actions(state, &mut enabled);
            let index = enabled.iter().position(|a| a == action);
            let _ = write!(fragment, "/{}", index.unwrap_or(usize::MAX));
            state = next;
        }
        fragment
    }
}

/// The lines of `after` that differ from `before`.
pub fn diff<M: Spec>(before: &M::SpecState, after: &M::SpecState) -> String {
    let mut out = String::new();
    for (old, new) in M::state_lines(before).iter().zip(M::state_lines(after)) {
        if *old != new {
            let _ = writeln!(out, "{new}");
        }
    }
    if out.is_empty() {
        out.push_str("(nothing changed)\n");
    }
    out
}

/// Every reachable state, in level order, with its parent link and the first state at which
/// each property was discovered (violated or witnessed).
pub struct Explored<M: Spec> {
    model: M,
    states: Vec<M::SpecState>,
    parents: Vec<Option<(usize, M::SpecAction)>>,
    hits: Vec<Option<usize>>,
    pub edges: usize,
}

impl<M: Spec> Explored<M> {
    pub fn unique_states(&self) -> usize {
        self.states.len()
    }

    /// Every reachable state, in level order.
    pub fn states(&self) -> &[M::SpecState] {
        &self.states
    }

    /// The verdict of every property of the catalogue.
    pub fn verdicts(&self) -> Vec<Verdict> {
        M::catalogue()
            .iter()
            .zip(&self.hits)
            .map(|(info, hit)| verdict(info, &self.model, hit.is_some()))
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
    pub fn discovery(&self, property: &str) -> Option<SpecPath<M>> {
        let index = M::catalogue().iter().position(|p| p.name == property)?;
        let mut cursor = self.hits[index]?;
        let mut steps = Vec::new();
        while let Some((parent, action)) = self.parents[cursor] {
            steps.push((action, self.states[cursor].clone()));
            cursor = parent;
        }
        steps.reverse();
        Some(SpecPath {
            init: self.states[cursor].clone(),
            steps,
        })
    }

    fn add(
        &mut self,
        index_of: &mut HashMap<M::SpecState, usize>,
        infos: &[PropertyInfo<M>],
        state: M::SpecState,
        parent: Option<(usize, M::SpecAction)>,
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
        index_of.insert(state.clone(), index);
        self.states.push(state);
        self.parents.push(parent);
        index
    }
}

/// Level-order search of every reachable state (these models are small: states are kept
/// whole).
pub fn explore<M: Spec>(model: &M) -> Explored<M> {
    let infos = M::catalogue();
    let mut explored = Explored {
        model: model.clone(),
        states: Vec::new(),
        parents: Vec::new(),
        hits: vec![None; infos.len()],
        edges: 0,
    };
    let mut index_of = HashMap::new();
    let mut queue = VecDeque::new();
    for state in model.init_states() {
        if !index_of.contains_key(&state) {
            queue.push_back(explored.add(&mut index_of, &infos, state, None));
        }
    }
    let mut actions = Vec::new();
    while let Some(index) = queue.pop_front() {
        let state = explored.states[index].clone();
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

/// The result of `check --architecture duplex|pair`.
pub struct ArchitectureReport {
    pub summary: String,
    pub verdicts: Vec<Verdict>,
    pub unique_states: usize,
    pub total_states: usize,
    pub max_depth: usize,
    pub elapsed: Duration,
    pub threads: usize,
}

impl ArchitectureReport {
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

/// Runs stateright's checker exhaustively over `model` with `threads` threads.
pub fn check<M: Spec>(model: &M, threads: usize) -> ArchitectureReport {
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
    let verdicts = M::catalogue()
        .iter()
        .map(|info| verdict(info, model, discoveries.contains_key(info.name)))
        .collect();
    ArchitectureReport {
        summary: model.summary(),
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
pub fn render_failures<M: Spec>(model: &M, report: &ArchitectureReport) -> String {
    let explored = explore(model);
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
                    model.flags(),
                    path.explorer_fragment(model)
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
