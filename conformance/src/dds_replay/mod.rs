//! The DDS-level replay: a trace's plan ([`crate::dds_plan`]) carried out by real
//! `rl controller --json-events` processes talking over DDS on loopback.
//!
//! Faults are real: a crash is `kill -9`, a restart or join is a new process, and a lost
//! heartbeat is dropped on arrival by the receiving process (the `fault-injection` build of
//! `rl` reads `drop-heartbeats-from <id>` / `accept-heartbeats-from <id>` on its stdin): a
//! `LoseHeartbeat { from, to }` in round `r` makes `to` drop `from`'s heartbeats for that
//! round, a loss in consecutive rounds keeps dropping.
//!
//! Timing (one round is one heartbeat period; rounds are multiples of it on the wall clock,
//! which controllers and harness share):
//!
//! - the processes start [`START_OFFSET_MS`] after a boundary; the first boundary at which
//!   any of them reports a change is the trace's boundary 1 (it must arrive within
//!   [`FIRST_REPORT_TIMEOUT`]);
//! - a round's faults are applied [`APPLY_OFFSET_MS`] after its boundary: after the
//!   boundary's decisions, before the heartbeats go out (a quarter period in);
//! - a boundary is observed [`OBSERVE_OFFSET_MS`] after it: each controller's latest `status`
//!   event with the later `alarm` events applied, mapped by the abstraction function;
//! - bounded waits ([`SETTLE_TIMEOUT`]) where the plan re-aligns or waits for the settled
//!   end, which must then hold for [`HOLD_ROUNDS`] more boundaries.
//!
//! If the first reports do not show the trace's boundary 1 (DDS discovery completed in
//! different rounds for different links, or took more than a round), or the harness was too
//! late to apply a fault on time, the attempt is not a replay of the trace: it is repeated
//! with fresh processes, up to [`ATTEMPTS`] times. Any other difference is a failure, reported
//! as expected against observed per controller with the tail of the processes' output.

use crate::abstraction::{self, IncarnationNumbers, Observed};
use crate::dds_plan::{Mode, Plan, RoundPlan, Selected};
use crate::diff::state_diff;
use crate::record::{round_of, LifeLog};
use crate::validate::Timing;
use model::traces::AbstractState;
use model::Action;
use rl::core::ControllerId;
use rl::event::{Event, EventLine};
use rl::procs::{wall_ms, Fleet, Line};
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ChildStdin;
use std::sync::mpsc::Receiver;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// Processes start this long after a round boundary.
pub const START_OFFSET_MS: u64 = 10;
/// A round's faults are applied this long after its boundary (heartbeats go out at a quarter
/// period).
pub const APPLY_OFFSET_MS: u64 = 20;
/// Applying later than this after the boundary would miss the round's heartbeats.
pub const APPLY_LATEST_MS: u64 = 50;
/// A boundary is observed this long after it (its reports are printed within milliseconds).
pub const OBSERVE_OFFSET_MS: u64 = 150;
/// The first reports must come within this long of the start.
pub const FIRST_REPORT_TIMEOUT: Duration = Duration::from_secs(10);
/// Bounded wait for a quiescent or settled boundary.
pub const SETTLE_TIMEOUT: Duration = Duration::from_secs(10);
/// The settled end must hold this many more boundaries.
pub const HOLD_ROUNDS: u64 = 2;
/// Attempts when the processes' timing does not line up with the trace.
pub const ATTEMPTS: usize = 3;
/// Lines of output shown with a failure.
const TAIL_LINES: usize = 50;

/// The `rl` configuration the replay runs with: the model's heartbeat period and dead-man
/// deadline, and an initialization window one round longer than the model's (3 rounds, not
/// 2): with 2, DDS discovery of a late process decides in which round its window expires,
/// which the late-join and fourth-controller traces depend on. The plan checks against the
/// model that every replayed trace reaches the same states with the 3-round window.
pub const CONFIG_TOML: &str = "\
# The DDS-level replay's timing (conformance/src/dds_replay.rs): one round = 250 ms.
[timing]
heartbeat_period_ms = 250
peer_deadline_ms = 500
init_window_ms = 750
";

