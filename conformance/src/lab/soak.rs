//! `soak --minutes M`: one system under random faults for M minutes, cycle after cycle (a
//! seeded random schedule, then a fault-free liveness phase that must settle), with each
//! controller's resident memory and open file descriptors sampled every minute. It fails on
//! any cycle's judge failure, on trace validation of the whole recording (left in
//! `OUT/soak-seedN/events/` with the samples in `resources.json`, and each failed cycle's
//! failures, timeline and measurements in `failed-cycles/cycle-K.txt`), or when a
//! controller's memory or descriptors grow faster than the thresholds below (least-squares
//! slope over its samples, the first minute left out as warm-up).
//!
//! Kills and clock offsets (which restart a controller) are left out of soak schedules: each
//! controller keeps one process for the whole soak, so its growth is measurable.

use super::error::LabError;
use super::expect;
use super::faults::Fault;
use super::judge;
use super::lan::CONTROLLER_IDS;
use super::run::{self, LIVENESS};
use super::scenario;
use super::session::{Session, Setup};
use super::validation;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

/// Growth that fails a soak: resident memory (MiB per minute) and open descriptors (per
/// minute), least-squares slopes over the samples after the first minute.
pub const RSS_SLOPE_LIMIT_MIB_PER_MIN: f64 = 1.0;
pub const FD_SLOPE_LIMIT_PER_MIN: f64 = 0.5;
const SAMPLE_EVERY: Duration = Duration::from_secs(60);

/// One controller's resources at one time.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Sample {
    pub at_min: f64,
    pub rss_mib: f64,
    pub fds: f64,
}

/// Resident memory (MiB) and open descriptors of process `pid`, from /proc.
pub fn resources(pid: u32) -> Option<(f64, f64)> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let rss_kib: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))?
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd")).ok()?.count();
    Some((rss_kib / 1024.0, fds as f64))
}

/// The least-squares slope of `(x, y)` points; `None` with fewer than three.
pub fn slope(points: &[(f64, f64)]) -> Option<f64> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mean_x, mean_y) = points
        .iter()
        .fold((0.0, 0.0), |(sx, sy), (x, y)| (sx + x / n, sy + y / n));
    let (mut covariance, mut variance) = (0.0, 0.0);
    for (x, y) in points {
        covariance += (x - mean_x) * (y - mean_y);
        variance += (x - mean_x) * (x - mean_x);
    }
    (variance > 0.0).then(|| covariance / variance)
}

/// Runs the soak, leaving its recording and samples in `OUT/soak-seedN/`; returns the
/// failures (empty: passed).
pub fn soak(minutes: u64, seed: u64, setup: &Setup, out: &Path) -> Result<Vec<String>, LabError> {
    let mut session = Session::start(setup)?;
    let started = Instant::now();
    let total = Duration::from_secs(minutes * 60);
    let mut samples: BTreeMap<u8, Vec<Sample>> = BTreeMap::new();
    let mut last_sample: Option<Instant> = None;
    let mut failures = Vec::new();
    // Each failed cycle's timeline, written beside the recording at the end.
    let mut failed_cycles: Vec<(u64, String)> = Vec::new();
    let mut cycle = 0u64;
    while started.elapsed() < total {
        let mut schedule = scenario::random(seed.wrapping_add(cycle));
        schedule.steps.retain(|s| {
            !matches!(
                s.fault,
                Fault::Kill(_) | Fault::ClockOffset(..) | Fault::ClockRate(..)
            )
        });
        // From the steps kept: each fault is judged on its own bound, in schedule order.
        let expected = expect::for_faults(schedule.steps.iter().map(|s| &s.fault));
        let cycle_from_ms = session.clock.now_ms();
        let first_fault = session.faults.len();
        session.play(&schedule.steps)?;
        sample_if_due(&session, started, &mut last_sample, &mut samples);
        session.pump(LIVENESS)?;
        sample_if_due(&session, started, &mut last_sample, &mut samples);
        let lives = session.procs.lives.clone();
        let faults = &session.faults[first_fault..];
        let mut metrics = judge::measure(
            &session.observed,
            &lives,
            faults,
            cycle_from_ms,
            session.clock.now_ms(),
            setup.architecture,
            setup.connext,
        );
        metrics.dead = session.dead();
        let cycle_failures = judge::failures(&metrics, &expected, Ok(()));
        if !cycle_failures.is_empty() {
            let measured = serde_json::to_string_pretty(&metrics).unwrap_or_default();
            failed_cycles.push((
                cycle,
                format!(
                    "{}\n{}\n{measured}\n",
                    cycle_failures.join("\n"),
                    run::timeline_of(faults, &metrics)
                ),
            ));
        }
        for failure in cycle_failures {
            let failure = format!(
                "cycle {cycle} (seed {}): {failure}",
                seed.wrapping_add(cycle)
            );
            eprintln!("lab soak: FAILED {failure}");
            failures.push(failure);
        }
        eprintln!(
            "lab soak: cycle {cycle} at {:.1} min: {} fault(s), {} failure(s) so far",
            started.elapsed().as_secs_f64() / 60.0,
            schedule.steps.len(),
            failures.len()
        );
        cycle += 1;
    }
    let lives = session.procs.lives.clone();
    session.stop()?;
    failures.extend(growth_failures(&samples));
    let dir = out.join(format!("soak-seed{seed}"));
    let _ = std::fs::remove_dir_all(&dir);
    validation::write_recording(&dir.join("events"), &session.observed, &lives)?;
    if let Err(why) = run::validate_with_timeout(dir.join("events")) {
        failures.push(format!("the model rejects the recorded events: {why}"));
    }
    for (failed, text) in &failed_cycles {
        let path = dir
            .join("failed-cycles")
            .join(format!("cycle-{failed}.txt"));
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| LabError::output(parent, e))?;
        }
        std::fs::write(&path, text).map_err(|e| LabError::output(&path, e))?;
    }
    let path = dir.join("resources.json");
    let text = serde_json::to_string_pretty(&samples).unwrap_or_default();
    std::fs::write(&path, text).map_err(|e| LabError::output(&path, e))?;
    Ok(failures)
}

