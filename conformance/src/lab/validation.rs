//! The recorded controller events of a run checked against the model, by the same trace
//! validation `validate-run` does (`crate::validate`). Each life's events are written to
//! `events/C1.log`, `events/C1#2.log`, ... in the run's directory, with `t_ms` taken back by
//! whole periods of a life's clock error (an offset, or what a fast clock has gained), onto
//! the rounds the controllers share (the model's rounds; `Life::round_clock_correction_ms`), so
//! `cargo run --release -p conformance --bin validate-run -- DIR/events` repeats the check.

use super::error::LabError;
use super::observe::Observations;
use super::procs::Life;
use crate::record::Recording;
use crate::validate::{self, Timing};
use std::io::Write;
use std::path::Path;

/// The recording's verdict: `Ok(summary)` or `Err(why)`.
pub type Verdict = Result<String, String>;

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
        for event in observed
            .controller
            .iter()
            .filter(|e| e.life == life.label())
        {
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
        .map_err(|e| e.to_string())?;
    let recording = Recording::read_dir(dir).map_err(|e| e.to_string())?;
    match validate::validate(&recording, &timing) {
        Ok(accepted) => Ok(accepted.to_string()),
        Err(rejection) => Err(rejection.to_string()),
    }
}
