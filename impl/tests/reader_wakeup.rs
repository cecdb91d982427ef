//! A DDS reader wakes the poll it is registered with, for every sample, for as long as it
//! runs: the voting loop sleeps in that poll and takes heartbeats and votes when it wakes.
//!
//! RustDDS signals a reader's poll through two notification channels, and its reader drained
//! only one (impl/vendor/rustdds/PATCHES.md, fix 3): after 100 samples the other was full,
//! and the poll never woke for a sample again, so the voting loop found heartbeats only when
//! a timer woke it, up to 100 ms after they arrived. And a reader whose wake-ups the voting
//! loop switches off and on again (the command reader, watched only while Secondary) wakes it
//! again each time it is switched on. Domain 232.

use rl_layer::config::{Dds, Timing};
use rl_layer::core::Heartbeat;
use rl_layer::dds::{mio, Session, WakeSwitch};
use std::time::{Duration, Instant};

const DOMAIN: u16 = 232;
const SAMPLES: usize = 250;

fn session() -> Session {
    let dds = Dds {
        domain: DOMAIN,
        ..Dds::default()
    };
    Session::new(&dds, &Timing::default()).unwrap()
}

#[test]
fn a_heartbeat_reader_wakes_its_poll_for_every_sample() {
    let reader_session = session();
    let mut heartbeats = reader_session.heartbeat_reader().unwrap();
    let writer_session = session();
    let writer = writer_session.heartbeat_writer().unwrap();
    let sent = Heartbeat::initial(2, 22);

    // Best effort: write until the reader is matched and hears one.
    let discovery_started = Instant::now();
    while heartbeats.take().is_empty() {
        assert!(
            discovery_started.elapsed() < Duration::from_secs(15),
            "the reader never heard the writer"
        );
        writer.write(&sent).unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }

    let poll = mio::Poll::new().unwrap();
    let token = mio::Token(3);
    poll.register(
        &heartbeats,
        token,
        mio::Ready::readable(),
        mio::PollOpt::edge(),
    )
    .unwrap();
    let mut events = mio::Events::with_capacity(8);
    let mut woken = 0;
    for sample in 0..SAMPLES {
        writer.write(&sent).unwrap();
        // A best-effort sample may be lost on a loaded machine: then the next one wakes it.
        let deadline = Instant::now() + Duration::from_secs(1);
        let mut woke = false;
        while !woke && Instant::now() < deadline {
            poll.poll(&mut events, Some(Duration::from_millis(200)))
                .unwrap();
            woke = events.iter().any(|event| event.token() == token);
        }
        let taken = heartbeats.take();
        if woke {
            woken += 1;
        } else {
            assert!(
                taken.is_empty(),
                "sample {sample} arrived ({} taken) without waking the poll",
                taken.len()
            );
        }
    }
    assert!(
        woken >= SAMPLES * 9 / 10,
        "the poll woke for {woken} of {SAMPLES} samples"
    );
}

/// Writes until a sample wakes `poll` (true) or `within` passes (false); takes what came.
fn wakes(
    poll: &mio::Poll,
    reader: &mut rl_layer::dds::Reader<rl_layer::wire::HeartbeatSample>,
    writer: &rl_layer::dds::Writer<rl_layer::wire::HeartbeatSample>,
    within: Duration,
) -> bool {
    let mut events = mio::Events::with_capacity(8);
    let deadline = Instant::now() + within;
    while Instant::now() < deadline {
        writer.write(&Heartbeat::initial(2, 22)).unwrap();
        poll.poll(&mut events, Some(Duration::from_millis(50)))
            .unwrap();
        if events.iter().any(|event| event.token() == mio::Token(4)) {
            reader.take();
            return true;
        }
    }
    reader.take();
    false
}

#[test]
fn a_reader_switched_off_and_on_again_wakes_its_poll_each_time_it_is_on() {
    let reader_session = session();
    let mut heartbeats = reader_session.heartbeat_reader().unwrap();
    let writer_session = session();
    let writer = writer_session.heartbeat_writer().unwrap();
    let poll = mio::Poll::new().unwrap();
    let mut switch = WakeSwitch::new();
    for round in 0..3 {
        switch
            .on(&poll, &heartbeats, mio::Token(4))
            .unwrap_or_else(|e| panic!("switching on, time {round}: {e}"));
        assert!(switch.is_on());
        assert!(
            wakes(&poll, &mut heartbeats, &writer, Duration::from_secs(15)),
            "switched on (time {round}), the reader never woke the poll"
        );
        switch.off(&poll, &heartbeats).unwrap();
        assert!(!switch.is_on());
        assert!(
            !wakes(&poll, &mut heartbeats, &writer, Duration::from_millis(500)),
            "switched off (time {round}), the reader woke the poll"
        );
    }
}
