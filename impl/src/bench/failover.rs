//! Failover: `kill -9` of the Primary, repeatedly, at one command deadline. Each kill lands
//! at a seeded random phase of the heartbeat round (promotion depends on it: the survivors
//! decide at round boundaries). Measured per kill: the command gap at the servo, the time to
//! the Secondary's promotion (its output at 30, and its status steady as Primary), and how
//! often the servo's owner changed controller; then the killed controller is restarted and the
//! next kill waits until all three are steady again.

use super::stats::{SplitMix64, Summary};
use super::watch::{OwnerChange, Watch};
use super::{BenchError, Setup};
use crate::procs::{wall_ms, Fleet};
use rl_layer::core::{ControllerId, Phase, Role};
use serde::Serialize;
use std::time::{Duration, Instant};

/// The reader that measures the command gap: `rl servo`, whose arbiter applies exclusive
/// ownership with the command deadline (`owner_changed.gap_ms`).
pub const GAP_READER: &str = "rl servo (arbiter)";

/// How long a formation, a promotion or a rejoin may take before it counts as failed.
const FORMATION_TIMEOUT: Duration = Duration::from_secs(20);
const PROMOTION_TIMEOUT: Duration = Duration::from_secs(10);
const REJOIN_TIMEOUT: Duration = Duration::from_secs(10);
/// After the rejoin, a little longer for late owner changes (a tie while writers are
/// re-created) to reach the count.
const OWNER_CHANGES_SETTLE: Duration = Duration::from_millis(250);

/// Why a kill did not give its figures, or left the fleet broken.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum KillFailure {
    /// Before the kill, no steady Primary and Secondary to kill and promote.
    NoPrimaryAndSecondary,
    /// The Secondary did not command at 30 within the timeout.
    NotPromoted,
    /// The servo reported no owner change away from the killed Primary.
    NoSwitchAtServo,
    /// The servo followed another controller than the Secondary.
    SwitchedPastTheSecondary,
    /// The restarted controller and the others were not all steady within the timeout.
    NotRejoined,
    /// The servo's owner changed more than once for the one kill (a blip or a failback).
    MoreThanOneOwnerChange,
    /// The command gap was over [`GAP_OVER_DEADLINE_MAX_PERCENT`] % of the deadline.
    GapOverDeadline,
}

/// The most a kill's command gap may be, in percent of the command deadline (1.15 ×): the
/// deadline, then the next writer's first sample within one re-publish period (a tenth of the
/// deadline), plus scheduling (docs/performance.md, "Why the command gap is the deadline").
/// In integers: 1.15 × 100 is a hair under 115 in floating point.
pub const GAP_OVER_DEADLINE_MAX_PERCENT: u64 = 115;

/// What a kill that did switch broke of RL's promise to the actuator: one owner change per
/// fault, within [`GAP_OVER_DEADLINE_MAX_PERCENT`] % of the deadline.
pub(super) fn broken_promise(
    owner_changes: u32,
    gap_ms: Option<u64>,
    deadline_ms: u64,
) -> Option<KillFailure> {
    if owner_changes > 1 {
        return Some(KillFailure::MoreThanOneOwnerChange);
    }
    match gap_ms {
        Some(gap_ms) if gap_ms * 100 > GAP_OVER_DEADLINE_MAX_PERCENT * deadline_ms => {
            Some(KillFailure::GapOverDeadline)
        }
        _ => None,
    }
}

