//! Groups: how the cost grows with the number of redundancy groups on one LAN. `N` groups of
//! three controllers on one domain, each group with its own `dds.group` and command topic and
//! its own `rl servo`, as the paper's navigation and actuator controllers share a network.
//!
//! Measured per `N`: the time from starting the processes to each group formed (its servo
//! following its Primary), every controller's RSS and CPU over a steady window, and one kill of
//! every group's Primary at once, judged as the failover benchmark judges a kill: one owner
//! change at the group's servo, to its Secondary, within 1.15 × the command deadline.

use super::failover::{broken_promise, controller_changes, KillFailure};
use super::resources::sample_usage;
use super::stats::Summary;
use super::watch::Watch;
use super::{BenchError, Setup};
use crate::procs::Fleet;
use rl_layer::core::{ControllerId, Role};
use serde::Serialize;
use std::time::{Duration, Instant};

/// How long every group may take to form: discovery among more participants takes longer.
const FORMATION_TIMEOUT: Duration = Duration::from_secs(60);
/// How long after the kills every group's Secondary may take to command at 30.
const PROMOTION_TIMEOUT: Duration = Duration::from_secs(10);
/// After the switches, a little longer for late owner changes to reach the count.
const OWNER_CHANGES_SETTLE: Duration = Duration::from_millis(1000);

/// One kill of one group's Primary.
#[derive(Clone, Debug, Serialize)]
pub struct GroupKill {
    pub group: String,
    pub killed: Option<ControllerId>,
    /// The command gap at the group's servo.
    pub gap_ms: Option<u64>,
    pub switched_to: Option<ControllerId>,
    /// Owner changes from one controller to another at the group's servo after the kill.
    pub owner_changes: u32,
    pub failure: Option<KillFailure>,
}

/// The figures for one number of groups.
#[derive(Clone, Debug, Serialize)]
pub struct GroupsResult {
    pub groups: u32,
    pub controllers: u32,
    /// From starting every process to each group formed, one sample per group.
    pub formation_ms: Summary,
    pub failed_formations: u32,
    /// Per controller, over the steady window.
    pub rss_kb: Summary,
    pub cpu_percent_of_one_core: Summary,
    pub seconds: u64,
    pub command_deadline_ms: u64,
    pub kills: Vec<GroupKill>,
    pub failed_kills: u32,
}

/// One group's processes and what they print.
struct Group {
    name: String,
    fleet: Fleet,
    watch: Watch,
    formed_ms: Option<u64>,
}

fn formed(watch: &Watch) -> bool {
    watch.formed() && watch.owner.is_some()
}

/// Runs `N` groups for each `N` of `counts`.
pub fn groups(
    setup: &Setup,
    counts: &[u32],
    seconds: u64,
) -> Result<Vec<GroupsResult>, BenchError> {
    let mut results = Vec::new();
    for &count in counts {
        let result = groups_of(setup, count, seconds)?;
        eprintln!(
            "groups {count}: formed {}/{count} (p50 {:.0} ms, max {:.0} ms), RSS p50 {:.0} kB max {:.0} kB, CPU p50 {:.2} % max {:.2} %, kills failed {}/{}",
            count - result.failed_formations,
            result.formation_ms.p50,
            result.formation_ms.max,
            result.rss_kb.p50,
            result.rss_kb.max,
            result.cpu_percent_of_one_core.p50,
            result.cpu_percent_of_one_core.max,
            result.failed_kills,
            result.kills.len()
        );
        results.push(result);
    }
    Ok(results)
}

