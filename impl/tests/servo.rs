//! The real simulator processes over real DDS on loopback: `rl servo --json` against command
//! and heartbeat writers in this test process (the JSON interface, ownership, failover gaps,
//! controller ids learned from heartbeats), and `rl shapes` read by an in-process camera
//! reader.
//!
//! Isolation: each test has its own DDS domain (tests/dds_loopback.rs uses 101..=106):
//! 120 failover on silence and return, 121 failover on writer deletion, 122 shapes.

use rl::sim::shapes::{X_MAX, Y_MAX};
use rl_layer::config::{Dds, Timing};
use rl_layer::core::types::{Assignment, Holder, Phase, Role};
use rl_layer::core::Heartbeat;
use rl_layer::dds::{guid_hex, Session};
use rl_layer::wire::ServoControl;
use serde_json::Value;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

const DISCOVERY_TIMEOUT: Duration = Duration::from_secs(20);
const COMMAND_PERIOD: Duration = Duration::from_millis(33);
const HEARTBEAT_PERIOD: Duration = Duration::from_millis(250);
const DEADLINE_MS: u64 = 100;

fn session(domain: u16) -> Session {
    let dds = Dds {
        domain,
        ..Dds::default()
    };
    Session::new(&dds, &Timing::default()).unwrap()
}

/// The servo process; killed when the test ends, pass or fail.
struct Servo {
    child: Child,
    lines: Receiver<String>,
}

impl Servo {
    fn start(domain: u16) -> Servo {
        let mut child = Command::new(env!("CARGO_BIN_EXE_rl"))
            .args(["servo", "--json", "--domain", &domain.to_string()])
            .args(["--duration-ms", "120000"])
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start rl servo");
        let stdout = child.stdout.take().unwrap();
        let (sender, lines) = mpsc::channel();
        rl::procs::read_lines(stdout, sender, Some);
        Servo { child, lines }
    }

    /// Reads events until `matches` accepts one, or panics after `timeout`. Every line must
    /// be one JSON object with an `event` field.
    fn wait_event(
        &self,
        timeout: Duration,
        what: &str,
        mut matches: impl FnMut(&Value) -> bool,
    ) -> Value {
        let end = Instant::now() + timeout;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            let line = match self.lines.recv_timeout(left) {
                Ok(line) => line,
                Err(_) => panic!("timed out after {timeout:?} waiting for {what}"),
            };
            let event: Value = serde_json::from_str(&line)
                .unwrap_or_else(|e| panic!("not one JSON object per line ({e}): {line}"));
            assert!(event.is_object(), "{line}");
            check_shape(&event);
            if matches(&event) {
                return event;
            }
        }
    }

    /// All events that arrive within `duration`.
    fn events_for(&self, duration: Duration) -> Vec<Value> {
        let end = Instant::now() + duration;
        let mut events = Vec::new();
        while let Ok(line) = self
            .lines
            .recv_timeout(end.saturating_duration_since(Instant::now()))
        {
            let event: Value = serde_json::from_str(&line).unwrap();
            check_shape(&event);
            events.push(event);
        }
        events
    }
}

