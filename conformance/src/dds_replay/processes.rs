//! The replay's child processes: `rl controller --json-events` with its stdin piped (the
//! fault-injection control), held before it votes until told, and `rl servo --json`, on
//! loopback or, for a trace with cuts, each in its node's network namespace of the virtual
//! LAN ([`Namespaces`]; `ip netns exec` execs the program, so the child's pid is the
//! program's and a signal reaches it). Every line they print reaches one channel, stamped
//! with the wall clock when it was read. The children are kept here, not in
//! `rl::procs::Fleet`, so the replay can tell a process that exited on its own
//! ([`Processes::exited`], `try_wait`) from one it killed.

use rl::procs::wall_ms;
use rl_layer::core::ControllerId;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, Sender};
use std::time::{Duration, Instant};

/// The control line that lets a held controller go: it starts its clock and votes.
pub const START_VOTING: &str = "start-voting\n";

/// The source name of the servo's lines.
pub const SERVO: &str = "servo";

/// A line a child printed: its source (`C1`, `C3#1`, `servo`; `C1!` for stderr), its text,
/// and the wall-clock milliseconds when it was read.
#[derive(Clone, Debug)]
pub struct Line {
    pub wall_ms: u64,
    pub source: String,
    pub text: String,
}

struct Process {
    source: String,
    child: Child,
    stdin: Option<ChildStdin>,
    /// Killed on purpose (the plan's crash): its exit is no failure.
    killed: bool,
    /// Its exit was already reported.
    exit_reported: bool,
}

/// The network namespace each process runs in, on the virtual LAN
/// (`crate::lab::lan::Lan::ns`).
#[derive(Clone, Debug, Default)]
pub struct Namespaces {
    pub controllers: BTreeMap<ControllerId, String>,
    pub servo: String,
}

/// The children of one attempt, stopped when dropped.
pub struct Processes {
    exe: PathBuf,
    /// Where each child runs; `None`: on loopback, in this namespace.
    namespaces: Option<Namespaces>,
    config: PathBuf,
    domain: u16,
    /// Environment for controllers only (`RL_MUTATION`).
    controller_env: Vec<(String, String)>,
    processes: Vec<Process>,
    lines: Sender<Line>,
}

impl Processes {
    /// Children of `exe` on `domain` with configuration `config`; controllers run with
    /// `RL_MUTATION=<mutation>` if one is given. Every line goes to the returned channel.
    pub fn new(
        exe: &Path,
        config: &Path,
        domain: u16,
        mutation: Option<&str>,
        namespaces: Option<Namespaces>,
    ) -> (Processes, Receiver<Line>) {
        let (lines, receiver) = mpsc::channel();
        let controller_env = mutation
            .map(|name| vec![("RL_MUTATION".to_string(), name.to_string())])
            .unwrap_or_default();
        let processes = Processes {
            exe: exe.to_path_buf(),
            namespaces,
            config: config.to_path_buf(),
            domain,
            controller_env,
            processes: Vec::new(),
            lines,
        };
        (processes, receiver)
    }

    /// `rl args ...` in namespace `ns` (`ip netns exec`, which passes the environment on), or
    /// here.
    fn command(&self, ns: Option<&str>, args: &[&str]) -> Command {
        let mut command = match ns {
            Some(ns) => {
                let mut command = Command::new("ip");
                command.args(["netns", "exec", ns]).arg(&self.exe);
                command
            }
            None => Command::new(&self.exe),
        };
        command
            .args(args)
            .arg("--config")
            .arg(&self.config)
            .arg("--domain")
            .arg(self.domain.to_string())
            .env("RUST_LOG", "warn")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        command
    }

    /// Starts `rl controller --id <id> --json-events` tagged `source`, its stdin piped, held
    /// before it votes (`RL_HOLD_START`) until it reads [`START_VOTING`].
    pub fn start_controller(&mut self, id: ControllerId, source: &str) -> std::io::Result<()> {
        let id_text = id.to_string();
        let ns = self
            .namespaces
            .as_ref()
            .map(|n| n.controllers.get(&id).cloned().ok_or(id))
            .transpose()
            .map_err(|id| std::io::Error::other(format!("no namespace for C{id}")))?;
        let args = ["controller", "--id", &id_text, "--json-events"];
        let mut command = self.command(ns.as_deref(), &args);
        command.stdin(Stdio::piped()).env("RL_HOLD_START", "1");
        for (key, value) in &self.controller_env {
            command.env(key, value);
        }
        self.spawn(command, source)
    }

