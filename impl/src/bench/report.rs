//! The benchmark's human-readable report: one line per figure, every command gap naming the
//! reader that measured it.

use super::stats::Summary;
use super::{BenchResult, GroupsReport};
use std::io::Write;

fn summary(x: &Summary) -> String {
    format!(
        "n={} min {:.0} p50 {:.0} p99 {:.0} max {:.0}",
        x.count, x.min, x.p50, x.p99, x.max
    )
}

/// Writes the report; a closed output is not an error worth more than the figures.
pub fn write_report(out: &mut impl Write, result: &BenchResult) -> std::io::Result<()> {
    writeln!(
        out,
        "rl bench (seed {}, {} cores): heartbeat period {} ms",
        result.seed, result.cores, result.heartbeat_period_ms
    )?;
    for f in &result.failover {
        writeln!(
            out,
            "failover @ deadline {} ms (re-publish {} ms): command gap at {}, ms: {}; p50/deadline {:.2}, p99/deadline {:.2}, max/deadline {:.2}",
            f.deadline_ms,
            f.command_republish_ms,
            f.gap_reader,
            summary(&f.gap_ms),
            f.gap_over_deadline_p50,
            f.gap_over_deadline_p99,
            f.gap_over_deadline_max
        )?;
        writeln!(
            out,
            "    promotion of the Secondary to 30 (kill to its output event), ms: {}; p50 {:.2} periods, p99 {:.2} periods",
            summary(&f.promotion_ms),
            f.promotion_over_period_p50,
            f.promotion_over_period_p99
        )?;
        writeln!(
            out,
            "    new Primary steady at 30 (kill to its status), ms: {}",
            summary(&f.steady_ms)
        )?;
        writeln!(
            out,
            "    owner changes at {} per kill (kill to all steady again): max {}; kills with more than one: {} of {}",
            f.gap_reader,
            f.owner_changes_max,
            f.kills_with_more_than_one_owner_change,
            f.kills
        )?;
        writeln!(
            out,
            "    tracking error (ball off centre, camera on the gimbal), px: every frame {}; worst in the 2 s before each kill {}, in the 2 s after {}; frames without the ball: {}",
            summary(&f.tracking_error_px),
            summary(&f.tracking_error_before_kill_max_px),
            summary(&f.tracking_error_after_kill_max_px),
            f.frames_unseen
        )?;
        writeln!(
            out,
            "    failed kills: {} of {}; controllers restarted after failing themselves: {}",
            f.failed_kills, f.kills, f.controllers_restarted
        )?;
    }
    let formation = &result.formation;
    writeln!(
        out,
        "formation after the third controller's start, Primary at 30, ms: {}",
        summary(&formation.primary_ms)
    )?;
    writeln!(
        out,
        "formation, all three steady, ms: {}",
        summary(&formation.all_steady_ms)
    )?;
    writeln!(
        out,
        "formation after the third controller's first heartbeat heard, Primary at 30, ms: {}; p50 {:.2} periods",
        summary(&formation.primary_after_first_heartbeat_ms),
        formation.primary_after_first_heartbeat_over_period_p50
    )?;
    writeln!(
        out,
        "    failed formations: {} of {}",
        formation.failed_formations, formation.runs
    )?;
    writeln!(
        out,
        "controller resources over {} s (network monitor on), the worst of three: max RSS {} kB, CPU {:.2}% of one core",
        result.resources.seconds,
        result.resources.rss_kb_max,
        result.resources.cpu_percent_of_one_core
    )?;
    for controller in &result.resources.controllers {
        writeln!(
            out,
            "    C{}: max RSS {} kB, CPU {:.2}% of one core",
            controller.id, controller.rss_kb_max, controller.cpu_percent_of_one_core
        )?;
    }
    if let Some(secured) = &result.security {
        let f = &secured.failover;
        writeln!(
            out,
            "with DDS Security: failover @ deadline {} ms: command gap, ms: {}; promotion, ms: {}; failed kills {} of {}",
            f.deadline_ms,
            summary(&f.gap_ms),
            summary(&f.promotion_ms),
            f.failed_kills,
            f.kills
        )?;
        writeln!(
            out,
            "with DDS Security: controller resources over {} s: max RSS {} kB, CPU {:.2}% of one core",
            secured.resources.seconds,
            secured.resources.rss_kb_max,
            secured.resources.cpu_percent_of_one_core
        )?;
        writeln!(
            out,
            "secured / unsecured: gap p50 {:.2}, gap max {:.2}, promotion p50 {:.2}, CPU {:.2}, RSS {:.2}",
            secured.gap_p50_ratio,
            secured.gap_max_ratio,
            secured.promotion_p50_ratio,
            secured.cpu_ratio,
            secured.rss_ratio
        )?;
    }
    Ok(())
}

/// Writes what `--groups` measured: one block per number of groups.
pub fn write_groups(out: &mut impl Write, report: &GroupsReport) -> std::io::Result<()> {
    writeln!(out, "rl bench --groups ({} cores)", report.cores)?;
    for r in &report.results {
        writeln!(
            out,
            "{} groups ({} controllers): formed {}/{}; from start to formed, ms: {}",
            r.groups,
            r.controllers,
            r.groups - r.failed_formations,
            r.groups,
            summary(&r.formation_ms)
        )?;
        writeln!(
            out,
            "    per controller over {} s: RSS kB p50 {:.0} max {:.0}; CPU % of one core p50 {:.2} max {:.2}",
            r.seconds, r.rss_kb.p50, r.rss_kb.max, r.cpu_percent_of_one_core.p50, r.cpu_percent_of_one_core.max
        )?;
        let gaps: Vec<String> = r
            .kills
            .iter()
            .map(|k| format!("{} {}", k.group, super::formation::shown_ms(k.gap_ms)))
            .collect();
        writeln!(
            out,
            "    every Primary killed at once: {} of {} kills failed; gap at each servo, ms: {}",
            r.failed_kills,
            r.kills.len(),
            gaps.join(", ")
        )?;
    }
    Ok(())
}

/// `rl bench --architectures`: one block per architecture.
pub fn write_architectures(
    out: &mut impl Write,
    report: &super::ArchitecturesReport,
) -> std::io::Result<()> {
    writeln!(out, "{} ({} cores)", report.command, report.cores)?;
    for r in &report.results {
        writeln!(
            out,
            "{:?} ({} controllers): RSS kB max {}; CPU % of one core max {:.2}",
            r.architecture,
            r.controllers.len(),
            r.rss_kb_max,
            r.cpu_percent_of_one_core
        )?;
        writeln!(
            out,
            "    {} kills of the servo's owner: gap ms {}; owner changes per fault (kill and return) {:.2}; alarm after the kill, ms {}",
            r.kills.len(),
            summary(&r.gap_ms),
            r.owner_changes_per_fault(),
            summary(&r.alarm_ms)
        )?;
    }
    Ok(())
}
