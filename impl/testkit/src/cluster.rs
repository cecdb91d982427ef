//! A cluster of real `rl` processes on one DDS domain for a process-level test: controllers
//! and a servo started through the tools' [`Fleet`], their JSON events collected as they come,
//! and bounded waits that report everything seen when they give up.

use crate::tempdir;
use rl::procs::{
    parse_servo_event, parse_voted_servo_event, Fleet, Line, ServoEvent, VotedServoEvent,
};
use rl_layer::core::{Phase, Role, Status};
use rl_layer::event::EventLine;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// A configuration for tests: the paper's timing, but a 1 s initialization window so that
/// formations with fewer than three controllers don't wait 10 s.
pub fn test_config(dir: &std::path::Path, extra: &str) -> PathBuf {
    let path = dir.join("rl.toml");
    std::fs::write(&path, format!("[timing]\ninit_window_ms = 1000\n{extra}\n")).unwrap();
    path
}

/// The source of the voting servo's lines.
pub const VOTING_SERVO: &str = "vote";

/// The processes of one test, what they said, and when.
pub struct Cluster {
    pub fleet: Fleet,
    lines: Receiver<Line>,
    pub started: Instant,
    /// Latest status per controller id (from `status` events).
    pub status: BTreeMap<u8, Status>,
    /// Every servo event, with when it was read.
    pub servo: Vec<(Instant, ServoEvent)>,
    /// Every event of the voting servo (`rl servo --vote`, [`Cluster::start_voting_servo`]),
    /// with when it was read.
    pub voted: Vec<(Instant, VotedServoEvent)>,
    /// Every controller event line, in arrival order.
    pub events: Vec<(Instant, EventLine)>,
    /// Everything the children printed, for failure reports.
    pub transcript: Vec<String>,
    /// Every line as `(source, text)`, terminal colours removed; stderr's source ends in `!`
    /// (`C1!`).
    pub lines_seen: Vec<(String, String)>,
    _dir: tempdir::Dir,
}

impl Cluster {
    /// A cluster on its own `domain` (each test uses a distinct one).
    pub fn new(tag: &str, domain: u16, config_extra: &str) -> Cluster {
        let dir = tempdir::Dir::new(tag);
        let config = test_config(&dir.0, config_extra);
        let (fleet, lines) = Fleet::new(crate::rl(), Some(&config), domain);
        Cluster {
            fleet,
            lines,
            started: Instant::now(),
            status: BTreeMap::new(),
            servo: Vec::new(),
            voted: Vec::new(),
            events: Vec::new(),
            transcript: Vec::new(),
            lines_seen: Vec::new(),
            _dir: dir,
        }
    }

    /// As [`Cluster::new`], its configuration beginning with `head`: plain values such as
    /// `architecture = "duplex"` must come before the file's first section.
    pub fn with_head(tag: &str, domain: u16, head: &str) -> Cluster {
        let cluster = Cluster::new(tag, domain, "");
        let config = cluster
            .fleet
            .config()
            .expect("a configuration")
            .to_path_buf();
        let text = std::fs::read_to_string(&config).expect("the test configuration");
        std::fs::write(&config, format!("{head}{text}")).expect("written");
        cluster
    }

    pub fn start(&mut self, id: u8) -> u32 {
        self.fleet
            .start_controller_with(id, &["--json-events"])
            .expect("start rl controller")
    }

    pub fn start_servo(&mut self) {
        self.fleet
            .start_other("servo", &["servo", "--json"])
            .expect("start rl servo");
    }

    /// Starts `rl servo --vote --json <extra>`, its lines from source `vote`.
    pub fn start_voting_servo(&mut self, extra: &[&str]) {
        let mut args = vec!["servo", "--vote", "--json"];
        args.extend_from_slice(extra);
        self.fleet
            .start_other(VOTING_SERVO, &args)
            .expect("start rl servo --vote");
    }

