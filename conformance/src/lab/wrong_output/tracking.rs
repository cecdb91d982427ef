//! The ball's tracking error at the camera (`rl shapes --json`: each frame, how far off the
//! frame's centre the ball was seen, or not seen at all), per phase of a wrong-output run:
//! before the fault, its first second (where a wrong Primary's commands move the gimbal), the
//! whole fault (until its heal), and after. Measured, not judged: it shows what a wrong
//! Primary costs the plant under each camera mode (the gimbal following the exclusive topic's
//! owner, or the vote), and the figure draws it.

use super::readings::Frame;
use crate::lab::error::LabError;
use crate::lab::judge::FaultRecord;
use crate::lab::session::Camera;
use plotters::prelude::*;
use serde::Serialize;
use std::path::Path;

/// The tracking error of one phase.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PhaseError {
    pub phase: String,
    pub from_ms: f64,
    pub to_ms: f64,
    pub frames: usize,
    /// Frames without the ball in view.
    pub lost: usize,
    /// Of the frames with the ball in view (px).
    pub median_px: Option<f64>,
    pub p95_px: Option<f64>,
    pub max_px: Option<f64>,
}

/// The tracking error of a run, per phase.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Tracking {
    pub camera: Camera,
    pub phases: Vec<PhaseError>,
}

/// The `q` quantile (0..=1) of `sorted`, nearest rank.
fn quantile(sorted: &[f64], q: f64) -> Option<f64> {
    let last = sorted.len().checked_sub(1)?;
    let rank = (q * last as f64).round() as usize;
    sorted.get(rank.min(last)).copied()
}

/// The error over `frames` from `from_ms` (inclusive) to `to_ms` (exclusive).
fn phase(name: &str, frames: &[Frame], from_ms: f64, to_ms: f64) -> PhaseError {
    let in_phase: Vec<&Frame> = frames
        .iter()
        .filter(|f| f.at_ms >= from_ms && f.at_ms < to_ms)
        .collect();
    let mut seen: Vec<f64> = in_phase.iter().filter_map(|f| f.error_px).collect();
    seen.sort_by(f64::total_cmp);
    PhaseError {
        phase: name.into(),
        from_ms,
        to_ms,
        frames: in_phase.len(),
        lost: in_phase.iter().filter(|f| f.error_px.is_none()).count(),
        median_px: quantile(&seen, 0.5),
        p95_px: quantile(&seen, 0.95),
        max_px: seen.last().copied(),
    }
}

/// The phases of a run: before its first fault, the fault's first second, the fault (to its
/// last heal), after.
pub fn measure(
    frames: &[Frame],
    faults: &[FaultRecord],
    judged_from_ms: f64,
    end_ms: f64,
    camera: Camera,
) -> Tracking {
    let applied = faults.iter().map(|f| f.applied_ms).fold(end_ms, f64::min);
    let healed = faults
        .iter()
        .map(|f| f.healed_ms.unwrap_or(end_ms))
        .fold(applied, f64::max);
    Tracking {
        camera,
        phases: vec![
            phase("before", frames, judged_from_ms, applied),
            phase(
                "first second",
                frames,
                applied,
                (applied + 1000.0).min(healed),
            ),
            phase("fault", frames, applied, healed),
            phase("after", frames, healed, end_ms),
        ],
    }
}

/// One summary line per phase.
pub fn summary(tracking: &Tracking) -> String {
    let px = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.1}"));
    let phases: Vec<String> = tracking
        .phases
        .iter()
        .map(|p| {
            format!(
                "{} {} px (p95 {}, max {}, {} of {} frames lost)",
                p.phase,
                px(p.median_px),
                px(p.p95_px),
                px(p.max_px),
                p.lost,
                p.frames
            )
        })
        .collect();
    let camera = match tracking.camera {
        Camera::Exclusive => "the exclusive owner",
        Camera::Vote => "the vote",
    };
    format!(
        "  tracking error, median (camera following {camera}): {}\n",
        phases.join("; ")
    )
}

/// A run's frames for a figure: its label and (s since its first fault, error px; `None`
/// when the ball was not in view).
pub type Series = (String, Vec<(f64, Option<f64>)>);

/// The frames of a run as seconds since its first fault (`applied_ms`).
pub fn series(label: &str, frames: &[Frame], applied_ms: f64) -> Series {
    let points = frames
        .iter()
        .map(|f| ((f.at_ms - applied_ms) / 1000.0, f.error_px))
        .collect();
    (label.to_string(), points)
}

/// The series a wrong-output run left in its directory `dir` (`tracking.json`, written by
/// `super::files::write_outputs`), labelled with its scenario and seed.
pub fn read_series(dir: &Path) -> Result<Series, LabError> {
    let path = dir.join("tracking.json");
    let text = std::fs::read_to_string(&path).map_err(|e| LabError::output(&path, e))?;
    let bad = |what: &str| LabError::Output {
        path: path.clone(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, what.to_string()),
    };
    let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| bad(&e.to_string()))?;
    let label = format!(
        "{} (seed {})",
        value["scenario"]
            .as_str()
            .ok_or_else(|| bad("no scenario"))?,
        value["seed"].as_u64().ok_or_else(|| bad("no seed"))?
    );
    let frames = value["frames"].as_array().ok_or_else(|| bad("no frames"))?;
    let points = frames
        .iter()
        .filter_map(|frame| Some((frame[0].as_f64()?, frame[1].as_f64())))
        .collect();
    Ok((label, points))
}

/// Draws the tracking error of each of `runs` against the time since its fault, from
/// `from_s` to `to_s`, with the fault's first moment marked; a lost ball is drawn at the top
/// (`lost_px`).
pub fn draw(
    path: &Path,
    title: &str,
    runs: &[Series],
    from_s: f64,
    to_s: f64,
) -> Result<(), LabError> {
    let fail = |e: &dyn std::fmt::Display| LabError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let lost_px = runs
        .iter()
        .flat_map(|(_, points)| points.iter().filter_map(|p| p.1))
        .fold(40.0_f64, f64::max)
        * 1.1;
    let root = SVGBackend::new(path, (1100, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(from_s..to_s, 0.0..lost_px * 1.05)
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .x_desc("seconds since the wrong commands began")
        .y_desc("ball off centre (px)")
        .draw()
        .map_err(|e| fail(&e))?;
    let colours = [
        RGBColor(217, 95, 2),
        RGBColor(27, 158, 119),
        RGBColor(117, 112, 179),
    ];
    for (i, (label, points)) in runs.iter().enumerate() {
        let colour = colours[i % colours.len()];
        let line = points
            .iter()
            .filter(|(t, _)| *t >= from_s && *t <= to_s)
            .map(|(t, e)| (*t, e.unwrap_or(lost_px)));
        chart
            .draw_series(LineSeries::new(line, colour.stroke_width(2)))
            .map_err(|e| fail(&e))?
            .label(label.clone())
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], colour.stroke_width(2)));
    }
    chart
        .draw_series([PathElement::new(
            [(0.0, 0.0), (0.0, lost_px * 1.05)],
            RED.stroke_width(1),
        )])
        .map_err(|e| fail(&e))?;
    chart
        .draw_series([Text::new(
            "ball not in view",
            (from_s, lost_px),
            ("sans-serif", 11),
        )])
        .map_err(|e| fail(&e))?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| fail(&e))?;
    root.present().map_err(|e| fail(&e))
}
