//! Architectures: the paper's three redundancy architectures measured side by side, under the
//! same faults and the same judge (docs/architectures.md). For each one its controllers run
//! with the camera and the servo (three voting, or the duplex's or the pair's two), and once
//! they command:
//! - every controller's RSS and CPU over `--resources-s` seconds;
//! - `--kills` kills of the controller the servo follows (`kill -9`), each restarted once a
//!   survivor has alarmed it (a service manager's restart delay of at least the heartbeat
//!   deadline, the duplex model's timing assumption), measuring at the servo the gap, the
//!   owner changes the kill and the return caused, and the time from the kill to the
//!   survivors' first alarm about it.

use super::resources::sample_usage;
use super::stats::Summary;
use super::watch::Watch;
use super::{BenchError, Setup};
use crate::procs::Fleet;
use rl_layer::config::ArchitectureName;
use rl_layer::core::ControllerId;
use serde::Serialize;
use std::time::Duration;

const FORMATION_TIMEOUT: Duration = Duration::from_secs(20);
/// How long a kill may take to be alarmed, and a restarted controller to command again.
const STEP_TIMEOUT: Duration = Duration::from_secs(10);
/// After a switch, a little longer for late owner changes to reach the count.
const SETTLE: Duration = Duration::from_millis(1000);

/// One kill of the servo's owner, and its restart.
#[derive(Clone, Debug, Serialize)]
pub struct ArchitectureKill {
    pub killed: ControllerId,
    /// The command gap at the servo's first move after the kill.
    pub gap_ms: Option<u64>,
    /// Owner changes between the kill and the restart.
    pub owner_changes_at_kill: u32,
    /// Owner changes from the restart until the restarted controller commands and a second
    /// has passed.
    pub owner_changes_at_return: u32,
    /// From the kill to the survivors' first alarm about the killed controller.
    pub alarm_ms: Option<u64>,
}

/// What one architecture measured.
#[derive(Clone, Debug, Serialize)]
pub struct ArchitectureResult {
    pub architecture: ArchitectureName,
    pub controllers: Vec<ControllerId>,
    pub kills: Vec<ArchitectureKill>,
    pub gap_ms: Summary,
    pub alarm_ms: Summary,
    /// The largest RSS and CPU (% of one core) of any of its controllers.
    pub rss_kb_max: u64,
    pub cpu_percent_of_one_core: f64,
}

impl ArchitectureResult {
    /// Owner changes per fault (a kill and its restart), over every kill.
    pub fn owner_changes_per_fault(&self) -> f64 {
        let changes: u32 = self
            .kills
            .iter()
            .map(|k| k.owner_changes_at_kill + k.owner_changes_at_return)
            .sum();
        f64::from(changes) / self.kills.len().max(1) as f64
    }
}

/// The controllers an architecture runs, with its defaults.
fn members(architecture: ArchitectureName) -> Vec<ControllerId> {
    match architecture {
        ArchitectureName::Voting => vec![1, 2, 3],
        ArchitectureName::Duplex | ArchitectureName::Pair => vec![1, 2],
    }
}

fn name(architecture: ArchitectureName) -> &'static str {
    match architecture {
        ArchitectureName::Voting => "voting",
        ArchitectureName::Duplex => "duplex",
        ArchitectureName::Pair => "pair",
    }
}

/// Measures each architecture in turn.
pub fn architectures(
    setup: &Setup,
    which: &[ArchitectureName],
    kills: u32,
    resources_s: u64,
) -> Result<Vec<ArchitectureResult>, BenchError> {
    which
        .iter()
        .map(|&architecture| measure(setup, architecture, kills, resources_s))
        .collect()
}