    /// Takes in every line printed so far (waiting up to `wait`).
    pub fn pump(&mut self, wait: Duration) {
        let deadline = Instant::now() + wait;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left.max(Duration::from_millis(1))) {
                Ok(line) => self.take(line),
                Err(_) => break,
            }
            if Instant::now() >= deadline {
                while let Ok(line) = self.lines.try_recv() {
                    self.take(line);
                }
                break;
            }
        }
    }

    fn take(&mut self, line: Line) {
        let t = line.at.duration_since(self.started).as_millis();
        self.transcript
            .push(format!("{t:>6} ms {:>7}: {}", line.source, line.text));
        self.lines_seen
            .push((line.source.clone(), without_terminal_colours(&line.text)));
        if line.source == "servo" {
            if let Some(event) = parse_servo_event(&line.text) {
                self.servo.push((line.at, event));
            }
        } else if line.source == VOTING_SERVO {
            if let Some(event) = parse_voted_servo_event(&line.text) {
                self.voted.push((line.at, event));
            }
        } else if let Some(event) = EventLine::parse(&line.text) {
            if let Some(status) = event.status() {
                self.status.insert(event.id, status.clone());
            }
            self.events.push((line.at, event));
        }
    }

    /// The lines `source` printed so far (`C1!` for controller 1's stderr).
    pub fn lines_from<'a>(&'a self, source: &'a str) -> impl Iterator<Item = &'a str> + 'a {
        self.lines_seen
            .iter()
            .filter(move |(from, _)| from == source)
            .map(|(_, text)| text.as_str())
    }

    /// Waits until `done` holds, at most `timeout`; panics with `what` and the transcript.
    pub fn wait_for(&mut self, what: &str, timeout: Duration, done: impl Fn(&Cluster) -> bool) {
        let deadline = Instant::now() + timeout;
        while !done(self) {
            if Instant::now() >= deadline {
                panic!(
                    "timed out after {:?} waiting for: {what}\nlast status: {}\n--- transcript (last 60 lines) ---\n{}",
                    timeout,
                    self.describe(),
                    self.transcript
                        .iter()
                        .rev()
                        .take(60)
                        .rev()
                        .cloned()
                        .collect::<Vec<_>>()
                        .join("\n")
                );
            }
            self.pump(Duration::from_millis(50));
        }
    }

    /// One line per controller: phase, role, strength.
    pub fn describe(&self) -> String {
        self.status
            .values()
            .map(|s| {
                format!(
                    "C{} {} {:?} {:?}",
                    s.report.id,
                    s.report.phase,
                    s.report.role.map(|r| r.name()),
                    s.report.strength
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    }

    pub fn role_of(&self, id: u8) -> Option<Role> {
        self.status.get(&id).and_then(|s| s.report.role)
    }

    pub fn steady_with(&self, id: u8, role: Option<Role>) -> bool {
        self.status.get(&id).is_some_and(|s| {
            s.report.phase == Phase::Steady
                && s.report.role == role
                && s.report.strength == role.map(Role::strength)
        })
    }

    /// The controller the servo follows now (its last owner change).
    pub fn servo_owner(&self) -> Option<u8> {
        self.servo.iter().rev().find_map(|(_, e)| match e {
            ServoEvent::OwnerChanged {
                to_controller_id, ..
            } => Some(*to_controller_id),
            _ => None,
        })?
    }

    /// The id of the controller whose last accepted command the servo saw.
    pub fn servo_commander(&self) -> Option<u8> {
        self.servo.iter().rev().find_map(|(_, e)| match e {
            ServoEvent::Command { controller_id, .. } => Some(*controller_id),
            _ => None,
        })?
    }
}

/// `text` without ANSI escape sequences (`ESC [ ... letter`).
pub fn without_terminal_colours(text: &str) -> String {
    let mut plain = String::with_capacity(text.len());
    let mut chars = text.chars();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            for c in chars.by_ref() {
                if c.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            plain.push(c);
        }
    }
    plain
}

/// How many of the children's last lines a failing test prints.
const LINES_ON_FAILURE: usize = 300;

impl Drop for Cluster {
    fn drop(&mut self) {
        self.fleet.stop_all();
        // A failing test shows what its processes said last (a stall, a new life, an error).
        // Their whole transcript goes to a file named there (status lines are most of it).
        if std::thread::panicking() {
            while let Ok(line) = self.lines.try_recv() {
                self.take(line);
            }
            let events: Vec<&String> = self
                .transcript
                .iter()
                .filter(|line| !line.contains(r#""event":"status""#))
                .collect();
            let from = events.len().saturating_sub(LINES_ON_FAILURE);
            eprintln!(
                "--- the processes' last {} lines but status:",
                events.len() - from
            );
            for line in &events[from..] {
                eprintln!("{line}");
            }
            let kept = std::env::temp_dir().join(format!(
                "rl-failed-test-{}-{}.log",
                std::process::id(),
                self.started.elapsed().as_millis()
            ));
            if std::fs::write(&kept, self.transcript.join("\n")).is_ok() {
                eprintln!("--- the whole transcript: {}", kept.display());
            }
        }
    }
}