/// The run's round lengths, read back through `rl`'s own configuration code.
pub fn timing() -> Result<Timing, String> {
    let config = rl::config::Config::from_toml_str(CONFIG_TOML, "replay configuration")
        .map_err(|e| e.to_string())?;
    Timing::from_config(&config.timing)
}

/// Builds `rl` with the `fault-injection` feature into `<workspace>/target/fault-injection`
/// (a target directory of its own, so the workspace's `target/release/rl` is not rebuilt back
/// and forth), once per process; returns the binary.
pub fn fault_injection_rl() -> Result<PathBuf, String> {
    static BUILT: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    BUILT.get_or_init(build_fault_injection_rl).clone()
}

fn build_fault_injection_rl() -> Result<PathBuf, String> {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let workspace = manifest.parent().unwrap_or(manifest);
    let target_dir = workspace.join("target").join("fault-injection");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_string());
    println!(
        "building rl with --features fault-injection into {} (once; the first build takes a \
         few minutes)",
        target_dir.display()
    );
    let started = Instant::now();
    let output = std::process::Command::new(&cargo)
        .current_dir(workspace)
        .args([
            "build",
            "--release",
            "-p",
            "rl",
            "--features",
            "fault-injection",
        ])
        .arg("--target-dir")
        .arg(&target_dir)
        .output()
        .map_err(|e| format!("could not run {cargo}: {e}"))?;
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr);
        let tail: Vec<&str> = stderr.lines().rev().take(30).collect();
        return Err(format!(
            "cargo build --release -p rl --features fault-injection --target-dir {} failed \
             ({}):\n{}",
            target_dir.display(),
            output.status,
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        ));
    }
    let exe = target_dir.join("release").join("rl");
    if !exe.is_file() {
        return Err(format!("cargo succeeded but {} is missing", exe.display()));
    }
    println!(
        "built {} in {:.1} s",
        exe.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(exe)
}

/// A replay that matched the model.
#[derive(Clone, Debug)]
pub struct Replayed {
    pub file: String,
    pub attempts: usize,
    /// Boundaries compared in lockstep (each on its own real round).
    pub lockstep_boundaries: usize,
    /// Real rounds from the first reports to the end of the hold.
    pub rounds: u64,
    pub elapsed: Duration,
    /// The recorded events (one log per process) and the run's `rl.toml`.
    pub record_dir: PathBuf,
}

/// Why an attempt did not conform.
#[derive(Debug)]
struct AttemptError {
    /// The processes' timing did not line up with the trace: try again.
    retry: bool,
    message: String,
}

/// Replays one selected trace on `domain`; the events are recorded in `record_dir`
/// (emptied first).
pub fn replay(
    selected: &Selected,
    exe: &Path,
    domain: u16,
    record_dir: &Path,
) -> Result<Replayed, String> {
    let timing = timing()?;
    let started = Instant::now();
    let mut reasons = Vec::new();
    for attempt in 1..=ATTEMPTS {
        prepare_dir(record_dir)?;
        let mut run = Run::start(selected, exe, domain, record_dir, timing.period_ms)?;
        let outcome = run.carry_out();
        run.stop();
        run.write_record(record_dir)?;
        match outcome {
            Ok((lockstep_boundaries, rounds)) => {
                return Ok(Replayed {
                    file: selected.plan.file.clone(),
                    attempts: attempt,
                    lockstep_boundaries,
                    rounds,
                    elapsed: started.elapsed(),
                    record_dir: record_dir.to_path_buf(),
                })
            }
            Err(error) if error.retry && attempt < ATTEMPTS => {
                println!(
                    "{}: attempt {attempt} did not line up with the trace, retrying: {}",
                    selected.plan.file,
                    error.message.lines().next().unwrap_or("")
                );
                reasons.push(error.message);
                std::thread::sleep(Duration::from_millis(300));
            }
            Err(error) => {
                let mut message = format!(
                    "DDS-level replay of traces/{} ({}: {}), attempt {attempt}:\n{}",
                    selected.plan.file, selected.curated.name, selected.plan.purpose, error.message
                );
                if !reasons.is_empty() {
                    let _ = write!(
                        message,
                        "\nearlier attempts did not line up with the trace:\n  {}",
                        reasons.join("\n  ")
                    );
                }
                let _ = write!(message, "\nthe events are kept in {}", record_dir.display());
                return Err(message);
            }
        }
    }
    Err(format!(
        "{}: no attempt lined up with the trace",
        selected.plan.file
    ))
}

