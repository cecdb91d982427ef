//! Generating the trace set: which paths of which scopes become traces, in which order, under
//! which names and descriptions.
//!
//! Numbers run in generation order over the scopes; the rest of a file name is a slug of what
//! the trace shows (a property, a transition class, a walk's seed), prefixed by the scope's
//! name outside the configured scope, so names are deterministic, stable and unique.

use super::{
    abstract_state, file_name, HeaderLine, IndexEntry, ScopeVerdict, StepLine, TraceSet, FORMAT,
};
use crate::properties::PropertyInfo;
use crate::search::{self, classes, Path, Stage, TransitionClass};
use crate::simulate;
use crate::types::Role;
use crate::{Config, RlModel};
use serde::Serialize;
use stateright::Expectation;
use std::collections::BTreeSet;

/// Random walks added to the set, and their length.
const WALKS: u64 = 24;
const WALK_STEPS: usize = 40;

/// What a scope contributes to the trace set.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Contribution {
    /// Witnesses, counterexamples, one trace per transition class, and random walks.
    Everything,
    /// Only the shortest counterexamples (the paper variant's findings).
    Counterexamples,
    /// No trace: only its reachable (action kind x stage) pairs, added to the denominator of
    /// the transition coverage. A scope larger than those the traces are cut from, so the
    /// coverage figure can fall short of every pair.
    Reachable,
}

/// One scope of the trace set.
#[derive(Clone)]
pub struct TraceScope {
    pub model: RlModel,
    pub contribution: Contribution,
    /// Prefixes its traces' names and descriptions (`link-failure`, `paper-f3`); empty for
    /// the configured scope.
    pub name: String,
}

impl TraceScope {
    pub fn new(config: Config, contribution: Contribution, name: &str) -> TraceScope {
        TraceScope {
            model: RlModel::new(config),
            contribution,
            name: name.to_string(),
        }
    }
}

/// The trace set `traces` writes: the configured scope, the persistent link failure, the
/// returns, the starved link (F17), the counterexamples of the paper variant's findings, and the coverage scopes
/// (`Config::coverage_scopes`) that only widen the reachable set.
pub fn standard(scope: Config) -> Vec<TraceScope> {
    let mut scopes = vec![
        TraceScope::new(scope, Contribution::Everything, ""),
        TraceScope::new(
            Config::link_failure(),
            Contribution::Everything,
            "link-failure",
        ),
        TraceScope::new(Config::returns(), Contribution::Everything, "returns"),
        TraceScope::new(Config::starved(), Contribution::Everything, "starved"),
    ];
    scopes.extend(Config::paper_findings().into_iter().map(|(fix, config)| {
        let name = format!("paper-{}", fix.label().to_lowercase());
        TraceScope::new(config, Contribution::Counterexamples, &name)
    }));
    scopes.extend(
        Config::coverage_scopes()
            .into_iter()
            .map(|(name, config)| TraceScope::new(config, Contribution::Reachable, name)),
    );
    scopes
}

/// Generates the trace set of one or more scopes of the model, numbered in order.
pub fn generate(scopes: &[TraceScope], mut progress: impl FnMut(usize, usize)) -> TraceSet {
    let mut set = TraceSet {
        files: Vec::new(),
        reachable: BTreeSet::new(),
        covered: BTreeSet::new(),
        unique_states: 0,
        scopes: Vec::new(),
    };
    let mut index = Vec::new();
    for scope in scopes {
        generate_scope(scope, &mut progress, &mut set, &mut index);
    }
    let index_text = serde_json::to_string_pretty(&index).unwrap_or_default() + "\n";
    set.files.push(("index.json".to_string(), index_text));
    // The reachable classes of the exhaustively searched scopes, for the conformance suite's
    // coverage: what the model can do, not what the traces happen to cover.
    let reachable: Vec<String> = set
        .reachable
        .iter()
        .map(|&(kind, stage)| coverage_class_name(kind, stage))
        .collect();
    let reachable_text = serde_json::to_string_pretty(&reachable).unwrap_or_default() + "\n";
    set.files.push((REACHABLE_FILE.to_string(), reachable_text));
    set
}

/// The file of the reachable (action kind x stage) classes: `["crash@initializing", ...]`.
pub const REACHABLE_FILE: &str = "reachable.json";

/// `tick@steady`: a coverage class as `index.json` and `reachable.json` name it.
pub fn coverage_class_name(kind: crate::ActionKind, stage: crate::search::Stage) -> String {
    format!("{}@{:?}", kind.name(), stage).to_lowercase()
}

/// A path chosen for the set, with what it is for.
struct Chosen {
    purpose: String,
    slug: String,
    description: String,
    path: Path,
}

fn generate_scope(
    scope: &TraceScope,
    progress: &mut impl FnMut(usize, usize),
    set: &mut TraceSet,
    index: &mut Vec<IndexEntry>,
) {
    let model = &scope.model;
    let explored = search::explore(model, usize::MAX, progress);
    set.unique_states += explored.unique_states;
    set.scopes
        .push(ScopeVerdict::of(&scope.name, &model.config, &explored));
    if scope.contribution == Contribution::Reachable {
        set.reachable.extend(explored.reachable_coverage_classes());
        return;
    }
    let mut chosen: Vec<Chosen> = Vec::new();
    let mut seen_actions: BTreeSet<Vec<crate::Action>> = BTreeSet::new();
    let mut add = |entry: Chosen, chosen: &mut Vec<Chosen>| {
        if seen_actions.insert(entry.path.actions()) {
            chosen.push(entry);
        }
    };
    for info in crate::properties::catalogue() {
        let counterexample = info.expectation == Expectation::Always;
        if scope.contribution == Contribution::Counterexamples && !counterexample {
            continue;
        }
        if let Some(path) = explored.discovery(info.name) {
            add(discovery(&model.config, &info, path), &mut chosen);
        }
    }
    if scope.contribution == Contribution::Everything {
        for (class, path) in explored.class_paths() {
            add(transition(&class, path), &mut chosen);
        }
        for seed in 1..=WALKS {
            add(walk(model, seed), &mut chosen);
        }
        set.reachable.extend(explored.reachable_coverage_classes());
    }
    write_chosen(scope, &chosen, set, index);
}

