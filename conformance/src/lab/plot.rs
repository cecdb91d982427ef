//! The picture of a run (SVG, plotters): one row per controller with the role each of its
//! lives reported over time, one row per actuator with its owner, the faults as shaded
//! intervals across all rows, and the largest command gap at each actuator marked in red.

use super::error::LabError;
use super::judge::FaultRecord;
use super::observe::{Observations, OwnerSpan};
use super::procs::Life;
use super::run::Outcome;
use plotters::prelude::*;
use rl_layer::core::{Phase, Role};
use std::path::Path;

const ROWS: [&str; 5] = ["C1", "C2", "C3", "rl servo", "Connext"];

fn role_colour(phase: Phase, role: Option<Role>) -> RGBColor {
    match (phase, role) {
        (Phase::Failed, _) => RGBColor(200, 30, 30),
        (_, Some(Role::Primary)) => RGBColor(27, 120, 55),
        (_, Some(Role::Secondary)) => RGBColor(50, 110, 190),
        (_, Some(Role::Tertiary)) => RGBColor(230, 160, 20),
        _ => RGBColor(170, 170, 170),
    }
}

fn owner_colour(owner: &str) -> RGBColor {
    match owner.get(..2) {
        Some("C1") => RGBColor(27, 158, 119),
        Some("C2") => RGBColor(217, 95, 2),
        Some("C3") => RGBColor(117, 112, 179),
        _ => RGBColor(120, 120, 120),
    }
}

/// The y extent of row `row` (0 at the top).
fn row_band(row: usize) -> (f64, f64) {
    let top = (ROWS.len() - row) as f64;
    (top - 0.85, top - 0.15)
}

/// A role segment of one controller life: from, to (s), phase, role.
type Segment = (f64, f64, Phase, Option<Role>);

/// Each life's role segments, from its status events, ended by its death or `end_ms`.
fn role_segments(observed: &Observations, lives: &[Life], end_ms: f64) -> Vec<(u8, Segment)> {
    let mut segments = Vec::new();
    for life in lives {
        let label = life.label();
        let end = life.ended_ms.unwrap_or(end_ms) / 1000.0;
        let statuses: Vec<(f64, Phase, Option<Role>)> = observed
            .controller
            .iter()
            .filter(|e| e.life == label)
            .filter_map(|e| {
                e.line
                    .status()
                    .map(|s| (e.at_ms / 1000.0, s.report.phase, s.report.role))
            })
            .collect();
        for (i, (at, phase, role)) in statuses.iter().enumerate() {
            let until = statuses.get(i + 1).map_or(end, |next| next.0).min(end);
            if until > *at {
                segments.push((life.id, (*at, until, *phase, *role)));
            }
        }
    }
    segments
}

/// Draws the run's picture to `path`.
pub fn draw(
    path: &Path,
    outcome: &Outcome,
    observed: &Observations,
    lives: &[Life],
    end_ms: f64,
) -> Result<(), LabError> {
    let fail = |e: &dyn std::fmt::Display| LabError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let root = SVGBackend::new(path, (1400, 460)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let x0 = (outcome.metrics.judged_from_ms / 1000.0 - 2.0).max(0.0);
    let x1 = end_ms / 1000.0;
    let verdict = if outcome.passed() { "PASS" } else { "FAIL" };
    let broken = outcome
        .mutation
        .as_ref()
        .map_or(String::new(), |m| format!(", mutation {m}"));
    let title = format!(
        "{} (seed {}{broken}): {verdict}",
        outcome.scenario, outcome.seed
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(80)
        .build_cartesian_2d(x0..x1, 0.0..ROWS.len() as f64)
        .map_err(|e| fail(&e))?;
    chart
        .configure_mesh()
        .disable_y_mesh()
        .x_desc("seconds since the run started")
        .y_labels(ROWS.len() * 2 + 1)
        .y_label_formatter(&|y| {
            let row = ROWS.len() as f64 - y;
            let index = row.floor() as usize;
            if (row - row.floor() - 0.5).abs() < 0.01 && index < ROWS.len() {
                ROWS[index].to_string()
            } else {
                String::new()
            }
        })
        .draw()
        .map_err(|e| fail(&e))?;
    shade_faults(&mut chart, &outcome.faults, end_ms).map_err(|e| fail(&e))?;
    for (id, (from, to, phase, role)) in role_segments(observed, lives, end_ms) {
        let (low, high) = row_band(usize::from(id.saturating_sub(1)).min(2));
        let colour = role_colour(phase, role);
        chart
            .draw_series([Rectangle::new(
                [(from.max(x0), low), (to.max(x0), high)],
                colour.filled(),
            )])
            .map_err(|e| fail(&e))?;
    }
    let m = &outcome.metrics;
    for (row, spans, gap) in [
        (3, Some(&m.servo_owners), m.servo_gap),
        (4, m.connext_owners.as_ref(), m.connext_gap),
    ] {
        draw_owners(
            &mut chart,
            row,
            spans.map_or(&[][..], Vec::as_slice),
            gap,
            x0,
        )
        .map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))
}

/// Each fault as a shaded interval across all rows, labelled at the top.
fn shade_faults(
    chart: &mut Chart<'_, '_>,
    faults: &[FaultRecord],
    end_ms: f64,
) -> Result<(), DrawingAreaErrorKind<std::io::Error>> {
    for fault in faults {
        let from = fault.applied_ms / 1000.0;
        let to = fault.healed_ms.unwrap_or(end_ms) / 1000.0;
        let shade = RGBAColor(220, 40, 40, 0.12);
        let top = ROWS.len() as f64;
        chart.draw_series([Rectangle::new([(from, 0.0), (to, top)], shade.filled())])?;
        let label = Text::new(fault.label.clone(), (from, top - 0.03), ("sans-serif", 11));
        chart.draw_series([label])?;
    }
    Ok(())
}

type Chart<'a, 'b> = ChartContext<
    'a,
    SVGBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// One actuator row: owner spans coloured by controller, named, the largest gap in red.
fn draw_owners(
    chart: &mut Chart<'_, '_>,
    row: usize,
    spans: &[OwnerSpan],
    gap: Option<(f64, f64)>,
    x0: f64,
) -> Result<(), DrawingAreaErrorKind<std::io::Error>> {
    let (low, high) = row_band(row);
    for (i, span) in spans.iter().enumerate() {
        let to = spans.get(i + 1).map_or(span.to_ms, |next| next.from_ms) / 1000.0;
        let from = (span.from_ms / 1000.0).max(x0);
        let colour = owner_colour(&span.owner);
        chart.draw_series([Rectangle::new(
            [(from, low), (to.max(from), high)],
            colour.filled(),
        )])?;
        chart.draw_series([Text::new(
            span.owner.clone(),
            (from, high + 0.1),
            ("sans-serif", 10),
        )])?;
    }
    if let Some((gap_ms, end_ms)) = gap {
        let (from, to) = ((end_ms - gap_ms) / 1000.0, end_ms / 1000.0);
        chart.draw_series([Rectangle::new(
            [(from, low - 0.1), (to, high + 0.1)],
            RED.filled(),
        )])?;
        let label = format!("largest gap {gap_ms:.0} ms");
        chart.draw_series([Text::new(
            label,
            (to, low - 0.05),
            ("sans-serif", 10).into_font().color(&RED),
        )])?;
    }
    Ok(())
}
