//! The guide's example, run: three copies of it in one process over real DDS (domain 217), a
//! reader of `nav/heading` beside them, and the Primary stopped.

use super::*;
use rl_layer::core::{Strength, TAKEOVER_STRENGTH};
use rl_layer::dds::{qos, Session};
use rustdds::{no_key, CDRDeserializerAdapter, QosPolicies, ReadCondition, TopicKind, GUID};
use std::collections::{BTreeMap, BTreeSet};
use std::thread::JoinHandle;

const DOMAIN: u16 = 217;

#[test]
fn the_control_law_points_at_the_waypoint() {
    assert_eq!(heading_to((0.0, 0.0), (0.0, 10.0)), 0.0);
    assert!((heading_to((0.0, 0.0), (10.0, 0.0)) - 90.0).abs() < 1e-3);
    assert!((heading_to((0.0, 0.0), (-10.0, 0.0)) - 270.0).abs() < 1e-3);
}

/// The reader follows the Primary's headings; when the Primary stops, the Secondary's writer
/// becomes the strongest (30) and the Tertiary's moves up (20), with no writer left at 10.
#[test]
fn three_copies_hand_the_heading_over_when_the_primary_stops() {
    let mut config = Config::default();
    config.dds.domain = DOMAIN;
    let copies: Vec<Copy> = (1..=3).map(|id| Copy::start(&config, id)).collect();
    let observer = Observer::open(&config);

    let formed = observer.wait_for_strengths(&[30, 20, 10], Duration::from_secs(30));
    assert!(formed, "no writers at 30/20/10: {:?}", observer.strengths());
    let primary_writes = observer.samples_at(30, Duration::from_secs(2));
    assert!(!primary_writes.is_empty(), "no heading from the 30 writer");
    assert!(
        primary_writes.iter().all(|h| h.from_id == 1),
        "the strongest writer is C1's: {primary_writes:?}"
    );

    let mut copies = copies.into_iter();
    let first = copies.next().expect("three copies");
    assert!(first.stop().is_ok(), "C1 stops cleanly");
    let handed_over = observer.wait_for_strengths(&[30, 20], Duration::from_secs(15));
    assert!(
        handed_over,
        "no writers at 30/20 after C1 stopped: {:?}",
        observer.strengths()
    );
    let new_primary_writes = observer.samples_at(30, Duration::from_secs(2));
    assert!(
        !new_primary_writes.is_empty(),
        "no heading from the new 30 writer"
    );
    assert!(
        new_primary_writes.iter().all(|h| h.from_id == 2),
        "C2 owns the heading now: {new_primary_writes:?}"
    );
    for copy in copies {
        assert!(copy.stop().is_ok());
    }
}

/// One copy of the example running in a thread, as `main` runs it.
struct Copy {
    stop: Arc<AtomicBool>,
    thread: JoinHandle<Result<(), rl_layer::Error>>,
}

impl Copy {
    fn start(config: &Config, id: ControllerId) -> Copy {
        let stop = Arc::new(AtomicBool::new(false));
        let (config, flag) = (config.clone(), Arc::clone(&stop));
        let thread = std::thread::spawn(move || run(&config, id, &flag));
        Copy { stop, thread }
    }

    fn stop(self) -> Result<(), rl_layer::Error> {
        self.stop.store(true, Ordering::SeqCst);
        self.thread.join().expect("the copy's thread did not panic")
    }
}

/// A plain DDS reader of the application's topic (not a controller), and its participant's
/// view of the writers' ownership strengths from discovery.
struct Observer {
    session: Session,
    reader: std::sync::Mutex<no_key::DataReader<Heading, CDRDeserializerAdapter<Heading>>>,
}

impl Observer {
    fn open(config: &Config) -> Observer {
        let session = Session::new(&config.dds, &config.timing).expect("an observer session");
        let participant = session.participant();
        let topic = participant
            .create_topic(
                HEADING_TOPIC.to_string(),
                HEADING_TYPE.to_string(),
                &QosPolicies::qos_none(),
                TopicKind::NoKey,
            )
            .expect("the heading topic");
        let subscriber = participant
            .create_subscriber(&QosPolicies::qos_none())
            .expect("a subscriber");
        let reader = subscriber
            .create_datareader_no_key::<Heading, CDRDeserializerAdapter<Heading>>(
                &topic,
                Some(qos::command_reader(&config.timing)),
            )
            .expect("a heading reader");
        Observer {
            session,
            reader: std::sync::Mutex::new(reader),
        }
    }

    fn strengths(&self) -> BTreeMap<GUID, Strength> {
        self.session.writer_strengths(HEADING_TOPIC)
    }

    /// Waits until the discovered writers have exactly these strengths, one each, beside the
    /// Secondary's takeover writer at 35, which RL keeps ready and which writes nothing
    /// (`rl_layer::dds::StrengthWriter`).
    fn wait_for_strengths(&self, expected: &[i32], within: Duration) -> bool {
        let expected: Vec<Strength> = expected.iter().map(|&s| Strength(s)).collect();
        let until = Instant::now() + within;
        while Instant::now() < until {
            let mut now: Vec<Strength> = self
                .strengths()
                .into_values()
                .filter(|strength| *strength != TAKEOVER_STRENGTH)
                .collect();
            now.sort_unstable_by(|a, b| b.cmp(a));
            if now == expected {
                return true;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        false
    }

    /// The headings written by the writers now at `strength`, read for `during`.
    fn samples_at(&self, strength: i32, during: Duration) -> Vec<Heading> {
        let writers: BTreeSet<GUID> = self
            .strengths()
            .into_iter()
            .filter(|(_, s)| *s == Strength(strength))
            .map(|(guid, _)| guid)
            .collect();
        let mut reader = self.reader.lock().expect("the reader's lock");
        let _ = reader.take(usize::MAX, ReadCondition::any()); // older samples
                                                               // Taken as they come: the reader keeps only the last few samples of all writers.
        let mut taken = Vec::new();
        let until = Instant::now() + during;
        while Instant::now() < until {
            taken.extend(
                reader
                    .take(usize::MAX, ReadCondition::any())
                    .expect("reading headings"),
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        taken
            .into_iter()
            .filter(|sample| writers.contains(&sample.sample_info().writer_guid()))
            .map(|sample| sample.into_value())
            .collect()
    }
}
