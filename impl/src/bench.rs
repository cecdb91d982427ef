//! `rl bench`: the failover, promotion, formation and resource benchmarks, measured on real
//! processes over DDS on this machine (docs/performance.md has the figures and the command).
//!
//! - failover: `kill -9` of the Primary, repeatedly; the command gap at `rl servo` (its
//!   `owner_changed.gap_ms`) and the promotion time of the Secondary (kill to its `output`
//!   event at strength 30), at each command deadline asked for;
//! - formation: two controllers start, the third 300 ms later; time from the third's start
//!   (its first heartbeat goes out at start) to the Primary commanding at 30, and to all three
//!   steady;
//! - resources: RSS and CPU of one controller at 4 Hz heartbeats and 30 Hz commands.

use crate::core::{Phase, Role};
use crate::event::{Event, EventLine};
use crate::procs::{parse_servo_event, wall_ms, Fleet, Line, ServoEvent};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// Arguments of `rl bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Kills of the Primary per command deadline.
    #[arg(long, default_value_t = 20, value_name = "N")]
    pub kills: u32,
    /// Command deadlines to measure failover at (ms, comma-separated).
    #[arg(
        long,
        default_value = "100,20",
        value_delimiter = ',',
        value_name = "MS"
    )]
    pub deadlines_ms: Vec<u64>,
    /// Fresh formations to time.
    #[arg(long, default_value_t = 10, value_name = "N")]
    pub formations: u32,
    /// Seconds of steady running to sample RSS and CPU over.
    #[arg(long, default_value_t = 10, value_name = "S")]
    pub resources_s: u64,
    /// DDS domain id (keep it away from running systems).
    #[arg(long, default_value_t = 220, value_name = "D")]
    pub domain: u16,
    /// Also print the results as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Order statistics of a sample of durations (ms).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Summary {
    pub count: usize,
    pub min: f64,
    pub p50: f64,
    pub p99: f64,
    pub max: f64,
}