fn measure(
    setup: &Setup,
    architecture: ArchitectureName,
    kills: u32,
    resources_s: u64,
) -> Result<ArchitectureResult, BenchError> {
    // The failover run's timing: deadline 100 ms, re-published every 10 ms.
    let config = setup.write_config(
        &format!("architecture-{}.toml", name(architecture)),
        &format!(
            "architecture = \"{}\"\n[timing]\ninit_window_ms = 1000\n",
            name(architecture)
        ),
    )?;
    let ids = members(architecture);
    let (mut fleet, mut watch) = setup.fleet(&config);
    setup.start_app(&mut fleet, "servo", &["servo", "--json"])?;
    setup.start_app(&mut fleet, "camera", &["shapes", "--json"])?;
    for &id in &ids {
        setup.start_controller(&mut fleet, id)?;
    }
    let commanding = |w: &Watch| w.all_steady(&ids) && w.owner.is_some();
    if !watch.wait(FORMATION_TIMEOUT, commanding) {
        return Err(BenchError::NoFormation {
            run: format!("{} run", name(architecture)),
            timeout_s: FORMATION_TIMEOUT.as_secs(),
        });
    }
    watch.pump(SETTLE);
    let mut pids = Vec::new();
    for &id in &ids {
        pids.push(fleet.pid(id).ok_or(BenchError::NotRunning { id })?);
    }
    let usage = sample_usage(&pids, resources_s, || {
        watch.pump(Duration::from_millis(500))
    })?;
    let mut measured = Vec::new();
    for kill in 1..=kills {
        let sample = kill_and_restart(setup, &mut fleet, &mut watch, &ids)?;
        eprintln!(
            "{}, kill {kill}/{kills}: C{} killed, gap {} ms, alarm {} ms, owner changes {} at the kill and {} at the return",
            name(architecture),
            sample.killed,
            super::formation::shown_ms(sample.gap_ms),
            super::formation::shown_ms(sample.alarm_ms),
            sample.owner_changes_at_kill,
            sample.owner_changes_at_return
        );
        measured.push(sample);
    }
    fleet.stop_all();
    Ok(ArchitectureResult {
        architecture,
        controllers: ids,
        gap_ms: Summary::of_measured(measured.iter().map(|k| k.gap_ms)),
        alarm_ms: Summary::of_measured(measured.iter().map(|k| k.alarm_ms)),
        kills: measured,
        rss_kb_max: usage.iter().map(|(rss, _)| *rss).max().unwrap_or(0),
        cpu_percent_of_one_core: usage.iter().map(|(_, cpu)| *cpu).fold(0.0, f64::max),
    })
}

/// Kills the servo's owner, waits for a survivor's alarm, restarts it, and waits for it to
/// command again.
fn kill_and_restart(
    setup: &Setup,
    fleet: &mut Fleet,
    watch: &mut Watch,
    ids: &[ControllerId],
) -> Result<ArchitectureKill, BenchError> {
    let killed = watch.owner.ok_or(BenchError::NoOwner)?;
    let changes_before = watch.owner_changes.len();
    let alarms_before = watch.alarms.len();
    let killed_at_ms = crate::procs::wall_ms();
    fleet
        .kill(killed)
        .map_err(|e| BenchError::io("killing a controller", e))?;
    let alarmed = |w: &Watch| {
        w.alarms[alarms_before..]
            .iter()
            .any(|a| a.about == killed && a.by != killed)
    };
    watch.wait(STEP_TIMEOUT, alarmed);
    watch.pump(SETTLE);
    let alarm_ms = watch.alarms[alarms_before..]
        .iter()
        .find(|a| a.about == killed && a.by != killed)
        .map(|a| a.t_ms.saturating_sub(killed_at_ms));
    let at_kill = &watch.owner_changes[changes_before..];
    let gap_ms = at_kill.first().and_then(|change| change.gap_ms);
    let owner_changes_at_kill = moves(at_kill);
    let changes_at_restart = watch.owner_changes.len();
    let old_life = watch.status.get(&killed).map(|s| s.report.incarnation);
    setup.start_controller(fleet, killed)?;
    let back = |w: &Watch| {
        let new_life = w.status.get(&killed).map(|s| s.report.incarnation) != old_life;
        new_life && w.all_steady(ids) && w.owner.is_some()
    };
    watch.wait(STEP_TIMEOUT, back);
    watch.pump(SETTLE);
    Ok(ArchitectureKill {
        killed,
        gap_ms,
        owner_changes_at_kill,
        owner_changes_at_return: moves(&watch.owner_changes[changes_at_restart..]),
        alarm_ms,
    })
}

/// Moves from one controller to another (a writer re-created by its owner is none).
fn moves(changes: &[super::watch::OwnerChange]) -> u32 {
    changes
        .iter()
        .filter(|c| c.from.is_some() && c.from != c.to)
        .count() as u32
}