/// One kill and what it measured.
#[derive(Clone, Debug, Serialize)]
pub struct KillSample {
    /// 1-based.
    pub kill: u32,
    pub killed: Option<ControllerId>,
    /// Milliseconds into the heartbeat round (wall clock) when the kill was sent.
    pub phase_ms: Option<u64>,
    pub gap_ms: Option<u64>,
    /// The controller the servo followed next (the Secondary, unless something is wrong).
    pub switched_to: Option<ControllerId>,
    /// From the kill to the Secondary's `output` event at strength 30.
    pub promotion_ms: Option<u64>,
    /// From the kill to the Secondary's status reporting it steady as Primary at 30.
    pub steady_ms: Option<u64>,
    /// Owner changes from one controller to another at the servo, from the kill until all
    /// three are steady again (one, the switch to the Secondary, unless the actuator moved
    /// more than once).
    pub owner_changes: u32,
    /// Controllers found FAILED (or exited) when the rejoin failed, restarted so that the next
    /// kill finds three controllers again.
    pub restarted: Vec<ControllerId>,
    pub failure: Option<KillFailure>,
    /// The camera's tracking error (pixels off centre) at its worst in the 2 s before the
    /// kill and in the 2 s after: what the kill did to the ball's place in the frame.
    pub tracking_error_before_max_px: Option<f64>,
    pub tracking_error_after_max_px: Option<f64>,
    /// Frames without the ball in the 2 s after the kill.
    pub frames_unseen_after: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct FailoverResult {
    pub deadline_ms: u64,
    pub command_republish_ms: u64,
    /// Who measured `gap_ms`.
    pub gap_reader: &'static str,
    pub gap_ms: Summary,
    pub gap_over_deadline_p50: f64,
    pub gap_over_deadline_p99: f64,
    pub gap_over_deadline_max: f64,
    pub promotion_ms: Summary,
    pub promotion_over_period_p50: f64,
    pub promotion_over_period_p99: f64,
    /// From the kill to the new Primary's status steady at 30.
    pub steady_ms: Summary,
    /// The most owner changes at the servo after one kill.
    pub owner_changes_max: u32,
    /// Kills after which the servo's owner changed controller more than once.
    pub kills_with_more_than_one_owner_change: u32,
    /// Controllers restarted after a failed rejoin (see [`KillSample::restarted`]).
    pub controllers_restarted: u32,
    pub kills: u32,
    pub failed_kills: u32,
    /// The camera's tracking error over every frame of the run (pixels off centre; the
    /// camera closes the loop through the gimbal, crate::sim::gimbal).
    pub tracking_error_px: Summary,
    /// Per kill, the worst tracking error in the 2 s before it and in the 2 s after.
    pub tracking_error_before_kill_max_px: Summary,
    pub tracking_error_after_kill_max_px: Summary,
    /// Frames in the run that did not see the ball.
    pub frames_unseen: usize,
    pub samples: Vec<KillSample>,
}

impl FailoverResult {
    fn of(
        deadline_ms: u64,
        republish_ms: u64,
        period_ms: u64,
        samples: Vec<KillSample>,
        (tracking_errors, frames_unseen): (Vec<f64>, usize),
    ) -> Self {
        let worst = |pick: fn(&KillSample) -> Option<f64>| {
            Summary::of(&samples.iter().filter_map(pick).collect::<Vec<f64>>())
        };
        let gap = Summary::of_measured(samples.iter().map(|s| s.gap_ms));
        let promotion = Summary::of_measured(samples.iter().map(|s| s.promotion_ms));
        let period = period_ms.max(1) as f64;
        let deadline = deadline_ms.max(1) as f64;
        FailoverResult {
            deadline_ms,
            command_republish_ms: republish_ms,
            gap_reader: GAP_READER,
            gap_over_deadline_p50: gap.p50 / deadline,
            gap_over_deadline_p99: gap.p99 / deadline,
            gap_over_deadline_max: gap.max / deadline,
            gap_ms: gap,
            promotion_over_period_p50: promotion.p50 / period,
            promotion_over_period_p99: promotion.p99 / period,
            promotion_ms: promotion,
            steady_ms: Summary::of_measured(samples.iter().map(|s| s.steady_ms)),
            owner_changes_max: samples.iter().map(|s| s.owner_changes).max().unwrap_or(0),
            kills_with_more_than_one_owner_change: samples
                .iter()
                .filter(|s| s.owner_changes > 1)
                .count() as u32,
            controllers_restarted: samples.iter().map(|s| s.restarted.len() as u32).sum(),
            kills: samples.len() as u32,
            failed_kills: samples.iter().filter(|s| s.failure.is_some()).count() as u32,
            tracking_error_px: Summary::of(&tracking_errors),
            tracking_error_before_kill_max_px: worst(|s| s.tracking_error_before_max_px),
            tracking_error_after_kill_max_px: worst(|s| s.tracking_error_after_max_px),
            frames_unseen,
            samples,
        }
    }
}

/// Kills the Primary `kills` times at command deadline `deadline_ms`, each at a phase drawn
/// from `phases`.
pub fn failover(
    setup: &Setup,
    deadline_ms: u64,
    kills: u32,
    phases: &mut SplitMix64,
) -> Result<FailoverResult, BenchError> {
    // The next writer's first sample lands up to one re-publish period after the deadline:
    // re-publishing at a tenth of the deadline keeps the gap within 1.1 x the deadline.
    let republish_ms = (deadline_ms / 10).max(1);
    let config = setup.write_config(
        &format!("failover-{deadline_ms}.toml"),
        &format!(
            "[timing]\ninit_window_ms = 1000\ncommand_deadline_ms = {deadline_ms}\ncommand_republish_ms = {republish_ms}\n"
        ),
    )?;
    let (mut fleet, mut watch) = setup.fleet(&config);
    setup.start_app(&mut fleet, "servo", &["servo", "--json"])?;
    setup.start_app(&mut fleet, "camera", &["shapes", "--json"])?;
    for id in 1..=3 {
        setup.start_controller(&mut fleet, id)?;
    }
    let formed = |w: &Watch| w.formed() && w.owner.is_some();
    if !watch.wait(FORMATION_TIMEOUT, formed) {
        return Err(BenchError::NoFormation {
            run: format!("failover run at deadline {deadline_ms} ms"),
            timeout_s: FORMATION_TIMEOUT.as_secs(),
        });
    }
    let period_ms = setup.heartbeat_period_ms;
    // The gimbal catches the ball first (it starts centred, the ball anywhere on its path).
    watch.pump(GIMBAL_SETTLE);
    let measuring_from = Instant::now();
    let mut samples = Vec::new();
    for kill in 1..=kills {
        let phase_ms = phases.below(period_ms);
        let mut sample = kill_once(setup, &mut fleet, &mut watch, kill, phase_ms)?;
        sample.failure = sample
            .failure
            .or_else(|| broken_promise(sample.owner_changes, sample.gap_ms, deadline_ms));
        eprintln!(
            "deadline {deadline_ms} ms, kill {kill}/{kills}: C{} killed {} ms into the round, gap {} ms ({GAP_READER}), promotion {} ms, steady {} ms, owner changes {}{}{}",
            sample.killed.map_or("-".into(), |id| id.to_string()),
            sample.phase_ms.map_or("-".into(), |p| p.to_string()),
            super::formation::shown_ms(sample.gap_ms),
            super::formation::shown_ms(sample.promotion_ms),
            super::formation::shown_ms(sample.steady_ms),
            sample.owner_changes,
            sample
                .restarted
                .iter()
                .map(|id| format!(", C{id} FAILED, restarted"))
                .collect::<String>(),
            sample
                .failure
                .map(|f| format!(", FAILED: {f:?}"))
                .unwrap_or_default()
        );
        samples.push(sample);
    }
    let tracking = watch.tracking_errors(measuring_from, Instant::now());
    fleet.stop_all();
    Ok(FailoverResult::of(
        deadline_ms,
        republish_ms,
        period_ms,
        samples,
        tracking,
    ))
}

/// How long the camera's loop runs before the first kill.
const GIMBAL_SETTLE: Duration = Duration::from_secs(3);

/// How long before and after a kill the camera's tracking error is compared.
const TRACKING_WINDOW: Duration = Duration::from_secs(2);

/// The next instant the wall clock is `phase_ms` into a heartbeat round (controllers' rounds
/// start at multiples of the period on the wall clock).
fn next_phase(phase_ms: u64, period_ms: u64) -> Instant {
    Instant::now() + Duration::from_millis(ms_until_phase(wall_ms(), phase_ms, period_ms))
}

/// From wall-clock `now_ms`, the wait until `phase_ms` into a round of `period_ms`
/// (`0..period_ms`).
fn ms_until_phase(now_ms: u64, phase_ms: u64, period_ms: u64) -> u64 {
    let period_ms = period_ms.max(1);
    (phase_ms % period_ms + period_ms - now_ms % period_ms) % period_ms
}

/// One kill of the Primary at `phase_ms` into a round, its measurements, the restart and the
/// wait for all three steady.
fn kill_once(
    setup: &Setup,
    fleet: &mut Fleet,
    watch: &mut Watch,
    kill: u32,
    phase_ms: u64,
) -> Result<KillSample, BenchError> {
    let mut sample = KillSample {
        kill,
        killed: None,
        phase_ms: None,
        gap_ms: None,
        switched_to: None,
        promotion_ms: None,
        steady_ms: None,
        owner_changes: 0,
        restarted: Vec::new(),
        failure: None,
        tracking_error_before_max_px: None,
        tracking_error_after_max_px: None,
        frames_unseen_after: 0,
    };
    watch.pump(Duration::from_millis(500));
    let (Some(primary), Some(secondary)) =
        (watch.holder(Role::Primary), watch.holder(Role::Secondary))
    else {
        sample.failure = Some(KillFailure::NoPrimaryAndSecondary);
        return Ok(sample);
    };
    watch.pump_until(next_phase(phase_ms, setup.heartbeat_period_ms));
    let changes_before = watch.owner_changes.len();
    let outputs_before = watch.outputs.len();
    let steady_before = watch.steady_primary.len();
    let killed_ms = wall_ms();
    let killed_at = Instant::now();
    fleet
        .kill(primary)
        .map_err(|source| BenchError::io(format!("kill -9 of controller {primary}"), source))?;
    sample.killed = Some(primary);
    sample.phase_ms = Some(killed_ms % setup.heartbeat_period_ms.max(1));
    watch.status.remove(&primary);
    let promoted_at = |w: &Watch| {
        w.outputs[outputs_before..]
            .iter()
            .find(|o| o.id == secondary && o.strength == Some(Role::Primary.strength()))
            .map(|o| o.t_ms)
    };
    let steady_at = |w: &Watch| {
        w.steady_primary[steady_before..]
            .iter()
            .find(|(id, _)| *id == secondary)
            .map(|(_, t_ms)| *t_ms)
    };
    let switched = |w: &Watch| {
        w.owner_changes[changes_before..]
            .iter()
            .find(|c| c.from == Some(primary))
            .copied()
    };
    watch.wait(PROMOTION_TIMEOUT, |w| {
        promoted_at(w).is_some() && steady_at(w).is_some() && switched(w).is_some()
    });
    sample.promotion_ms = promoted_at(watch).map(|t| t.saturating_sub(killed_ms));
    sample.steady_ms = steady_at(watch).map(|t| t.saturating_sub(killed_ms));
    let switch = switched(watch);
    sample.gap_ms = switch.and_then(|c| c.gap_ms);
    sample.switched_to = switch.and_then(|c| c.to);
    sample.failure = if sample.promotion_ms.is_none() {
        Some(KillFailure::NotPromoted)
    } else if sample.gap_ms.is_none() {
        Some(KillFailure::NoSwitchAtServo)
    } else if sample.switched_to != Some(secondary) {
        Some(KillFailure::SwitchedPastTheSecondary)
    } else {
        None
    };
    watch.pump_until(killed_at + TRACKING_WINDOW);
    let worst = |errors: Vec<f64>| errors.into_iter().reduce(f64::max);
    let (before, _) = watch.tracking_errors(killed_at - TRACKING_WINDOW, killed_at);
    let (after, unseen_after) = watch.tracking_errors(killed_at, killed_at + TRACKING_WINDOW);
    sample.tracking_error_before_max_px = worst(before);
    sample.tracking_error_after_max_px = worst(after);
    sample.frames_unseen_after = unseen_after;
    setup.start_controller(fleet, primary)?;
    if !watch.wait(REJOIN_TIMEOUT, Watch::formed) {
        sample.failure = sample.failure.or(Some(KillFailure::NotRejoined));
        sample.restarted = restart_failed(setup, fleet, watch)?;
    }
    watch.pump(OWNER_CHANGES_SETTLE);
    sample.owner_changes = controller_changes(&watch.owner_changes[changes_before..]);
    Ok(sample)
}

/// Restarts every controller that reports itself FAILED or has exited (`kill -9` and a new
/// process, as the service manager would), then waits for all three steady; returns their ids.
/// Without it, one controller that failed itself would leave every later kill with two.
fn restart_failed(
    setup: &Setup,
    fleet: &mut Fleet,
    watch: &mut Watch,
) -> Result<Vec<ControllerId>, BenchError> {
    let mut failed: Vec<ControllerId> = Vec::new();
    for id in fleet.running().collect::<Vec<_>>() {
        let failed_itself = watch
            .status
            .get(&id)
            .is_some_and(|s| s.report.phase == Phase::Failed);
        if failed_itself || matches!(fleet.exit_status(id), Ok(Some(_))) {
            failed.push(id);
        }
    }
    for &id in &failed {
        fleet
            .kill(id)
            .map_err(|source| BenchError::io(format!("kill -9 of controller {id}"), source))?;
        watch.status.remove(&id);
        setup.start_controller(fleet, id)?;
    }
    if !failed.is_empty() {
        watch.wait(REJOIN_TIMEOUT, Watch::formed);
    }
    Ok(failed)
}

/// How many of `changes` moved the servo from one controller to another (a controller that
/// re-creates its writer at a new strength stays the owner).
pub(super) fn controller_changes(changes: &[OwnerChange]) -> u32 {
    changes.iter().filter(|c| c.from != c.to).count() as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(gap_ms: Option<u64>, failure: Option<KillFailure>) -> KillSample {
        KillSample {
            kill: 1,
            killed: Some(1),
            phase_ms: Some(10),
            gap_ms,
            switched_to: Some(2),
            promotion_ms: gap_ms.map(|g| g * 8),
            steady_ms: gap_ms.map(|g| g * 8),
            owner_changes: if failure.is_some() { 3 } else { 1 },
            restarted: Vec::new(),
            failure,
            tracking_error_before_max_px: Some(10.0),
            tracking_error_after_max_px: Some(20.0),
            frames_unseen_after: 0,
        }
    }

    #[test]
    fn failed_kills_are_counted_and_their_missing_figures_left_out() {
        let result = FailoverResult::of(
            100,
            10,
            250,
            vec![
                sample(Some(100), None),
                sample(None, Some(KillFailure::NotPromoted)),
                sample(Some(110), Some(KillFailure::NotRejoined)),
            ],
            (vec![4.0, 8.0, 30.0], 1),
        );
        assert_eq!((result.kills, result.failed_kills), (3, 2));
        assert_eq!(result.gap_ms.count, 2);
        assert_eq!(result.gap_over_deadline_p99, 1.1);
        assert_eq!(result.gap_over_deadline_max, 1.1);
        assert_eq!(result.steady_ms.max, 880.0);
        assert_eq!(
            (
                result.owner_changes_max,
                result.kills_with_more_than_one_owner_change
            ),
            (3, 2)
        );
        assert_eq!(result.promotion_over_period_p50, 3.2);
        assert_eq!(result.gap_reader, "rl servo (arbiter)");
        assert_eq!(result.tracking_error_px.max, 30.0);
        assert_eq!(result.frames_unseen, 1);
        assert_eq!(result.tracking_error_after_kill_max_px.max, 20.0);
    }

    #[test]
    fn a_kill_that_moves_the_actuator_twice_or_late_is_a_failed_kill() {
        // (owner changes, gap ms, deadline ms)
        // Measured figures: 110 ms at a 100 ms deadline is within 1.15 x; 116 ms is not.
        assert_eq!(broken_promise(1, Some(110), 100), None);
        assert_eq!(broken_promise(1, Some(115), 100), None);
        assert_eq!(
            broken_promise(1, Some(116), 100),
            Some(KillFailure::GapOverDeadline)
        );
        assert_eq!(broken_promise(1, Some(23), 20), None);
        assert_eq!(
            broken_promise(1, Some(24), 20),
            Some(KillFailure::GapOverDeadline)
        );
        // A blip: the servo followed the Tertiary for a moment, then the new Primary.
        assert_eq!(
            broken_promise(2, Some(104), 100),
            Some(KillFailure::MoreThanOneOwnerChange)
        );
    }

    #[test]
    fn a_writer_re_created_by_its_owner_is_no_owner_change() {
        let change = |from, to| OwnerChange {
            gap_ms: Some(100),
            from: Some(from),
            to: Some(to),
        };
        // The switch to the Secondary, its writer re-created at 30, a tie blip to the
        // Tertiary and back.
        let changes = [change(1, 2), change(2, 2), change(2, 3), change(3, 2)];
        assert_eq!(controller_changes(&changes[..2]), 1);
        assert_eq!(controller_changes(&changes), 3);
    }

    #[test]
    fn a_kill_waits_for_its_phase_of_the_round() {
        assert_eq!(ms_until_phase(1000, 10, 250), 10);
        assert_eq!(ms_until_phase(1010, 10, 250), 0);
        assert_eq!(ms_until_phase(1011, 10, 250), 249);
        assert_eq!(ms_until_phase(1249, 0, 250), 1);
        for now_ms in 5000..5250 {
            assert_eq!((now_ms + ms_until_phase(now_ms, 137, 250)) % 250, 137);
        }
    }
}
