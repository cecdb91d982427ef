//! The plan's timing assumptions, checked against the model: a trace is replayed on real
//! processes only if the ways real timing departs from the model's cannot change its outcome.
//!
//! - its states are the same under the run's round lengths (checked while the plan is
//!   built);
//! - faults after a pulled cable is plugged back in wait for a quiescent boundary;
//! - a controller whose cables are plugged back in ends in the same settled state if it is
//!   heard one or two rounds later.
//!
//! DDS discovery is no assumption: every process is discovered before it votes (held, see
//! [`super::config`]).

use super::plan::{run_rounds, Mode, Plan, PlanError, RoundPlan};
use model::traces::abstract_state;

/// Every timing assumption of `plan`, checked against the model.
pub(super) fn check_timing(plan: &Plan) -> Result<(), PlanError> {
    if plan.boundaries.len() < 2 {
        return Err(PlanError::NoRoundEnds);
    }
    check_no_faults_while_free(plan)?;
    check_heard_late_after_replug(plan)
}

/// Faults after a pulled cable is plugged back in must wait for a quiescent boundary.
fn check_no_faults_while_free(plan: &Plan) -> Result<(), PlanError> {
    let modes = plan.modes();
    for (k, round) in plan.rounds.iter().enumerate().skip(1) {
        if !round.is_empty() && modes[k] == Mode::Free {
            return Err(PlanError::FaultsAfterReplug { round: k });
        }
    }
    Ok(())
}

/// A controller whose cables are plugged back in ([`Plan::newcomers`]) is heard once its
/// neighbours are resolved again: not in the round of the heal (as in the model), but one or
/// two rounds later; it must settle the same way.
fn check_heard_late_after_replug(plan: &Plan) -> Result<(), PlanError> {
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
                    PlanError::ReplugHeardLateRun {
                        newcomers: format!("C{newcomers:?}"),
                        cause: Box::new(cause),
                    }
                })?;
            let settled = states.last().map(abstract_state);
            if settled.as_ref() != Some(&last) {
                return Err(PlanError::ReplugHeardLate {
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
