//! The RL API as an application sees it, over real DDS (domains 219, 218): three controllers in one
//! process; what RL does is pushed to the application, and a role writer of the application's
//! own type follows the role.

use rl_layer::api::{AperiodicPolicy, Options, OwnerFeed, Plain, Redundancy, RoleWriter};
use rl_layer::config::Config;
use rl_layer::core::{Role, Strength};
use rl_layer::event::{Event, EventLine};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

const DOMAIN: u16 = 219;
const FEED_DOMAIN: u16 = 218;

#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct Setpoint {
    value: i32,
}

/// The owner's setpoint as `feed` sees it within `within`, while `writers` keep writing
/// (each its own value).
fn owners_setpoint(
    session: &rl_layer::dds::Session,
    feed: &mut OwnerFeed<Plain<Setpoint>>,
    writers: &mut [(&mut RoleWriter<Setpoint>, i32)],
    within: Duration,
) -> Option<i32> {
    let started = Instant::now();
    let mut seen = None;
    while started.elapsed() < within {
        for (writer, value) in writers.iter_mut() {
            let _ = writer.write(Setpoint { value: *value });
        }
        let now_ms = u64::try_from(started.elapsed().as_millis()).unwrap_or(u64::MAX);
        if let Some((setpoint, _writer)) = feed.take(session, now_ms) {
            seen = Some(setpoint.value);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    seen
}

/// The first event line within `within` that `wanted` accepts.
fn wait_for(
    events: &Receiver<EventLine>,
    within: Duration,
    wanted: impl Fn(&Event) -> bool,
) -> Option<EventLine> {
    let until = Instant::now() + within;
    while let Some(left) = until.checked_duration_since(Instant::now()) {
        match events.recv_timeout(left) {
            Ok(line) if wanted(&line.event) => return Some(line),
            Ok(_) => {}
            Err(_) => return None,
        }
    }
    None
}

#[test]
fn role_changes_and_alarms_are_pushed_and_the_role_writer_follows_them() {
    let mut config = Config::default();
    config.dds.domain = DOMAIN;
    let start = |id| Redundancy::start(&config, id, Options::default()).expect("RL starts");
    let (c1, c2, c3) = (start(1), start(2), start(3));
    let events = c2.events();
    let mut setpoints: RoleWriter<Setpoint> = c2
        .role_writer(
            "plant/setpoint",
            "plant::Setpoint",
            AperiodicPolicy::Republish,
        )
        .expect("a role writer");
    let secondary = |event: &Event| {
        matches!(
            event,
            Event::Output {
                role: Some(Role::Secondary),
                strength: Some(Strength(20))
            }
        )
    };
    assert!(
        wait_for(&events, Duration::from_secs(20), secondary).is_some(),
        "C2 was not told it is Secondary"
    );
    assert_eq!(setpoints.write(Setpoint { value: 1 }).ok(), Some(true));
    assert_eq!(setpoints.strength(), Some(Strength(20)));

    drop(c1);
    let lost = |event: &Event| {
        matches!(
            event,
            Event::Alarm {
                about: 1,
                raised: true,
                ..
            }
        )
    };
    assert!(
        wait_for(&events, Duration::from_secs(10), lost).is_some(),
        "no alarm about C1 pushed"
    );
    let primary = |event: &Event| {
        matches!(
            event,
            Event::Output {
                role: Some(Role::Primary),
                strength: Some(Strength(30))
            }
        )
    };
    assert!(
        wait_for(&events, Duration::from_secs(10), primary).is_some(),
        "C2 was not told it is Primary"
    );
    // Without a new sample, keep_alive follows the role (a promotion creates the writer at
    // 30) and republishes the last setpoint once command_republish_ms has passed.
    std::thread::sleep(Duration::from_millis(
        config.timing.command_republish_ms + 5,
    ));
    assert_eq!(setpoints.keep_alive().ok(), Some(true));
    assert_eq!(setpoints.strength(), Some(Strength(30)));
    assert_eq!(
        setpoints.keep_alive().ok(),
        Some(false),
        "not due again at once"
    );
    drop((c2, c3));
}

/// A standby follows the owner of an application's topic (bumpless transfer): the Primary's
/// samples while it lives, the new Primary's after it stops; the Secondary's, also written
/// all along, never.
#[test]
fn a_standby_follows_the_owner_of_an_application_topic() {
    let mut config = Config::default();
    config.dds.domain = FEED_DOMAIN;
    let start = |id| Redundancy::start(&config, id, Options::default()).expect("RL starts");
    let (c1, c2, c3) = (start(1), start(2), start(3));
    let writer = |rl: &Redundancy| -> RoleWriter<Setpoint> {
        rl.role_writer(
            "plant/setpoint",
            "plant::Setpoint",
            AperiodicPolicy::Periodic,
        )
        .expect("a role writer")
    };
    let (mut w1, mut w2) = (writer(&c1), writer(&c2));
    let mut feed = c3
        .owner_feed::<Setpoint>("plant/setpoint", "plant::Setpoint")
        .expect("an owner feed");
    let formed = Instant::now() + Duration::from_secs(20);
    while c1.role() != Some(Role::Primary) || c2.role() != Some(Role::Secondary) {
        assert!(Instant::now() < formed, "no formation: {:?}", c1.status());
        std::thread::sleep(Duration::from_millis(50));
    }
    let both = &mut [(&mut w1, 1), (&mut w2, 2)];
    let seen = owners_setpoint(c3.session(), &mut feed, both, Duration::from_secs(2));
    assert_eq!(seen, Some(1), "the Primary's setpoint");
    drop(w1);
    drop(c1);
    let only = &mut [(&mut w2, 2)];
    let seen = owners_setpoint(c3.session(), &mut feed, only, Duration::from_secs(5));
    assert_eq!(seen, Some(2), "the new Primary's setpoint");
    drop((c2, c3));
}
