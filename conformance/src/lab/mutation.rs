//! Runs against a deliberately broken `rl` (`lab run --mutation NAME`): a lab that cannot
//! fail proves nothing, so it must be seen failing a build whose voting rule is broken
//! (docs/faults.md, "The lab catches a broken build"; `conformance/tests/lab_mutation.rs`).
//!
//! The voting reader's rule can be broken the same way (`lab run --vote-mutation NAME`): the
//! voting reader of the wrong-output scenarios, and only it, gets `RL_VOTE_MUTATION=NAME`, and
//! a wrong Primary's commands must then be caught at it (`super::wrong_output`).
//!
//! The controllers, and only they, get `RL_MUTATION=NAME`. An `rl` built with the `mutation`
//! feature reads it (`impl/core/src/mutation.rs`) and says so on stderr at start; any other
//! build ignores it without a word. So a mutation run checks, once the system formed, that
//! every controller announced the broken rule: a run whose `rl` did not is an error (exit 2),
//! never a verdict, since its PASS would say nothing about the mutation.

use super::error::LabError;
use std::path::Path;

/// The environment variable a `mutation` build of `rl controller` reads.
pub const VARIABLE: &str = "RL_MUTATION";

/// The names a `mutation` build of `rl` knows (`rl_layer::core::mutation::Mutation::name`). The
/// lab's own `rl` dependency is built without that feature, so a test keeps the two equal.
pub const NAMES: [&str; 8] = [
    "promote-without-failure",
    "ignore-minority-vote",
    "failback",
    "admit-fourth",
    "stay-when-unplugged",
    "write-before-compare",
    "keep-incarnation-on-resume",
    "no-epoch-ranking",
];

/// The environment variable a `mutation` build of `rl servo --vote` reads.
pub const VOTE_VARIABLE: &str = "RL_VOTE_MUTATION";

/// The broken voting rules a `mutation` build of `rl servo --vote` knows: a value taken from
/// one source (the output model's `--output-mutation accept-single-source`).
pub const VOTE_NAMES: [&str; 1] = ["accept-single-source"];

/// What a `mutation` build prints on stderr when it runs a broken rule (`impl/layer/src/runtime.rs`).
const ANNOUNCED: &str = "(RL_MUTATION)";
/// What it prints, before it exits, when `RL_MUTATION` names no mutation it knows.
const REJECTED: &str = "is not a mutation";

/// Why the controllers `labels` (`C1`, ...) do not run mutation `name`, if they do not, from
/// the stderr lines so far (`(source, text)`): a line in which `rl` rejected the name, or, once
/// the system has `formed`, a controller that never announced it.
pub fn refused(
    name: &str,
    rl: &Path,
    stderr: &[(String, String)],
    labels: &[String],
    formed: bool,
) -> Option<LabError> {
    let said = |label: &str, what: &str| {
        stderr
            .iter()
            .any(|(source, text)| source == label && text.contains(what))
    };
    if let Some((_, text)) = stderr
        .iter()
        .find(|(source, text)| labels.iter().any(|l| l == source) && text.contains(REJECTED))
    {
        return Some(LabError::MutationRejected {
            name: name.into(),
            rl: rl.to_path_buf(),
            message: text.clone(),
        });
    }
    let silent: Vec<String> = labels
        .iter()
        .filter(|label| !said(label, ANNOUNCED))
        .cloned()
        .collect();
    (formed && !silent.is_empty()).then(|| LabError::MutationIgnored {
        name: name.into(),
        rl: rl.to_path_buf(),
        silent: silent.join(", "),
    })
}

/// With `--vote-mutation NAME`: an error unless the voting reader (its stderr lines among
/// `stderr`, `(source, text)`) announced it runs the broken rule, as a `mutation` build does.
pub fn require_vote_mutation_announced(
    name: Option<&str>,
    rl: &Path,
    stderr: &[(String, String)],
) -> Result<(), LabError> {
    let Some(name) = name else {
        return Ok(());
    };
    let voter = super::wrong_output::readings::VOTER;
    let announced = stderr
        .iter()
        .any(|(source, text)| source == voter && text.contains(VOTE_ANNOUNCED));
    if announced {
        return Ok(());
    }
    Err(LabError::MutationIgnored {
        name: name.into(),
        rl: rl.to_path_buf(),
        silent: voter.into(),
    })
}

/// What a `mutation` build of `rl servo --vote` prints on stderr when it votes by a broken
/// rule (`impl/src/sim/mod.rs`).
const VOTE_ANNOUNCED: &str = "(RL_VOTE_MUTATION)";

#[cfg(test)]
mod tests {
    use super::*;

    fn labels() -> Vec<String> {
        ["C1", "C2", "C3"].map(String::from).to_vec()
    }

    fn announced_by(sources: &[&str]) -> Vec<(String, String)> {
        sources
            .iter()
            .map(|s| {
                let text =
                    "WARN rl: running with the deliberately broken rule failback (RL_MUTATION)";
                (s.to_string(), text.to_string())
            })
            .collect()
    }

    #[test]
    fn every_controller_announcing_it_is_a_mutation_run() {
        let stderr = announced_by(&["C1", "C2", "C3"]);
        assert!(refused("failback", Path::new("rl"), &stderr, &labels(), true).is_none());
    }

    #[test]
    fn a_silent_controller_once_formed_is_an_ignored_mutation() {
        let stderr = announced_by(&["C1", "C3", "servo"]);
        let rl = Path::new("target/release/rl");
        assert!(refused("failback", rl, &stderr, &labels(), false).is_none());
        let error = refused("failback", rl, &stderr, &labels(), true).map(|e| e.to_string());
        let error = error.unwrap_or_default();
        assert!(error.contains("C2") && !error.contains("C1"), "{error}");
        assert!(error.contains("--features mutation"), "{error}");
    }

    #[test]
    fn a_rejected_name_is_reported_before_formation() {
        let stderr = vec![(
            "C2".to_string(),
            "rl: RL_MUTATION=x is not a mutation; known: failback".to_string(),
        )];
        let error = refused("x", Path::new("rl"), &stderr, &labels(), false);
        assert!(matches!(error, Some(LabError::MutationRejected { .. })));
    }
}
