//! Child processes for the demo, the benchmarks and the tests: controllers started and killed
//! for real (`kill -9`, SIGSTOP/SIGCONT), and the servo simulator's JSON event stream.

use rl_layer::core::types::ControllerId;
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::Instant;

pub use crate::sim::servo::vote::VotedServoEvent;
pub use crate::sim::servo::ServoEvent;

/// A line a child printed, with the time it was read.
#[derive(Clone, Debug)]
pub struct Line {
    pub at: Instant,
    pub source: String,
    pub text: String,
}

/// Sends every line of a child's stdout (and stderr, tagged `source!`) to a channel.
fn forward_lines(child: &mut Child, source: &str, to: mpsc::Sender<Line>) {
    if let Some(stdout) = child.stdout.take() {
        spawn_line_reader(stdout, source.to_string(), to.clone());
    }
    if let Some(stderr) = child.stderr.take() {
        spawn_line_reader(stderr, format!("{source}!"), to);
    }
}

/// A thread that sends each line read from `input` as a [`Line`] until the input or the
/// channel closes.
fn spawn_line_reader(
    input: impl std::io::Read + Send + 'static,
    source: String,
    to: mpsc::Sender<Line>,
) {
    read_lines(input, to, move |text| {
        Some(Line {
            at: Instant::now(),
            source: source.clone(),
            text,
        })
    });
}

/// The one line reader of every child-process harness (the demo, the bench, the fault lab,
/// the DDS-level replay, the process tests): a thread that sends `keep(line)` for each line
/// of `input` (stamped when read, on the harness's own clock; `None` drops the line) until the
/// input or the channel closes.
pub fn read_lines<L: Send + 'static>(
    input: impl std::io::Read + Send + 'static,
    to: mpsc::Sender<L>,
    keep: impl Fn(String) -> Option<L> + Send + 'static,
) {
    std::thread::spawn(move || {
        for text in BufReader::new(input).lines().map_while(Result::ok) {
            if let Some(line) = keep(text) {
                if to.send(line).is_err() {
                    break;
                }
            }
        }
    });
}

