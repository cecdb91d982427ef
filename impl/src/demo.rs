//! `rl demo`: the paper's demonstration on one machine. Three controllers, the camera and the
//! servo simulators run as child processes; every few seconds the Primary is killed
//! (`kill -9`) and restarted, and a timeline shows what a user would see: the servo switching
//! to the Secondary within the command deadline, the promotion, the alarms, the rejoin in the
//! lowest role. `--record DIR` keeps every child's output (JSON events) for later checking.

use crate::core::{Phase, Role};
use crate::event::{Event, EventLine};
use crate::procs::{parse_servo_event, Fleet, ServoEvent};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Arguments of `rl demo`.
#[derive(clap::Args, Debug)]
pub struct DemoArgs {
    /// Kill the Primary this many seconds after the system has settled.
    #[arg(long, default_value_t = 6, value_name = "S")]
    pub kill_every_s: u64,
    /// Restart the killed controller after this many seconds.
    #[arg(long, default_value_t = 3, value_name = "S")]
    pub down_s: u64,
    /// Stop after this many kill/restart cycles (0 = until Ctrl-C).
    #[arg(long, default_value_t = 0, value_name = "N")]
    pub cycles: u32,
    /// DDS domain id.
    #[arg(long, default_value_t = 53, value_name = "D")]
    pub domain: u16,
    /// Configuration file passed to every child.
    #[arg(long, value_name = "PATH")]
    pub config: Option<PathBuf>,
    /// Write every child's output to DIR/<name>.log (controllers' JSON events included).
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
}

/// What the demo knows of one controller, from its events.
#[derive(Clone, Debug, Default)]
struct Seen {
    phase: Option<Phase>,
    role: Option<Role>,
    strength: Option<u8>,
}

/// The next line printed by a child, or `None` once `until` has passed.
fn next_line(
    lines: &std::sync::mpsc::Receiver<crate::procs::Line>,
    until: Instant,
) -> Option<crate::procs::Line> {
    let left = until.saturating_duration_since(Instant::now());
    if left.is_zero() {
        return None;
    }
    lines.recv_timeout(left).ok()
}

