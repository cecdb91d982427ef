//! The committed trace set: the paths the conformance suite replays against the implementation.
//!
//! Each trace is a JSON Lines file named `NNNN-what-it-shows.jsonl` (the number, then a slug
//! of its purpose): a header line ([`HeaderLine`]: format, model hash, configuration, purpose,
//! a one-line description, the initial state), then one [`StepLine`] per step with the action
//! and the abstract state after it. The set holds the shortest path to every transition
//! class, to every property's discovery, and seeded random walks; `index.json` (a list of
//! [`IndexEntry`]) says what each file covers. Output is byte-identical run to run.
//!
//! These types are the format: the model writes them and the conformance suite reads them
//! back with the same types. Generation is in `generate`, the directory's files in `files`.

mod files;
mod generate;

pub use files::{compare, write, TraceFileError};
pub use generate::{
    coverage_class_name, generate, standard, Contribution, TraceScope, REACHABLE_FILE,
};

use crate::search::{CoverageClass, Stage};
use crate::state::{Action, ActionKind, State};
use crate::types::{Assignment, Life, Phase, Role};
use crate::Config;
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::fmt::Write;

/// The trace format's name; bump it when the line layout changes.
pub const FORMAT: &str = "rl-trace/2";

/// A hash of the specification's source: a trace records which model produced it.
pub fn model_hash() -> String {
    let sources = [
        include_str!("../protocol/mod.rs"),
        include_str!("../protocol/round.rs"),
        include_str!("../protocol/vote.rs"),
        include_str!("../protocol/agreement.rs"),
        include_str!("../protocol/minority.rs"),
        include_str!("../protocol/gray.rs"),
        include_str!("../protocol/actuator.rs"),
        include_str!("../state.rs"),
        include_str!("../action.rs"),
        include_str!("../types.rs"),
        include_str!("../fixes.rs"),
        include_str!("../config.rs"),
        include_str!("../properties.rs"),
    ];
    // FNV-1a, 64 bit: stable across platforms and releases, unlike std's hasher.
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for source in sources {
        for byte in source.bytes() {
            hash ^= u64::from(byte);
            hash = hash.wrapping_mul(0x0100_0000_01b3);
        }
    }
    format!("{hash:016x}")
}

/// One controller as a trace records it: what the conformance suite compares.
#[derive(Serialize, Deserialize, PartialEq, Eq, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub struct AbstractController {
    pub id: u8,
    pub life: Life,
    pub incarnation: u8,
    pub phase: Option<Phase>,
    pub role: Option<Role>,
    pub strength: Option<u8>,
    /// Peers it believes alive (its membership view, FAILED ones included).
    pub sees: Vec<u8>,
    pub failed: Vec<u8>,
    pub alarms: Vec<u8>,
    pub agreed: Option<String>,
    pub vote: Option<String>,
}

/// Every controller as a trace records it, and the actuator's owner.
#[derive(Serialize, Deserialize, PartialEq, Eq, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub struct AbstractState {
    pub controllers: Vec<AbstractController>,
    pub actuator_owner: Option<u8>,
}

fn assignment(a: Option<Assignment>) -> Option<String> {
    a.map(|a| a.to_string())
}

/// The stages in the order the coverage table shows them.
pub const STAGES: [Stage; 7] = [
    Stage::NotStarted,
    Stage::Down,
    Stage::Paused,
    Stage::Initializing,
    Stage::Voting,
    Stage::Steady,
    Stage::Failed,
];

/// The coverage table, one line per action kind, one column per stage: `covered`, `MISSED`
/// (reachable, not covered), `unreachable_covered` (covered, not reachable in the scope the
/// reachable set comes from) or `-`. Shared with the conformance suite, which prints the same
/// table for the replayed traces.
pub fn coverage_table(
    reachable: &BTreeSet<CoverageClass>,
    covered: &BTreeSet<CoverageClass>,
    unreachable_covered: &str,
) -> String {
    let mut out = String::new();
    let _ = write!(out, "{:<16}", "action \\ stage");
    for stage in STAGES {
        let _ = write!(out, "{:>13}", format!("{stage:?}").to_lowercase());
    }
    out.push('\n');
    for kind in ActionKind::ALL {
        let _ = write!(out, "{:<16}", kind.name());
        for stage in STAGES {
            let class = (kind, stage);
            let cell = match (reachable.contains(&class), covered.contains(&class)) {
                (true, true) => "covered",
                (true, false) => "MISSED",
                (false, true) => unreachable_covered,
                (false, false) => "-",
            };
            let _ = write!(out, "{cell:>13}");
        }
        out.push('\n');
    }
    out
}

/// The abstract state a trace step records.
pub fn abstract_state(state: &State) -> AbstractState {
    let ids = |c: &crate::Controller, pred: &dyn Fn(&crate::state::Peer) -> bool| -> Vec<u8> {
        c.peers
            .iter()
            .enumerate()
            .filter(|(i, p)| *i + 1 != usize::from(c.id) && pred(p))
            .map(|(i, _)| (i + 1) as u8)
            .filter(|id| usize::from(*id) <= state.controllers.len())
            .collect()
    };
    AbstractState {
        controllers: state
            .controllers
            .iter()
            .map(|c| {
                let up = c.is_up();
                AbstractController {
                    id: c.id,
                    life: c.life,
                    incarnation: c.incarnation,
                    phase: up.then_some(c.phase),
                    role: c.role.filter(|_| up),
                    strength: c.output.filter(|_| up),
                    sees: if up {
                        ids(c, &|p| p.alive.is_some())
                    } else {
                        vec![]
                    },
                    failed: if up { ids(c, &|p| p.failed) } else { vec![] },
                    alarms: if up { ids(c, &|p| p.alarm) } else { vec![] },
                    agreed: assignment(c.agreed.filter(|_| up)),
                    vote: assignment(c.vote.filter(|_| up)),
                }
            })
            .collect(),
        actuator_owner: state.actuator_owner(),
    }
}

