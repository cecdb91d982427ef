//! Whole-model checks: a pinned state count, every witness discovered, and mutation tests
//! showing the checker reports deliberately broken rules. The scopes the traces are cut from
//! (the configured one, the persistent link failure, the returns) are checked and pinned by
//! the one search that generates the traces (`tests/traces.rs`).

use model::traces::ScopeVerdict;
use model::{search, Config, Mutation, RlModel};
use stateright::{Checker, HasDiscoveries, Model};
use std::collections::BTreeSet;

/// Three founders and the given late joiners and fault budgets.
fn scope(late_joiners: u8, crashes: u8, restarts: u8, lost_heartbeats: u8) -> Config {
    Config {
        late_joiners,
        max_crashes: crashes,
        max_restarts: restarts,
        max_lost_heartbeats: lost_heartbeats,
        ..Config::default()
    }
}

/// Three founders, no late joiner, no faults: small enough to pin exactly.
fn small() -> Config {
    scope(0, 0, 0, 0)
}

#[test]
fn pinned_unique_state_count_of_a_small_configuration() {
    let checker = RlModel::new(small())
        .checker()
        .finish_when(HasDiscoveries::AnyOf(BTreeSet::new()))
        .spawn_bfs()
        .join();
    // Any change of this number is a change of the specification's behaviour: review it.
    assert_eq!(checker.unique_state_count(), 431);
}

#[test]
fn our_search_agrees_with_statrights_state_count() {
    let model = RlModel::new(small());
    let explored = search::explore(&model, usize::MAX, |_, _| {});
    let checker = model
        .checker()
        .finish_when(HasDiscoveries::AnyOf(BTreeSet::new()))
        .spawn_bfs()
        .join();
    assert_eq!(explored.unique_states, checker.unique_state_count());
}

/// Runs our exhaustive search; returns the names of the failed properties.
fn failures(config: Config) -> Vec<&'static str> {
    let model = RlModel::new(config.clone());
    let explored = search::explore(&model, 10_000_000, |_, _| {});
    assert!(
        !explored.truncated,
        "the configuration must be small enough to finish"
    );
    ScopeVerdict::of("", &config, &explored).failed()
}

#[test]
fn a_crash_restart_and_late_joiner_without_loss_hold_with_every_witness() {
    // The default scope (one lost heartbeat) is run by `check` in CI; this one fits a test.
    assert_eq!(failures(scope(1, 1, 1, 0)), Vec::<&str>::new());
}

fn mutated(mutation: Mutation, base: Config) -> Vec<&'static str> {
    failures(Config {
        mutation: Some(mutation),
        ..base
    })
}

#[test]
fn mutation_promote_without_failure_is_caught() {
    let failed = mutated(Mutation::PromoteWithoutFailure, scope(0, 0, 0, 1));
    assert!(
        failed.contains(&"actuator has a single owner"),
        "{failed:?}"
    );
}

#[test]
fn mutation_failback_is_caught() {
    let failed = mutated(Mutation::Failback, scope(1, 1, 1, 0));
    assert!(
        failed.contains(&"a live Primary is never demoted"),
        "{failed:?}"
    );
}

#[test]
fn mutation_output_before_role_is_caught() {
    let failed = mutated(Mutation::OutputBeforeRole, scope(1, 1, 1, 0));
    assert!(
        failed.contains(&"no command output without a role"),
        "{failed:?}"
    );
}

#[test]
fn mutation_admit_fourth_is_caught() {
    // The fourth takes Tertiary beside the real Tertiary: the system never settles and the
    // fourth is never seen ignored.
    let failed = mutated(Mutation::AdmitFourth, scope(1, 1, 1, 0));
    assert!(failed.contains(&"settles after faults stop"), "{failed:?}");
    assert!(failed.contains(&"fourth controller ignored"), "{failed:?}");
}

#[test]
fn a_slowed_controller_and_an_unnoticed_stall_hold_with_every_witness_in_scope() {
    assert_eq!(failures(Config::gray()), Vec::<&str>::new());
    assert_eq!(failures(Config::unnoticed_stall()), Vec::<&str>::new());
}

#[test]
fn mutation_failback_makes_a_sick_controller_primary_again() {
    // The restarted life of a slowed Primary that doubted itself is ranked by id and takes the
    // Primary back while still slowed. Every restart of that life can do it again, so the
    // search never ends; the counterexample is in its first states.
    let config = Config {
        mutation: Some(Mutation::Failback),
        ..Config::gray()
    };
    let explored = search::explore(&RlModel::new(config), 300_000, |_, _| {});
    assert!(explored
        .discovery("a sick controller is not made Primary again")
        .is_some());
    let healthy = search::explore(&RlModel::new(Config::gray()), 5_000_000, |_, _| {});
    assert!(!healthy.truncated);
    assert!(healthy
        .discovery("a sick controller is not made Primary again")
        .is_none());
}

#[test]
fn mutation_ignore_minority_vote_is_caught() {
    let failed = mutated(Mutation::IgnoreMinorityVote, Config::link_failure());
    assert!(failed.contains(&"minority voter FAILED"), "{failed:?}");
}
