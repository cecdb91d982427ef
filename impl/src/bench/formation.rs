//! Formation: two controllers start, the third 300 ms later; timed from the third's start
//! (its first heartbeat goes out at start) to the Primary commanding at 30 and to all three
//! steady, and from its first heartbeat that the bench's own DDS reader heard (discovery of
//! a new participant takes part of the first figure).

use super::stats::Summary;
use super::watch::Watch;
use super::{BenchError, Setup};
use crate::procs::wall_ms;
use rl_layer::core::{ControllerId, Role};
use rl_layer::dds::Reader;
use rl_layer::wire::HeartbeatSample;
use serde::Serialize;
use std::time::Duration;

const FORMATION_TIMEOUT: Duration = Duration::from_secs(15);
/// The controller that starts last.
const THIRD: ControllerId = 3;

/// Why a formation run gave no figures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FormationFailure {
    /// Not all three steady within the timeout.
    NotFormed,
    /// The third controller printed no `started` event.
    NoStartSeen,
    /// Nobody commanded at 30.
    NoPrimary,
}

/// One formation run and what it measured.
#[derive(Clone, Debug, Serialize)]
pub struct FormationSample {
    /// 1-based.
    pub run: u32,
    pub primary_ms: Option<u64>,
    pub all_steady_ms: Option<u64>,
    pub primary_after_first_heartbeat_ms: Option<u64>,
    pub failure: Option<FormationFailure>,
}

#[derive(Clone, Debug, Serialize)]
pub struct FormationResult {
    /// From the third controller's process start to the Primary commanding at 30.
    pub primary_ms: Summary,
    pub all_steady_ms: Summary,
    /// From the first heartbeat of the third controller that the bench's own DDS reader
    /// received.
    pub primary_after_first_heartbeat_ms: Summary,
    pub primary_after_first_heartbeat_over_period_p50: f64,
    pub runs: u32,
    pub failed_formations: u32,
    pub samples: Vec<FormationSample>,
}

impl FormationResult {
    fn of(period_ms: u64, samples: Vec<FormationSample>) -> FormationResult {
        let after_heartbeat =
            Summary::of_measured(samples.iter().map(|s| s.primary_after_first_heartbeat_ms));
        FormationResult {
            primary_ms: Summary::of_measured(samples.iter().map(|s| s.primary_ms)),
            all_steady_ms: Summary::of_measured(samples.iter().map(|s| s.all_steady_ms)),
            primary_after_first_heartbeat_over_period_p50: after_heartbeat.p50
                / period_ms.max(1) as f64,
            primary_after_first_heartbeat_ms: after_heartbeat,
            runs: samples.len() as u32,
            failed_formations: samples.iter().filter(|s| s.failure.is_some()).count() as u32,
            samples,
        }
    }
}

/// Times `runs` fresh formations.
pub fn formation(setup: &Setup, runs: u32) -> Result<FormationResult, BenchError> {
    let config = setup.write_config("formation.toml", "")?;
    let listener_config = rl_layer::config::Config {
        dds: rl_layer::config::Dds {
            domain: setup.domain,
            ..Default::default()
        },
        ..Default::default()
    };
    let session = rl_layer::dds::Session::new(&listener_config.dds, &listener_config.timing)?;
    let mut heartbeats = session.heartbeat_reader()?;
    let mut samples = Vec::new();
    for run in 1..=runs {
        let sample = form_once(setup, &config, &mut heartbeats, run)?;
        eprintln!(
            "formation {run}/{runs}: primary {} ms, all {} ms, after the first heartbeat {} ms{}",
            shown_ms(sample.primary_ms),
            shown_ms(sample.all_steady_ms),
            shown_ms(sample.primary_after_first_heartbeat_ms),
            sample
                .failure
                .map(|f| format!(", FAILED: {f:?}"))
                .unwrap_or_default()
        );
        samples.push(sample);
        // Let the old participants' traffic die down before the next run.
        std::thread::sleep(Duration::from_millis(500));
    }
    Ok(FormationResult::of(setup.heartbeat_period_ms, samples))
}

fn form_once(
    setup: &Setup,
    config: &std::path::Path,
    heartbeats: &mut Reader<HeartbeatSample>,
    run: u32,
) -> Result<FormationSample, BenchError> {
    let (mut fleet, mut watch) = setup.fleet(config);
    setup.start_controller(&mut fleet, 1)?;
    setup.start_controller(&mut fleet, 2)?;
    watch.pump(Duration::from_millis(300));
    let _ = heartbeats.take();
    setup.start_controller(&mut fleet, THIRD)?;
    let mut first_heard: Option<u64> = None;
    let formed = watch.wait(FORMATION_TIMEOUT, |w: &Watch| {
        if first_heard.is_none() && heartbeats.take().iter().any(|h| h.value.id == THIRD) {
            first_heard = Some(wall_ms());
        }
        w.all_steady(&[1, 2, THIRD])
    });
    fleet.stop_all();
    let third_started = watch
        .started
        .iter()
        .find(|(id, _)| *id == THIRD)
        .map(|(_, t)| *t);
    let primary_at = watch
        .outputs
        .iter()
        .find(|o| o.strength == Some(Role::Primary.strength()))
        .map(|o| o.t_ms);
    let last_output = watch.outputs.iter().map(|o| o.t_ms).max();
    let failure = match (formed, third_started, primary_at) {
        (false, _, _) => Some(FormationFailure::NotFormed),
        (true, None, _) => Some(FormationFailure::NoStartSeen),
        (true, Some(_), None) => Some(FormationFailure::NoPrimary),
        (true, Some(_), Some(_)) => None,
    };
    let since = |from: Option<u64>, to: Option<u64>| match (failure, from, to) {
        (None, Some(from), Some(to)) => Some(to.saturating_sub(from)),
        _ => None,
    };
    Ok(FormationSample {
        run,
        primary_ms: since(third_started, primary_at),
        all_steady_ms: since(third_started, last_output),
        primary_after_first_heartbeat_ms: since(first_heard, primary_at),
        failure,
    })
}

/// A measured duration, or `-` where it was not measured.
pub(super) fn shown_ms(ms: Option<u64>) -> String {
    ms.map_or("-".into(), |ms| ms.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_formations_are_counted_and_left_out_of_the_figures() {
        let ok = FormationSample {
            run: 1,
            primary_ms: Some(500),
            all_steady_ms: Some(520),
            primary_after_first_heartbeat_ms: Some(400),
            failure: None,
        };
        let failed = FormationSample {
            run: 2,
            primary_ms: None,
            all_steady_ms: None,
            primary_after_first_heartbeat_ms: None,
            failure: Some(FormationFailure::NotFormed),
        };
        let result = FormationResult::of(250, vec![ok, failed]);
        assert_eq!((result.runs, result.failed_formations), (2, 1));
        assert_eq!(result.primary_ms.count, 1);
        assert_eq!(result.primary_after_first_heartbeat_over_period_p50, 1.6);
    }
}