impl Drop for Servo {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The documented fields and their JSON types.
fn check_shape(event: &Value) {
    let number_or_null = |v: &Value| v.is_u64() || v.is_null();
    match event["event"].as_str() {
        Some("command") => {
            assert!(event["t_ms"].is_u64(), "{event}");
            assert_eq!(
                event["writer_guid"].as_str().map(str::len),
                Some(32),
                "{event}"
            );
            assert!(number_or_null(&event["controller_id"]), "{event}");
            assert!(event["strength"].is_i64(), "{event}");
            assert!(event["pan"].is_u64() && event["tilt"].is_u64(), "{event}");
        }
        Some("owner_changed") => {
            assert!(event["t_ms"].is_u64(), "{event}");
            assert!(number_or_null(&event["from_controller_id"]), "{event}");
            assert!(number_or_null(&event["to_controller_id"]), "{event}");
            assert!(number_or_null(&event["gap_ms"]), "{event}");
        }
        _ => panic!("unknown event: {event}"),
    }
}

fn is_command_from(event: &Value, controller: u64) -> bool {
    event["event"] == "command" && event["controller_id"] == controller
}

fn is_change(event: &Value, from: u64, to: u64) -> bool {
    event["event"] == "owner_changed"
        && event["from_controller_id"] == from
        && event["to_controller_id"] == to
}

/// A simulated controller: heartbeats at 4 Hz and commands at 30 Hz from one participant.
struct Controller {
    id: u8,
    commanding: Arc<AtomicBool>,
    /// Requested command strength; 0 = no command writer.
    strength: Arc<AtomicI32>,
    running: Arc<AtomicBool>,
    thread: Option<thread::JoinHandle<()>>,
    writer_guid: Arc<std::sync::Mutex<Option<String>>>,
}

impl Controller {
    fn start(domain: u16, id: u8, role: Role) -> Controller {
        let commanding = Arc::new(AtomicBool::new(true));
        let strength = Arc::new(AtomicI32::new(role.strength().value()));
        let running = Arc::new(AtomicBool::new(true));
        let writer_guid = Arc::new(std::sync::Mutex::new(None));
        let (commanding_flag, strength_wanted, running_flag, guid_out) = (
            commanding.clone(),
            strength.clone(),
            running.clone(),
            writer_guid.clone(),
        );
        let thread = thread::spawn(move || {
            let session = session(domain);
            let heartbeats = session.heartbeat_writer().unwrap();
            let mut commands = session.command_writer(None).unwrap();
            let holder = |id| Holder {
                id,
                incarnation: u64::from(id),
            };
            let agreed = Assignment::from_ranked([holder(1), holder(2)]);
            let beat = Heartbeat {
                id,
                incarnation: u64::from(id),
                phase: Phase::Steady,
                role: Some(role),
                strength: Some(role.strength()),
                agreed: Some(agreed),
                vote: Some(agreed),
                epoch: 1,
                provisional: false,
                established_strength: Some(role.strength()),
                took_over_from: None,
            };
            let mut last_beat = Instant::now() - HEARTBEAT_PERIOD;
            while running_flag.load(Ordering::Relaxed) {
                let wanted = match strength_wanted.load(Ordering::Relaxed) {
                    0 => None,
                    s => Some(rl_layer::core::Strength(s)),
                };
                commands.set_strength(wanted).unwrap();
                *guid_out.lock().unwrap() = commands.guid().map(guid_hex);
                if last_beat.elapsed() >= HEARTBEAT_PERIOD {
                    heartbeats.write(&beat).unwrap();
                    last_beat = Instant::now();
                }
                if commanding_flag.load(Ordering::Relaxed) {
                    commands
                        .write(ServoControl {
                            pan: 100 * u16::from(id),
                            tilt: 500,
                            frequency: 60,
                        })
                        .unwrap();
                }
                thread::sleep(COMMAND_PERIOD);
            }
        });
        Controller {
            id,
            commanding,
            strength,
            running,
            thread: Some(thread),
            writer_guid,
        }
    }

    fn set_commanding(&self, on: bool) {
        self.commanding.store(on, Ordering::Relaxed);
    }

    fn drop_command_writer(&self) {
        self.strength.store(0, Ordering::Relaxed);
    }

