//! What a wrong-output run leaves beside every run's output (`super::super::run`): in its
//! directory `voter.log` (the voting reader's decisions, in time order, to read a failure by)
//! and `tracking.json` (the camera's frames, which `lab figure` draws with other runs'), and
//! its tracking figure `OUT/NAME-seedN-tracking.svg`.

use super::{readings, tracking};
use crate::lab::error::LabError;
use crate::lab::observe::Observations;

/// A wrong-output run's own outputs: in its directory `dir`, `tracking.json` (every camera
/// frame, as seconds since the fault and px off centre) and `voter.log` (the voting reader's
/// decisions in time order), and the tracking figure at `figure`.
pub fn write_outputs(
    dir: &std::path::Path,
    figure: &std::path::Path,
    outcome: &crate::lab::run::Outcome,
    observed: &Observations,
) -> Result<(), LabError> {
    let write = |name: &str, text: String| {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| LabError::output(&path, e))
    };
    write("voter.log", voter_log(&observed.outputs))?;
    let applied_ms = outcome.faults.first().map_or(0.0, |f| f.applied_ms);
    let (label, points) = tracking::series(&outcome.scenario, &observed.outputs.frames, applied_ms);
    let json = serde_json::json!({ "scenario": label, "seed": outcome.seed, "frames": points });
    write("tracking.json", json.to_string())?;
    let last_s = points.last().map_or(1.0, |p| p.0);
    let title = format!(
        "{} (seed {}): the ball off centre at the camera",
        outcome.scenario, outcome.seed
    );
    tracking::draw(figure, &title, &[(label, points)], -1.0, last_s.min(8.0))
}

/// The voting reader's decisions in time order, one a line: lab seconds, what it decided.
fn voter_log(outputs: &readings::Readings) -> String {
    let mut lines: Vec<(f64, String)> = Vec::new();
    for a in &outputs.accepted {
        let agreeing: Vec<String> = a.agreeing.iter().map(|id| format!("C{id}")).collect();
        let text = format!(
            "accepted  input {} pan {} tilt {} from {}",
            a.input,
            a.pan,
            a.tilt,
            agreeing.join("+")
        );
        lines.push((a.at_ms, text));
    }
    for d in &outputs.dissents {
        let what = if d.raised { "raised" } else { "cleared" };
        lines.push((d.at_ms, format!("dissent   C{} {what}", d.id)));
    }
    for n in &outputs.no_majority {
        let fresh: Vec<String> = n.fresh.iter().map(|id| format!("C{id}")).collect();
        let action = if n.hold { "hold" } else { "safe" };
        lines.push((
            n.at_ms,
            format!("no majority ({action}), fresh {}", fresh.join("+")),
        ));
    }
    lines.sort_by(|a, b| a.0.total_cmp(&b.0));
    lines
        .into_iter()
        .map(|(at, text)| format!("{:9.3} s  {text}\n", at / 1000.0))
        .collect()
}
