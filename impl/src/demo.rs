//! `rl demo`: the paper's demonstration on one machine. Three controllers, the camera and the
//! servo simulators run as child processes; every few seconds the Primary is killed
//! (`kill -9`) and restarted, and a timeline shows what a user would see: the servo switching
//! to the Secondary within the command deadline, the promotion, the alarms, the rejoin in the
//! lowest role, and the camera on the gimbal keeping the ball near the centre throughout (the
//! live line says how far off, in pixels). `--record DIR` keeps every child's output (JSON
//! events) for later checking.
//!
//! `--architecture duplex|pair` shows the paper's two other architectures with their two
//! controllers (the duplex's Primary killed and restarted, or the pair's commanding one), and
//! `--controllers 1` the paper's first step: one controller, whose death stops the tracking.
//!
//! `--chain` runs the paper's chain instead (crate::chain): three navigation controllers
//! (group `nav`) aim, three actuator controllers (the configuration's group) command the
//! servo, and the kills alternate between the two groups' Primaries.

mod architecture;

pub use self::architecture::DemoArchitecture;
use self::architecture::{architecture_name, controller_ids, write_children_config};
use crate::chain::ChainLine;
use crate::procs::{parse_servo_event, Fleet, Line, ServoEvent};
use crate::sim::shapes::CameraFrame;
use rl_layer::core::{ControllerId, Phase, Role, Strength};
use rl_layer::event::{Event, EventLine};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::mpsc::Receiver;
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
    /// Write every child's output to `DIR/<name>.log` (controllers' JSON events included).
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// Serve the live status page (`rl status --serve`) here; `off` for none.
    #[arg(long, default_value = "127.0.0.1:8053", value_name = "ADDR|off")]
    pub status_page: String,
    /// The paper's chain: a navigation group (`rl chain nav`, group `nav`) turns the camera's
    /// ball into aims and an actuator group (`rl chain act`) turns the navigation Primary's
    /// aims into servo commands; the kills alternate between the two groups' Primaries.
    #[arg(long, conflicts_with_all = ["architecture", "controllers"])]
    pub chain: bool,
    /// The redundancy architecture to show (the paper's three): `voting` (three controllers
    /// vote roles), `duplex` (a configured Primary and Standby; the Primary takes the
    /// actuator back on its return) or `pair` (two controllers both commanding, each
    /// comparing two implementations of its control law). Overrides the configuration's.
    #[arg(long, value_enum, value_name = "NAME")]
    pub architecture: Option<DemoArchitecture>,
    /// How many controllers to run: the paper's first step is one (killing it stops the
    /// tracking); voting takes 1 to 3 (default 3), duplex and pair exactly 2 (their default).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u8).range(1..=3))]
    pub controllers: Option<u8>,
}

pub use crate::error::DemoError;

/// What the demo knows of one controller, from its events.
#[derive(Clone, Debug, Default)]
struct Seen {
    phase: Option<Phase>,
    role: Option<Role>,
    strength: Option<Strength>,
}

/// One group of three controllers in the demo, and what it knows of them.
struct Group {
    /// How its lines and the timeline name it: `""` (the one group), `nav `, `act `.
    label: &'static str,
    fleet: Fleet,
    seen: BTreeMap<ControllerId, Seen>,
}

impl Group {
    fn new(label: &'static str, fleet: Fleet) -> Group {
        Group {
            label,
            fleet,
            seen: BTreeMap::new(),
        }
    }

    fn steady(&self) -> usize {
        self.seen
            .values()
            .filter(|s| s.phase == Some(Phase::Steady))
            .count()
    }

    fn holder(&self, role: Role) -> Option<ControllerId> {
        self.seen
            .iter()
            .find(|(_, s)| s.role == Some(role))
            .map(|(id, _)| *id)
    }

    /// The controller whose lines come from `source`, if it is one of this group's.
    fn controller_of(&self, source: &str) -> Option<ControllerId> {
        source
            .strip_prefix(self.label)?
            .strip_prefix('C')?
            .parse()
            .ok()
    }
}

