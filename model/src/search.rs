//! Our own breadth-first search with parent pointers.
//!
//! stateright 0.31's checker reports a property's discovery but not the shortest one (later
//! matches overwrite it), so counterexamples, witnesses and trace generation use this search:
//! level order makes the first hit of every property, and the first edge of every transition
//! class, the shortest path there. Only fingerprints and parent links are kept per state.

use crate::properties::{catalogue, PropertyInfo};
use crate::state::{Action, ActionKind, State};
use crate::types::{Life, Phase, Role};
use crate::RlModel;
use serde::{Deserialize, Serialize};
use stateright::{Expectation, Model};
use std::collections::hash_map::DefaultHasher;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::hash::{Hash, Hasher};

/// Where a controller stands before an action: its phase, or why it has none.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    NotStarted,
    Down,
    Paused,
    Initializing,
    Voting,
    Steady,
    Failed,
}

impl Stage {
    pub fn of(state: &State, id: crate::Id) -> Stage {
        let c = state.controller(id);
        match c.life {
            Life::NotStarted => Stage::NotStarted,
            Life::Down => Stage::Down,
            Life::Paused => Stage::Paused,
            Life::Up => match c.phase {
                Phase::Initializing => Stage::Initializing,
                Phase::Voting => Stage::Voting,
                Phase::Steady => Stage::Steady,
                Phase::Failed => Stage::Failed,
            },
        }
    }
}

/// Coverage is counted over (action kind x the acting controller's stage before the action).
pub type CoverageClass = (ActionKind, Stage);

/// Traces are chosen per finer class: the acting controller's stage and role before and after.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct TransitionClass {
    pub kind: ActionKind,
    pub before: Stage,
    pub role_before: Option<Role>,
    pub after: Stage,
    pub role_after: Option<Role>,
}

/// The classes of one edge: a tick acts on every live controller, other actions on one.
pub fn classes(before: &State, action: &Action, after: &State) -> Vec<TransitionClass> {
    let actors: Vec<crate::Id> = match action.actor() {
        Some(id) => vec![id],
        None => before.up().map(|c| c.id).collect(),
    };
    actors
        .into_iter()
        .map(|id| TransitionClass {
            kind: action.kind(),
            before: Stage::of(before, id),
            role_before: before.controller(id).role,
            after: Stage::of(after, id),
            role_after: after.controller(id).role,
        })
        .collect()
}

#[derive(Clone, Copy)]
struct Node {
    /// `None` for an initial state.
    parent: Option<u32>,
    /// The action from the parent, or the index of the initial state.
    step: Step,
}

#[derive(Clone, Copy)]
enum Step {
    Init(usize),
    Action(Action),
}

/// The result of an exhaustive search.
pub struct Explored {
    model: RlModel,
    nodes: Vec<Node>,
    pub unique_states: usize,
    pub edges: usize,
    pub max_depth: usize,
    /// Per property (by catalogue order): the first state violating an `always` property or
    /// satisfying a `sometimes` property.
    hits: Vec<Option<u32>>,
    /// The first edge of every transition class: (source node, action).
    class_edges: BTreeMap<TransitionClass, (u32, Action)>,
    pub coverage: BTreeMap<CoverageClass, usize>,
    /// True when the search stopped at its state limit.
    pub truncated: bool,
}

fn fingerprint(state: &State) -> u64 {
    let mut hasher = DefaultHasher::new();
    state.hash(&mut hasher);
    hasher.finish()
}

/// Explores every reachable state (up to `state_limit`), calling `progress` now and then.
pub fn explore(
    model: &RlModel,
    state_limit: usize,
    progress: impl FnMut(usize, usize),
) -> Explored {
    breadth_first(
        model,
        state_limit,
        true,
        progress,
        |explored, node, state, action, next| {
            for class in classes(state, &action, next) {
                *explored
                    .coverage
                    .entry((class.kind, class.before))
                    .or_default() += 1;
                explored.class_edges.entry(class).or_insert((node, action));
            }
            false
        },
    )
}

/// The shortest path whose last step satisfies `predicate(before, action, after)`, among at
/// most `state_limit` states: a check of a transition rather than a state (finding F8's
/// "raised to Primary strength while hearing another Primary").
pub fn find_transition(
    model: &RlModel,
    state_limit: usize,
    predicate: impl Fn(&State, &Action, &State) -> bool,
) -> Option<Path> {
    let mut found = None;
    let explored = breadth_first(
        model,
        state_limit,
        false,
        |_, _| {},
        |_, node, state, action, next| {
            let hit = predicate(state, &action, next);
            if hit {
                found = Some((node, action));
            }
            hit
        },
    );
    found.map(|(node, action)| {
        let mut path = explored.path_to(node);
        path.push(&explored.model, action);
        path
    })
}

