//! The recorded controller events of a run checked against the model, by the same trace
//! validation `validate-run` does (`crate::validate`). Each life's events are written to
//! `events/C1.log`, `events/C1#2.log`, ... in the run's directory, with `t_ms` taken back by
//! whole periods of a life's clock error (an offset, or what a fast clock has gained), onto
//! the rounds the controllers share (the model's rounds; `Life::round_clock_correction_ms`), so
//! `cargo run --release -p conformance --bin validate-run -- DIR/events` repeats the check.
//!
//! A life that found itself the odd one out of three (its `odd_one_out` event: its commands
//! wrong, its role and heartbeats right) ends there in the recording: to the role model a
//! controller that leaves on a local fault is a crash, and its restart a new life
//! (docs/protocol.md, "Output voting"); the role model has no local faults.

use super::error::LabError;
use super::observe::Observations;
use super::procs::Life;
use crate::record::{RecordError, Recording};
use crate::validate::{self, Accepted, Rejection, Timing, TimingError};
use rl_layer::event::Event;
use std::io::Write;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

/// The recording's verdict: accepted by the model (with the search's size), or why not.
pub type Verdict = Result<Accepted, NotAccepted>;

/// Why a run's recording was not accepted.
#[derive(Clone, Debug, thiserror::Error)]
pub enum NotAccepted {
    /// RL's default timing cannot be checked against the model.
    #[error("rl's default timing: {0}")]
    Timing(Arc<TimingError>),
    /// The recorded events could not be read.
    #[error(transparent)]
    Recording(Arc<RecordError>),
    /// The model does not explain the run.
    #[error("{0}")]
    Rejected(Rejection),
    /// The search did not finish in time.
    #[error("did not finish within {} s", .0.as_secs())]
    TimedOut(Duration),
    /// Not checked: the run's controllers ran another architecture than the voting rules the
    /// trace validation knows (its rules are checked by `model check --architecture`).
    #[error("not checked: the {0}'s rules are the model's `check --architecture {0}`, the trace validation is voting's")]
    NotVoting(&'static str),
}

/// The verdict in `result.json`: `{"accepted": summary}` or `{"rejected": why}`.
pub fn serialize_verdict<S: serde::Serializer>(
    verdict: &Verdict,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut map = serializer.serialize_map(Some(1))?;
    match verdict {
        Ok(accepted) => map.serialize_entry("accepted", &accepted.to_string())?,
        Err(why) => map.serialize_entry("rejected", &why.to_string())?,
    }
    map.end()
}

/// Writes every life's events under `dir` (created).
pub fn write_recording(
    dir: &Path,
    observed: &Observations,
    lives: &[Life],
) -> Result<(), LabError> {
    std::fs::create_dir_all(dir).map_err(|e| LabError::output(dir, e))?;
    for life in lives {
        let path = dir.join(format!("{}.log", life.label()));
        let mut file = std::fs::File::create(&path).map_err(|e| LabError::output(&path, e))?;
        let label = life.label();
        let events = observed.controller.iter().filter(|e| e.life == label);
        for event in events.take_while(|e| !matches!(e.line.event, Event::OddOneOut { .. })) {
            let mut line = event.line.clone();
            line.t_ms = line
                .t_ms
                .saturating_add_signed(-life.round_clock_correction_ms(line.t_ms));
            writeln!(file, "{}", line.to_json()).map_err(|e| LabError::output(&path, e))?;
        }
    }
    Ok(())
}

/// Validates the recording in `dir` against the model with `rl`'s default timing.
pub fn validate_recording(dir: &Path) -> Verdict {
    let timing = Timing::from_config(&rl_layer::config::Config::default().timing)
        .map_err(|e| NotAccepted::Timing(Arc::new(e)))?;
    let recording = Recording::read_dir(dir).map_err(|e| NotAccepted::Recording(Arc::new(e)))?;
    validate::validate(&recording, &timing).map_err(|rejection| NotAccepted::Rejected(*rejection))
}