/// The next line printed by a child, or `None` once `until` has passed.
fn next_line(lines: &Receiver<Line>, until: Instant) -> Option<Line> {
    let left = until.saturating_duration_since(Instant::now());
    if left.is_zero() {
        return None;
    }
    lines.recv_timeout(left).ok()
}

fn spawn_error(e: std::io::Error) -> crate::Error {
    crate::Error::io("starting a child process", e)
}

pub fn run(mut args: DemoArgs) -> Result<(), crate::Error> {
    // The children would each refuse a bad domain or configuration; say it once, at once.
    let mut config = crate::cli::load_config(args.config.as_deref(), Some(args.domain))?;
    if let Some(architecture) = args.architecture {
        config.architecture = architecture.config_name();
    }
    let ids = controller_ids(&config, args.controllers)?;
    let stop = crate::cli::stop_on_signals()?;
    let exe = std::env::current_exe().map_err(|e| crate::Error::io("locating rl", e))?;
    if let Some(dir) = &args.record {
        std::fs::create_dir_all(dir)
            .map_err(|e| crate::Error::io(format!("creating {}", dir.display()), e))?;
    }
    // An architecture given on the command line reaches the children in a configuration of
    // the demo's own (the given one with it), kept beside the recording or in the temp dir.
    if args.architecture.is_some() {
        args.config = Some(write_children_config(&config, args.record.as_deref())?);
    }
    let (fleet, lines) = Fleet::new(&exe, args.config.as_deref(), args.domain);
    let groups = if args.chain {
        println!(
            "rl demo --chain: 3 navigation and 3 actuator controllers, camera and servo on \
             domain {} (Ctrl-C to stop)",
            args.domain
        );
        vec![
            Group::new("nav ", fleet.sharing(&["chain", "nav"], "nav ")),
            Group::new("act ", fleet.sharing(&["chain", "act"], "act ")),
        ]
    } else {
        println!(
            "rl demo: {} controller{} ({}), camera and servo on domain {} (Ctrl-C to stop)",
            ids.len(),
            if ids.len() == 1 { "" } else { "s" },
            architecture_name(config.architecture),
            args.domain
        );
        vec![Group::new("", fleet.sharing(&["controller"], ""))]
    };
    let ids = if args.chain { vec![1, 2, 3] } else { ids };
    let mut demo = Demo::new(args, fleet, groups, ids);
    demo.start_children()?;
    let outcome = loop {
        if stop.load(Ordering::SeqCst) {
            break Ok(());
        }
        // Drain for 20 ms at most: the servo prints a line every few milliseconds, so waiting
        // for a quiet gap would never reach the kill schedule below.
        let drain_until = Instant::now() + Duration::from_millis(20);
        while let Some(line) = next_line(&lines, drain_until) {
            demo.take(line)?;
        }
        if let Err(error) = demo.check_controllers() {
            break Err(error.into());
        }
        let now = Instant::now();
        if !demo.follow_schedule(now)? {
            break Ok(());
        }
        demo.print_roles_every_2_s(now);
    };
    println!("{} stopping", demo.stamp(Instant::now()));
    for group in &mut demo.groups {
        group.fleet.stop_all();
    }
    demo.fleet.stop_all();
    outcome
}

/// The demo's state: the children, what they reported, and the kill/restart schedule.
struct Demo {
    args: DemoArgs,
    /// The camera, the servo and the page.
    fleet: Fleet,
    /// The controllers: one group, or the chain's navigation and actuator groups (the
    /// servo's owners are the last group's).
    groups: Vec<Group>,
    started: Instant,
    recordings: BTreeMap<String, std::fs::File>,
    /// The last stderr line of each child, to say why one exited.
    last_stderr: BTreeMap<String, String>,
    owner: Option<ControllerId>,
    /// The chain: the navigation controller whose aims each actuator controller applies.
    aims_from: BTreeMap<ControllerId, Option<ControllerId>>,
    last_pan_tilt: (u16, u16),
    /// The camera's tracking errors (pixels off centre) since the last live line, and the
    /// frames in which it did not see the ball.
    tracking_errors_px: Vec<f64>,
    frames_unseen: u32,
    settled_since: Option<Instant>,
    /// The group and id of the controller killed, and when.
    killed: Option<(usize, ControllerId, Instant)>,
    /// The controllers of each group (a duplex's or a pair's two, one to three voting).
    ids: Vec<ControllerId>,
    cycles: u32,
    next_summary: Instant,
}