/// A trace's first line. Unknown fields are rejected on reading, so that a format change is
/// noticed rather than half read.
#[derive(Serialize, Deserialize, PartialEq, Eq, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub struct HeaderLine {
    /// [`FORMAT`] of the writer.
    pub format: String,
    /// [`model_hash`] of the writer.
    pub model_hash: String,
    pub config: Config,
    /// What the trace was chosen for (`witness: ...`, `transition: ...`, ...); stable, so
    /// tools select traces by it.
    pub purpose: String,
    /// One line saying what the trace shows.
    pub description: String,
    /// Which of the model's initial states the trace starts from.
    pub initial_state_index: usize,
    pub initial: AbstractState,
}

/// Every line after the header: one step.
#[derive(Serialize, Deserialize, PartialEq, Eq, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub struct StepLine {
    /// 1-based.
    pub step: usize,
    pub action: Action,
    /// The abstract state after the action.
    pub state: AbstractState,
}

/// One entry of `index.json`: a trace file, what it is for, its length and the coverage
/// classes it covers (`tick@steady`, `join@notstarted`, ...).
#[derive(Serialize, Deserialize, PartialEq, Eq, Debug, Clone)]
#[serde(deny_unknown_fields)]
pub struct IndexEntry {
    pub file: String,
    /// The number the file name starts with.
    pub number: usize,
    pub purpose: String,
    pub description: String,
    pub steps: usize,
    pub covers: Vec<String>,
}

/// A trace's file name: its number (4 digits) and a slug of what it shows.
pub fn file_name(number: usize, slug: &str) -> String {
    format!("{number:04}-{slug}.jsonl")
}

/// The number a trace file name starts with (`0005-late-joiner-becomes-tertiary.jsonl` is 5).
pub fn number_of(file_name: &str) -> Option<usize> {
    let digits: String = file_name.chars().take_while(char::is_ascii_digit).collect();
    if digits.is_empty() {
        return None;
    }
    digits.parse().ok()
}

/// A generated trace set, ready to write or compare.
pub struct TraceSet {
    /// (file name, contents), in a fixed order; `index.json` and `reachable.json` last.
    pub files: Vec<(String, String)>,
    pub reachable: BTreeSet<CoverageClass>,
    pub covered: BTreeSet<CoverageClass>,
    pub unique_states: usize,
    /// What each exhaustively searched scope showed of the properties, in generation order:
    /// the search that makes the traces is also the one that checks the scope, so no scope is
    /// explored twice to check it.
    pub scopes: Vec<ScopeVerdict>,
}

/// One scope's exhaustive search, as the trace set's generation saw it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScopeVerdict {
    /// The scope's name (`""` for the configured scope, `link-failure`, `paper-f3`, ...).
    pub name: String,
    pub unique_states: usize,
    /// The `always` properties it violates (expected only of the paper variant's scopes).
    pub violated: Vec<&'static str>,
    /// The `sometimes` properties that apply to its configuration and were never witnessed.
    pub unwitnessed: Vec<&'static str>,
}

impl ScopeVerdict {
    /// What an exhaustive search of the scope `name` (configuration `config`) showed of each
    /// property of the catalogue.
    pub fn of(name: &str, config: &Config, explored: &crate::search::Explored) -> ScopeVerdict {
        let mut verdict = ScopeVerdict {
            name: name.to_string(),
            unique_states: explored.unique_states,
            violated: Vec::new(),
            unwitnessed: Vec::new(),
        };
        for info in crate::properties::catalogue() {
            let found = explored.discovery(info.name).is_some();
            match info.expectation {
                stateright::Expectation::Always if found => verdict.violated.push(info.name),
                stateright::Expectation::Sometimes if !found && info.applies(config) => {
                    verdict.unwitnessed.push(info.name)
                }
                _ => {}
            }
        }
        verdict
    }

    /// The properties not as expected: the violated ones, then the unwitnessed ones.
    pub fn failed(&self) -> Vec<&'static str> {
        self.violated
            .iter()
            .chain(&self.unwitnessed)
            .copied()
            .collect()
    }

    /// Every property as expected: nothing violated, every applicable witness found.
    pub fn holds(&self) -> bool {
        self.violated.is_empty() && self.unwitnessed.is_empty()
    }
}

impl TraceSet {
    pub fn coverage_percent(&self) -> f64 {
        if self.reachable.is_empty() {
            return 100.0;
        }
        100.0 * self.covered.intersection(&self.reachable).count() as f64
            / self.reachable.len() as f64
    }

    /// The transition coverage table: action kind x stage of the acting controller.
    pub fn coverage_report(&self) -> String {
        // The set's paper-variant counterexamples cover classes the default scope cannot reach;
        // the table is about the default scope.
        let mut out = coverage_table(&self.reachable, &self.covered, "-");
        let _ = write!(
            out,
            "transition coverage: {} of {} reachable (action kind x phase) pairs = {:.1}% \
             ({} states explored, {} traces)",
            self.covered.intersection(&self.reachable).count(),
            self.reachable.len(),
            self.coverage_percent(),
            self.unique_states,
            self.files
                .iter()
                .filter(|(name, _)| name.ends_with(".jsonl"))
                .count()
        );
        out
    }
}
