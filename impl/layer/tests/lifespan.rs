//! LIFESPAN on the reading side, over real DDS (domain 221): an actuator view drops a command
//! that arrives later than its writer's lifespan, judged against the writer's own best delay,
//! so the two clocks need not agree.
//!
//! The writer here stamps its first samples 300 ms ahead of its clock (a writer whose clock is
//! ahead of the reader's) and then stamps them on time: to the reader those are 300 ms later
//! than the writer's best, as a stalled or starved writer's commands are, though the writer's
//! own lifespan check (RustDDS fix 18) lets them out.

use rl_layer::config::Config;
use rl_layer::core::Strength;
use rl_layer::dds::Session;
use rl_layer::owner_feed::{Delivery, OwnerFeed};
use rl_layer::trust::CommandTrust;
use rl_layer::wire::{ServoControl, SERVO_CONTROL_TYPE_NAME};
use rustdds::{DomainParticipantBuilder, QosPolicyBuilder, Timestamp, TopicKind};
use std::time::{Duration, Instant};

const DOMAIN: u16 = 221;
/// How far ahead of its clock the writer stamps its first samples.
const AHEAD_MS: i64 = 300;

#[test]
fn a_command_later_than_its_writers_lifespan_is_dropped() {
    let mut config = Config::default();
    config.dds.domain = DOMAIN;
    let lifespan_ms = config.timing.command_deadline_ms;
    let participant = DomainParticipantBuilder::new(DOMAIN)
        .build()
        .expect("a participant");
    let plain = QosPolicyBuilder::new().build();
    let topic = participant
        .create_topic(
            config.dds.command_topic.clone(),
            SERVO_CONTROL_TYPE_NAME.to_string(),
            &plain,
            TopicKind::NoKey,
        )
        .expect("the command topic");
    let writer = participant
        .create_publisher(&plain)
        .expect("a publisher")
        .create_datawriter_no_key_cdr::<ServoControl>(
            &topic,
            Some(rl_layer::dds::qos::command_writer(
                &config.timing,
                Strength(30),
            )),
        )
        .expect("a command writer");

    let session = Session::new(&config.dds, &config.timing).expect("the reader's session");
    let reader = session.command_reader().expect("a command reader");
    let any_writer = CommandTrust::new(config.timing.peer_deadline_ms, true);
    let mut feed = OwnerFeed::open_trusting(
        &session,
        reader,
        config.timing.command_deadline_ms,
        any_writer,
    )
    .expect("an owner feed");

    let started = Instant::now();
    let mut offered = 0;
    let mut expired = Vec::new();
    for sent in 0..200u16 {
        // The first 2 s stamped ahead (the baseline), then on time.
        let ahead = started.elapsed() < Duration::from_secs(2);
        let stamp = if ahead {
            Timestamp::now() + rustdds::Duration::from_millis(AHEAD_MS)
        } else {
            Timestamp::now()
        };
        let command = ServoControl {
            pan: sent,
            tilt: 500,
            frequency: 60,
        };
        writer.write(command, Some(stamp)).expect("written");
        std::thread::sleep(Duration::from_millis(10));
        let now_ms = u64::try_from(started.elapsed().as_millis()).unwrap_or(u64::MAX);
        for delivery in feed.deliveries(&session, now_ms) {
            match delivery {
                Delivery::Offered { late_ms, .. } => {
                    assert!(
                        late_ms.is_some_and(|late| late <= i64::try_from(lifespan_ms).unwrap()),
                        "offered a sample {late_ms:?} ms late"
                    );
                    offered += 1;
                }
                Delivery::Expired {
                    late_ms,
                    lifespan_ms: announced,
                    ..
                } => {
                    assert_eq!(
                        announced, lifespan_ms,
                        "the writer's lifespan from discovery"
                    );
                    expired.push(late_ms);
                }
                Delivery::Refused { refusal, .. } => panic!("refused: {refusal}"),
            }
        }
        if !expired.is_empty() && offered > 0 {
            break;
        }
    }
    assert!(offered > 0, "no sample stamped ahead was offered");
    let first = expired.first().copied();
    assert!(
        first.is_some_and(|late| (AHEAD_MS - 50..=AHEAD_MS + 50).contains(&late)),
        "the first sample stamped on time after the baseline is {AHEAD_MS} ms late and \
         expired: {expired:?} ({offered} offered)"
    );
}