    /// Starts `rl servo --json`.
    pub fn start_servo(&mut self) -> std::io::Result<()> {
        let ns = self.namespaces.as_ref().map(|n| n.servo.clone());
        let command = self.command(ns.as_deref(), &["servo", "--json"]);
        self.spawn(command, SERVO)
    }

    fn spawn(&mut self, mut command: Command, source: &str) -> std::io::Result<()> {
        let mut child = command.spawn()?;
        if let Some(stdout) = child.stdout.take() {
            read_lines(stdout, source.to_string(), self.lines.clone());
        }
        if let Some(stderr) = child.stderr.take() {
            read_lines(stderr, format!("{source}!"), self.lines.clone());
        }
        let stdin = child.stdin.take();
        self.processes.push(Process {
            source: source.to_string(),
            child,
            stdin,
            killed: false,
            exit_reported: false,
        });
        Ok(())
    }

    fn find(&mut self, source: &str) -> Option<&mut Process> {
        self.processes.iter_mut().find(|p| p.source == source)
    }

    /// `kill -9` and reap.
    pub fn kill(&mut self, source: &str) -> std::io::Result<()> {
        if let Some(process) = self.find(source) {
            process.killed = true;
            process.stdin = None;
            if process.child.try_wait()?.is_none() {
                process.child.kill()?;
            }
            process.child.wait()?;
        }
        Ok(())
    }

    /// Sends `signal` (SIGSTOP, SIGCONT) to a running child.
    pub fn signal(&mut self, source: &str, signal: i32) -> std::io::Result<()> {
        let process = self
            .find(source)
            .filter(|p| !p.killed)
            .ok_or_else(|| std::io::Error::other("not started, or killed"))?;
        rl::procs::signal(process.child.id(), signal)
    }

    /// Writes `text` to a controller's stdin (the fault-injection control).
    pub fn send(&mut self, source: &str, text: &str) -> std::io::Result<()> {
        let stdin = self
            .find(source)
            .and_then(|p| p.stdin.as_mut())
            .ok_or_else(|| std::io::Error::other("no stdin (not started, or killed)"))?;
        stdin.write_all(text.as_bytes())?;
        stdin.flush()
    }

    /// Children that exited although nobody killed them, each reported once: `(source,
    /// status)`.
    pub fn exited(&mut self) -> Vec<(String, ExitStatus)> {
        let mut out = Vec::new();
        for process in &mut self.processes {
            if process.killed || process.exit_reported {
                continue;
            }
            if let Ok(Some(status)) = process.child.try_wait() {
                process.exit_reported = true;
                out.push((process.source.clone(), status));
            }
        }
        out
    }

    /// SIGTERM to every child still running, then SIGKILL whoever is left after a second.
    pub fn stop_all(&mut self) {
        for process in &mut self.processes {
            process.stdin = None;
            if matches!(process.child.try_wait(), Ok(None)) {
                // A paused child takes SIGTERM only once it runs again.
                let _ = rl::procs::signal(process.child.id(), libc::SIGCONT);
                let _ = rl::procs::signal(process.child.id(), libc::SIGTERM);
            }
        }
        let deadline = Instant::now() + Duration::from_secs(1);
        for process in &mut self.processes {
            while Instant::now() < deadline {
                if !matches!(process.child.try_wait(), Ok(None)) {
                    break;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            let _ = process.child.kill();
            let _ = process.child.wait();
        }
        self.processes.clear();
    }
}

impl Drop for Processes {
    fn drop(&mut self) {
        self.stop_all();
    }
}

/// Each line of `input`, stamped with the wall clock, until it or the channel closes.
fn read_lines(input: impl std::io::Read + Send + 'static, source: String, to: Sender<Line>) {
    rl::procs::read_lines(input, to, move |text| {
        Some(Line {
            wall_ms: wall_ms(),
            source: source.clone(),
            text,
        })
    });
}
