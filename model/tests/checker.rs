//! Whole-model checks: a pinned state count, every witness discovered, and mutation tests
//! showing the checker reports deliberately broken rules.

use model::properties::catalogue;
use model::{search, Config, Mutation, RlModel, Variant};
use stateright::{Checker, Expectation, HasDiscoveries, Model};
use std::collections::BTreeSet;

/// Three founders, no late joiner, no faults: small enough to pin exactly.
fn small() -> Config {
    Config {
        late_joiners: 0,
        max_crashes: 0,
        max_restarts: 0,
        ..Config::default()
    }
}

#[test]
fn pinned_unique_state_count_of_a_small_configuration() {
    let checker = RlModel::new(small())
        .checker()
        .finish_when(HasDiscoveries::AnyOf(BTreeSet::new()))
        .spawn_bfs()
        .join();
    // Any change of this number is a change of the specification's behaviour: review it.
    assert_eq!(checker.unique_state_count(), 771);
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
    let explored = search::explore(&model, 5_000_000, |_, _| {});
    assert!(
        !explored.truncated,
        "the configuration must be small enough to finish"
    );
    catalogue()
        .into_iter()
        .filter(|info| {
            let found = explored.discovery(info.name).is_some();
            match info.expectation {
                Expectation::Always => found,
                Expectation::Sometimes => !found && info.applies(&config),
                Expectation::Eventually => false,
            }
        })
        .map(|info| info.name)
        .collect()
}

#[test]
fn default_configuration_holds_and_every_witness_is_discovered() {
    assert_eq!(failures(Config::default()), Vec::<&str>::new());
}

#[test]
fn loss_witnesses_are_discovered_when_heartbeats_can_be_lost() {
    let config = Config {
        late_joiners: 0,
        max_crashes: 0,
        max_restarts: 0,
        max_lost_heartbeats: 2,
        ..Config::default()
    };
    let model = RlModel::new(config);
    let explored = search::explore(&model, 5_000_000, |_, _| {});
    for name in ["minority voter FAILED", "re-vote after heartbeat loss"] {
        assert!(explored.discovery(name).is_some(), "{name} not witnessed");
    }
}

fn mutated(mutation: Mutation, lost_heartbeats: u8) -> Vec<&'static str> {
    failures(Config {
        late_joiners: 1,
        max_crashes: 1,
        max_restarts: 1,
        max_lost_heartbeats: lost_heartbeats,
        mutation: Some(mutation),
        ..Config::default()
    })
}

#[test]
fn mutation_promote_without_failure_is_caught() {
    let failed = failures(Config {
        late_joiners: 0,
        max_crashes: 0,
        max_restarts: 0,
        max_lost_heartbeats: 1,
        mutation: Some(Mutation::PromoteWithoutFailure),
        ..Config::default()
    });
    assert!(
        failed.contains(&"actuator has a single owner"),
        "{failed:?}"
    );
}

#[test]
fn mutation_failback_is_caught() {
    let failed = mutated(Mutation::Failback, 0);
    assert!(
        failed.contains(&"a heard Primary is never demoted"),
        "{failed:?}"
    );
}

#[test]
fn mutation_output_before_role_is_caught() {
    let failed = mutated(Mutation::OutputBeforeRole, 0);
    assert!(
        failed.contains(&"no command output without a role"),
        "{failed:?}"
    );
}

#[test]
fn mutation_admit_fourth_is_caught() {
    // The fourth takes Tertiary beside the real Tertiary: the system never settles and the
    // fourth is never seen ignored.
    let failed = mutated(Mutation::AdmitFourth, 0);
    assert!(failed.contains(&"settles after faults stop"), "{failed:?}");
    assert!(failed.contains(&"fourth controller ignored"), "{failed:?}");
}

#[test]
fn mutation_ignore_minority_vote_is_caught() {
    let failed = failures(Config {
        late_joiners: 0,
        max_crashes: 0,
        max_restarts: 0,
        max_lost_heartbeats: 2,
        mutation: Some(Mutation::IgnoreMinorityVote),
        ..Config::default()
    });
    assert!(failed.contains(&"minority voter FAILED"), "{failed:?}");
}

#[test]
fn paper_variant_differs_from_default() {
    assert_ne!(
        model::Rules::of(Variant::Paper),
        model::Rules::of(Variant::Default)
    );
}