fn sample_if_due(
    session: &Session,
    started: Instant,
    last: &mut Option<Instant>,
    samples: &mut BTreeMap<u8, Vec<Sample>>,
) {
    if last.is_some_and(|at| at.elapsed() < SAMPLE_EVERY) {
        return;
    }
    *last = Some(Instant::now());
    let at_min = started.elapsed().as_secs_f64() / 60.0;
    for id in CONTROLLER_IDS {
        if let Some((rss_mib, fds)) = session.procs.pid(id).and_then(resources) {
            eprintln!("lab soak: {at_min:.1} min C{id}: {rss_mib:.1} MiB resident, {fds} open fds");
            samples.entry(id).or_default().push(Sample {
                at_min,
                rss_mib,
                fds,
            });
        }
    }
}

/// A failure per controller whose memory or descriptors grew past the limits.
pub fn growth_failures(samples: &BTreeMap<u8, Vec<Sample>>) -> Vec<String> {
    let mut failures = Vec::new();
    for (id, series) in samples {
        let warm: Vec<&Sample> = series.iter().filter(|s| s.at_min >= 1.0).collect();
        let rss: Vec<(f64, f64)> = warm.iter().map(|s| (s.at_min, s.rss_mib)).collect();
        let fds: Vec<(f64, f64)> = warm.iter().map(|s| (s.at_min, s.fds)).collect();
        let show = |s: Option<f64>| s.map_or("-".into(), |s| format!("{s:.3}"));
        eprintln!(
            "lab soak: C{id}: resident memory {} MiB/min, open descriptors {}/min ({} samples after the first minute)",
            show(slope(&rss)),
            show(slope(&fds)),
            warm.len()
        );
        if let Some(growth) = slope(&rss).filter(|g| *g > RSS_SLOPE_LIMIT_MIB_PER_MIN) {
            failures.push(format!("C{id}: resident memory grows {growth:.2} MiB/min (limit {RSS_SLOPE_LIMIT_MIB_PER_MIN})"));
        }
        if let Some(growth) = slope(&fds).filter(|g| *g > FD_SLOPE_LIMIT_PER_MIN) {
            failures.push(format!(
                "C{id}: open descriptors grow {growth:.2}/min (limit {FD_SLOPE_LIMIT_PER_MIN})"
            ));
        }
    }
    failures
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_is_least_squares() {
        assert_eq!(slope(&[(0.0, 1.0), (1.0, 3.0), (2.0, 5.0)]), Some(2.0));
        assert_eq!(slope(&[(0.0, 1.0), (1.0, 3.0)]), None);
    }

    #[test]
    fn growth_past_the_limit_fails_and_flat_series_pass() {
        let series = |rss: f64| {
            (0..5)
                .map(|m| Sample {
                    at_min: m as f64,
                    rss_mib: 20.0 + rss * m as f64,
                    fds: 30.0,
                })
                .collect()
        };
        let samples = BTreeMap::from([(1, series(0.1)), (2, series(3.0))]);
        let failures = growth_failures(&samples);
        assert_eq!(failures.len(), 1);
        assert!(failures[0].starts_with("C2: resident memory grows 3.00"));
    }
}