impl Summary {
    /// Nearest-rank percentiles.
    pub fn of(values: &[f64]) -> Summary {
        let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
        sorted.sort_by(f64::total_cmp);
        let rank = |p: f64| -> f64 {
            if sorted.is_empty() {
                return f64::NAN;
            }
            let index = ((p * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1;
            sorted[index]
        };
        Summary {
            count: sorted.len(),
            min: sorted.first().copied().unwrap_or(f64::NAN),
            p50: rank(0.50),
            p99: rank(0.99),
            max: sorted.last().copied().unwrap_or(f64::NAN),
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct FailoverResult {
    pub deadline_ms: u64,
    pub command_republish_ms: u64,
    pub gap_ms: Summary,
    pub gap_over_deadline_p50: f64,
    pub gap_over_deadline_p99: f64,
    pub promotion_ms: Summary,
    pub failed_kills: u32,
}

#[derive(Clone, Debug, Serialize)]
pub struct FormationResult {
    /// From the third controller's process start.
    pub primary_ms: Summary,
    pub all_steady_ms: Summary,
    /// From the first heartbeat of the third controller that a DDS reader (the bench's own)
    /// received: discovery of a new participant takes part of the time above.
    pub primary_after_first_heartbeat_ms: Summary,
}

#[derive(Clone, Debug, Serialize)]
pub struct ResourceResult {
    pub rss_kb_max: u64,
    pub cpu_percent_of_one_core: f64,
    pub seconds: u64,
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchResult {
    pub heartbeat_period_ms: u64,
    pub failover: Vec<FailoverResult>,
    pub formation: FormationResult,
    pub resources: ResourceResult,
}

/// The bench's view of a running fleet, from the children's JSON lines.
struct Watch {
    lines: Receiver<Line>,
    status: BTreeMap<u8, crate::core::Status>,
    /// (controller, wall ms, strength) of every `output` event.
    outputs: Vec<(u8, u64, Option<u8>)>,
    /// (wall ms of the first event of each controller start) `started` events.
    started: Vec<(u8, u64)>,
    /// (gap, from, to) of every owner change.
    owner_changes: Vec<(Option<u64>, Option<u8>, Option<u8>)>,
    owner: Option<u8>,
}

impl Watch {
    fn new(lines: Receiver<Line>) -> Watch {
        Watch {
            lines,
            status: BTreeMap::new(),
            outputs: Vec::new(),
            started: Vec::new(),
            owner_changes: Vec::new(),
            owner: None,
        }
    }

    fn pump(&mut self, wait: Duration) {
        let until = Instant::now() + wait;
        while let Ok(line) = self
            .lines
            .recv_timeout(until.saturating_duration_since(Instant::now()))
        {
            if line.source == "servo" {
                if let Some(ServoEvent::OwnerChanged {
                    gap_ms,
                    from_controller_id,
                    to_controller_id,
                    ..
                }) = parse_servo_event(&line.text)
                {
                    self.owner = to_controller_id;
                    self.owner_changes
                        .push((gap_ms, from_controller_id, to_controller_id));
                }
            } else if let Some(line) = EventLine::parse(&line.text) {
                match line.event {
                    Event::Status { status } => {
                        self.status.insert(line.id, status);
                    }
                    Event::Output { strength, .. } => {
                        self.outputs.push((line.id, line.t_ms, strength));
                    }
                    Event::Started => self.started.push((line.id, line.t_ms)),
                    _ => {}
                }
            }
            if Instant::now() >= until {
                break;
            }
        }
    }

    fn wait(&mut self, timeout: Duration, mut done: impl FnMut(&Watch) -> bool) -> bool {
        let until = Instant::now() + timeout;
        while !done(self) {
            if Instant::now() >= until {
                return false;
            }
            self.pump(Duration::from_millis(10));
        }
        true
    }

    fn holder(&self, role: Role) -> Option<u8> {
        self.status
            .values()
            .find(|s| s.report.phase == Phase::Steady && s.report.role == Some(role))
            .map(|s| s.report.id)
    }

    fn all_steady(&self, ids: &[u8]) -> bool {
        ids.iter().all(|id| {
            self.status
                .get(id)
                .is_some_and(|s| s.report.phase == Phase::Steady && s.report.strength.is_some())
        })
    }
}

fn write_config(dir: &Path, name: &str, text: &str) -> Result<PathBuf, crate::Error> {
    let path = dir.join(name);
    std::fs::write(&path, text)
        .map_err(|e| crate::Error::io(format!("writing {}", path.display()), e))?;
    Ok(path)
}

fn spawn_error(e: std::io::Error) -> crate::Error {
    crate::Error::io("starting a child process", e)
}

/// Kills the Primary `kills` times at command deadline `deadline_ms`.
fn failover(
    exe: &Path,
    dir: &Path,
    domain: u16,
    deadline_ms: u64,
    kills: u32,
) -> Result<FailoverResult, crate::Error> {
    // The next writer's first sample lands up to one re-publish period after the deadline:
    // re-publishing at a tenth of the deadline keeps the gap within 1.1 x the deadline.
    let republish_ms = (deadline_ms / 10).max(1);
    let config = write_config(
        dir,
        &format!("failover-{deadline_ms}.toml"),
        &format!(
            "[timing]\ninit_window_ms = 1000\ncommand_deadline_ms = {deadline_ms}\ncommand_republish_ms = {republish_ms}\n"
        ),
    )?;
    let (mut fleet, lines) = Fleet::new(exe, Some(&config), domain);
    let mut watch = Watch::new(lines);
    fleet
        .start_other("servo", &["servo", "--json"])
        .map_err(spawn_error)?;
    for id in 1..=3 {
        fleet
            .start_controller_with(id, &["--json-events"])
            .map_err(spawn_error)?;
    }
    let formed = |w: &Watch| w.all_steady(&[1, 2, 3]) && w.owner.is_some();
    if !watch.wait(Duration::from_secs(20), formed) {
        return Err(crate::Error::Runtime(format!(
            "bench: no formation at deadline {deadline_ms} ms"
        )));
    }
    let mut gaps = Vec::new();
    let mut promotions = Vec::new();
    let mut failed_kills = 0;
    for kill in 1..=kills {
        watch.pump(Duration::from_millis(500));
        let (Some(primary), Some(secondary)) =
            (watch.holder(Role::Primary), watch.holder(Role::Secondary))
        else {
            failed_kills += 1;
            continue;
        };
        let changes_before = watch.owner_changes.len();
        let outputs_before = watch.outputs.len();
        let killed_ms = wall_ms();
        fleet
            .kill(primary)
            .map_err(|e| crate::Error::io("kill -9", e))?;
        watch.status.remove(&primary);
        let promoted = watch.wait(Duration::from_secs(10), |w| {
            w.outputs[outputs_before..]
                .iter()
                .any(|(id, _, s)| *id == secondary && *s == Some(30))
        });
        let gap = watch.owner_changes[changes_before..]
            .iter()
            .find(|(_, from, _)| *from == Some(primary))
            .and_then(|(gap, _, _)| *gap);
        match (promoted, gap) {
            (true, Some(gap)) => {
                gaps.push(gap as f64);
                let at = watch.outputs[outputs_before..]
                    .iter()
                    .find(|(id, _, s)| *id == secondary && *s == Some(30))
                    .map(|(_, t, _)| *t)
                    .unwrap_or(killed_ms);
                promotions.push(at.saturating_sub(killed_ms) as f64);
            }
            _ => failed_kills += 1,
        }
        fleet
            .start_controller_with(primary, &["--json-events"])
            .map_err(spawn_error)?;
        let rejoined = watch.wait(Duration::from_secs(10), |w| w.all_steady(&[1, 2, 3]));
        if !rejoined {
            failed_kills += 1;
        }
        eprintln!(
            "deadline {deadline_ms} ms, kill {kill}/{kills}: C{primary} killed, gap {:?} ms, promotion {:?} ms",
            gap,
            promotions.last()
        );
    }
    fleet.stop_all();
    let gap = Summary::of(&gaps);
    Ok(FailoverResult {
        deadline_ms,
        command_republish_ms: republish_ms,
        gap_over_deadline_p50: gap.p50 / deadline_ms as f64,
        gap_over_deadline_p99: gap.p99 / deadline_ms as f64,
        gap_ms: gap,
        promotion_ms: Summary::of(&promotions),
        failed_kills,
    })
}

fn formation(
    exe: &Path,
    dir: &Path,
    domain: u16,
    runs: u32,
) -> Result<FormationResult, crate::Error> {
    let config = write_config(dir, "formation.toml", "")?;
    let mut primary_ms = Vec::new();
    let mut all_ms = Vec::new();
    let mut after_heartbeat_ms = Vec::new();
    let listener_config = crate::config::Config {
        dds: crate::config::Dds {
            domain,
            ..Default::default()
        },
        ..Default::default()
    };
    let session = crate::dds::Session::new(&listener_config.dds, &listener_config.timing)
        .map_err(|e| crate::Error::Dds(e.to_string()))?;
    let mut heartbeats = session
        .heartbeat_reader()
        .map_err(|e| crate::Error::Dds(e.to_string()))?;
    for run in 1..=runs {
        let (mut fleet, lines) = Fleet::new(exe, Some(&config), domain);
        let mut watch = Watch::new(lines);
        fleet
            .start_controller_with(1, &["--json-events"])
            .map_err(spawn_error)?;
        fleet
            .start_controller_with(2, &["--json-events"])
            .map_err(spawn_error)?;
        watch.pump(Duration::from_millis(300));
        let _ = heartbeats.take();
        fleet
            .start_controller_with(3, &["--json-events"])
            .map_err(spawn_error)?;
        let mut first_heard: Option<u64> = None;
        let formed = watch.wait(Duration::from_secs(15), |w| {
            if first_heard.is_none() && heartbeats.take().iter().any(|h| h.value.id == 3) {
                first_heard = Some(wall_ms());
            }
            w.all_steady(&[1, 2, 3])
        });
        let third_started = watch
            .started
            .iter()
            .find(|(id, _)| *id == 3)
            .map(|(_, t)| *t);
        let primary_at = watch
            .outputs
            .iter()
            .find(|(_, _, s)| *s == Some(30))
            .map(|(_, t, _)| *t);
        let last_steady = watch.outputs.iter().map(|(_, t, _)| *t).max();
        if let (true, Some(start), Some(primary), Some(last)) =
            (formed, third_started, primary_at, last_steady)
        {
            primary_ms.push(primary.saturating_sub(start) as f64);
            all_ms.push(last.saturating_sub(start) as f64);
            if let Some(heard) = first_heard {
                after_heartbeat_ms.push(primary.saturating_sub(heard) as f64);
            }
        }
        eprintln!(
            "formation {run}/{runs}: primary {:?} ms, all {:?} ms",
            primary_ms.last(),
            all_ms.last()
        );
        fleet.stop_all();
        // Let the old participants' traffic die down before the next run.
        std::thread::sleep(Duration::from_millis(500));
    }
    Ok(FormationResult {
        primary_ms: Summary::of(&primary_ms),
        all_steady_ms: Summary::of(&all_ms),
        primary_after_first_heartbeat_ms: Summary::of(&after_heartbeat_ms),
    })
}

/// utime + stime of a process, in clock ticks, and its resident set in kB.
fn proc_usage(pid: u32) -> Option<(u64, u64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name (which may contain spaces) start after the last ')'.
    let after = stat.rsplit_once(')')?.1;
    let fields: Vec<&str> = after.split_whitespace().collect();
    let ticks = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let rss_kb = status
        .lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()?;
    Some((ticks, rss_kb))
}

fn resources(
    exe: &Path,
    dir: &Path,
    domain: u16,
    seconds: u64,
) -> Result<ResourceResult, crate::Error> {
    // 30 Hz commands: the camera at 30 Hz, re-publishing no faster.
    let config = write_config(
        dir,
        "resources.toml",
        "[timing]\ninit_window_ms = 1000\ncommand_republish_ms = 34\n",
    )?;
    let (mut fleet, lines) = Fleet::new(exe, Some(&config), domain);
    let mut watch = Watch::new(lines);
    fleet
        .start_other("camera", &["shapes", "--rate-hz", "30"])
        .map_err(spawn_error)?;
    for id in 1..=3 {
        fleet
            .start_controller_with(id, &["--json-events"])
            .map_err(spawn_error)?;
    }
    if !watch.wait(Duration::from_secs(20), |w| w.all_steady(&[1, 2, 3])) {
        return Err(crate::Error::Runtime(
            "bench: no formation for the resource run".into(),
        ));
    }
    watch.pump(Duration::from_secs(1));
    let pid = fleet
        .pid(1)
        .ok_or_else(|| crate::Error::Runtime("bench: controller 1 not running".into()))?;
    let ticks_per_s = {
        // SAFETY: sysconf has no memory effects.
        let ticks = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
        if ticks > 0 {
            ticks as f64
        } else {
            100.0
        }
    };
    let (ticks_before, mut rss_max) =
        proc_usage(pid).ok_or_else(|| crate::Error::Runtime("bench: /proc unreadable".into()))?;
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs(seconds) {
        watch.pump(Duration::from_millis(500));
        if let Some((_, rss)) = proc_usage(pid) {
            rss_max = rss_max.max(rss);
        }
    }
    let (ticks_after, _) =
        proc_usage(pid).ok_or_else(|| crate::Error::Runtime("bench: /proc unreadable".into()))?;
    let cpu = (ticks_after - ticks_before) as f64 / ticks_per_s / started.elapsed().as_secs_f64();
    fleet.stop_all();
    Ok(ResourceResult {
        rss_kb_max: rss_max,
        cpu_percent_of_one_core: cpu * 100.0,
        seconds,
    })
}

pub fn run(args: BenchArgs) -> Result<(), crate::Error> {
    let exe = std::env::current_exe().map_err(|e| crate::Error::io("locating rl", e))?;
    let dir = std::env::temp_dir().join(format!("rl-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)
        .map_err(|e| crate::Error::io("creating a temporary directory", e))?;
    let mut failovers = Vec::new();
    for &deadline_ms in &args.deadlines_ms {
        if deadline_ms == 0 {
            return Err(crate::Error::Usage(
                "--deadlines-ms: a deadline must be at least 1 ms".into(),
            ));
        }
        failovers.push(failover(&exe, &dir, args.domain, deadline_ms, args.kills)?);
    }
    let formation = formation(&exe, &dir, args.domain, args.formations)?;
    let resources = resources(&exe, &dir, args.domain, args.resources_s)?;
    let _ = std::fs::remove_dir_all(&dir);
    let result = BenchResult {
        heartbeat_period_ms: crate::config::Timing::default().heartbeat_period_ms,
        failover: failovers,
        formation,
        resources,
    };
    print_result(&result);
    if args.json {
        let json =
            serde_json::to_string(&result).map_err(|e| crate::Error::Runtime(e.to_string()))?;
        println!("{json}");
    }
    Ok(())
}

fn print_result(result: &BenchResult) {
    let s = |x: &Summary| {
        format!(
            "n={} min {:.0} p50 {:.0} p99 {:.0} max {:.0}",
            x.count, x.min, x.p50, x.p99, x.max
        )
    };
    println!("heartbeat period {} ms", result.heartbeat_period_ms);
    for f in &result.failover {
        println!(
            "failover @ deadline {} ms (re-publish {} ms): command gap ms {}; p50/deadline {:.2}, p99/deadline {:.2}; failed kills {}",
            f.deadline_ms, f.command_republish_ms, s(&f.gap_ms), f.gap_over_deadline_p50, f.gap_over_deadline_p99, f.failed_kills
        );
        println!(
            "    promotion of the Secondary to 30, ms: {}",
            s(&f.promotion_ms)
        );
    }
    println!(
        "formation after the third controller's start, Primary at 30, ms: {}",
        s(&result.formation.primary_ms)
    );
    println!(
        "formation, all three steady, ms: {}",
        s(&result.formation.all_steady_ms)
    );
    println!(
        "formation after the third controller's first heartbeat heard, Primary at 30, ms: {}",
        s(&result.formation.primary_after_first_heartbeat_ms)
    );
    println!(
        "controller resources over {} s: max RSS {} kB, CPU {:.2}% of one core",
        result.resources.seconds,
        result.resources.rss_kb_max,
        result.resources.cpu_percent_of_one_core
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let values: Vec<f64> = (1..=100).map(f64::from).collect();
        let s = Summary::of(&values);
        assert_eq!(
            (s.count, s.min, s.p50, s.p99, s.max),
            (100, 1.0, 50.0, 99.0, 100.0)
        );
        let s = Summary::of(&[5.0, 1.0, 3.0]);
        assert_eq!((s.p50, s.p99), (3.0, 5.0));
        assert!(Summary::of(&[]).p50.is_nan());
    }
}
