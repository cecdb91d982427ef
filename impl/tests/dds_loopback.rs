//! Real DDS on this machine, in one process: every endpoint of `rl_layer::dds` against real RustDDS
//! participants (one per simulated controller, as in production), no mocks.
//!
//! Isolation: each test has its own DDS domain so tests running in parallel (and other test
//! files: tests/servo.rs uses 120..=125) never hear each other:
//! 101 ownership failover, 102 strength re-creation, 103 heartbeat/vote round trip,
//! 104 transient-local votes, 105 malformed samples, 106 ROS 2 status, 107 heartbeat bursts.

use rl_layer::arbiter::Arbiter;
use rl_layer::config::{Dds, Timing};
use rl_layer::core::types::{Assignment, Holder, Phase, Role, VoteRecord};
use rl_layer::core::Heartbeat;
use rl_layer::core::Strength;
use rl_layer::dds::{mio, ControllerDirectory, Session, GUID};
use rl_layer::wire::{HeartbeatSample, RosString, ServoControl, WireSample, HEARTBEAT_TYPE_NAME};
use rustdds::{
    policy::{Durability, History, Reliability},
    serialization::CDRSerializerAdapter,
    DomainParticipant, Keyed, QosPolicyBuilder, TopicKind,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

/// Discovery on loopback takes well under a second; allow for a loaded machine.
const DISCOVERY_TIMEOUT: Duration = Duration::from_secs(15);
const COMMAND_PERIOD: Duration = Duration::from_millis(33);

fn session(domain: u16) -> Session {
    let dds = Dds {
        domain,
        ..Dds::default()
    };
    Session::new(&dds, &Timing::default()).unwrap()
}

/// Polls `check` every 10 ms until it returns `Some`, or panics after `timeout` with `what`.
fn wait_for<T>(timeout: Duration, what: &str, mut check: impl FnMut() -> Option<T>) -> T {
    let start = Instant::now();
    loop {
        if let Some(value) = check() {
            return value;
        }
        assert!(
            start.elapsed() < timeout,
            "timed out after {timeout:?} waiting for {what}"
        );
        thread::sleep(Duration::from_millis(10));
    }
}

fn holder(id: u8, incarnation: u64) -> Holder {
    Holder { id, incarnation }
}

fn heartbeat(from: u8, role: Role) -> Heartbeat {
    let agreed = Assignment::from_ranked([holder(1, 11), holder(2, 22), holder(3, 33)]);
    Heartbeat {
        phase: Phase::Steady,
        role: Some(role),
        strength: Some(role.strength()),
        agreed: Some(agreed),
        vote: Some(agreed),
        epoch: 1,
        established_strength: Some(role.strength()),
        ..Heartbeat::initial(from, u64::from(from) * 11)
    }
}

/// A controller's command stream: publishes every `COMMAND_PERIOD` while `publishing` is set,
/// until `running` is cleared.
struct Publisher {
    publishing: Arc<AtomicBool>,
    running: Arc<AtomicBool>,
    thread: Option<thread::JoinHandle<()>>,
    guid: GUID,
}

impl Publisher {
    fn start(session: Session, strength: i32, pan: u16) -> Publisher {
        let mut writer = session.command_writer(Some(Strength(strength))).unwrap();
        let guid = writer.guid().unwrap();
        let publishing = Arc::new(AtomicBool::new(true));
        let running = Arc::new(AtomicBool::new(true));
        let (publishing_flag, running_flag) = (publishing.clone(), running.clone());
        let thread = thread::spawn(move || {
            let command = ServoControl {
                pan,
                tilt: 500,
                frequency: 60,
            };
            while running_flag.load(Ordering::Relaxed) {
                if publishing_flag.load(Ordering::Relaxed) {
                    writer.write(command).unwrap();
                }
                thread::sleep(COMMAND_PERIOD);
            }
            drop(writer);
            drop(session);
        });
        Publisher {
            publishing,
            running,
            thread: Some(thread),
            guid,
        }
    }

    fn silence(&self) {
        self.publishing.store(false, Ordering::Relaxed);
    }
}

impl Drop for Publisher {
    fn drop(&mut self) {
        self.running.store(false, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// A command reader driven by a mio poll, with the arbiter applied.
struct Actuator {
    session: Session,
    reader: rl_layer::dds::Reader<ServoControl>,
    poll: mio::Poll,
    events: mio::Events,
    arbiter: Arbiter<GUID>,
    start: Instant,
    /// (t_ms, writer, accepted)
    log: Vec<(u64, GUID, bool)>,
    changes: Vec<rl_layer::arbiter::OwnerChange<GUID>>,
}

impl Actuator {
    fn new(session: Session) -> Actuator {
        let reader = session.command_reader().unwrap();
        let poll = mio::Poll::new().unwrap();
        poll.register(
            &reader,
            mio::Token(0),
            mio::Ready::readable(),
            mio::PollOpt::edge(),
        )
        .unwrap();
        let deadline_ms = session.timing().command_deadline_ms;
        Actuator {
            session,
            reader,
            poll,
            events: mio::Events::with_capacity(8),
            arbiter: Arbiter::new(deadline_ms),
            start: Instant::now(),
            log: Vec::new(),
            changes: Vec::new(),
        }
    }

    fn strengths(&self) -> BTreeMap<GUID, Strength> {
        self.session.command_writer_strengths()
    }

    /// Processes what arrives during `duration`.
    fn run_for(&mut self, duration: Duration) {
        let end = Instant::now() + duration;
        let mut strengths = self.strengths();
        while Instant::now() < end {
            self.poll
                .poll(&mut self.events, Some(Duration::from_millis(10)))
                .unwrap();
            for sample in self.reader.take() {
                if !strengths.contains_key(&sample.writer) {
                    strengths = self.strengths();
                }
                let strength = strengths.get(&sample.writer).copied().unwrap_or_default();
                let now_ms = self.start.elapsed().as_millis() as u64;
                let decision = self.arbiter.offer(sample.writer, strength, now_ms);
                self.log.push((now_ms, sample.writer, decision.accepted));
                self.changes.extend(decision.owner_changed);
            }
        }
    }

    fn accepted_since(&self, t_ms: u64) -> Vec<GUID> {
        self.log
            .iter()
            .filter(|(t, _, accepted)| *t >= t_ms && *accepted)
            .map(|(_, writer, _)| *writer)
            .collect()
    }

    fn now_ms(&self) -> u64 {
        self.start.elapsed().as_millis() as u64
    }
}

#[test]
fn arbiter_follows_the_strongest_writer_and_fails_over_within_the_deadline() {
    const DOMAIN: u16 = 101;
    let mut actuator = Actuator::new(session(DOMAIN));
    let primary = Publisher::start(session(DOMAIN), 30, 300);
    let secondary = Publisher::start(session(DOMAIN), 20, 200);
    wait_for(DISCOVERY_TIMEOUT, "both command writers discovered", || {
        let strengths = actuator.strengths();
        (strengths.get(&primary.guid) == Some(&Strength(30))
            && strengths.get(&secondary.guid) == Some(&Strength(20)))
        .then_some(())
    });

    // Let the first samples settle ownership, then watch one second of steady state.
    actuator.run_for(Duration::from_millis(500));
    let steady_from = actuator.now_ms();
    actuator.run_for(Duration::from_secs(1));
    let steady: Vec<_> = actuator
        .log
        .iter()
        .filter(|(t, _, _)| *t >= steady_from)
        .collect();
    assert!(
        steady.iter().any(|(_, w, _)| *w == secondary.guid),
        "the reader receives the weaker writer too (RustDDS does not filter)"
    );
    assert!(
        steady.iter().filter(|(_, w, _)| *w == primary.guid).count() >= 20,
        "the primary publishes at ~30 Hz: {steady:?}"
    );
    for (t, writer, accepted) in &steady {
        assert_eq!(
            *accepted,
            *writer == primary.guid,
            "at {t} ms only the strength-30 writer is accepted"
        );
    }

    // The Primary goes silent (as a crashed process whose writer is still matched).
    let changes_before = actuator.changes.len();
    primary.silence();
    actuator.run_for(Duration::from_millis(800));
    let failover = actuator.changes[changes_before..]
        .iter()
        .find(|change| change.to == secondary.guid)
        .unwrap_or_else(|| panic!("no failover to the secondary: {:?}", actuator.changes));
    assert_eq!(failover.from, Some(primary.guid));
    let gap_ms = failover.gap_ms.unwrap();
    eprintln!("failover after silence: {gap_ms} ms without accepted commands");
    let deadline_ms = actuator.arbiter.deadline_ms();
    assert!(
        gap_ms > deadline_ms && gap_ms <= deadline_ms + 33 + 100,
        "gap {gap_ms} ms: expected the deadline ({deadline_ms} ms) plus at most one period \
         (33 ms) and scheduling slack"
    );
    let after = actuator.accepted_since(actuator.now_ms() - 300);
    assert!(!after.is_empty() && after.iter().all(|w| *w == secondary.guid));
    drop(primary);
    drop(secondary);
}

#[test]
fn recreated_command_writer_is_seen_with_its_new_strength() {
    const DOMAIN: u16 = 102;
    let reader_session = session(DOMAIN);
    let mut reader = reader_session.command_reader().unwrap();
    let writer_session = session(DOMAIN);
    let mut writer = writer_session.command_writer(Some(Strength(20))).unwrap();
    assert_eq!(writer.strength(), Some(Strength(20)));
    let old_guid = writer.guid().unwrap();
    assert_eq!(
        rl_layer::dds::participant_key(old_guid),
        writer_session.participant_key(),
        "a writer's GUID starts with its participant's prefix"
    );
    wait_for(DISCOVERY_TIMEOUT, "the strength-20 writer", || {
        (reader_session.command_writer_strengths().get(&old_guid) == Some(&Strength(20)))
            .then_some(())
    });

    // Unchanged strength: the same writer.
    writer.set_strength(Some(Strength(20))).unwrap();
    assert_eq!(writer.guid(), Some(old_guid));

    writer.set_strength(Some(Strength(30))).unwrap();
    let new_guid = writer.guid().unwrap();
    assert_ne!(new_guid, old_guid, "a new strength is a new writer");
    let command = ServoControl {
        pan: 1,
        tilt: 2,
        frequency: 60,
    };
    // A promotion: the old, weaker writer keeps writing for two deadlines while readers
    // discover the new one, then goes.
    wait_for(
        DISCOVERY_TIMEOUT,
        "the new writer at strength 30, the old one gone",
        || {
            assert!(writer.write(command).unwrap());
            let strengths = reader_session.command_writer_strengths();
            (strengths.get(&new_guid) == Some(&Strength(30)) && !strengths.contains_key(&old_guid))
                .then_some(())
        },
    );
    let received = wait_for(DISCOVERY_TIMEOUT, "a command from the new writer", || {
        assert!(writer.write(command).unwrap());
        reader
            .take()
            .into_iter()
            .find(|sample| sample.writer == new_guid)
    });
    assert_eq!(received.value, command);

    // No strength: no writer at all.
    writer.set_strength(None).unwrap();
    assert_eq!(writer.guid(), None);
    assert_eq!(writer.strength(), None);
    assert!(!writer.write(command).unwrap());
    wait_for(DISCOVERY_TIMEOUT, "the writer removed", || {
        reader_session
            .command_writer_strengths()
            .is_empty()
            .then_some(())
    });
}

#[test]
fn heartbeats_and_votes_round_trip_and_name_their_participant() {
    const DOMAIN: u16 = 103;
    let reader_session = session(DOMAIN);
    let mut heartbeats = reader_session.heartbeat_reader().unwrap();
    let mut votes = reader_session.vote_reader().unwrap();
    let writer_session = session(DOMAIN);
    let heartbeat_writer = writer_session.heartbeat_writer().unwrap();
    let vote_writer = writer_session.vote_writer().unwrap();

    let sent = heartbeat(2, Role::Secondary);
    // Best effort: write until the reader is matched and hears one.
    let received = wait_for(DISCOVERY_TIMEOUT, "a heartbeat", || {
        heartbeat_writer.write(&sent).unwrap();
        heartbeats.take().pop()
    });
    assert_eq!(received.value, sent);
    assert_eq!(
        rl_layer::dds::participant_key(received.writer),
        writer_session.participant_key()
    );
    let mut directory = ControllerDirectory::new();
    directory.note_heartbeat(&received);
    let command_writer = writer_session.command_writer(Some(Strength(20))).unwrap();
    assert_eq!(
        directory.controller_of(command_writer.guid().unwrap()),
        Some(2),
        "the controller's command writer maps to its id through the heartbeat"
    );
    assert_eq!(
        directory.controller_of(reader_session.participant_guid()),
        None
    );

    let record = VoteRecord {
        from: 2,
        incarnation: 22,
        vote: Some(Assignment::from_ranked([holder(1, 11), holder(2, 22)])),
    };
    vote_writer.write(&record).unwrap();
    let received = wait_for(DISCOVERY_TIMEOUT, "a vote", || votes.take().pop());
    assert_eq!(received.value, record);
    assert_eq!(heartbeats.malformed_count(), 0);
    assert_eq!(votes.malformed_count(), 0);

    // Invalid values are refused before they reach the wire.
    let invalid = Heartbeat {
        strength: Some(Strength(30)),
        ..heartbeat(3, Role::Tertiary)
    };
    let error = heartbeat_writer.write(&invalid).unwrap_err().to_string();
    assert!(error.contains("heartbeat.strength"), "{error}");
}

#[test]
fn late_reader_receives_the_latest_transient_local_votes() {
    const DOMAIN: u16 = 104;
    // Three controllers vote (controller 1 twice) before any reader exists.
    let voters: Vec<_> = (1..=3u8).map(|_| session(DOMAIN)).collect();
    let writers: Vec<_> = voters.iter().map(|s| s.vote_writer().unwrap()).collect();
    let vote_of = |from: u8, incarnation: u64, primary: u8| VoteRecord {
        from,
        incarnation,
        vote: Some(Assignment::from_ranked([holder(primary, 1)])),
    };
    for (index, writer) in writers.iter().enumerate() {
        let id = index as u8 + 1;
        writer.write(&vote_of(id, 100, 1)).unwrap();
    }
    writers[0].write(&vote_of(1, 101, 2)).unwrap();
    thread::sleep(Duration::from_millis(300));

    let late = session(DOMAIN);
    let mut reader = late.vote_reader().unwrap();
    let mut latest = BTreeMap::new();
    wait_for(DISCOVERY_TIMEOUT, "the three durable votes", || {
        for vote in reader.take() {
            latest.insert(vote.value.from, vote.value);
        }
        (latest.len() == 3 && latest[&1].incarnation == 101).then_some(())
    });
    assert_eq!(latest[&1], vote_of(1, 101, 2));
    assert_eq!(latest[&2], vote_of(2, 100, 1));
    assert_eq!(latest[&3], vote_of(3, 100, 1));
}

/// A different type published under the heartbeat topic's name and type name: too short to
/// decode as a heartbeat.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct Impostor {
    from_id: u8,
    junk: u16,
}

impl Keyed for Impostor {
    type K = u8;
    fn key(&self) -> u8 {
        self.from_id
    }
}

#[test]
fn malformed_heartbeats_are_dropped_without_panicking() {
    const DOMAIN: u16 = 105;
    let reader_session = session(DOMAIN);
    let mut reader = reader_session.heartbeat_reader().unwrap();
    let writer_session = session(DOMAIN);
    let writer = writer_session.heartbeat_writer().unwrap();

    // An independent participant speaking a different shape on the same topic.
    let rogue = DomainParticipant::new(DOMAIN).unwrap();
    let qos = QosPolicyBuilder::new()
        .reliability(Reliability::BestEffort)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 1 })
        .build();
    let topic = rogue
        .create_topic(
            Dds::default().heartbeat_topic,
            HEARTBEAT_TYPE_NAME.to_string(),
            &qos,
            TopicKind::WithKey,
        )
        .unwrap();
    let rogue_writer = rogue
        .create_publisher(&qos)
        .unwrap()
        .create_datawriter::<Impostor, CDRSerializerAdapter<Impostor>>(&topic, None)
        .unwrap();

    let good = heartbeat(1, Role::Primary);
    let bad_phase = HeartbeatSample {
        phase: 9,
        ..HeartbeatSample::encode(&heartbeat(2, Role::Secondary))
    };
    let bad_id = HeartbeatSample {
        from_id: 0,
        ..HeartbeatSample::encode(&heartbeat(3, Role::Tertiary))
    };
    let mut received = Vec::new();
    wait_for(
        DISCOVERY_TIMEOUT,
        "valid heartbeats and three kinds of malformed ones",
        || {
            rogue_writer
                .write(
                    Impostor {
                        from_id: 4,
                        junk: 7,
                    },
                    None,
                )
                .unwrap();
            writer.write_sample(bad_phase).unwrap();
            writer.write_sample(bad_id).unwrap();
            writer.write(&good).unwrap();
            received.extend(reader.take());
            (received.len() >= 3 && reader.malformed_count() >= 9).then_some(())
        },
    );
    assert!(
        received.iter().all(|sample| sample.value == good),
        "only the valid heartbeat gets through: {received:?}"
    );
}

#[test]
fn ros_status_is_published_as_std_msgs_string() {
    const DOMAIN: u16 = 106;
    let controller = session(DOMAIN);
    let mut node = controller.ros_node(1).unwrap();
    assert_eq!(node.fully_qualified_name(), "/rl/rl_controller_1");
    let status = controller.status_publisher(&mut node).unwrap();

    let listener = session(DOMAIN);
    let mut listener_node = listener.ros_node(9).unwrap();
    let topic = listener_node
        .create_topic(
            &ros2_client::Name::new("", "status").unwrap(),
            ros2_client::MessageTypeName::new("std_msgs", "String"),
            &ros2_client::QosProfile::default(),
        )
        .unwrap();
    let subscription = listener_node
        .create_subscription::<RosString>(&topic, None)
        .unwrap();
    let (message, _) = wait_for(DISCOVERY_TIMEOUT, "the status string", || {
        status.publish("controller 1: steady primary").unwrap();
        subscription.take().unwrap()
    });
    assert_eq!(message.data, "controller 1: steady primary");
}

#[test]
fn heartbeats_of_three_controllers_written_together_all_arrive() {
    // The reader keeps the last heartbeat per controller (keyed), not the last of all: three
    // heartbeats landing between two takes must all be delivered.
    const DOMAIN: u16 = 107;
    const ROUNDS: usize = 20;
    let reader_session = session(DOMAIN);
    let mut reader = reader_session.heartbeat_reader().unwrap();
    let controllers: Vec<_> = (1..=3u8).map(|_| session(DOMAIN)).collect();
    let writers: Vec<_> = controllers
        .iter()
        .map(|s| s.heartbeat_writer().unwrap())
        .collect();
    let roles = [Role::Primary, Role::Secondary, Role::Tertiary];
    let beats: Vec<_> = roles
        .iter()
        .enumerate()
        .map(|(index, role)| heartbeat(index as u8 + 1, *role))
        .collect();
    let write_all = || {
        for (writer, beat) in writers.iter().zip(&beats) {
            writer.write(beat).unwrap();
        }
    };
    let mut heard = std::collections::BTreeSet::new();
    wait_for(DISCOVERY_TIMEOUT, "heartbeats of all three", || {
        write_all();
        heard.extend(reader.take().into_iter().map(|s| s.value.id));
        (heard.len() == 3).then_some(())
    });
    thread::sleep(Duration::from_millis(100));
    let _ = reader.take();

    let mut complete_rounds = 0;
    for _ in 0..ROUNDS {
        write_all();
        thread::sleep(Duration::from_millis(50));
        let mut ids: Vec<_> = reader.take().into_iter().map(|s| s.value.id).collect();
        ids.sort();
        if ids == [1, 2, 3] {
            complete_rounds += 1;
        }
    }
    assert!(
        complete_rounds >= ROUNDS - 2,
        "all three heartbeats in only {complete_rounds} of {ROUNDS} rounds"
    );
}

#[test]
fn a_standby_raise_waits_two_command_deadlines_and_a_first_writer_or_primary_raise_does_not() {
    const DOMAIN: u16 = 108;
    let writer_session = session(DOMAIN);
    let wait = Duration::from_millis(Timing::default().command_deadline_ms * 2);
    let (s10, s20, s30) = (Some(Strength(10)), Some(Strength(20)), Some(Strength(30)));
    let mut standby = writer_session.command_writer(None).unwrap();
    standby.set_strength(s10).unwrap();
    assert_eq!(standby.strength(), s10, "a first writer is created at once");
    let asked = Instant::now();
    standby.set_strength(s20).unwrap();
    assert_eq!(standby.strength(), s10, "a standby's raise waits");
    let raised = wait_for(wait * 3, "the standby's raise", || {
        standby.set_strength(s20).unwrap();
        (standby.strength() == s20).then(|| asked.elapsed())
    });
    assert_eq!(standby.strength(), s20);
    assert!(
        raised >= wait,
        "raised after {raised:?}, before two command deadlines ({wait:?})"
    );
    let mut primary = writer_session.command_writer(s10).unwrap();
    primary.set_strength(s30).unwrap();
    assert_eq!(primary.strength(), s30, "a Primary's raise is immediate");
    primary.set_strength(s10).unwrap();
    assert_eq!(primary.strength(), s10, "lowering is immediate");
}
