//! Transition coverage: which (action kind x stage of the acting controller) pairs a replay
//! exercised, counted as the model counts them (`model/src/search.rs`, `CoverageClass`).
//!
//! A tick acts on every live controller; every other action on the controller it names. The
//! stage is the actor's before the action: not started, down, or its phase. The reachable
//! pairs are the model's: its trace generator writes the shortest path to every reachable
//! transition class, so the union of `index.json`'s `covers` over the default-variant traces
//! is the reachable set of the default-variant scopes (recomputing it here would take the
//! model's full search, about a minute and over 1 GB).

pub use model::search::CoverageClass;
use model::search::Stage;
use model::traces::{AbstractController, AbstractState};
use model::{Action, ActionKind, Life, Phase};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;

pub use model::traces::STAGES;

/// Where a controller stands, from its abstract state.
pub fn stage(c: &AbstractController) -> Stage {
    match (c.life, c.phase) {
        (Life::NotStarted, _) => Stage::NotStarted,
        (Life::Down, _) => Stage::Down,
        (Life::Up, Some(Phase::Voting)) => Stage::Voting,
        (Life::Up, Some(Phase::Steady)) => Stage::Steady,
        (Life::Up, Some(Phase::Failed)) => Stage::Failed,
        (Life::Up, Some(Phase::Initializing) | None) => Stage::Initializing,
    }
}

/// The pairs one action exercises from the state before it.
pub fn classes(before: &AbstractState, action: &Action) -> Vec<CoverageClass> {
    let actor = action.actor();
    before
        .controllers
        .iter()
        .filter(|c| match actor {
            Some(id) => c.id == id,
            None => c.life == Life::Up,
        })
        .map(|c| (action.kind(), stage(c)))
        .collect()
}

/// `tick@steady`, as `index.json` names a pair.
pub fn class_name(class: CoverageClass) -> String {
    format!("{}@{:?}", class.0.name(), class.1).to_lowercase()
}

/// The pair `index.json` names, if it is one.
pub fn parse_class(name: &str) -> Option<CoverageClass> {
    ActionKind::ALL
        .iter()
        .flat_map(|kind| STAGES.iter().map(move |stage| (*kind, *stage)))
        .find(|class| class_name(*class) == name)
}

/// The reachable pairs: the union of what the model says the given trace files cover.
pub fn reachable_from_index<'a>(
    index: &BTreeMap<String, BTreeSet<String>>,
    files: impl IntoIterator<Item = &'a str>,
) -> Result<BTreeSet<CoverageClass>, String> {
    let mut reachable = BTreeSet::new();
    for file in files {
        let covers = index
            .get(file)
            .ok_or_else(|| format!("index.json has no entry for {file}"))?;
        for name in covers {
            reachable.insert(
                parse_class(name).ok_or_else(|| format!("index.json: unknown pair {name:?}"))?,
            );
        }
    }
    Ok(reachable)
}

/// Covered against reachable pairs.
#[derive(Clone, Debug, Default)]
pub struct Coverage {
    pub reachable: BTreeSet<CoverageClass>,
    pub covered: BTreeSet<CoverageClass>,
}

impl Coverage {
    pub fn covered_reachable(&self) -> usize {
        self.covered.intersection(&self.reachable).count()
    }

    pub fn percent(&self) -> f64 {
        if self.reachable.is_empty() {
            return 100.0;
        }
        100.0 * self.covered_reachable() as f64 / self.reachable.len() as f64
    }

    /// The table the model's `traces` command prints, for the replayed traces.
    pub fn report(&self) -> String {
        let mut out = model::traces::coverage_table(&self.reachable, &self.covered, "extra");
        let _ = write!(
            out,
            "core-level transition coverage: {} of {} reachable (action kind x phase) pairs = \
             {:.1}%",
            self.covered_reachable(),
            self.reachable.len(),
            self.percent()
        );
        out
    }
}