/// Level-order search with parent links. `on_edge(explored, source node, state, action,
/// next)` sees every edge and stops the search by returning true; `check_properties` records
/// the first hit of every catalogue property.
fn breadth_first(
    model: &RlModel,
    state_limit: usize,
    check_properties: bool,
    mut progress: impl FnMut(usize, usize),
    mut on_edge: impl FnMut(&mut Explored, u32, &State, Action, &State) -> bool,
) -> Explored {
    let infos: Vec<PropertyInfo> = if check_properties {
        catalogue()
    } else {
        Vec::new()
    };
    let mut explored = Explored {
        model: model.clone(),
        nodes: Vec::new(),
        unique_states: 0,
        edges: 0,
        max_depth: 0,
        hits: vec![None; catalogue().len()],
        class_edges: BTreeMap::new(),
        coverage: BTreeMap::new(),
        truncated: false,
    };
    let mut seen: HashMap<u64, u32> = HashMap::new();
    let mut queue = explored.seed(&mut seen, &infos);
    let mut actions = Vec::new();
    while let Some((node, depth, state)) = queue.pop_front() {
        explored.max_depth = explored.max_depth.max(depth as usize);
        actions.clear();
        model.actions(&state, &mut actions);
        for action in actions.iter().copied() {
            let Some(next) = model.next_state(&state, action) else {
                continue;
            };
            explored.edges += 1;
            if on_edge(&mut explored, node, &state, action, &next) {
                explored.unique_states = explored.nodes.len();
                return explored;
            }
            let key = fingerprint(&next);
            if seen.contains_key(&key) {
                continue;
            }
            if explored.nodes.len() >= state_limit {
                explored.truncated = true;
                continue;
            }
            let child = explored.push(
                &mut seen,
                &next,
                Node {
                    parent: Some(node),
                    step: Step::Action(action),
                },
            );
            explored.check(&infos, child, &next);
            queue.push_back((child, depth + 1, next));
        }
        if explored.nodes.len() % 100_000 < 8 {
            progress(explored.nodes.len(), explored.edges);
        }
    }
    explored.unique_states = explored.nodes.len();
    explored
}

impl Explored {
    /// The initial states, as the search's first level.
    fn seed(
        &mut self,
        seen: &mut HashMap<u64, u32>,
        infos: &[PropertyInfo],
    ) -> VecDeque<(u32, u32, State)> {
        let mut queue = VecDeque::new();
        for (index, state) in self.model.init_states().into_iter().enumerate() {
            if seen.contains_key(&fingerprint(&state)) {
                continue;
            }
            let node = self.push(
                seen,
                &state,
                Node {
                    parent: None,
                    step: Step::Init(index),
                },
            );
            self.check(infos, node, &state);
            queue.push_back((node, 0, state));
        }
        queue
    }

    fn push(&mut self, seen: &mut HashMap<u64, u32>, state: &State, node: Node) -> u32 {
        let index = self.nodes.len() as u32;
        self.nodes.push(node);
        seen.insert(fingerprint(state), index);
        index
    }

    fn check(&mut self, infos: &[PropertyInfo], node: u32, state: &State) {
        for (slot, info) in self.hits.iter_mut().zip(infos) {
            if slot.is_some() {
                continue;
            }
            let holds = (info.condition)(&self.model, state);
            let hit = match info.expectation {
                Expectation::Always => !holds,
                Expectation::Sometimes => holds,
                Expectation::Eventually => false,
            };
            if hit {
                *slot = Some(node);
            }
        }
    }

    /// The shortest path to the property's discovery, if there is one.
    pub fn discovery(&self, property: &str) -> Option<Path> {
        let index = catalogue().iter().position(|p| p.name == property)?;
        self.hits[index].map(|node| self.path_to(node))
    }

    /// The shortest path ending with the first edge of each transition class.
    pub fn class_paths(&self) -> Vec<(TransitionClass, Path)> {
        self.class_edges
            .iter()
            .map(|(class, (node, action))| {
                let mut path = self.path_to(*node);
                path.push(&self.model, *action);
                (*class, path)
            })
            .collect()
    }

    pub fn reachable_coverage_classes(&self) -> Vec<CoverageClass> {
        self.coverage.keys().copied().collect()
    }

    fn path_to(&self, node: u32) -> Path {
        let mut actions = Vec::new();
        let mut cursor = node;
        let init = loop {
            let entry = self.nodes[cursor as usize];
            match (entry.parent, entry.step) {
                (Some(parent), Step::Action(action)) => {
                    actions.push(action);
                    cursor = parent;
                }
                (_, Step::Init(index)) => break index,
                (None, Step::Action(_)) => unreachable!("an initial node always records Init"),
            }
        };
        actions.reverse();
        Path::replay(&self.model, init, &actions)
    }
}

/// A path: an initial state and the steps from it.
#[derive(Clone, Debug)]
pub struct Path {
    pub init_index: usize,
    pub init: State,
    pub steps: Vec<(Action, State)>,
}

impl Path {
    /// The path as stateright's explorer addresses it: `#/steps/<init>/<action>/...`, each
    /// action by its position among the actions enabled in the state before it.
    pub fn explorer_fragment(&self, model: &RlModel) -> String {
        let mut fragment = format!("#/steps/{}", self.init_index);
        let mut state = &self.init;
        for (action, next) in &self.steps {
            let mut enabled = Vec::new();
            crate::protocol::actions(&model.config, state, &mut enabled);
            let index = enabled
                .iter()
                .position(|a| a == action)
                .unwrap_or(usize::MAX);
            fragment.push_str(&format!("/{index}"));
            state = next;
        }
        fragment
    }

    /// Re-executes `actions` from the `init_index`th initial state.
    pub fn replay(model: &RlModel, init_index: usize, actions: &[Action]) -> Path {
        let init = model.init_states()[init_index].clone();
        let mut path = Path {
            init_index,
            init,
            steps: Vec::new(),
        };
        for action in actions {
            path.push(model, *action);
        }
        path
    }

    pub fn push(&mut self, model: &RlModel, action: Action) {
        let last = self.last().clone();
        if let Some(next) = model.next_state(&last, action) {
            self.steps.push((action, next));
        }
    }

    pub fn last(&self) -> &State {
        self.steps.last().map_or(&self.init, |(_, s)| s)
    }

    pub fn actions(&self) -> Vec<Action> {
        self.steps.iter().map(|(a, _)| *a).collect()
    }

    pub fn render(&self) -> String {
        crate::render::numbered_steps(&self.init, &self.steps)
    }
}
