//! The plan's timing assumptions, checked against the model: a trace is replayed on real
//! processes only if the ways real timing departs from the model's cannot change its outcome.
//!
//! - its states are the same under the run's round lengths (the run's window is one round
//!   longer than the model's, see [`super::CONFIG_TOML`]; checked while the plan is built);
//! - some controller reports a change at the first round's end (the replay aligns on it);
//! - faults after a late start wait for a quiescent boundary;
//! - a controller heard one round later at start (DDS discovery) changes nothing;
//! - a process started after round 0, or a controller whose cables are plugged back in, ends
//!   in the same settled state if it is heard one or two rounds later.

use super::plan::{run_rounds, step, Mode, Plan, PlanError, RoundPlan};
use model::traces::{abstract_state, AbstractState};
use model::{Action, Phase};

/// Every timing assumption of `plan`, checked against the model.
pub(super) fn check_timing(plan: &Plan) -> Result<(), PlanError> {
    if plan.boundaries.len() < 2 {
        return Err(PlanError::NoRoundEnds);
    }
    check_first_report(plan)?;
    check_no_faults_while_free(plan)?;
    check_discovery_at_start(plan)?;
    check_discovery_after_late_starts(plan)
}

/// The replay takes the first round with reports for boundary 1: some controller must report
/// a change there (a new phase or a peer heard), or that round is unknown.
fn check_first_report(plan: &Plan) -> Result<(), PlanError> {
    let reports = |c: &model::Controller| {
        c.is_up()
            && (c.phase != Phase::Initializing
                || c.peers
                    .iter()
                    .any(|p| p.alive.is_some() || p.alarm || p.failed))
    };
    if plan.boundaries[1].controllers.iter().any(reports) {
        Ok(())
    } else {
        Err(PlanError::NoFirstReport)
    }
}

/// Faults after a late start must wait for a quiescent boundary.
fn check_no_faults_while_free(plan: &Plan) -> Result<(), PlanError> {
    let modes = plan.modes();
    for (k, round) in plan.rounds.iter().enumerate().skip(1) {
        if !round.is_empty() && modes[k] == Mode::Free {
            return Err(PlanError::FaultsAfterLateStart { round: k });
        }
    }
    Ok(())
}

/// The processes started at round 0: the initial ones and round 0's restarts and joins.
fn starters(plan: &Plan) -> Vec<u8> {
    let mut ids = plan.initial_up.clone();
    for action in &plan.rounds[0].lifecycle {
        if let Action::Join { controller } | Action::Restart { controller } = action {
            ids.push(*controller);
        }
    }
    ids.sort_unstable();
    ids.dedup();
    ids
}

/// Discovery at start: a controller may be heard one round later than the trace says (it
/// then counts one more quiet round of its window). Every combination must lead to the same
/// states.
fn check_discovery_at_start(plan: &Plan) -> Result<(), PlanError> {
    let config = &plan.config;
    let expected: Vec<AbstractState> = plan.boundaries.iter().map(abstract_state).collect();
    let starters = starters(plan);
    for mask in 1u32..(1 << starters.len()) {
        let mut start = plan.boundaries[0].clone();
        for action in &plan.rounds[0].lifecycle {
            start = step(config, &start, *action)?;
        }
        for (bit, id) in starters.iter().enumerate() {
            let c = start.controller_mut(*id);
            if mask & (1 << bit) != 0 && c.is_up() && c.phase == Phase::Initializing {
                c.window_quiet_rounds = 1.min(config.window_rounds);
            }
        }
        let mut rest = plan.rounds.clone();
        rest[0].lifecycle.clear();
        let states = run_rounds(config, start, &rest)?;
        let got: Vec<AbstractState> = states.iter().map(abstract_state).collect();
        // Boundary 0 is before round 0's starts and crashes; compare from boundary 1.
        if got.get(1..) != expected.get(1..) {
            let late: Vec<String> = starters
                .iter()
                .enumerate()
                .filter(|(bit, _)| mask & (1 << bit) != 0)
                .map(|(_, id)| format!("C{id}"))
                .collect();
            return Err(PlanError::DiscoveryAtStart {
                late: late.join(", "),
            });
        }
    }
    Ok(())
}

/// A process started after round 0 is heard once discovered: not in the round it starts (as
/// the model's join is), but one or two rounds later; it must settle the same way. So must a
/// controller whose cables are plugged back in ([`Plan::newcomers`]).
fn check_discovery_after_late_starts(plan: &Plan) -> Result<(), PlanError> {
    let config = &plan.config;
    let last = plan.expected(plan.last());
    for k in 1..plan.rounds.len() {
        let newcomers = plan.newcomers(k);
        if newcomers.is_empty() {
            continue;
        }
        for delay in 0..=1usize {
            let delayed = muted_rounds(plan, k, &newcomers, delay);
            let states =
                run_rounds(config, plan.boundaries[k].clone(), &delayed).map_err(|cause| {
                    PlanError::LateDiscoveryRun {
                        newcomers: format!("C{newcomers:?}"),
                        cause: Box::new(cause),
                    }
                })?;
            let settled = states.last().map(abstract_state);
            if settled.as_ref() != Some(&last) {
                return Err(PlanError::DiscoveryAfterLateStart {
                    round: k,
                    rounds: delay + 1,
                });
            }
        }
    }
    Ok(())
}

/// The plan's rounds from `k` on, with the newcomers' links lost in round `k` and in `delay`
/// more rounds inserted after it.
fn muted_rounds(plan: &Plan, k: usize, newcomers: &[u8], delay: usize) -> Vec<RoundPlan> {
    let mut rounds: Vec<RoundPlan> = plan.rounds[k..].to_vec();
    let mut muted = RoundPlan::default();
    for newcomer in newcomers {
        for other in plan.config.ids().filter(|o| o != newcomer) {
            muted.lost.insert((*newcomer, other));
            muted.lost.insert((other, *newcomer));
        }
    }
    // The start's own round and `delay` more rounds without the newcomer's links.
    let mut first = rounds.remove(0);
    first.lost.extend(muted.lost.iter().copied());
    let mut delayed = vec![first];
    for _ in 0..delay {
        delayed.push(muted.clone());
    }
    delayed.extend(rounds);
    delayed
}