/// A property's shortest discovery: a witness, or a counterexample.
fn discovery(config: &Config, info: &PropertyInfo, path: Path) -> Chosen {
    if info.expectation == Expectation::Always {
        let variant = format!("{:?}", config.variant).to_lowercase();
        Chosen {
            purpose: format!("counterexample ({variant} variant): {}", info.name),
            slug: format!("violates-{}", slug(info.name)),
            description: format!(
                "Counterexample to \"{}\" ({variant} variant): {}",
                info.name, info.meaning
            ),
            path,
        }
    } else {
        Chosen {
            purpose: format!("witness: {}", info.name),
            slug: slug(info.name),
            description: format!("Witness of \"{}\": {}", info.name, info.meaning),
            path,
        }
    }
}

fn transition(class: &TransitionClass, path: Path) -> Chosen {
    let role = |r: Option<Role>| r.map_or("none", Role::name).to_lowercase();
    let stage = |s: Stage| format!("{s:?}").to_lowercase();
    let purpose = format!(
        "transition: {} by a {} controller ({}) -> {} ({})",
        class.kind.name(),
        stage(class.before),
        role(class.role_before),
        stage(class.after),
        role(class.role_after)
    );
    let with_role = |s: Stage, r: Option<Role>| match r {
        Some(r) => format!("{}-{}", slug(&format!("{s:?}")), role(Some(r))),
        None => slug(&format!("{s:?}")),
    };
    Chosen {
        slug: format!(
            "{}-{}-to-{}",
            slug(class.kind.name()),
            with_role(class.before, class.role_before),
            with_role(class.after, class.role_after)
        ),
        description: format!(
            "The shortest path to a {} by a {} controller ({}) that leaves it {} ({})",
            class.kind.name().replace('_', " "),
            stage(class.before),
            role(class.role_before),
            stage(class.after),
            role(class.role_after)
        ),
        purpose,
        path,
    }
}

fn walk(model: &RlModel, seed: u64) -> Chosen {
    Chosen {
        purpose: format!("random walk, seed {seed}"),
        slug: format!("random-walk-seed-{seed}"),
        description: format!("A random walk of up to {WALK_STEPS} steps from seed {seed}"),
        path: simulate::walk(model, seed, WALK_STEPS),
    }
}

/// Lower-case words joined by `-`: `NotStarted` and `not_started` give `not-started`.
pub(super) fn slug(text: &str) -> String {
    let mut words: Vec<String> = Vec::new();
    let mut word = String::new();
    let mut previous_lower = false;
    for c in text.chars() {
        if c.is_ascii_alphanumeric() {
            if c.is_ascii_uppercase() && previous_lower && !word.is_empty() {
                words.push(std::mem::take(&mut word));
            }
            previous_lower = c.is_ascii_lowercase() || c.is_ascii_digit();
            word.push(c.to_ascii_lowercase());
        } else {
            if !word.is_empty() {
                words.push(std::mem::take(&mut word));
            }
            previous_lower = false;
        }
    }
    if !word.is_empty() {
        words.push(word);
    }
    words.join("-")
}

fn write_chosen(
    scope: &TraceScope,
    chosen: &[Chosen],
    set: &mut TraceSet,
    index: &mut Vec<IndexEntry>,
) {
    let hash = super::model_hash();
    for entry in chosen {
        let number = set.files.len() + 1;
        let (slug, description) = if scope.name.is_empty() {
            (entry.slug.clone(), entry.description.clone())
        } else {
            (
                format!("{}-{}", scope.name, entry.slug),
                format!("{} [{} scope]", entry.description, scope.name),
            )
        };
        let name = file_name(number, &slug);
        let path = &entry.path;
        let header = HeaderLine {
            format: FORMAT.to_string(),
            model_hash: hash.clone(),
            config: scope.model.config.clone(),
            purpose: entry.purpose.clone(),
            description: description.clone(),
            initial_state_index: path.init_index,
            initial: abstract_state(&path.init),
        };
        let mut text = to_json(&header) + "\n";
        let mut before = &path.init;
        let mut covers = BTreeSet::new();
        for (step, (action, after)) in path.steps.iter().enumerate() {
            for class in classes(before, action, after) {
                set.covered.insert((class.kind, class.before));
                covers.insert(coverage_class_name(class.kind, class.before));
            }
            text.push_str(&to_json(&StepLine {
                step: step + 1,
                action: *action,
                state: abstract_state(after),
            }));
            text.push('\n');
            before = after;
        }
        index.push(IndexEntry {
            file: name.clone(),
            number,
            purpose: entry.purpose.clone(),
            description,
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

#[cfg(test)]
mod tests {
    use super::slug;

    #[test]
    fn slugs_are_lower_case_words() {
        assert_eq!(
            slug("late joiner becomes Tertiary"),
            "late-joiner-becomes-tertiary"
        );
        assert_eq!(slug("NotStarted"), "not-started");
        assert_eq!(slug("lose_heartbeat"), "lose-heartbeat");
        assert_eq!(
            slug("FAILED only after heartbeat loss"),
            "failed-only-after-heartbeat-loss"
        );
        assert_eq!(
            slug("formation with 3 controllers"),
            "formation-with-3-controllers"
        );
    }
}
