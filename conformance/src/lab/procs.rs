//! The processes of a run, each inside its node's namespace: three `rl controller
//! --json-events` (with `--network-a`/`--network-b`, their addresses on the two nets, when the
//! `rl` monitors networks, and `--config` when they form a named group, `super::two_groups`),
//! `rl servo --json` and the Connext reader on the actuator side (and, in the wrong-output
//! scenarios, `rl servo --vote --json` beside them), `rl shapes` on the camera. Every line they
//! print comes back on one channel stamped with the lab clock. A controller's stdin stays open
//! for its life: a `fault-injection` build reads `wrong-commands` lines there
//! (`super::wrong_output`).
//!
//! A controller's life is one process: `C2` for the first, `C2#2` after a restart. A
//! controller that exits 75 (it voted itself FAILED) is restarted a second later, as the
//! systemd unit does (`impl/debian/rl@.service`, `RestartForceExitStatus=75`); any other exit
//! of a process that should be running is a death the alive judge reports.

use super::clock::LabClock;
use super::error::LabError;
use super::faults::{WrongAnswer, RIGHT_COMMANDS_LINE};
use super::host::LIBFAKETIME;
use super::lan::{Lan, Net, Node};
use super::wrong_output::Injection;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::Sender;
use std::time::Duration;

/// A line a process printed: when (lab ms), which process (`C1#2`, `servo`, ...; stderr lines
/// carry `!` after the name) and the text.
#[derive(Clone, Debug)]
pub struct Line {
    pub at_ms: f64,
    pub source: String,
    pub text: String,
}

/// One controller life as the run saw it.
#[derive(Clone, Debug)]
pub struct Life {
    pub id: u8,
    /// 1 for the first process with this id, 2 after its first restart, ...
    pub number: u32,
    pub pid: u32,
    /// Its wall clock's offset (seconds): the clock-offset fault.
    pub clock_offset_s: f64,
    /// Its clocks' rate (1.0: true; 1.01: 1% fast): the clock-drift fault.
    pub clock_rate: f64,
    pub started_ms: f64,
    /// When it started, on the true wall clock (Unix ms): where a fast clock starts gaining.
    pub started_wall_ms: f64,
    /// When it was killed, stopped or exited (lab ms).
    pub ended_ms: Option<f64>,
    /// SIGSTOP .. SIGCONT intervals (lab ms).
    pub paused: Vec<(f64, Option<f64>)>,
    /// How it ended, when it ended by itself.
    pub exit: Option<String>,
}

impl Life {
    /// What the lab takes off an event this life stamped at `t_ms` (its own wall clock, Unix
    /// ms): its clock's error at that moment (the offset, plus what a fast clock has gained
    /// since the process started) to the nearest whole heartbeat period. Controllers follow the
    /// Primary's round phase (`rl_layer::round_clock`), so the rest of an error is absorbed by the
    /// controllers themselves, and taking off the whole periods puts every life on the
    /// system's shared round clock (the model's rounds). A fast clock's correction grows with
    /// its error, so a restart onto the true clock continues the old life's rounds instead of
    /// starting in rounds the old life had already stamped.
    pub fn round_clock_correction_ms(&self, t_ms: u64) -> i64 {
        let period_ms = rl_layer::config::Config::default()
            .timing
            .heartbeat_period_ms as f64;
        let offset_ms = self.clock_offset_s * 1000.0;
        // libfaketime's clock: started + offset + (true - started) x rate; solved for its
        // error (clock - true) at the clock's reading `t_ms`.
        let run_on_own_clock_ms = (t_ms as f64 - self.started_wall_ms - offset_ms).max(0.0);
        let gained_ms = if self.clock_rate > 0.0 {
            run_on_own_clock_ms * (self.clock_rate - 1.0) / self.clock_rate
        } else {
            0.0
        };
        (((offset_ms + gained_ms) / period_ms).round() * period_ms) as i64
    }

    /// `C2`, or `C2#3` for its third process.
    pub fn label(&self) -> String {
        label(self.id, self.number)
    }
}

/// `C2`, or `C2#3` for the third process of controller 2.
pub fn label(id: u8, number: u32) -> String {
    match number {
        1 => format!("C{id}"),
        n => format!("C{id}#{n}"),
    }
}

