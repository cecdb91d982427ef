//! The mutation check: a suite that cannot fail proves nothing. Each test configures one
//! deliberate break of a voting rule in the core (`rl_layer::core::mutation`, feature `mutation`),
//! replays every default-variant trace, and asserts that the replay fails with a readable
//! diff showing the broken field, model value against core value, and that at least one
//! committed transcript (the insta snapshots) differs from what the mutated core did.
//!
//! The mutation is a field of each core's configuration, so these tests run in parallel with
//! each other and with the conformance suite without affecting it.

use conformance::core_replay::{self as replay, transcript, Failure, Replayed};
use conformance::diff::{NAME_WIDTH, VALUE_WIDTH};
use conformance::trace::{self, Trace};
use rl_layer::core::mutation::Mutation;
use rl_layer::core::CoreConfig;

fn traces() -> Vec<Trace> {
    trace::read_dir(&trace::default_dir()).expect("the trace set is readable")
}

/// Replays every default-variant trace with `mutation` configured.
fn replays_under(mutation: Mutation) -> Vec<Replayed> {
    let configure = move |config: CoreConfig| config.with_mutation(Some(mutation));
    traces()
        .iter()
        .filter(|trace| replay::skip_reason(trace).is_none())
        .map(|trace| replay::replay_with(trace, &configure))
        .collect()
}

/// The failures among the replays under `mutation`; also asserts that at least one
/// transcript differs from its committed snapshot.
fn failures_under(mutation: Mutation) -> Vec<Failure> {
    let replays = replays_under(mutation);
    let snapshots = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots");
    let changed: Vec<&str> = replays
        .iter()
        .filter(|r| {
            transcript::committed(&snapshots, &r.file).as_deref() != Some(r.transcript.trim_end())
        })
        .map(|r| r.file.as_str())
        .collect();
    let failures: Vec<Failure> = replays.iter().filter_map(|r| r.failure.clone()).collect();
    println!(
        "{mutation:?}: {} of {} replayed traces fail; {} transcripts differ from their snapshots",
        failures.len(),
        replays.len(),
        changed.len()
    );
    assert!(
        !changed.is_empty(),
        "{mutation:?}: every transcript equals its committed snapshot; the snapshots cannot \
         see this rule broken"
    );
    failures
}

/// The rows of a failure's diff marked as different: (field, model value, core value).
fn differing_rows(message: &str) -> Vec<(String, String, String)> {
    message
        .lines()
        .filter_map(|line| line.strip_prefix("  >> "))
        .filter(|rest| !rest.starts_with("actuator owner"))
        .filter_map(|rest| {
            let core_column = NAME_WIDTH + VALUE_WIDTH;
            let name = rest.get(..NAME_WIDTH)?.trim().to_string();
            let model_value = rest.get(NAME_WIDTH..core_column)?.trim().to_string();
            let core_value = rest.get(core_column..)?.trim().to_string();
            Some((name, model_value, core_value))
        })
        .collect()
}

/// Asserts that some failure's readable diff shows `field` differing as `shows` accepts
/// (model value, core value); prints that failure.
fn assert_some_diff_shows(mutation: Mutation, field: &str, shows: impl Fn(&str, &str) -> bool) {
    let failures = failures_under(mutation);
    assert!(
        !failures.is_empty(),
        "{mutation:?}: every trace still conforms; the suite cannot see this rule broken"
    );
    let found = failures.iter().map(ToString::to_string).find(|message| {
        differing_rows(message)
            .iter()
            .any(|(name, model_value, core_value)| name == field && shows(model_value, core_value))
    });
    match found {
        Some(message) => println!("{message}"),
        None => panic!(
            "{mutation:?}: no failure shows the expected {field} difference; the first one:\n{}",
            failures[0]
        ),
    }
}

#[test]
fn promote_without_failure_is_caught() {
    // A Secondary that misses one heartbeat of its Primary takes Primary without a vote.
    assert_some_diff_shows(Mutation::PromoteWithoutFailure, "role", |model, core| {
        model == "secondary" && core == "primary"
    });
}

#[test]
fn ignore_minority_vote_is_caught() {
    // The model marks the minority voter FAILED; the mutated core never does.
    assert_some_diff_shows(Mutation::IgnoreMinorityVote, "failed", |model, core| {
        model != "{}" && core == "{}"
    });
}

#[test]
fn failback_is_caught() {
    // A restarted incarnation (`#1`) is voted Primary again instead of coming in below.
    assert_some_diff_shows(Mutation::Failback, "vote", |model, core| {
        let primary = |vote: &str| vote.split(' ').next().unwrap_or("").contains('#');
        primary(core) && !primary(model)
    });
}

#[test]
fn admit_fourth_is_caught() {
    // The fourth controller votes itself in as Tertiary.
    assert_some_diff_shows(Mutation::AdmitFourth, "vote", |model, core| {
        core.contains("T=4") && !model.contains("T=4")
    });
}

#[test]
fn stay_when_unplugged_is_caught() {
    // The model's unplugged controller starts again (initializing); the mutated one goes on.
    assert_some_diff_shows(Mutation::StayWhenUnplugged, "phase", |model, core| {
        model == "initializing" && core != "initializing"
    });
}

#[test]
fn keep_incarnation_on_resume_is_caught() {
    // The model's resumed controller starts again (initializing); the mutated one goes on.
    assert_some_diff_shows(Mutation::KeepIncarnationOnResume, "phase", |model, core| {
        model == "initializing" && core != "initializing"
    });
}

#[test]
fn no_epoch_ranking_is_caught() {
    // After a healed cut the model's vote keeps the majority's roles; the mutated one ranks
    // the result agreed alone with it and votes otherwise.
    assert_some_diff_shows(Mutation::NoEpochRanking, "vote", |model, core| {
        model != core
    });
}

#[test]
fn without_a_configured_mutation_the_hooks_are_inert() {
    let snapshots = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/snapshots");
    let traces = traces();
    for trace in traces.iter().filter(|t| replay::skip_reason(t).is_none()) {
        let replayed = replay::replay_with(trace, &|config: CoreConfig| config.with_mutation(None));
        if let Some(failure) = replayed.failure {
            panic!("with no mutation configured:\n{failure}");
        }
        assert_eq!(
            transcript::committed(&snapshots, &trace.file).as_deref(),
            Some(replayed.transcript.trim_end()),
            "{}: the committed snapshot is what the correct core does",
            trace.file
        );
    }
}
