//! Unit tests of single transitions: each rule as a literal before/after.

use model::{Action, Config, Life, Phase, RlModel, Role};
use stateright::Model;

fn model() -> RlModel {
    RlModel::new(Config::default())
}

/// The initial state with controllers 1..=k started.
fn start(k: usize) -> model::State {
    model().init_states()[k - 1].clone()
}

fn step(state: &model::State, action: Action) -> model::State {
    model()
        .next_state(state, action)
        .unwrap_or_else(|| panic!("{action} not enabled"))
}

/// Ticks until no timer or vote is due, then once more.
fn settle(mut state: model::State, rounds: usize) -> model::State {
    let m = model();
    for _ in 0..rounds {
        loop {
            let mut actions = Vec::new();
            m.actions(&state, &mut actions);
            let urgent = actions
                .iter()
                .find(|a| matches!(a, Action::ExpireWindow { .. } | Action::DeliverVotes { .. }));
            match urgent {
                Some(action) => state = step(&state, *action),
                None => break,
            }
        }
        state = step(&state, Action::Tick);
    }
    state
}

/// Three founders formed, then the Primary (C1) crashed and the survivors re-voted.
fn formed_then_primary_crashed() -> model::State {
    let state = settle(start(3), 6);
    let state = step(&state, Action::Crash { controller: 1 });
    settle(state, 5)
}

#[test]
fn three_founders_vote_roles_by_lowest_id() {
    // Roles in 2 rounds; each standby raises once the role above reports its writer
    // established (F13): the Tertiary commands from round 6.
    let state = settle(start(3), 6);
    let roles: Vec<_> = state.controllers.iter().map(|c| c.role).collect();
    assert_eq!(
        roles,
        vec![
            Some(Role::Primary),
            Some(Role::Secondary),
            Some(Role::Tertiary),
            None
        ]
    );
    let strengths: Vec<_> = state.controllers.iter().map(|c| c.output).collect();
    assert_eq!(strengths, vec![Some(30), Some(20), Some(10), None]);
    assert_eq!(state.actuator_owner(), Some(1));
}

#[test]
fn no_output_while_initializing() {
    let state = step(&start(3), Action::Tick);
    assert!(state.up().all(|c| c.output.is_none()));
}

#[test]
fn window_closes_at_three_distinct_heartbeats() {
    let state = step(&start(3), Action::Tick);
    assert!(state.up().all(|c| c.phase == Phase::Voting));
}

#[test]
fn a_lone_controller_waits_for_the_window_then_takes_primary() {
    let state = step(&start(1), Action::Tick);
    assert_eq!(state.controller(1).phase, Phase::Initializing);
    let state = settle(state, 3);
    assert_eq!(state.controller(1).role, Some(Role::Primary));
}

#[test]
fn primary_crash_promotes_every_lower_role() {
    let state = formed_then_primary_crashed();
    assert_eq!(state.controller(2).role, Some(Role::Primary));
    assert_eq!(state.controller(3).role, Some(Role::Secondary));
    assert_eq!(state.actuator_owner(), Some(2));
    assert!(
        state.controller(2).peer(1).alarm,
        "the survivors raise an alarm"
    );
}

#[test]
fn restarted_primary_comes_back_in_the_lowest_role() {
    let state = formed_then_primary_crashed();
    let state = step(&state, Action::Restart { controller: 1 });
    let state = settle(state, 6);
    assert_eq!(state.controller(1).incarnation, 1);
    assert_eq!(state.controller(1).role, Some(Role::Tertiary));
    assert_eq!(state.controller(2).role, Some(Role::Primary), "no failback");
    assert!(!state.controller(2).peer(1).alarm, "the alarm is cleared");
}

#[test]
fn late_joiner_takes_the_lowest_free_role() {
    let state = settle(start(2), 4);
    let state = step(&state, Action::Join { controller: 4 });
    let state = settle(state, 6);
    assert_eq!(state.controller(4).role, Some(Role::Tertiary));
    assert_eq!(state.controller(1).role, Some(Role::Primary));
}

#[test]
fn a_fourth_controller_is_ignored() {
    let state = settle(start(3), 3);
    let state = step(&state, Action::Join { controller: 4 });
    let state = settle(state, 6);
    let fourth = state.controller(4);
    assert_eq!(fourth.life, Life::Up);
    assert_eq!(
        (fourth.phase, fourth.role, fourth.output),
        (Phase::Steady, None, None)
    );
}

#[test]
fn a_crashed_controllers_vote_disappears() {
    let state = settle(start(3), 3);
    let state = step(&state, Action::Crash { controller: 3 });
    assert_eq!(state.controller(3).vote, None);
    assert!(!model::protocol::vote_pending(
        &Config::default(),
        &state,
        3,
        1
    ));
}

#[test]
fn lost_heartbeat_is_one_way() {
    let m = RlModel::new(Config {
        max_lost_heartbeats: 2,
        ..Config::default()
    });
    let state = settle(start(3), 3);
    let state = m
        .next_state(&state, Action::LoseHeartbeat { from: 1, to: 2 })
        .expect("enabled");
    let state = m.next_state(&state, Action::Tick).expect("enabled");
    assert_eq!(state.controller(2).peer(1).silent_rounds, 1);
    assert_eq!(state.controller(1).peer(2).silent_rounds, 0);
}

#[test]
fn a_slowed_tertiary_that_sleeps_through_two_round_ends_and_hears_late_stands_alone_at_its_strength(
) {
    // The fault lab's starved controller (starve-primary, docs/faults.md): its loop slept
    // through two round ends and took its peers' heartbeats in after the third. It lost both
    // and, alone, is the provisional Primary of its own result, holding the strength it had
    // (F11: a newly provisional Primary keeps its strength for a round), below the Primary.
    let m = RlModel::new(Config::slowed_receiver());
    let step = |state: &model::State, action: Action| {
        m.next_state(state, action)
            .unwrap_or_else(|| panic!("{action} not enabled"))
    };
    let mut state = settle(start(3), 8);
    assert_eq!(state.controller(3).output, Some(10));
    for action in [
        Action::Slow { controller: 3 },
        Action::HearLate { to: 3 },
        Action::Tick,
        Action::Oversleep { controller: 3 },
    ] {
        state = step(&state, action);
    }
    let before_sleep = state.controller(3).clone();
    state = step(&state, Action::Oversleep { controller: 3 });
    assert_eq!(
        state.controller(3),
        &before_sleep,
        "no round end of its own"
    );
    assert!(
        state.controller(1).peer(3).alive.is_none(),
        "its peers lost it"
    );
    state = step(&state, Action::HearLate { to: 3 });
    state = step(&state, Action::Tick);
    let c3 = state.controller(3);
    assert_eq!(c3.role, Some(Role::Primary));
    assert!(c3.provisional);
    assert_eq!(c3.output, Some(10));
    assert_eq!(state.controller(1).role, Some(Role::Primary));
    assert_eq!(state.controller(1).output, Some(30));
}
