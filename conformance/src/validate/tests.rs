//! Tests of the validation search and its per-controller round decomposition.

use super::search::step_model;
use super::*;
use model::protocol;
use model::state::History;
use model::traces::AbstractController;
use model::RlModel;
use model::{Action, Life, Phase};

/// The round's end acts on each controller separately: a receiver's next state under a
/// choice of lost heartbeats is the same whether the others' losses are chosen with it or
/// not, and whatever the others' hidden counters are.
#[test]
fn a_round_end_decomposes_per_receiver() {
    let rl_model = RlModel::new(model::Config::default());
    // The walks stay in the default scope; the round ends are checked without budgets.
    let config = model::Config {
        max_lost_heartbeats: u8::MAX,
        ..model::Config::default()
    };
    let mut checked = 0;
    for seed in 0..40 {
        let path = model::simulate::walk(&rl_model, seed, 30);
        for state in std::iter::once(&path.init).chain(path.steps.iter().map(|(_, s)| s)) {
            let mut state = state.clone();
            state.lost_links = 0;
            state.history = History::default();
            let up: Vec<u8> = state.up().map(|c| c.id).collect();
            let mut enabled = Vec::new();
            protocol::actions(&config, &state, &mut enabled);
            if !enabled.contains(&Action::Tick) {
                continue;
            }
            // Every link lost with probability 1/2, from the seed.
            let mut bits = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ checked;
            let mut joint = state.clone();
            let mut lost_to: BTreeMap<u8, u16> = BTreeMap::new();
            for &to in &up {
                let senders: Vec<u8> = up.iter().copied().filter(|s| *s != to).collect();
                for (bit, &from) in senders.iter().enumerate() {
                    bits = bits.rotate_left(7) ^ 0x5555;
                    if bits & 1 == 1 {
                        joint = protocol::next_state(
                            &config,
                            &joint,
                            Action::LoseHeartbeat { from, to },
                        )
                        .expect("a loss is always a step");
                        *lost_to.entry(to).or_default() |= 1 << bit;
                    }
                }
            }
            let together = protocol::next_state(&config, &joint, Action::Tick).expect("tick");
            // The others' hidden counters replaced: the receiver must not notice.
            let mut others_hidden = state.clone();
            for c in others_hidden.controllers.iter_mut() {
                c.self_dissent_rounds = 3;
                c.window_quiet_rounds = 0;
                for p in c.peers.iter_mut() {
                    p.silent_rounds = 1;
                    p.dissent_rounds = 2;
                }
            }
            for &to in &up {
                let index = usize::from(to) - 1;
                let senders: Vec<u8> = up.iter().copied().filter(|s| *s != to).collect();
                let lost = lost_to.get(&to).copied().unwrap_or(0);
                let alone = round_end_of(
                    &config,
                    &others_hidden,
                    to,
                    &state.controllers[index],
                    &senders,
                );
                let (mine, _) = alone
                    .iter()
                    .find(|(_, mask)| *mask == lost)
                    .expect("every loss choice is explored");
                let mut expected = together.controllers[index].clone();
                if let Some(expired) =
                    step_model(&config, &together, Action::ExpireWindow { controller: to })
                {
                    expected = expired.controllers[index].clone();
                }
                assert_eq!(mine, &expected, "C{to} in {state:?}");
                checked += 1;
            }
        }
    }
    assert!(checked > 500, "only {checked} receivers checked");
}

#[test]
fn a_lost_failed_peer_may_be_missing_from_sees_and_failed() {
    let observed = AbstractController {
        id: 1,
        life: Life::Up,
        incarnation: 0,
        phase: Some(Phase::Steady),
        role: Some(model::Role::Primary),
        strength: Some(30),
        sees: vec![2, 3],
        failed: vec![2],
        alarms: vec![2],
        agreed: None,
        vote: None,
    };
    let lost = AbstractController {
        sees: vec![3],
        failed: vec![],
        ..observed.clone()
    };
    assert!(differences(&lost, &observed).is_empty());
    let lost_unfailed = AbstractController {
        sees: vec![2],
        ..observed.clone()
    };
    assert_eq!(differences(&lost_unfailed, &observed), vec!["sees"]);
}

/// The search reads a `round_ends_missed` line as the model's `Oversleep`: the sleeper's
/// state stays as it was, and every other controller ends the round as at a tick with the
/// sleeper's heartbeat lost.
#[test]
fn an_overslept_round_end_leaves_the_sleeper_as_it_was() {
    let config = model::Config::slowed_receiver();
    let rl_model = RlModel::new(config.clone());
    let mut checked = 0;
    for seed in 0..200 {
        let path = model::simulate::walk(&rl_model, seed, 40);
        for state in path.steps.iter().map(|(_, s)| s) {
            let mut enabled = Vec::new();
            protocol::actions(&config, state, &mut enabled);
            for action in enabled {
                let Action::Oversleep { controller } = action else {
                    continue;
                };
                let index = usize::from(controller) - 1;
                let slept = protocol::next_state(&config, state, action).expect("enabled");
                assert_eq!(
                    slept.controllers[index], state.controllers[index],
                    "C{controller} slept through the round in {state:?}"
                );
                let late = protocol::next_state(
                    &config,
                    state,
                    Action::LateHeartbeat { from: controller },
                )
                .expect("an oversleep's heartbeat is late");
                let ticked = protocol::next_state(&config, &late, Action::Tick).expect("tick");
                for c in state.controllers.iter().filter(|c| c.id != controller) {
                    let i = usize::from(c.id) - 1;
                    assert_eq!(slept.controllers[i], ticked.controllers[i], "C{}", c.id);
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 50, "only {checked} oversleeps checked");
}