pub fn run(args: DemoArgs) -> Result<(), crate::Error> {
    let stop = crate::controller::stop_on_signals()?;
    let exe = std::env::current_exe().map_err(|e| crate::Error::io("locating rl", e))?;
    if let Some(dir) = &args.record {
        std::fs::create_dir_all(dir)
            .map_err(|e| crate::Error::io(format!("creating {}", dir.display()), e))?;
    }
    let (mut fleet, lines) = Fleet::new(&exe, args.config.as_deref(), args.domain);
    let started = Instant::now();
    let stamp = |at: Instant| format!("[{:6.1}s]", at.duration_since(started).as_secs_f64());
    println!(
        "rl demo: 3 controllers, camera and servo on domain {} (Ctrl-C to stop)",
        args.domain
    );
    let spawn = |e: std::io::Error| crate::Error::io("starting a child process", e);
    fleet.start_other("camera", &["shapes"]).map_err(spawn)?;
    fleet
        .start_other("servo", &["servo", "--json"])
        .map_err(spawn)?;
    for id in 1..=3 {
        fleet
            .start_controller_with(id, &["--json-events"])
            .map_err(spawn)?;
    }
    let mut recordings: BTreeMap<String, std::fs::File> = BTreeMap::new();
    let mut seen: BTreeMap<u8, Seen> = BTreeMap::new();
    let mut owner: Option<u8> = None;
    let mut last_pan_tilt = (0u16, 0u16);
    let mut settled_since: Option<Instant> = None;
    let mut killed: Option<(u8, Instant)> = None;
    let mut cycles = 0u32;
    let mut next_summary = started + Duration::from_secs(2);
    while !stop.load(Ordering::SeqCst) {
        // Drain for 20 ms at most: the servo prints a line every few milliseconds, so waiting
        // for a quiet gap would never reach the kill schedule below.
        let drain_until = Instant::now() + Duration::from_millis(20);
        while let Some(line) = next_line(&lines, drain_until) {
            if let Some(dir) = &args.record {
                let file = match recordings.get_mut(&line.source) {
                    Some(file) => file,
                    None => {
                        let path = dir.join(format!("{}.log", line.source.replace('!', ".stderr")));
                        let file = std::fs::File::create(&path).map_err(|e| {
                            crate::Error::io(format!("creating {}", path.display()), e)
                        })?;
                        recordings.entry(line.source.clone()).or_insert(file)
                    }
                };
                let _ = writeln!(file, "{}", line.text);
            }
            if line.source == "servo" {
                match parse_servo_event(&line.text) {
                    Some(ServoEvent::OwnerChanged {
                        from_controller_id,
                        to_controller_id,
                        gap_ms,
                        strength,
                        ..
                    }) => {
                        owner = to_controller_id;
                        if from_controller_id.is_some() && from_controller_id == to_controller_id {
                            // The same controller with a new writer: its strength changed.
                            println!(
                                "{} servo: C{} now commands at strength {strength}",
                                stamp(line.at),
                                to_controller_id.unwrap_or(0)
                            );
                            continue;
                        }
                        let name =
                            |id: Option<u8>| id.map(|i| format!("C{i}")).unwrap_or("-".into());
                        let gap = gap_ms
                            .map(|g| format!(" after a {g} ms gap"))
                            .unwrap_or_default();
                        println!(
                            "{} servo: owner {} -> {}{gap}",
                            stamp(line.at),
                            name(from_controller_id),
                            name(to_controller_id)
                        );
                    }
                    Some(ServoEvent::Command { pan, tilt, .. }) => last_pan_tilt = (pan, tilt),
                    None => {}
                }
                continue;
            }
            let Some(line_event) = EventLine::parse(&line.text) else {
                continue;
            };
            let entry = seen.entry(line_event.id).or_default();
            match &line_event.event {
                Event::Status { status } => {
                    let changed = entry.phase != Some(status.report.phase)
                        || entry.role != status.report.role;
                    entry.phase = Some(status.report.phase);
                    entry.role = status.report.role;
                    entry.strength = status.report.strength;
                    if changed {
                        let role = status
                            .report
                            .role
                            .map(|r| format!("{r} ({})", status.report.strength.unwrap_or(0)))
                            .unwrap_or_else(|| "no role".into());
                        println!(
                            "{} C{}: {} {}",
                            stamp(line.at),
                            line_event.id,
                            status.report.phase,
                            role
                        );
                    }
                }
                Event::Alarm {
                    about,
                    reason,
                    raised,
                } => {
                    let what = if *raised { "raises" } else { "clears" };
                    println!(
                        "{} C{}: {what} alarm for C{about} ({reason:?})",
                        stamp(line.at),
                        line_event.id
                    );
                }
                Event::Output { strength, .. } => entry.strength = *strength,
                _ => {}
            }
        }
        let now = Instant::now();
        let settled = seen
            .values()
            .filter(|s| s.phase == Some(Phase::Steady))
            .count()
            == 3
            && owner.is_some()
            && killed.is_none();
        if settled {
            settled_since.get_or_insert(now);
        } else {
            settled_since = None;
        }
        if let Some((id, at)) = killed {
            if now.duration_since(at) >= Duration::from_secs(args.down_s) {
                println!("{} restart C{id}", stamp(now));
                fleet
                    .start_controller_with(id, &["--json-events"])
                    .map_err(spawn)?;
                killed = None;
                cycles += 1;
            }
        } else if settled_since.is_some_and(|since| {
            now.duration_since(since) >= Duration::from_secs(args.kill_every_s)
        }) {
            if args.cycles > 0 && cycles >= args.cycles {
                break;
            }
            let primary = seen
                .iter()
                .find(|(_, s)| s.role == Some(Role::Primary))
                .map(|(id, _)| *id);
            if let Some(id) = primary {
                println!("{} kill -9 C{id} (the Primary)", stamp(now));
                fleet
                    .kill(id)
                    .map_err(|e| crate::Error::io("killing a controller", e))?;
                seen.remove(&id);
                killed = Some((id, now));
            }
        }
        if now >= next_summary {
            next_summary = now + Duration::from_secs(2);
            let roles: Vec<String> = Role::ALL
                .iter()
                .map(|role| {
                    let holder = seen
                        .iter()
                        .find(|(_, s)| s.role == Some(*role))
                        .map(|(id, _)| *id);
                    format!(
                        "{}={}",
                        &role.name()[..1].to_uppercase(),
                        holder.map(|i| format!("C{i}")).unwrap_or("-".into())
                    )
                })
                .collect();
            println!(
                "{} roles {} | servo owner {} | pan {} tilt {}",
                stamp(now),
                roles.join(" "),
                owner.map(|i| format!("C{i}")).unwrap_or("-".into()),
                last_pan_tilt.0,
                last_pan_tilt.1
            );
        }
    }
    println!("{} stopping", stamp(Instant::now()));
    fleet.stop_all();
    Ok(())
}
