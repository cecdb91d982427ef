//! The actuators that judge a process test, counted at controller granularity: `rl servo
//! --json` (its `owner_changed` events) and an RTI Connext reader with the paper's QoS
//! (`tests/interop/connext_reader.py`: exclusive ownership, reliable, a deadline). A writer's
//! participant (the first 12 bytes of its GUID) is one life of one controller, across the
//! writers it re-creates at new strengths, so owner changes are counted by participant; which
//! controller a participant is comes from the heartbeats it sends, heard by a DDS reader in the
//! test process. [`Timeline`] puts faults, roles and owner changes on one clock for failure
//! reports.

use rl::procs::ServoEvent;
use std::collections::BTreeMap;
use std::fmt;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// The PyPI package the Connext reader needs (as `.ci/run` installs it).
pub const CONNEXT_PACKAGE: &str = "rticonnextdds-connector==1.2.4";
/// How often a Connext participant checks writers' liveliness leases by default
/// (`max_liveliness_loss_detection_period`).
pub const CONNEXT_LIVELINESS_CHECK_MS: u64 = 60_000;

/// Panics unless python3 can import the peer's DDS module (the test was asked for, so its
/// peer must be there).
pub fn require_peer(module: &str, package: &str) {
    let imported = Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        imported,
        "python3 cannot import {module} (pip install {package})"
    );
}

/// The participant of a writer: its GUID's first 12 bytes (24 hex digits).
pub fn participant_of(guid_hex: &str) -> String {
    guid_hex.chars().take(24).collect()
}

/// One life of one controller: `C2`, or `C2#3` for its third process.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Life {
    pub id: u8,
    /// 1 for the first process with this id, 2 after its first restart, ...
    pub life: u32,
}

impl fmt::Display for Life {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.life {
            1 => write!(f, "C{}", self.id),
            n => write!(f, "C{}#{n}", self.id),
        }
    }
}

/// Which controller life each participant is, from the heartbeats it sends.
pub struct Lives {
    heartbeats: rl_layer::dds::Reader<rl_layer::wire::HeartbeatSample>,
    by_participant: BTreeMap<String, Life>,
    lives_of: BTreeMap<u8, u32>,
    // Dropped last: the reader belongs to it.
    _session: rl_layer::dds::Session,
}

impl Lives {
    /// A heartbeat reader on `domain`.
    pub fn new(domain: u16) -> Lives {
        let config = rl_layer::config::Config {
            dds: rl_layer::config::Dds {
                domain,
                ..Default::default()
            },
            ..Default::default()
        };
        let session = rl_layer::dds::Session::new(&config.dds, &config.timing).unwrap();
        let heartbeats = session.heartbeat_reader().unwrap();
        Lives {
            heartbeats,
            by_participant: BTreeMap::new(),
            lives_of: BTreeMap::new(),
            _session: session,
        }
    }

    /// Takes the heartbeats received so far; a participant heard for the first time is the
    /// next life of its controller id.
    pub fn listen(&mut self) {
        for heartbeat in self.heartbeats.take() {
            let participant = participant_of(&rl_layer::dds::guid_hex(heartbeat.writer));
            if !self.by_participant.contains_key(&participant) {
                let id = heartbeat.value.id;
                let life = self.lives_of.entry(id).or_insert(0);
                *life += 1;
                let life = Life { id, life: *life };
                self.by_participant.insert(participant, life);
            }
        }
    }

    pub fn of(&self, participant: &str) -> Option<Life> {
        self.by_participant.get(participant).copied()
    }

    /// `C2#2`, or the participant itself when no heartbeat of it was heard.
    pub fn name(&self, participant: &str) -> String {
        self.of(participant)
            .map_or_else(|| format!("?{participant}"), |life| life.to_string())
    }

    /// The participant of `life`, once a heartbeat of it was heard.
    pub fn participant(&self, life: Life) -> Option<&str> {
        self.by_participant
            .iter()
            .find(|(_, l)| **l == life)
            .map(|(p, _)| p.as_str())
    }

    /// The latest life of controller `id` heard so far.
    pub fn latest(&self, id: u8) -> Option<Life> {
        self.lives_of.get(&id).map(|&life| Life { id, life })
    }
}

/// The two judges.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Judge {
    Servo,
    Connext,
}

impl Judge {
    pub const BOTH: [Judge; 2] = [Judge::Servo, Judge::Connext];

    pub fn name(self) -> &'static str {
        match self {
            Judge::Servo => "rl servo",
            Judge::Connext => "connext",
        }
    }
}

/// The actuator followed another participant from `at_ms` (test clock) on.
#[derive(Clone, Debug, PartialEq)]
pub struct OwnerChange {
    pub at_ms: f64,
    pub from: String,
    pub to: String,
}

/// The owner changes in a sequence of `(time, owner participant)`: each time the participant
/// differs from the one before (the first owner is the starting point, not a change).
pub fn owner_changes(owners: impl IntoIterator<Item = (f64, String)>) -> Vec<OwnerChange> {
    let mut changes = Vec::new();
    let mut current: Option<String> = None;
    for (at_ms, owner) in owners {
        match &current {
            Some(previous) if *previous != owner => {
                changes.push(OwnerChange {
                    at_ms,
                    from: previous.clone(),
                    to: owner.clone(),
                });
            }
            _ => {}
        }
        current = Some(owner);
    }
    changes
}