fn prepare_dir(dir: &Path) -> Result<(), String> {
    if dir.exists() {
        std::fs::remove_dir_all(dir).map_err(|e| format!("emptying {}: {e}", dir.display()))?;
    }
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    std::fs::write(dir.join("rl.toml"), CONFIG_TOML)
        .map_err(|e| format!("writing {}: {e}", dir.join("rl.toml").display()))
}

/// One process of the run.
struct Life {
    log: LifeLog,
    /// The real round it was started in (it is up from the next boundary on).
    spawned_round: u64,
    /// The real round it was killed in (down from the next boundary on).
    killed_round: Option<u64>,
    /// Whether its stamp came from its own output yet.
    stamped: bool,
    stdin: Option<ChildStdin>,
    /// Peers whose heartbeats it drops now.
    dropping: BTreeSet<ControllerId>,
}

struct Run<'a> {
    plan: &'a Plan,
    fleet: Fleet,
    lines: Receiver<Line>,
    period_ms: u64,
    lives: Vec<Life>,
    /// Everything the processes printed, `(source, line)`, in arrival order.
    output: Vec<(String, String)>,
    /// Readable lines for failure reports.
    transcript: Vec<String>,
    /// The real round of the first boundary, once known.
    first_round: Option<u64>,
}

impl<'a> Run<'a> {
    fn start(
        selected: &'a Selected,
        exe: &Path,
        domain: u16,
        dir: &Path,
        period_ms: u64,
    ) -> Result<Run<'a>, String> {
        let config = dir.join("rl.toml");
        let (mut fleet, lines) = Fleet::new(exe, Some(&config), domain);
        fleet.env("RUST_LOG", "warn");
        Ok(Run {
            plan: &selected.plan,
            fleet,
            lines,
            period_ms,
            lives: Vec::new(),
            output: Vec::new(),
            transcript: Vec::new(),
            first_round: None,
        })
    }

    fn carry_out(&mut self) -> Result<(usize, u64), AttemptError> {
        let plan = self.plan;
        // Round 0: the initial controllers and round 0's faults, right after a boundary.
        let start_round = round_of(wall_ms(), self.period_ms) + 1;
        self.sleep_until(start_round * self.period_ms + START_OFFSET_MS);
        for id in plan.initial_up.clone() {
            self.spawn(id, start_round)?;
        }
        self.apply(&plan.rounds[0], start_round)?;
        let first = self.await_first_reports()?;
        let modes = plan.modes();
        let mut base = (1usize, first);
        let mut lockstep = 0;
        let mut last_real = first;
        for (k, mode) in modes.iter().enumerate().skip(1) {
            match mode {
                Mode::Start => {}
                Mode::Lockstep => {
                    let real = base.1 + (k - base.0) as u64;
                    if let Some(round) = plan.rounds.get(k) {
                        self.apply_on_time(round, real)?;
                    }
                    self.sleep_until(real * self.period_ms + OBSERVE_OFFSET_MS);
                    if k == 1 {
                        self.compare(k, real, "the first reports")
                            .map_err(|mut e| {
                                // DDS discovery, not the protocol: try again.
                                e.retry = true;
                                e
                            })?;
                    } else {
                        self.compare(k, real, "lockstep")?;
                    }
                    lockstep += 1;
                    last_real = real;
                }
                Mode::Realign => {
                    let matched = self.await_state(k, 2)?;
                    base = (k, matched + 1);
                    self.apply_on_time(&plan.rounds[k], matched + 1)?;
                    last_real = matched + 1;
                }
                Mode::Free => {
                    if k == plan.last() {
                        last_real = self.await_state(k, 1)?;
                    }
                }
            }
        }
        for real in last_real + 1..=last_real + HOLD_ROUNDS {
            self.sleep_until(real * self.period_ms + OBSERVE_OFFSET_MS);
            self.compare(plan.last(), real, "settled end, held")?;
        }
        Ok((lockstep, last_real + HOLD_ROUNDS + 1 - first))
    }

    /// Waits for the first reports: their round is the trace's boundary 1 (compared in the
    /// lockstep, where a difference means the start did not line up with the trace).
    fn await_first_reports(&mut self) -> Result<u64, AttemptError> {
        let deadline = Instant::now() + FIRST_REPORT_TIMEOUT;
        let first = loop {
            self.pump(Duration::from_millis(5));
            let earliest = self
                .lives
                .iter()
                .flat_map(|l| l.log.events.iter())
                .filter(|e| matches!(e.event, Event::Status { .. }))
                .map(|e| e.t_ms)
                .min();
            if let Some(t_ms) = earliest {
                break round_of(t_ms, self.period_ms);
            }
            if Instant::now() >= deadline {
                return Err(self.failure(
                    false,
                    format!(
                        "no controller reported anything within {FIRST_REPORT_TIMEOUT:?} of \
                         the start (DDS discovery failed?)"
                    ),
                ));
            }
        };
        self.first_round = Some(first);
        let late_ms = wall_ms().saturating_sub(first * self.period_ms);
        if late_ms > APPLY_LATEST_MS && self.plan.rounds.get(1).is_some_and(|r| !r.is_empty()) {
            return Err(self.failure(
                true,
                format!("the first reports were read {late_ms} ms after their boundary, too late to apply round 1's faults"),
            ));
        }
        // Discovery: every process started in round 0 must be heard from the trace's round 0
        // or the round before (the plan checked that both lead to the same states).
        for life in self.lives.iter().filter(|l| l.killed_round.is_none()) {
            let heard_late = (first - 1).saturating_sub(life.spawned_round);
            if heard_late > 1 {
                return Err(self.failure(
                    true,
                    format!(
                        "C{} was first heard {heard_late} rounds after it started (DDS \
                         discovery); the plan allows one",
                        life.log.id
                    ),
                ));
            }
        }
        Ok(first)
    }

    /// Waits until boundary `k`'s state is observed at `times` consecutive boundaries;
    /// returns the real round of the last.
    fn await_state(&mut self, k: usize, times: u64) -> Result<u64, AttemptError> {
        let expected = self.plan.expected(k);
        let deadline = Instant::now() + SETTLE_TIMEOUT;
        let mut run = 0;
        let mut real = round_of(wall_ms(), self.period_ms);
        loop {
            self.sleep_until(real * self.period_ms + OBSERVE_OFFSET_MS);
            let observed = self.observe(real)?;
            if observed == expected {
                run += 1;
                if run >= times {
                    return Ok(real);
                }
            } else {
                run = 0;
                if Instant::now() >= deadline {
                    return Err(self.failure(
                        false,
                        format!(
                            "boundary {k} of {} ({}) was not reached within {SETTLE_TIMEOUT:?}; \
                             at round {real}:\n{}",
                            self.plan.last(),
                            if k == self.plan.last() {
                                "the settled end"
                            } else {
                                "quiescent, faults follow"
                            },
                            state_diff("processes", "the processes'", &expected, &observed)
                        ),
                    ));
                }
            }
            real += 1;
        }
    }

    fn compare(&mut self, k: usize, real: u64, how: &str) -> Result<(), AttemptError> {
        let expected = self.plan.expected(k);
        let observed = self.observe(real)?;
        if observed == expected {
            return Ok(());
        }
        let first = self.first_round.unwrap_or(real);
        Err(self.failure(
            false,
            format!(
                "at boundary {k} of {} ({how}; real round {real}, {} after the first reports):\n{}",
                self.plan.last(),
                real - first,
                state_diff("processes", "the processes'", &expected, &observed)
            ),
        ))
    }

    /// A round's faults, at its start: on time or not at all.
    fn apply_on_time(&mut self, round: &RoundPlan, real: u64) -> Result<(), AttemptError> {
        let boundary_ms = real * self.period_ms;
        self.sleep_until(boundary_ms + APPLY_OFFSET_MS);
        let late_ms = wall_ms().saturating_sub(boundary_ms);
        if late_ms > APPLY_LATEST_MS && !round.is_empty() {
            return Err(self.failure(
                true,
                format!("the harness reached round {real} {late_ms} ms late, after its heartbeats"),
            ));
        }
        self.apply(round, real)
    }

    /// Starts, kills, and sets every live process's dropped peers to the round's losses.
    fn apply(&mut self, round: &RoundPlan, real: u64) -> Result<(), AttemptError> {
        for action in &round.lifecycle {
            match *action {
                Action::Crash { controller } => {
                    if let Err(e) = self.fleet.kill(controller) {
                        return Err(self.failure(false, format!("kill -9 C{controller}: {e}")));
                    }
                    if let Some(life) = self.current_mut(controller) {
                        life.killed_round = Some(real);
                        life.stdin = None;
                    }
                }
                Action::Join { controller } | Action::Restart { controller } => {
                    self.spawn(controller, real)?;
                }
                _ => {}
            }
        }
        for life in self.lives.iter_mut().filter(|l| l.killed_round.is_none()) {
            let id = life.log.id;
            let wanted: BTreeSet<ControllerId> = round
                .lost
                .iter()
                .filter(|(_, to)| *to == id)
                .map(|(from, _)| *from)
                .collect();
            let Some(stdin) = life.stdin.as_mut() else {
                continue;
            };
            let mut commands = String::new();
            for from in wanted.difference(&life.dropping) {
                let _ = writeln!(commands, "drop-heartbeats-from {from}");
            }
            for from in life.dropping.difference(&wanted) {
                let _ = writeln!(commands, "accept-heartbeats-from {from}");
            }
            if !commands.is_empty() {
                stdin
                    .write_all(commands.as_bytes())
                    .and_then(|()| stdin.flush())
                    .map_err(|e| AttemptError {
                        retry: false,
                        message: format!("C{id}'s fault-injection control (stdin): {e}"),
                    })?;
                life.dropping = wanted;
            }
        }
        Ok(())
    }

    fn current_mut(&mut self, id: ControllerId) -> Option<&mut Life> {
        self.lives.iter_mut().rev().find(|l| l.log.id == id)
    }

    fn spawn(&mut self, id: ControllerId, real: u64) -> Result<(), AttemptError> {
        let number = self.lives.iter().filter(|l| l.log.id == id).count() as u8;
        let source = if number == 0 {
            format!("C{id}")
        } else {
            format!("C{id}#{number}")
        };
        let started = self
            .fleet
            .start_controller_piped(id, &source, &["--json-events"]);
        let stdin = match started {
            Ok((_, stdin)) => stdin,
            Err(e) => {
                return Err(self.failure(false, format!("starting rl controller --id {id}: {e}")))
            }
        };
        self.lives.push(Life {
            log: LifeLog {
                id,
                // Until it prints its stamp: a placeholder no real start produces.
                incarnation: u64::MAX - (u64::from(id) << 8) - u64::from(number),
                source,
                events: Vec::new(),
            },
            spawned_round: real,
            killed_round: None,
            stamped: false,
            stdin: Some(stdin),
            dropping: BTreeSet::new(),
        });
        Ok(())
    }

    /// What the processes reported by the boundary of real round `real`, abstracted.
    fn observe(&self, real: u64) -> Result<AbstractState, AttemptError> {
        let mut numbers = IncarnationNumbers::new();
        for life in &self.lives {
            numbers.started(life.log.id, life.log.incarnation);
        }
        let count = self.plan.boundaries[0].controllers.len();
        let observed: Vec<Observed> = (1..=count as ControllerId)
            .map(|id| {
                let life = self
                    .lives
                    .iter()
                    .rev()
                    .find(|l| l.log.id == id && l.spawned_round < real);
                match life {
                    None => Observed::NotStarted,
                    Some(life) if life.killed_round.is_some_and(|k| k < real) => Observed::Down {
                        incarnation: life.log.incarnation,
                    },
                    Some(life) => {
                        Observed::Up(Box::new(life.log.status_at_boundary(real, self.period_ms)))
                    }
                }
            })
            .collect();
        abstraction::abstract_state(&observed, &numbers).map_err(|e| AttemptError {
            retry: false,
            message: format!("abstraction: {e}"),
        })
    }

    /// Takes in what the processes printed, waiting up to `wait` for the first line.
    fn pump(&mut self, wait: Duration) {
        let mut first = true;
        loop {
            let line = if first {
                self.lines.recv_timeout(wait).ok()
            } else {
                self.lines.try_recv().ok()
            };
            first = false;
            let Some(line) = line else {
                break;
            };
            self.take(line);
        }
    }

    fn take(&mut self, line: Line) {
        let now = wall_ms();
        let round = round_of(now, self.period_ms);
        let relative = self.first_round.map_or(String::new(), |f| {
            format!(" ({:+})", round as i64 - f as i64)
        });
        let shown = match EventLine::parse(&line.text) {
            Some(event) => {
                let is_leds = matches!(event.event, Event::Leds { .. });
                let shown = (!is_leds).then(|| crate::record::describe_event(&event, None));
                if let Some(life) = self.lives.iter_mut().find(|l| l.log.source == line.source) {
                    if !life.stamped {
                        life.log.incarnation = event.incarnation;
                        life.stamped = true;
                    }
                    life.log.events.push(event);
                }
                shown
            }
            None => Some(without_terminal_colours(&line.text)),
        };
        if let Some(shown) = shown {
            self.transcript.push(format!(
                "{now} round {round}{relative} {}: {shown}",
                line.source
            ));
        }
        self.output.push((line.source, line.text));
    }

    fn sleep_until(&mut self, target_ms: u64) {
        loop {
            let now = wall_ms();
            if now >= target_ms {
                self.pump(Duration::ZERO);
                return;
            }
            self.pump(Duration::from_millis((target_ms - now).min(20)));
        }
    }

    fn failure(&self, retry: bool, problem: String) -> AttemptError {
        let mut message = problem;
        let _ = writeln!(message, "  plan: {}", self.plan.describe());
        let lives: Vec<String> = self
            .lives
            .iter()
            .map(|l| {
                format!(
                    "{} (started round {}{})",
                    l.log.source,
                    l.spawned_round,
                    l.killed_round
                        .map_or(String::new(), |k| format!(", killed round {k}"))
                )
            })
            .collect();
        let _ = writeln!(message, "  processes: {}", lives.join(", "));
        let _ = writeln!(
            message,
            "  --- the last {TAIL_LINES} lines the processes printed (wall ms, round, rounds \
             since the first reports; leds events left out) ---"
        );
        let skip = self.transcript.len().saturating_sub(TAIL_LINES);
        for line in &self.transcript[skip..] {
            let _ = writeln!(message, "  {line}");
        }
        AttemptError { retry, message }
    }

    /// Stops every process (SIGTERM, then SIGKILL) and takes in their last lines.
    fn stop(&mut self) {
        self.fleet.stop_all();
        self.pump(Duration::from_millis(200));
    }

    /// One log per process (`C1.log`, `C3#1.log`, `C1.stderr.log`) in `dir`.
    fn write_record(&self, dir: &Path) -> Result<(), String> {
        let mut files: BTreeMap<String, String> = BTreeMap::new();
        for (source, text) in &self.output {
            let name = format!("{}.log", source.replace('!', ".stderr"));
            let file = files.entry(name).or_default();
            file.push_str(text);
            file.push('\n');
        }
        for (name, text) in files {
            let path = dir.join(&name);
            std::fs::write(&path, text).map_err(|e| format!("writing {}: {e}", path.display()))?;
        }
        Ok(())
    }
}

/// A log line without its ANSI colour sequences (`ESC [ ... m`).
fn without_terminal_colours(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut chars = text.chars();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            for end in chars.by_ref() {
                if end.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            out.push(c);
        }
    }
    out
}
