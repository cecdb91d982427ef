//! Transition coverage: which (action kind x stage of the acting controller) pairs a replay
//! exercised, counted as the model counts them (`model/src/search.rs`, `CoverageClass`).
//!
//! A tick acts on every live controller; every other action on the controller it names. The
//! stage is the actor's before the action: not started, down, or its phase, taken from the
//! cores' own status (abstracted), not from the trace. The reachable pairs are the model's:
//! its exhaustive search of the trace set's scopes writes them to `traces/reachable.json`
//! (recomputing them here would take the full search, about a minute and over 1 GB), so a
//! reachable pair no replay exercises lowers the share.

pub use model::search::CoverageClass;
use model::search::Stage;
use model::traces::{AbstractController, AbstractState};
use model::{Action, ActionKind, Life, Phase};
use std::collections::BTreeSet;
use std::fmt::Write;
use std::path::Path;

pub use model::traces::STAGES;

/// Where a controller stands, from its abstract state.
pub fn stage(c: &AbstractController) -> Stage {
    match (c.life, c.phase) {
        (Life::NotStarted, _) => Stage::NotStarted,
        (Life::Down, _) => Stage::Down,
        (Life::Paused, _) => Stage::Paused,
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

/// `tick@steady`, as `index.json` and `reachable.json` name a pair.
pub fn class_name(class: CoverageClass) -> String {
    model::traces::coverage_class_name(class.0, class.1)
}

/// The pair a trace file names, if it is one.
pub fn parse_class(name: &str) -> Option<CoverageClass> {
    ActionKind::ALL
        .iter()
        .flat_map(|kind| STAGES.iter().map(move |stage| (*kind, *stage)))
        .find(|class| class_name(*class) == name)
}

/// Why the reachable set could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ReachableError {
    /// The file is missing or unreadable.
    #[error("{path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// Not a JSON list of names.
    #[error("{path}: {source}")]
    Json {
        path: String,
        #[source]
        source: serde_json::Error,
    },
    /// A name that is no (action kind x stage) pair.
    #[error("{path}: unknown pair {name:?}")]
    UnknownPair { path: String, name: String },
}

/// The reachable pairs the model's exhaustive search found in the trace set's scopes
/// (`traces/reachable.json`, written by `model -- traces`): what the model can do, not what
/// the traces happen to cover.
pub fn reachable_from_model(trace_dir: &Path) -> Result<BTreeSet<CoverageClass>, ReachableError> {
    let path = trace_dir.join(model::traces::REACHABLE_FILE);
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(&path).map_err(|source| ReachableError::Io {
        path: shown.clone(),
        source,
    })?;
    let names: Vec<String> =
        serde_json::from_str(&text).map_err(|source| ReachableError::Json {
            path: shown.clone(),
            source,
        })?;
    names
        .into_iter()
        .map(|name| {
            parse_class(&name).ok_or_else(|| ReachableError::UnknownPair {
                path: shown.clone(),
                name,
            })
        })
        .collect()
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
