//! The committed trace set: the paths the conformance suite replays against the implementation.
//!
//! Each trace is a JSON Lines file: a header line (format, model hash, configuration, purpose),
//! then one line per step with the action and the abstract state after it. The set holds the
//! shortest path to every transition class, to every property's discovery, and seeded random
//! walks; `index.json` says what each file covers. Output is byte-identical run to run.

use crate::search::{self, classes, CoverageClass, Path, Stage, TransitionClass};
use crate::simulate;
use crate::state::{ActionKind, State};
use crate::types::{Assignment, Life, Phase, Role};
use crate::{Config, RlModel};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write;
use std::path::{Path as FsPath, PathBuf};

/// The trace directory or one of its files could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum TraceFileError {
    /// Reading, writing, listing or removing `path` failed.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

fn io_error(path: &FsPath) -> impl FnOnce(std::io::Error) -> TraceFileError + '_ {
    move |source| TraceFileError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Random walks added to the set, and their length.
const WALKS: u64 = 24;
const WALK_STEPS: usize = 40;

/// The trace format's name; bump it when the line layout changes.
pub const FORMAT: &str = "rl-trace/1";

/// A hash of the specification's source: a trace records which model produced it.
pub fn model_hash() -> String {
    let sources = [
        include_str!("protocol/mod.rs"),
        include_str!("protocol/round.rs"),
        include_str!("protocol/vote.rs"),
        include_str!("protocol/agreement.rs"),
        include_str!("protocol/minority.rs"),
        include_str!("state.rs"),
        include_str!("types.rs"),
        include_str!("fixes.rs"),
        include_str!("config.rs"),
        include_str!("properties.rs"),
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
#[derive(Serialize, PartialEq, Eq, Debug, Clone)]
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

#[derive(Serialize, PartialEq, Eq, Debug, Clone)]
pub struct AbstractState {
    pub controllers: Vec<AbstractController>,
    pub actuator_owner: Option<u8>,
}

fn assignment(a: Option<Assignment>) -> Option<String> {
    a.map(|a| a.to_string())
}

/// The stages in the order the coverage table shows them.
pub const STAGES: [Stage; 6] = [
    Stage::NotStarted,
    Stage::Down,
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

#[derive(Serialize)]
struct Header<'a> {
    format: &'a str,
    model_hash: &'a str,
    config: &'a Config,
    purpose: &'a str,
    initial_state_index: usize,
    initial: AbstractState,
}

#[derive(Serialize)]
struct Step<'a> {
    step: usize,
    action: &'a crate::Action,
    state: AbstractState,
}

#[derive(Serialize)]
struct IndexEntry {
    file: String,
    purpose: String,
    steps: usize,
    covers: Vec<String>,
}

/// A generated trace set, ready to write or compare.
pub struct TraceSet {
    /// (file name, contents), in a fixed order; `index.json` last.
    pub files: Vec<(String, String)>,
    pub reachable: BTreeSet<CoverageClass>,
    pub covered: BTreeSet<CoverageClass>,
    pub unique_states: usize,
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
            self.files.len().saturating_sub(1)
        );
        out
    }
}

/// What a scope contributes to the trace set.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Contribution {
    /// Witnesses, counterexamples, one trace per transition class, and random walks.
    Everything,
    /// Only the shortest counterexamples (the paper variant's findings).
    Counterexamples,
}

/// The trace set `traces` writes: the default scope, the persistent link failure, and the
/// counterexamples of the paper variant's findings.
pub fn standard(scope: Config) -> Vec<(RlModel, Contribution)> {
    let mut scopes = vec![
        (RlModel::new(scope), Contribution::Everything),
        (
            RlModel::new(Config::link_failure()),
            Contribution::Everything,
        ),
    ];
    scopes.extend(
        Config::paper_findings()
            .into_iter()
            .map(|config| (RlModel::new(config), Contribution::Counterexamples)),
    );
    scopes
}

/// Generates the trace set of one or more scopes of the model, numbered in order.
pub fn generate(
    models: &[(RlModel, Contribution)],
    mut progress: impl FnMut(usize, usize),
) -> TraceSet {
    let mut set = TraceSet {
        files: Vec::new(),
        reachable: BTreeSet::new(),
        covered: BTreeSet::new(),
        unique_states: 0,
    };
    let mut index = Vec::new();
    for (model, contribution) in models {
        generate_scope(model, *contribution, &mut progress, &mut set, &mut index);
    }
    let index_text = serde_json::to_string_pretty(&index).unwrap_or_default() + "\n";
    set.files.push(("index.json".to_string(), index_text));
    set
}