/// A process that is not a controller: the servo, the camera, the Connext reader.
struct Helper {
    name: &'static str,
    child: Child,
    exited: Option<String>,
}

/// The processes of a run.
pub struct Procs {
    rl: PathBuf,
    domain: u16,
    clock: LabClock,
    lines: Sender<Line>,
    namespaces: BTreeMap<Node, String>,
    /// Every controller life, in start order.
    pub lives: Vec<Life>,
    running: BTreeMap<u8, Child>,
    /// Each running controller's stdin, open for its life (fault-injection lines).
    stdins: BTreeMap<u8, ChildStdin>,
    /// Every wrong output asked of a controller, in order.
    pub injections: Vec<Injection>,
    /// The clock offset each controller id gets when it next starts.
    pub clock_offsets_s: BTreeMap<u8, f64>,
    /// The clock rate (1.0: true) each controller id gets when it next starts.
    pub clock_rates: BTreeMap<u8, f64>,
    helpers: Vec<Helper>,
    /// Restarts due (lab ms) of controllers that exited 75.
    restarts_due: BTreeMap<u8, f64>,
    /// The deliberately broken rule every controller life runs (`RL_MUTATION`), if any.
    pub mutation: Option<String>,
    /// Whether the `rl` takes `--network-a`/`--network-b` (it runs network alarm participants).
    pub two_networks: bool,
    /// The configuration file every controller life gets (`--config`): a redundancy group's
    /// (`super::two_groups`); `None`, the defaults, in every other scenario.
    pub config: Option<PathBuf>,
}

/// Whether `rl controller` at `rl` takes `--network-a` (its `--help` says so).
pub fn monitors_networks(rl: &std::path::Path) -> bool {
    Command::new(rl)
        .args(["controller", "--help"])
        .output()
        .is_ok_and(|out| String::from_utf8_lossy(&out.stdout).contains("--network-a"))
}

impl Procs {
    pub fn new(rl: PathBuf, domain: u16, lan: &Lan, clock: LabClock, lines: Sender<Line>) -> Procs {
        Procs {
            two_networks: monitors_networks(&rl),
            rl,
            domain,
            clock,
            lines,
            namespaces: Node::all().iter().map(|n| (*n, lan.ns(*n))).collect(),
            lives: Vec::new(),
            running: BTreeMap::new(),
            stdins: BTreeMap::new(),
            injections: Vec::new(),
            clock_offsets_s: BTreeMap::new(),
            clock_rates: BTreeMap::new(),
            helpers: Vec::new(),
            restarts_due: BTreeMap::new(),
            mutation: None,
            config: None,
        }
    }

    /// The `rl` binary the processes run.
    pub fn rl(&self) -> &std::path::Path {
        &self.rl
    }

    /// `ip netns exec NS env [faketime] [RL_MUTATION] program args`. `ip netns exec` passes
    /// the lab's environment on; `RL_MUTATION` and `RL_VOTE_MUTATION` are taken out of it, so
    /// only a controller of a `--mutation` run, or the voting servo of a `--vote-mutation` run,
    /// ever has one.
    fn command(
        &self,
        node: Node,
        env: &[(String, String)],
        program: &str,
        args: &[&str],
    ) -> Command {
        let mut command = Command::new("ip");
        command
            .env_remove(super::mutation::VARIABLE)
            .env_remove(super::mutation::VOTE_VARIABLE)
            .args(["netns", "exec", &self.namespaces[&node], "env"])
            .args(env.iter().map(|(k, v)| format!("{k}={v}")))
            .arg(program)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        command
    }

    fn forward(&self, child: &mut Child, source: &str) {
        if let Some(stdout) = child.stdout.take() {
            spawn_reader(stdout, source.to_string(), self.clock, self.lines.clone());
        }
        if let Some(stderr) = child.stderr.take() {
            spawn_reader(stderr, format!("{source}!"), self.clock, self.lines.clone());
        }
    }

