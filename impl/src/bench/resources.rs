//! Resources: RSS and CPU of each of the three controllers at 4 Hz heartbeats and 30 Hz
//! commands (the camera simulator at 30 Hz), read from `/proc`, with their network monitors
//! on as deployed (both networks on loopback: the monitor's two DDS participants cost the same
//! there). The headline figures are the worst controller's: the targets hold per controller,
//! and the roles do not cost the same (only the Secondary measures its peers' commands, F17).

use super::{BenchError, Setup};
use serde::Serialize;
use std::time::{Duration, Instant};

/// Network A and B both on loopback (by address and by interface name, which RL takes as two
/// networks): the network monitor runs its two participants.
const NETWORK_MONITOR_ON_LOOPBACK: &[&str] = &["--network-a", "127.0.0.1", "--network-b", "lo"];

/// The controllers measured: C1, C2 and C3 (Primary, Secondary and Tertiary once formed).
const MEASURED: [rl_layer::core::ControllerId; 3] = [1, 2, 3];

#[derive(Clone, Debug, Serialize)]
pub struct ResourceResult {
    /// The largest of the controllers' maximum RSS.
    pub rss_kb_max: u64,
    /// The largest of the controllers' CPU shares.
    pub cpu_percent_of_one_core: f64,
    pub seconds: u64,
    /// Each controller's own figures.
    pub controllers: Vec<ControllerUsage>,
}

/// One controller's resources over the run.
#[derive(Clone, Debug, Serialize)]
pub struct ControllerUsage {
    pub id: rl_layer::core::ControllerId,
    pub rss_kb_max: u64,
    pub cpu_percent_of_one_core: f64,
}

/// utime + stime of a process, in clock ticks, and its resident set in kB.
fn proc_usage(pid: u32) -> Result<(u64, u64), BenchError> {
    let unreadable = || BenchError::ProcUnreadable { pid };
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).map_err(|_| unreadable())?;
    let status =
        std::fs::read_to_string(format!("/proc/{pid}/status")).map_err(|_| unreadable())?;
    parse_usage(&stat, &status).ok_or_else(unreadable)
}

/// `(utime + stime, VmRSS kB)` from the text of `/proc/<pid>/stat` and `/proc/<pid>/status`.
fn parse_usage(stat: &str, status: &str) -> Option<(u64, u64)> {
    // Fields after the command name (which may contain spaces) start after the last ')'.
    let after = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
    let rss_kb = status
        .lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some((ticks, rss_kb))
}

fn ticks_per_second() -> f64 {
    // SAFETY: sysconf has no memory effects.
    let ticks = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    if ticks > 0 {
        ticks as f64
    } else {
        100.0
    }
}

/// Each process's largest RSS (kB) and CPU share (percent of one core) over `seconds`, read
/// from `/proc` after every `pump` (which keeps the children's output drained meanwhile).
pub(super) fn sample_usage(
    pids: &[u32],
    seconds: u64,
    mut pump: impl FnMut(),
) -> Result<Vec<(u64, f64)>, BenchError> {
    let mut before = Vec::new();
    for pid in pids {
        before.push(proc_usage(*pid)?);
    }
    let mut rss_max: Vec<u64> = before.iter().map(|(_, rss)| *rss).collect();
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs(seconds) {
        pump();
        for (pid, rss) in pids.iter().zip(rss_max.iter_mut()) {
            *rss = (*rss).max(proc_usage(*pid)?.1);
        }
    }
    let elapsed_s = started.elapsed().as_secs_f64();
    let mut usage = Vec::new();
    for ((pid, (ticks_before, _)), rss_kb_max) in pids.iter().zip(&before).zip(rss_max) {
        let (ticks_after, _) = proc_usage(*pid)?;
        let cpu = ticks_after.saturating_sub(*ticks_before) as f64 / ticks_per_second() / elapsed_s;
        usage.push((rss_kb_max, cpu * 100.0));
    }
    Ok(usage)
}

pub fn resources(setup: &Setup, seconds: u64) -> Result<ResourceResult, BenchError> {
    // 30 Hz commands: the camera at 30 Hz, re-publishing no faster.
    let config = setup.write_config(
        "resources.toml",
        "[timing]\ninit_window_ms = 1000\ncommand_republish_ms = 34\n",
    )?;
    let (mut fleet, mut watch) = setup.fleet(&config);
    setup.start_app(&mut fleet, "camera", &["shapes", "--rate-hz", "30"])?;
    for id in 1..=3 {
        setup.start_controller_with(&mut fleet, id, NETWORK_MONITOR_ON_LOOPBACK)?;
    }
    if !watch.wait(Duration::from_secs(20), super::watch::Watch::formed) {
        return Err(BenchError::NoFormation {
            run: "resource run".into(),
            timeout_s: 20,
        });
    }
    watch.pump(Duration::from_secs(1));
    let mut pids = Vec::new();
    for id in MEASURED {
        pids.push(fleet.pid(id).ok_or(BenchError::NotRunning { id })?);
    }
    let usage = sample_usage(&pids, seconds, || watch.pump(Duration::from_millis(500)))?;
    let controllers: Vec<ControllerUsage> = MEASURED
        .iter()
        .zip(usage)
        .map(
            |(id, (rss_kb_max, cpu_percent_of_one_core))| ControllerUsage {
                id: *id,
                rss_kb_max,
                cpu_percent_of_one_core,
            },
        )
        .collect();
    fleet.stop_all();
    Ok(ResourceResult {
        rss_kb_max: controllers.iter().map(|c| c.rss_kb_max).max().unwrap_or(0),
        cpu_percent_of_one_core: controllers
            .iter()
            .map(|c| c.cpu_percent_of_one_core)
            .fold(0.0, f64::max),
        seconds,
        controllers,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn usage_is_read_after_the_command_name() {
        let stat = "42 (rl (x) y) S 1 2 3 4 5 6 7 8 9 10 120 30 0 0";
        let status = "Name:\trl\nVmRSS:\t   14404 kB\n";
        assert_eq!(parse_usage(stat, status), Some((150, 14404)));
        assert_eq!(parse_usage("42 (rl) S 1", status), None);
        assert_eq!(parse_usage(stat, "Name:\trl\n"), None);
    }
}