fn generate_scope(
    model: &RlModel,
    contribution: Contribution,
    progress: &mut impl FnMut(usize, usize),
    set: &mut TraceSet,
    index: &mut Vec<IndexEntry>,
) {
    let explored = search::explore(model, usize::MAX, progress);
    let mut chosen: Vec<(String, Path)> = Vec::new();
    let mut seen_actions: BTreeSet<Vec<crate::Action>> = BTreeSet::new();
    let mut add = |purpose: String, path: Path, chosen: &mut Vec<(String, Path)>| {
        let key = path.actions();
        if seen_actions.insert(key) {
            chosen.push((purpose, path));
        }
    };
    let variant = format!("{:?}", model.config.variant).to_lowercase();
    for info in crate::properties::catalogue() {
        let counterexample = info.expectation == stateright::Expectation::Always;
        if contribution == Contribution::Counterexamples && !counterexample {
            continue;
        }
        if let Some(path) = explored.discovery(info.name) {
            let what = if counterexample {
                format!("counterexample ({variant} variant)")
            } else {
                "witness".to_string()
            };
            add(format!("{what}: {}", info.name), path, &mut chosen);
        }
    }
    if contribution == Contribution::Counterexamples {
        set.unique_states += explored.unique_states;
        write_chosen(model, &chosen, set, index);
        return;
    }
    for (class, path) in explored.class_paths() {
        add(class_purpose(&class), path, &mut chosen);
    }
    for seed in 1..=WALKS {
        add(
            format!("random walk, seed {seed}"),
            simulate::walk(model, seed, WALK_STEPS),
            &mut chosen,
        );
    }
    write_chosen(model, &chosen, set, index);
    set.reachable.extend(explored.reachable_coverage_classes());
    set.unique_states += explored.unique_states;
}

fn write_chosen(
    model: &RlModel,
    chosen: &[(String, Path)],
    set: &mut TraceSet,
    index: &mut Vec<IndexEntry>,
) {
    let hash = model_hash();
    for (purpose, path) in chosen {
        let name = format!("{:04}.jsonl", set.files.len() + 1);
        let mut text = String::new();
        let header = Header {
            format: FORMAT,
            model_hash: &hash,
            config: &model.config,
            purpose,
            initial_state_index: path.init_index,
            initial: abstract_state(&path.init),
        };
        text.push_str(&to_json(&header));
        text.push('\n');
        let mut before = &path.init;
        let mut covers = BTreeSet::new();
        for (step, (action, after)) in path.steps.iter().enumerate() {
            for class in classes(before, action, after) {
                set.covered.insert((class.kind, class.before));
                covers.insert(format!("{}@{:?}", class.kind.name(), class.before).to_lowercase());
            }
            text.push_str(&to_json(&Step {
                step: step + 1,
                action,
                state: abstract_state(after),
            }));
            text.push('\n');
            before = after;
        }
        index.push(IndexEntry {
            file: name.clone(),
            purpose: purpose.clone(),
            steps: path.steps.len(),
            covers: covers.into_iter().collect(),
        });
        set.files.push((name, text));
    }
}

fn to_json(value: &impl Serialize) -> String {
    // Our own types always serialize; an empty line would fail `traces --check` visibly.
    serde_json::to_string(value).unwrap_or_default()
}

fn class_purpose(class: &TransitionClass) -> String {
    let role = |r: Option<Role>| r.map_or("none", Role::name);
    format!(
        "transition: {} by a {:?} controller ({}) -> {:?} ({})",
        class.kind.name(),
        class.before,
        role(class.role_before),
        class.after,
        role(class.role_after)
    )
    .to_lowercase()
}

/// Writes the set, replacing the trace files already in `dir`.
pub fn write(set: &TraceSet, dir: &FsPath) -> Result<(), TraceFileError> {
    std::fs::create_dir_all(dir).map_err(io_error(dir))?;
    for old in existing(dir)? {
        let path = dir.join(&old);
        std::fs::remove_file(&path).map_err(io_error(&path))?;
    }
    for (name, text) in &set.files {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(io_error(&path))?;
    }
    Ok(())
}

/// The files that differ between the set and `dir` (missing, extra or changed).
pub fn compare(set: &TraceSet, dir: &FsPath) -> Result<Vec<String>, TraceFileError> {
    let on_disk: BTreeSet<String> = existing(dir)?.into_iter().collect();
    let generated: BTreeMap<&str, &str> = set
        .files
        .iter()
        .map(|(n, t)| (n.as_str(), t.as_str()))
        .collect();
    let mut differences = Vec::new();
    for (name, text) in &generated {
        match std::fs::read_to_string(dir.join(name)) {
            Ok(committed) if committed == *text => {}
            Ok(_) => differences.push(format!("{name} (content changed)")),
            Err(_) => differences.push(format!("{name} (missing)")),
        }
    }
    for name in on_disk {
        if !generated.contains_key(name.as_str()) {
            differences.push(format!("{name} (no longer generated)"));
        }
    }
    Ok(differences)
}

fn existing(dir: &FsPath) -> Result<Vec<String>, TraceFileError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(io_error(dir)(e)),
    };
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(io_error(dir))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".jsonl") || name == "index.json" {
            names.push(name);
        }
    }
    names.sort();
    Ok(names)
}