    /// Starts the next life of controller `id` (with its clock offset, if it has one).
    pub fn start_controller(&mut self, id: u8) -> Result<(), LabError> {
        if self.running.contains_key(&id) {
            // Overlapping faults may both restart it: one process per id.
            return Ok(());
        }
        let offset_s = self.clock_offsets_s.get(&id).copied().unwrap_or(0.0);
        let rate = self.clock_rates.get(&id).copied().unwrap_or(1.0);
        let mut env = if offset_s == 0.0 && rate == 1.0 {
            Vec::new()
        } else if rate == 1.0 {
            // The wall clock only: the round clock then starts off and runs true.
            vec![
                ("LD_PRELOAD".into(), LIBFAKETIME.into()),
                ("FAKETIME".into(), format!("{offset_s:+}")),
                ("FAKETIME_DONT_FAKE_MONOTONIC".into(), "1".into()),
            ]
        } else {
            // Every clock, monotonic included, and sleeps, at `rate`: a fast crystal.
            vec![
                ("LD_PRELOAD".into(), LIBFAKETIME.into()),
                ("FAKETIME".into(), format!("{offset_s:+} x{rate}")),
            ]
        };
        if let Some(name) = &self.mutation {
            env.push((super::mutation::VARIABLE.into(), name.clone()));
        }
        let rl = self.rl.display().to_string();
        let (id_text, domain) = (id.to_string(), self.domain.to_string());
        let mut args = vec![
            "controller".to_string(),
            "--id".into(),
            id_text,
            "--json-events".into(),
            "--domain".into(),
            domain,
        ];
        if let Some(config) = &self.config {
            args.extend(["--config".to_string(), config.display().to_string()]);
        }
        if self.two_networks {
            let me = Node::Controller(id);
            for (option, net) in [("--network-a", Net::A), ("--network-b", Net::B)] {
                args.extend([option.to_string(), me.addr(net)]);
            }
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let number = self.lives.iter().filter(|l| l.id == id).count() as u32 + 1;
        let mut child = self
            .command(Node::Controller(id), &env, &rl, &args)
            .stdin(Stdio::piped())
            .spawn()
            .map_err(|source| LabError::Spawn {
                what: label(id, number),
                source,
            })?;
        self.forward(&mut child, &label(id, number));
        if let Some(stdin) = child.stdin.take() {
            self.stdins.insert(id, stdin);
        }
        self.lives.push(Life {
            id,
            number,
            pid: child.id(),
            clock_offset_s: offset_s,
            clock_rate: rate,
            started_ms: self.clock.now_ms(),
            started_wall_ms: super::clock::wall_ms(),
            ended_ms: None,
            paused: Vec::new(),
            exit: None,
        });
        self.running.insert(id, child);
        Ok(())
    }

    /// Asks the running life of controller `id` for wrong commands (`Some`) or right ones
    /// again (`None`), on its stdin, and records it. A controller without a process is left
    /// alone (nothing is recorded, so the judges see no injection); one whose stdin is closed
    /// has just exited, and a restarted life starts right anyway.
    pub fn inject_wrong_output(
        &mut self,
        id: u8,
        wrong: Option<WrongAnswer>,
    ) -> Result<(), LabError> {
        let now = self.clock.now_ms();
        let Some(life) = self.current(id).map(|l| l.label()) else {
            return Ok(());
        };
        let line = wrong.map_or_else(|| RIGHT_COMMANDS_LINE.to_string(), WrongAnswer::line);
        if let Some(stdin) = self.stdins.get_mut(&id) {
            let _ = writeln!(stdin, "{line}").and_then(|()| stdin.flush());
        }
        match wrong {
            Some(wrong) => self.injections.push(Injection {
                id,
                life,
                wrong,
                from_ms: now,
                healed_ms: None,
            }),
            None => {
                for open in self.injections.iter_mut().filter(|i| i.id == id) {
                    open.healed_ms.get_or_insert(now);
                }
            }
        }
        Ok(())
    }

    /// The life of controller `id` that runs now.
    pub fn current(&mut self, id: u8) -> Option<&mut Life> {
        self.running.contains_key(&id).then_some(())?;
        self.lives.iter_mut().rev().find(|l| l.id == id)
    }

    /// `kill -9` (after SIGCONT if paused) and reap.
    pub fn kill(&mut self, id: u8) {
        self.end(id, libc::SIGKILL);
    }

    /// SIGTERM, so it says `stopped`; SIGKILL after two seconds.
    pub fn stop(&mut self, id: u8) {
        self.end(id, libc::SIGTERM);
    }

    fn end(&mut self, id: u8, signal: i32) {
        let now = self.clock.now_ms();
        self.stdins.remove(&id);
        let Some(mut child) = self.running.remove(&id) else {
            return;
        };
        let _ = rl::procs::signal(child.id(), libc::SIGCONT);
        let _ = rl::procs::signal(child.id(), signal);
        let deadline = std::time::Instant::now() + Duration::from_secs(2);
        while !matches!(child.try_wait(), Ok(Some(_))) && std::time::Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(10));
        }
        let _ = child.kill();
        let _ = child.wait();
        if let Some(life) = self.lives.iter_mut().rev().find(|l| l.id == id) {
            life.ended_ms = Some(now);
            close_pause(life, now);
        }
    }

    /// SIGSTOP (`stop`) or SIGCONT to controller `id`.
    pub fn pause(&mut self, id: u8, stop: bool) -> Result<(), LabError> {
        let now = self.clock.now_ms();
        let Some(pid) = self.running.get(&id).map(Child::id) else {
            return Ok(());
        };
        let signal = if stop { libc::SIGSTOP } else { libc::SIGCONT };
        rl::procs::signal(pid, signal).map_err(|e| {
            LabError::command(
                "kill",
                &[if stop { "-STOP" } else { "-CONT" }],
                e.to_string(),
            )
        })?;
        self.mark_paused_at(id, stop, now);
        Ok(())
    }

    /// Records that controller `id` stands still from now (`paused`) or runs again, stopped
    /// by other means than a signal (a freezer cgroup): the recording's pauses.
    pub fn mark_paused(&mut self, id: u8, paused: bool) {
        let now = self.clock.now_ms();
        self.mark_paused_at(id, paused, now);
    }

    fn mark_paused_at(&mut self, id: u8, paused: bool, now: f64) {
        if let Some(life) = self.current(id) {
            if paused {
                life.paused.push((now, None));
            } else {
                close_pause(life, now);
            }
        }
    }

    /// The DDS domain the processes run on.
    pub fn domain(&self) -> u16 {
        self.domain
    }

    /// Starts a helper process on `node`: `rl` with `args`, or another program.
    pub fn start_helper(
        &mut self,
        name: &'static str,
        node: Node,
        program: Option<&str>,
        args: &[&str],
    ) -> Result<(), LabError> {
        self.start_helper_with(name, node, program, args, &[])
    }

    /// [`Procs::start_helper`] with `env` set for it alone.
    pub fn start_helper_with(
        &mut self,
        name: &'static str,
        node: Node,
        program: Option<&str>,
        args: &[&str],
        env: &[(String, String)],
    ) -> Result<(), LabError> {
        let rl = self.rl.display().to_string();
        let program = program.unwrap_or(&rl);
        let mut child = self
            .command(node, env, program, args)
            .spawn()
            .map_err(|source| LabError::Spawn {
                what: name.into(),
                source,
            })?;
        self.forward(&mut child, name);
        self.helpers.push(Helper {
            name,
            child,
            exited: None,
        });
        Ok(())
    }

    /// Notices exits: a controller that exited 75 is restarted a second later; any other exit
    /// is recorded on its life (or helper) for the alive judge.
    pub fn poll(&mut self) -> Result<(), LabError> {
        let now = self.clock.now_ms();
        let mut exited = Vec::new();
        for (id, child) in &mut self.running {
            if let Ok(Some(status)) = child.try_wait() {
                exited.push((*id, status));
            }
        }
        for (id, status) in exited {
            self.running.remove(&id);
            self.stdins.remove(&id);
            if let Some(life) = self.lives.iter_mut().rev().find(|l| l.id == id) {
                life.ended_ms = Some(now);
                life.exit = Some(status.to_string());
            }
            if status.code() == Some(rl_layer::failed_exit::EXIT_STATUS.into()) {
                self.restarts_due.insert(id, now + 1000.0);
            }
        }
        let due: Vec<u8> = self
            .restarts_due
            .iter()
            .filter(|(_, at)| **at <= now)
            .map(|(id, _)| *id)
            .collect();
        for id in due {
            self.restarts_due.remove(&id);
            self.start_controller(id)?;
        }
        for helper in &mut self.helpers {
            if helper.exited.is_none() {
                if let Ok(Some(status)) = helper.child.try_wait() {
                    helper.exited = Some(status.to_string());
                }
            }
        }
        Ok(())
    }

    /// Whether controller `id` has a running process.
    pub fn is_running(&self, id: u8) -> bool {
        self.running.contains_key(&id)
    }

    /// The pid of controller `id`'s running process.
    pub fn pid(&self, id: u8) -> Option<u32> {
        self.running.get(&id).map(Child::id)
    }

    /// Processes that should run and do not: controllers without a process (and no restart
    /// due) and helpers that exited, each with how it ended.
    pub fn dead(&self, ids: &[u8]) -> Vec<String> {
        let mut dead = Vec::new();
        for id in ids {
            if !self.running.contains_key(id) && !self.restarts_due.contains_key(id) {
                let how = self
                    .lives
                    .iter()
                    .rev()
                    .find(|l| l.id == *id)
                    .and_then(|l| l.exit.clone())
                    .unwrap_or_else(|| "never started".into());
                dead.push(format!("C{id} ({how})"));
            }
        }
        for helper in &self.helpers {
            if let Some(how) = &helper.exited {
                dead.push(format!("{} ({how})", helper.name));
            }
        }
        dead
    }

    /// Stops everything: controllers with SIGTERM (their `stopped` event), helpers killed.
    /// The actuators go first, so they never see the controllers leave.
    pub fn stop_all(&mut self) {
        for helper in &mut self.helpers {
            let _ = helper.child.kill();
            let _ = helper.child.wait();
        }
        self.helpers.clear();
        let ids: Vec<u8> = self.running.keys().copied().collect();
        for id in ids {
            self.stop(id);
        }
    }
}