/// The servo's owners in order: the participant of each `owner_changed` event's new writer,
/// with when the test read it (ms since `since`).
pub fn servo_owners(servo: &[(Instant, ServoEvent)], since: Instant) -> Vec<(f64, String)> {
    servo
        .iter()
        .filter_map(|(at, event)| match event {
            ServoEvent::OwnerChanged { to_writer_guid, .. } => Some((
                at.saturating_duration_since(since).as_secs_f64() * 1000.0,
                participant_of(to_writer_guid),
            )),
            _ => None,
        })
        .collect()
}

/// Wall-clock milliseconds (fractional), comparable with the Connext reader's `t_ms`.
pub fn wall_ms_f64() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1000.0)
}

/// A sample the Connext reader received: when (ms since the test's start) and from whom.
#[derive(Clone, Debug)]
pub struct ConnextSample {
    pub at_ms: f64,
    pub participant: String,
}

/// `connext_reader.py` running on a domain; its samples are collected by [`Self::pump`].
pub struct ConnextReader {
    child: Child,
    lines: Receiver<String>,
    /// Wall-clock ms at the test's start: turns the reader's Unix times into test times.
    wall_at_start_ms: f64,
    pub samples: Vec<ConnextSample>,
}

impl ConnextReader {
    /// Starts the reader with the paper's deadline `deadline_ms`; it runs until dropped.
    /// It checks writers' liveliness every `liveliness_check_ms` at the longest (Connext's
    /// default is [`CONNEXT_LIVELINESS_CHECK_MS`]). `started` is the test's start (the clock
    /// of every time it reports).
    pub fn start(
        domain: u16,
        deadline_ms: u64,
        liveliness_check_ms: u64,
        started: Instant,
    ) -> ConnextReader {
        // The reader lives with the interop tests, beside the test kit (impl/tests/interop).
        let script = format!(
            "{}/../tests/interop/connext_reader.py",
            env!("CARGO_MANIFEST_DIR")
        );
        let mut child = Command::new("python3")
            .arg(script)
            .arg(domain.to_string())
            .args([
                "--duration",
                "900",
                "--deadline-ms",
                &deadline_ms.to_string(),
                "--liveliness-check-ms",
                &liveliness_check_ms.to_string(),
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start connext_reader.py");
        let stdout = child.stdout.take().expect("the reader's stdout");
        let (sender, lines) = mpsc::channel();
        rl::procs::read_lines(stdout, sender, Some);
        ConnextReader {
            child,
            lines,
            wall_at_start_ms: wall_ms_f64() - started.elapsed().as_secs_f64() * 1000.0,
            samples: Vec::new(),
        }
    }

    /// Takes in the samples printed so far.
    pub fn pump(&mut self) {
        while let Ok(line) = self.lines.try_recv() {
            let Ok(value) = serde_json::from_str::<serde_json::Value>(&line) else {
                continue;
            };
            if let (Some(t_ms), Some(guid)) = (reception_ms(&value), value["writer_guid"].as_str())
            {
                self.samples.push(ConnextSample {
                    at_ms: t_ms - self.wall_at_start_ms,
                    participant: participant_of(guid),
                });
            }
        }
    }

    /// Whether the reader still runs (it exits only on an error before its duration).
    pub fn running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// Whether every sample of the last `window_ms` (test clock, up to `now_ms`) came from
    /// `participant`, and there were some.
    pub fn follows(&self, participant: &str, now_ms: f64, window_ms: f64) -> bool {
        let recent: Vec<&ConnextSample> = self
            .samples
            .iter()
            .filter(|s| s.at_ms >= now_ms - window_ms)
            .collect();
        recent.len() >= 5 && recent.iter().all(|s| s.participant == participant)
    }

    /// Its owners in order (one entry per sample) from sample `from` on.
    pub fn owners(&self, from: usize) -> Vec<(f64, String)> {
        self.samples[from.min(self.samples.len())..]
            .iter()
            .map(|s| (s.at_ms, s.participant.clone()))
            .collect()
    }
}

impl Drop for ConnextReader {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Faults, role changes and owner changes on the test clock, printed in time order.
#[derive(Clone, Default)]
pub struct Timeline {
    entries: Vec<(f64, String, String)>,
}

impl Timeline {
    pub fn add(&mut self, at_ms: f64, source: &str, text: impl Into<String>) {
        self.entries.push((at_ms, source.to_string(), text.into()));
    }
}

impl fmt::Display for Timeline {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut entries: Vec<&(f64, String, String)> = self.entries.iter().collect();
        entries.sort_by(|a, b| a.0.total_cmp(&b.0));
        writeln!(f, "--- timeline (ms since the test started) ---")?;
        for (at_ms, source, text) in entries {
            writeln!(f, "{at_ms:>9.1} {source:>9}  {text}")?;
        }
        Ok(())
    }
}

/// Milliseconds from `since` to `at`.
pub fn ms_between(since: Instant, at: Instant) -> f64 {
    at.saturating_duration_since(since).as_secs_f64() * 1000.0
}

/// When the Connext reader received a sample: the reception time Connext recorded (`rx_ms`),
/// or, from a reader that does not print it, when the script handled it (`t_ms`, which adds
/// the Python process's scheduling, up to 10 ms on an idle machine).
fn reception_ms(value: &serde_json::Value) -> Option<f64> {
    value["rx_ms"].as_f64().or_else(|| value["t_ms"].as_f64())
}