    fn guid(&self) -> Option<String> {
        self.writer_guid.lock().unwrap().clone()
    }
}

impl Drop for Controller {
    fn drop(&mut self) {
        self.running.store(false, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[test]
fn servo_follows_the_primary_fails_over_on_silence_and_takes_it_back() {
    const DOMAIN: u16 = 120;
    let servo = Servo::start(DOMAIN);
    let primary = Controller::start(DOMAIN, 1, Role::Primary);
    let secondary = Controller::start(DOMAIN, 2, Role::Secondary);
    assert_eq!((primary.id, secondary.id), (1, 2));

    // Steady state: commands from controller 1 only, at strength 30, named by its heartbeat.
    let first = servo.wait_event(DISCOVERY_TIMEOUT, "a command from controller 1", |e| {
        is_command_from(e, 1)
    });
    assert_eq!(first["strength"], 30);
    assert_eq!(first["pan"], 100);
    assert_eq!(
        Some(first["writer_guid"].as_str().unwrap().to_string()),
        primary.guid()
    );
    let steady = servo.events_for(Duration::from_millis(700));
    let commands: Vec<_> = steady.iter().filter(|e| e["event"] == "command").collect();
    assert!(commands.len() >= 10, "~30 Hz of commands: {steady:?}");
    assert!(
        steady.iter().all(|e| is_command_from(e, 1)),
        "only the Primary while it is live: {steady:?}"
    );

    // The Primary goes silent: the servo switches to controller 2 after the deadline.
    primary.set_commanding(false);
    let change = servo.wait_event(Duration::from_secs(5), "owner change 1 -> 2", |e| {
        is_change(e, 1, 2)
    });
    let gap_ms = change["gap_ms"].as_u64().unwrap();
    eprintln!("failover after silence: {gap_ms} ms without commands");
    assert!(
        gap_ms > DEADLINE_MS && gap_ms <= DEADLINE_MS + 33 + 120,
        "gap {gap_ms} ms: expected the deadline plus at most one period and slack"
    );
    let next = servo.wait_event(Duration::from_secs(1), "a command from controller 2", |e| {
        e["event"] == "command"
    });
    assert!(is_command_from(&next, 2), "{next}");
    assert_eq!(next["strength"], 20);
    assert_eq!(next["pan"], 200);

    // The Primary is back: it takes over at once (no deadline to wait for).
    primary.set_commanding(true);
    let back = servo.wait_event(Duration::from_secs(5), "owner change 2 -> 1", |e| {
        is_change(e, 2, 1)
    });
    assert!(back["gap_ms"].as_u64().unwrap() <= 33 + 120, "{back}");
    let after = servo.events_for(Duration::from_millis(500));
    assert!(
        after.iter().all(|e| is_command_from(e, 1)),
        "the Primary again: {after:?}"
    );
}

#[test]
fn servo_fails_over_when_the_owner_deletes_its_writer() {
    const DOMAIN: u16 = 121;
    let servo = Servo::start(DOMAIN);
    let primary = Controller::start(DOMAIN, 1, Role::Primary);
    let secondary = Controller::start(DOMAIN, 2, Role::Secondary);
    servo.wait_event(DISCOVERY_TIMEOUT, "a command from controller 1", |e| {
        is_command_from(e, 1)
    });
    let _ = servo.events_for(Duration::from_millis(300));

    // The Primary stops commanding (its role is gone): no writer at all.
    primary.drop_command_writer();
    let change = servo.wait_event(Duration::from_secs(5), "owner change 1 -> 2", |e| {
        is_change(e, 1, 2)
    });
    let gap_ms = change["gap_ms"].as_u64().unwrap();
    eprintln!("failover after writer deletion: {gap_ms} ms without commands");
    assert!(gap_ms <= DEADLINE_MS + 33 + 120, "{change}");
    let after = servo.events_for(Duration::from_millis(500));
    assert!(
        after.iter().any(|e| is_command_from(e, 2))
            && after
                .iter()
                .all(|e| e["event"] != "command" || is_command_from(e, 2)),
        "{after:?}"
    );
    assert_eq!(primary.guid(), None);
    assert!(secondary.guid().is_some());
}

#[test]
fn shapes_publishes_a_moving_yellow_circle_and_others() {
    const DOMAIN: u16 = 122;
    let reader_session = session(DOMAIN);
    let mut camera = reader_session.camera_reader().unwrap();
    let mut shapes = Command::new(env!("CARGO_BIN_EXE_rl"))
        .args(["shapes", "--domain", &DOMAIN.to_string(), "--rate-hz", "50"])
        .args(["--duration-ms", "60000"])
        .stdout(Stdio::null())
        .spawn()
        .expect("start rl shapes");
    let mut yellow = Vec::new();
    let mut colors = std::collections::BTreeSet::new();
    let end = Instant::now() + DISCOVERY_TIMEOUT;
    while Instant::now() < end && (yellow.len() < 20 || colors.len() < 3) {
        for sample in camera.take() {
            let shape = sample.value;
            assert!((0..=X_MAX).contains(&shape.x) && (0..=Y_MAX).contains(&shape.y));
            if shape.color == "YELLOW" {
                yellow.push((shape.x, shape.y));
            }
            colors.insert(shape.color);
        }
        thread::sleep(Duration::from_millis(10));
    }
    let _ = shapes.kill();
    let _ = shapes.wait();
    assert!(yellow.len() >= 20, "YELLOW samples: {yellow:?}");
    assert_eq!(
        colors.into_iter().collect::<Vec<_>>(),
        ["BLUE", "RED", "YELLOW"]
    );
    yellow.dedup();
    assert!(yellow.len() >= 10, "the YELLOW circle moves: {yellow:?}");
}