impl Drop for Procs {
    fn drop(&mut self) {
        self.stop_all();
    }
}

fn close_pause(life: &mut Life, now: f64) {
    if let Some(last) = life.paused.last_mut() {
        if last.1.is_none() {
            last.1 = Some(now);
        }
    }
}

/// Each line of `input`, stamped on the lab clock, until it or the channel closes.
fn spawn_reader(
    input: impl std::io::Read + Send + 'static,
    source: String,
    clock: LabClock,
    to: Sender<Line>,
) {
    rl::procs::read_lines(input, to, move |text| {
        Some(Line {
            at_ms: clock.now_ms(),
            source: source.clone(),
            text,
        })
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Unix time in ms (2026).
    const STARTED: u64 = 1_795_000_000_000;

    fn life(clock_offset_s: f64, clock_rate: f64) -> Life {
        Life {
            id: 3,
            number: 1,
            pid: 0,
            clock_offset_s,
            clock_rate,
            started_ms: 0.0,
            started_wall_ms: STARTED as f64,
            ended_ms: None,
            paused: Vec::new(),
            exit: None,
        }
    }

    #[test]
    fn an_offset_clock_is_taken_back_by_whole_periods() {
        let late = life(-3600.0, 1.0);
        assert_eq!(
            late.round_clock_correction_ms(STARTED - 3_600_000),
            -3_600_000
        );
        // 0.1 s ahead: less than half a period, absorbed by following the Primary's phase.
        assert_eq!(life(0.1, 1.0).round_clock_correction_ms(STARTED + 100), 0);
        assert_eq!(life(0.2, 1.0).round_clock_correction_ms(STARTED + 200), 250);
    }

    #[test]
    fn a_fast_clock_is_taken_back_by_what_it_has_gained() {
        let fast = life(0.0, 1.01);
        // 10 s of true time read 10.1 s on its clock: 100 ms gained, under half a period.
        assert_eq!(fast.round_clock_correction_ms(STARTED + 10_100), 0);
        // 16 s: 160 ms gained, nearer one period than none.
        assert_eq!(fast.round_clock_correction_ms(STARTED + 16_160), 250);
        assert_eq!(
            life(0.0, 1.0).round_clock_correction_ms(STARTED + 16_160),
            0
        );
    }
}