impl Demo {
    fn new(args: DemoArgs, fleet: Fleet, groups: Vec<Group>, ids: Vec<ControllerId>) -> Demo {
        let started = Instant::now();
        Demo {
            args,
            fleet,
            groups,
            started,
            recordings: BTreeMap::new(),
            last_stderr: BTreeMap::new(),
            owner: None,
            aims_from: BTreeMap::new(),
            last_pan_tilt: (0, 0),
            tracking_errors_px: Vec::new(),
            frames_unseen: 0,
            settled_since: None,
            killed: None,
            ids,
            cycles: 0,
            next_summary: started + Duration::from_secs(2),
        }
    }

    /// `[  12.3s]`: time since the demo started.
    fn stamp(&self, at: Instant) -> String {
        format!("[{:6.1}s]", at.duration_since(self.started).as_secs_f64())
    }

    /// The servo's controllers' label (`act ` in the chain).
    fn servo_group_label(&self) -> &'static str {
        self.groups.last().map_or("", |group| group.label)
    }

    fn start_children(&mut self) -> Result<(), crate::Error> {
        if self.args.status_page != "off" {
            let addr = self.args.status_page.clone();
            self.fleet
                .start_other("page", &["status", "--serve", &addr])
                .map_err(spawn_error)?;
            println!(
                "{} live status page (LEDs, roles, alarms, metrics): http://{addr}/",
                self.stamp(Instant::now())
            );
        }
        self.fleet
            .start_other("camera", &["shapes", "--json"])
            .map_err(spawn_error)?;
        self.fleet
            .start_other("servo", &["servo", "--json"])
            .map_err(spawn_error)?;
        for group in 0..self.groups.len() {
            for id in self.ids.clone() {
                self.start_controller(group, id)?;
            }
        }
        Ok(())
    }

    fn start_controller(&mut self, group: usize, id: ControllerId) -> Result<(), crate::Error> {
        self.groups[group]
            .fleet
            .start_controller_with(id, &["--json-events"])
            .map(|_| ())
            .map_err(spawn_error)
    }

    /// Records, then shows what a line says.
    fn take(&mut self, line: Line) -> Result<(), crate::Error> {
        self.record(&line)?;
        if let Some(source) = line.source.strip_suffix('!') {
            self.last_stderr.insert(source.to_string(), line.text);
        } else if line.source == "servo" {
            self.on_servo_line(&line);
        } else if line.source == "camera" {
            if let Ok(frame) = serde_json::from_str::<CameraFrame>(&line.text) {
                match frame.error_px {
                    Some(error_px) => self.tracking_errors_px.push(error_px),
                    None => self.frames_unseen += 1,
                }
            }
        } else if let Some(event) = EventLine::parse(&line.text) {
            let group = self
                .groups
                .iter()
                .position(|g| g.controller_of(&line.source).is_some());
            if let Some(group) = group {
                self.on_controller_event(group, line.at, &event);
            }
        } else if let Some(ChainLine::AimOwner { id, from, to }) = ChainLine::parse(&line.text) {
            self.aims_from.insert(id, to);
            if from.is_some() {
                let name = |id: Option<u8>| id.map(|i| format!("C{i}")).unwrap_or("-".into());
                println!(
                    "{} act C{id}: aims from nav {} now (was {})",
                    self.stamp(line.at),
                    name(to),
                    name(from)
                );
            }
        }
        Ok(())
    }

    /// With `--record DIR`: appends the line to DIR/<source>.log (stderr: <source>.stderr.log).
    fn record(&mut self, line: &Line) -> Result<(), crate::Error> {
        let Some(dir) = &self.args.record else {
            return Ok(());
        };
        let file = match self.recordings.get_mut(&line.source) {
            Some(file) => file,
            None => {
                let name = line.source.replace('!', ".stderr").replace(' ', "-");
                let path = dir.join(format!("{name}.log"));
                let file = std::fs::File::create(&path)
                    .map_err(|e| crate::Error::io(format!("creating {}", path.display()), e))?;
                self.recordings.entry(line.source.clone()).or_insert(file)
            }
        };
        let _ = writeln!(file, "{}", line.text);
        Ok(())
    }

    fn on_servo_line(&mut self, line: &Line) {
        match parse_servo_event(&line.text) {
            Some(ServoEvent::OwnerChanged {
                from_controller_id,
                to_controller_id,
                gap_ms,
                strength,
                ..
            }) => {
                self.owner = to_controller_id;
                let label = self.servo_group_label();
                if from_controller_id.is_some() && from_controller_id == to_controller_id {
                    // The same controller with a new writer: its strength changed.
                    println!(
                        "{} servo: {label}C{} now commands at strength {strength}",
                        self.stamp(line.at),
                        to_controller_id.unwrap_or(0)
                    );
                    return;
                }
                let name =
                    |id: Option<u8>| id.map(|i| format!("{label}C{i}")).unwrap_or("-".into());
                let gap = gap_ms
                    .map(|g| format!(" after a {g} ms gap"))
                    .unwrap_or_default();
                println!(
                    "{} servo: owner {} -> {}{gap}",
                    self.stamp(line.at),
                    name(from_controller_id),
                    name(to_controller_id)
                );
            }
            Some(ServoEvent::Command { pan, tilt, .. }) => self.last_pan_tilt = (pan, tilt),
            Some(ServoEvent::Expired {
                controller_id,
                late_ms,
                lifespan_ms,
                ..
            }) => {
                let label = self.servo_group_label();
                let from = controller_id.map_or("-".into(), |id| format!("{label}C{id}"));
                println!(
                    "{} servo: dropped a command of {from} {late_ms} ms late (lifespan {lifespan_ms} ms)",
                    self.stamp(line.at)
                );
            }
            None => {}
        }
    }

    fn on_controller_event(&mut self, group: usize, at: Instant, line: &EventLine) {
        let stamp = self.stamp(at);
        let label = self.groups[group].label;
        let entry = self.groups[group].seen.entry(line.id).or_default();
        match &line.event {
            Event::Status { status } => {
                let changed =
                    entry.phase != Some(status.report.phase) || entry.role != status.report.role;
                entry.phase = Some(status.report.phase);
                entry.role = status.report.role;
                entry.strength = status.report.strength;
                if changed {
                    let role = status
                        .report
                        .role
                        .map(|r| format!("{r} ({})", status.report.strength.unwrap_or_default()))
                        .unwrap_or_else(|| "no role".into());
                    println!(
                        "{stamp} {label}C{}: {} {role}",
                        line.id, status.report.phase
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
                    "{stamp} {label}C{}: {what} alarm for {label}C{about} ({reason:?})",
                    line.id
                );
            }
            Event::Output { strength, .. } => entry.strength = *strength,
            _ => {}
        }
    }

    /// A controller the demo did not kill must still run.
    fn check_controllers(&mut self) -> Result<(), DemoError> {
        for group in &mut self.groups {
            let running: Vec<ControllerId> = group.fleet.running().collect();
            for id in running {
                if let Ok(Some(status)) = group.fleet.exit_status(id) {
                    let controller = group.fleet.source_of(id);
                    return Err(DemoError::ControllerExited {
                        last_words: self.last_stderr.get(&controller).cloned(),
                        controller,
                        status,
                    });
                }
            }
        }
        Ok(())
    }

    /// Kills a Primary once the system has been settled `--kill-every-s` (the groups' in
    /// turn), restarts it after `--down-s`; `Ok(false)` when `--cycles` are done.
    fn follow_schedule(&mut self, now: Instant) -> Result<bool, crate::Error> {
        let all_steady = self
            .groups
            .iter()
            .all(|group| group.steady() == self.ids.len());
        if all_steady && self.owner.is_some() && self.killed.is_none() {
            self.settled_since.get_or_insert(now);
        } else {
            self.settled_since = None;
        }
        if let Some((group, id, at)) = self.killed {
            if now.duration_since(at) >= Duration::from_secs(self.args.down_s) {
                let label = self.groups[group].label;
                println!("{} restart {label}C{id}", self.stamp(now));
                self.start_controller(group, id)?;
                self.killed = None;
                self.cycles += 1;
            }
            return Ok(true);
        }
        let kill_due = self.settled_since.is_some_and(|since| {
            now.duration_since(since) >= Duration::from_secs(self.args.kill_every_s)
        });
        if !kill_due {
            return Ok(true);
        }
        if self.args.cycles > 0 && self.cycles >= self.args.cycles {
            return Ok(false);
        }
        let group_index = self.cycles as usize % self.groups.len();
        let stamp = self.stamp(now);
        let group = &mut self.groups[group_index];
        // A pair's two both report the Primary's role: the one the servo follows is killed.
        let primaries = group
            .seen
            .values()
            .filter(|s| s.role == Some(Role::Primary))
            .count();
        let target = match group.holder(Role::Primary) {
            Some(id) if primaries == 1 => Some((id, "the Primary")),
            _ => self.owner.map(|id| (id, "the servo's owner")),
        };
        if let Some((id, which)) = target {
            println!("{stamp} kill -9 {}C{id} ({which})", group.label);
            group
                .fleet
                .kill(id)
                .map_err(|e| crate::Error::io("killing a controller", e))?;
            group.seen.remove(&id);
            self.killed = Some((group_index, id, now));
        }
        Ok(true)
    }

    /// `roles P=C1 S=C2 T=C3 | servo owner C1 | pan .. tilt .. | ball off centre ..`, every
    /// 2 s (per group in the chain, with whose aims the actuator Primary applies): the
    /// tracking error is the camera's over those 2 s (median and worst, pixels).
    fn print_roles_every_2_s(&mut self, now: Instant) {
        if now < self.next_summary {
            return;
        }
        self.next_summary = now + Duration::from_secs(2);
        let name = |id: Option<ControllerId>| id.map(|i| format!("C{i}")).unwrap_or("-".into());
        let mut parts: Vec<String> = self
            .groups
            .iter()
            .map(|group| {
                let roles: Vec<String> = Role::ALL
                    .iter()
                    .map(|role| {
                        let initial = role.name()[..1].to_uppercase();
                        format!("{initial}={}", name(group.holder(*role)))
                    })
                    .collect();
                format!("{}roles {}", group.label, roles.join(" "))
            })
            .collect();
        if self.args.chain {
            let primary = self.groups.last().and_then(|g| g.holder(Role::Primary));
            let aims = primary.and_then(|id| self.aims_from.get(&id).copied().flatten());
            parts.push(format!("aims from nav {}", name(aims)));
        }
        let label = self.servo_group_label();
        let owner = self
            .owner
            .map_or("-".to_string(), |id| format!("{label}C{id}"));
        let tracking = self.tracking_summary();
        println!(
            "{} {} | servo owner {owner} | pan {} tilt {} | {tracking}",
            self.stamp(now),
            parts.join(" | "),
            self.last_pan_tilt.0,
            self.last_pan_tilt.1
        );
    }

    /// `ball off centre 4 px (worst 9)`, over the frames since the last call.
    fn tracking_summary(&mut self) -> String {
        let mut errors = std::mem::take(&mut self.tracking_errors_px);
        errors.sort_by(f64::total_cmp);
        let tracking = match (errors.get(errors.len() / 2), errors.last()) {
            (Some(median), Some(worst)) => {
                format!("ball off centre {median:.0} px (worst {worst:.0})")
            }
            _ => "ball not seen".to_string(),
        };
        let unseen = std::mem::take(&mut self.frames_unseen);
        if unseen > 0 && !errors.is_empty() {
            format!("{tracking}, out of view in {unseen} frames")
        } else {
            tracking
        }
    }
}