fn groups_of(setup: &Setup, count: u32, seconds: u64) -> Result<GroupsResult, BenchError> {
    let deadline_ms = rl_layer::config::Timing::default().command_deadline_ms;
    let started = Instant::now();
    let mut groups = Vec::new();
    for index in 1..=count {
        let name = format!("g{index}");
        let config = setup.write_config(
            &format!("groups-{count}-{name}.toml"),
            &format!(
                "[timing]\ninit_window_ms = 1000\n[dds]\ngroup = \"{name}\"\ncommand_topic = \"{name}/servo_control\"\n"
            ),
        )?;
        let (mut fleet, watch) = setup.fleet(&config);
        setup.start_app(&mut fleet, "servo", &["servo", "--json"])?;
        for id in 1..=3 {
            setup.start_controller(&mut fleet, id)?;
        }
        groups.push(Group {
            name,
            fleet,
            watch,
            formed_ms: None,
        });
    }
    let until = started + FORMATION_TIMEOUT;
    while Instant::now() < until && groups.iter().any(|g| g.formed_ms.is_none()) {
        for group in &mut groups {
            group.watch.pump(Duration::from_millis(5));
            if group.formed_ms.is_none() && formed(&group.watch) {
                group.formed_ms = Some(started.elapsed().as_millis() as u64);
            }
        }
    }
    let formation: Vec<Option<u64>> = groups.iter().map(|g| g.formed_ms).collect();
    let (rss_kb, cpu) = usage(&mut groups, seconds)?;
    let kills = kill_every_primary(&mut groups, deadline_ms)?;
    for group in &mut groups {
        group.fleet.stop_all();
    }
    Ok(GroupsResult {
        groups: count,
        controllers: 3 * count,
        formation_ms: Summary::of_measured(formation.iter().copied()),
        failed_formations: formation.iter().filter(|f| f.is_none()).count() as u32,
        rss_kb: Summary::of(&rss_kb),
        cpu_percent_of_one_core: Summary::of(&cpu),
        seconds,
        command_deadline_ms: deadline_ms,
        failed_kills: kills.iter().filter(|k| k.failure.is_some()).count() as u32,
        kills,
    })
}

/// Every controller's largest RSS (kB) and CPU share (percent of one core) over `seconds`.
fn usage(groups: &mut [Group], seconds: u64) -> Result<(Vec<f64>, Vec<f64>), BenchError> {
    let mut pids = Vec::new();
    for group in groups.iter() {
        for id in 1..=3 {
            pids.push(group.fleet.pid(id).ok_or(BenchError::NotRunning { id })?);
        }
    }
    let usage = sample_usage(&pids, seconds, || {
        for group in groups.iter_mut() {
            group.watch.pump(Duration::from_millis(20));
        }
    })?;
    Ok(usage
        .into_iter()
        .map(|(rss_kb, cpu)| (rss_kb as f64, cpu))
        .unzip())
}

/// Kills every formed group's Primary at once and judges each group's servo.
fn kill_every_primary(
    groups: &mut [Group],
    deadline_ms: u64,
) -> Result<Vec<GroupKill>, BenchError> {
    let mut plans = Vec::new();
    for group in groups.iter_mut() {
        let primary = group.watch.holder(Role::Primary);
        let secondary = group.watch.holder(Role::Secondary);
        let changes_before = group.watch.owner_changes.len();
        plans.push((primary, secondary, changes_before));
    }
    for (group, (primary, _, _)) in groups.iter_mut().zip(&plans) {
        if let Some(primary) = primary {
            group.fleet.kill(*primary).map_err(|source| {
                BenchError::io(format!("kill -9 of {}'s C{primary}", group.name), source)
            })?;
        }
    }
    let switched = |watch: &Watch, primary: ControllerId, from: usize| {
        watch.owner_changes[from..]
            .iter()
            .find(|c| c.from == Some(primary))
            .copied()
    };
    let until = Instant::now() + PROMOTION_TIMEOUT;
    let all_switched = |groups: &[Group]| {
        groups
            .iter()
            .zip(&plans)
            .all(|(g, (p, _, from))| p.is_none_or(|p| switched(&g.watch, p, *from).is_some()))
    };
    while Instant::now() < until && !all_switched(groups) {
        for group in groups.iter_mut() {
            group.watch.pump(Duration::from_millis(5));
        }
    }
    let settle = Instant::now() + OWNER_CHANGES_SETTLE;
    while Instant::now() < settle {
        for group in groups.iter_mut() {
            group.watch.pump(Duration::from_millis(5));
        }
    }
    let mut kills = Vec::new();
    for (group, (primary, secondary, from)) in groups.iter().zip(plans) {
        let switch = primary.and_then(|p| switched(&group.watch, p, from));
        let owner_changes = controller_changes(&group.watch.owner_changes[from..]);
        let gap_ms = switch.and_then(|c| c.gap_ms);
        let switched_to = switch.and_then(|c| c.to);
        let failure = if primary.is_none() || secondary.is_none() {
            Some(KillFailure::NoPrimaryAndSecondary)
        } else if gap_ms.is_none() {
            Some(KillFailure::NoSwitchAtServo)
        } else if switched_to != secondary {
            Some(KillFailure::SwitchedPastTheSecondary)
        } else {
            broken_promise(owner_changes, gap_ms, deadline_ms)
        };
        kills.push(GroupKill {
            group: group.name.clone(),
            killed: primary,
            gap_ms,
            switched_to,
            owner_changes,
            failure,
        });
    }
    Ok(kills)
}