/// Sends a signal to a process.
pub fn signal(pid: u32, signal: i32) -> std::io::Result<()> {
    let pid = libc::pid_t::try_from(pid).map_err(std::io::Error::other)?;
    // SAFETY: kill(2) has no memory effects; a bad pid is reported through errno.
    if unsafe { libc::kill(pid, signal) } == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Controllers (and simulators) run as child processes of one `rl` executable.
pub struct Fleet {
    exe: PathBuf,
    config: Option<PathBuf>,
    domain: u16,
    extra_env: Vec<(String, String)>,
    /// The subcommand a controller runs (`controller`, or a chain stage: `chain nav`).
    controller_command: Vec<String>,
    /// Before `C<id>` in the lines' source (`nav `: a group's controllers beside another's).
    source_prefix: String,
    controllers: BTreeMap<ControllerId, Child>,
    others: Vec<Child>,
    lines: mpsc::Sender<Line>,
}

impl Fleet {
    /// A fleet of `exe` processes on `domain`; every child's output goes to the returned
    /// channel, one [`Line`] per line.
    pub fn new(exe: &Path, config: Option<&Path>, domain: u16) -> (Fleet, Receiver<Line>) {
        let (lines, receiver) = mpsc::channel();
        (
            Fleet {
                exe: exe.to_path_buf(),
                config: config.map(Path::to_path_buf),
                domain,
                extra_env: Vec::new(),
                controller_command: vec!["controller".into()],
                source_prefix: String::new(),
                controllers: BTreeMap::new(),
                others: Vec::new(),
                lines,
            },
            receiver,
        )
    }

    /// Another fleet on the same domain, configuration and line channel whose controllers run
    /// `rl <controller_command> --id N` and whose lines come from `<source_prefix>C<N>`: a
    /// second group of controllers (the chain demo's navigation and actuator groups).
    pub fn sharing(&self, controller_command: &[&str], source_prefix: &str) -> Fleet {
        Fleet {
            exe: self.exe.clone(),
            config: self.config.clone(),
            domain: self.domain,
            extra_env: self.extra_env.clone(),
            controller_command: controller_command.iter().map(|s| s.to_string()).collect(),
            source_prefix: source_prefix.to_string(),
            controllers: BTreeMap::new(),
            others: Vec::new(),
            lines: self.lines.clone(),
        }
    }

    /// The source of controller `id`'s lines.
    pub fn source_of(&self, id: ControllerId) -> String {
        format!("{}C{id}", self.source_prefix)
    }

    /// The configuration file every child gets (unless started with its own).
    pub fn config(&self) -> Option<&Path> {
        self.config.as_deref()
    }

    /// An environment variable every child gets (e.g. `RUST_LOG`).
    pub fn env(&mut self, key: &str, value: &str) {
        self.extra_env.push((key.into(), value.into()));
    }

    fn command(&self, args: &[&str]) -> Command {
        self.command_configured(args, self.config.as_deref())
    }

    fn command_configured(&self, args: &[&str], config: Option<&Path>) -> Command {
        let mut command = Command::new(&self.exe);
        command.args(args);
        if let Some(config) = config {
            command.arg("--config").arg(config);
        }
        command
            .arg("--domain")
            .arg(self.domain.to_string())
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        for (key, value) in &self.extra_env {
            command.env(key, value);
        }
        command
    }

    /// Starts `rl controller --id <id>`; returns its pid.
    pub fn start_controller(&mut self, id: ControllerId) -> std::io::Result<u32> {
        self.start_controller_with(id, &[])
    }

    /// Starts `rl controller --id <id> <extra>`; returns its pid.
    pub fn start_controller_with(
        &mut self,
        id: ControllerId,
        extra: &[&str],
    ) -> std::io::Result<u32> {
        let config = self.config.clone();
        self.spawn_controller(id, config.as_deref(), extra)
    }

    /// Starts `rl controller --id <id> <extra>` with its own configuration file (each
    /// secured controller names its own keystore); returns its pid.
    pub fn start_controller_configured(
        &mut self,
        id: ControllerId,
        config: &Path,
        extra: &[&str],
    ) -> std::io::Result<u32> {
        self.spawn_controller(id, Some(config), extra)
    }

    fn spawn_controller(
        &mut self,
        id: ControllerId,
        config: Option<&Path>,
        extra: &[&str],
    ) -> std::io::Result<u32> {
        let id_text = id.to_string();
        let mut args: Vec<&str> = self.controller_command.iter().map(String::as_str).collect();
        args.extend_from_slice(&["--id", &id_text]);
        args.extend_from_slice(extra);
        let mut child = self.command_configured(&args, config).spawn()?;
        forward_lines(&mut child, &self.source_of(id), self.lines.clone());
        let pid = child.id();
        self.controllers.insert(id, child);
        Ok(pid)
    }

    /// Starts another `rl` subcommand with its own configuration file, tagged `source`.
    pub fn start_other_configured(
        &mut self,
        source: &str,
        config: &Path,
        args: &[&str],
    ) -> std::io::Result<u32> {
        let mut child = self.command_configured(args, Some(config)).spawn()?;
        forward_lines(&mut child, source, self.lines.clone());
        let pid = child.id();
        self.others.push(child);
        Ok(pid)
    }

    /// Starts another `rl` subcommand (e.g. `shapes`, `servo --json`) tagged `source`.
    pub fn start_other(&mut self, source: &str, args: &[&str]) -> std::io::Result<u32> {
        let mut child = self.command(args).spawn()?;
        forward_lines(&mut child, source, self.lines.clone());
        let pid = child.id();
        self.others.push(child);
        Ok(pid)
    }

    pub fn pid(&self, id: ControllerId) -> Option<u32> {
        self.controllers.get(&id).map(Child::id)
    }

    /// The ids of the controllers started and not killed (some may have exited since:
    /// [`Fleet::exit_status`] tells).
    pub fn running(&self) -> impl Iterator<Item = ControllerId> + '_ {
        self.controllers.keys().copied()
    }

    /// How controller `id` ended, if it has (`None` while it runs or when it was never
    /// started).
    pub fn exit_status(&mut self, id: ControllerId) -> std::io::Result<Option<ExitStatus>> {
        match self.controllers.get_mut(&id) {
            Some(child) => child.try_wait(),
            None => Ok(None),
        }
    }

    /// `kill -9` and reap.
    pub fn kill(&mut self, id: ControllerId) -> std::io::Result<()> {
        if let Some(mut child) = self.controllers.remove(&id) {
            child.kill()?;
            child.wait()?;
        }
        Ok(())
    }

    /// SIGSTOP (`stop = true`) or SIGCONT.
    pub fn pause(&self, id: ControllerId, stop: bool) -> std::io::Result<()> {
        match self.controllers.get(&id) {
            Some(child) => signal(child.id(), if stop { libc::SIGSTOP } else { libc::SIGCONT }),
            None => Ok(()),
        }
    }

    /// SIGTERM to everyone, then SIGKILL whoever is still running after a second.
    pub fn stop_all(&mut self) {
        let mut children: Vec<Child> = std::mem::take(&mut self.controllers)
            .into_values()
            .chain(std::mem::take(&mut self.others))
            .collect();
        for child in &children {
            let _ = signal(child.id(), libc::SIGCONT);
            let _ = signal(child.id(), libc::SIGTERM);
        }
        let deadline = Instant::now() + std::time::Duration::from_secs(1);
        for child in &mut children {
            while Instant::now() < deadline {
                if matches!(child.try_wait(), Ok(Some(_))) {
                    break;
                }
                std::thread::sleep(std::time::Duration::from_millis(10));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

impl Drop for Fleet {
    fn drop(&mut self) {
        self.stop_all();
    }
}

/// Parses a servo JSON line; `None` for anything else (human lines, partial output).
pub fn parse_servo_event(text: &str) -> Option<ServoEvent> {
    serde_json::from_str(text).ok()
}

/// Parses a line of `rl servo --vote --json`; `None` for anything else.
pub fn parse_voted_servo_event(text: &str) -> Option<VotedServoEvent> {
    serde_json::from_str(text).ok()
}

/// Wall-clock milliseconds now (comparable with controller event times on this machine).
pub fn wall_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

impl Fleet {
    /// Starts `rl controller --id <id> <extra>` with its stdin piped (the `fault-injection`
    /// build reads `drop-heartbeats-from <id>` / `accept-heartbeats-from <id>` lines there)
    /// and its output tagged `source` (e.g. `C3#1` for a restarted controller, so each life's
    /// lines stay apart); returns its pid and stdin.
    pub fn start_controller_piped(
        &mut self,
        id: ControllerId,
        source: &str,
        extra: &[&str],
    ) -> std::io::Result<(u32, std::process::ChildStdin)> {
        let id_text = id.to_string();
        let mut args = vec!["controller", "--id", &id_text];
        args.extend_from_slice(extra);
        let mut child = self.command(&args).stdin(Stdio::piped()).spawn()?;
        let stdin = child
            .stdin
            .take()
            .ok_or_else(|| std::io::Error::other("the child's stdin was not piped"))?;
        forward_lines(&mut child, source, self.lines.clone());
        let pid = child.id();
        self.controllers.insert(id, child);
        Ok((pid, stdin))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn servo_lines_parse_by_their_event_field() {
        let command = r#"{"event":"command","t_ms":12,"writer_guid":"01.02","controller_id":null,"strength":30,"pan":500,"tilt":400,"frequency":60}"#;
        assert_eq!(
            parse_servo_event(command),
            Some(ServoEvent::Command {
                t_ms: 12,
                writer_guid: "01.02".into(),
                controller_id: None,
                strength: rl_layer::core::Strength(30),
                pan: 500,
                tilt: 400,
                frequency: 60,
                late_ms: None,
            })
        );
        let expired = r#"{"event":"expired","t_ms":40,"writer_guid":"01","controller_id":1,"late_ms":290,"lifespan_ms":100}"#;
        assert_eq!(parse_servo_event(expired).map(|e| e.t_ms()), Some(40));
        let change = r#"{"event":"owner_changed","t_ms":99,"from_controller_id":1,"to_controller_id":2,"gap_ms":104,"from_writer_guid":"01","to_writer_guid":"02","strength":20}"#;
        assert!(matches!(
            parse_servo_event(change),
            Some(ServoEvent::OwnerChanged {
                gap_ms: Some(104),
                ..
            })
        ));
        assert_eq!(parse_servo_event("owner: C1"), None);
    }
}
