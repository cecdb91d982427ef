//! The arrival verdicts on literal delays: the rate-limited Primary measured in the fault lab
//! (`tbf-primary`: samples 23, 79 and 148 ms after they were written, at most 12 ms before),
//! clocks that disagree or drift, and silence.

use super::*;

/// Commands every 33 ms, as the camera's frames come.
const EVERY_MS: u64 = 33;

fn writer(n: u8) -> GUID {
    let mut bytes = [0u8; 16];
    bytes[0] = n;
    bytes[15] = 0x03;
    GUID::from_bytes(bytes)
}

fn watch() -> ArrivalWatch {
    ArrivalWatch::new(100)
}

/// A watch that has heard `writers` of controllers 1 to 9 (writer n for controller n) on time
/// for [`ESTABLISHED_MS`], ending at `at_ms`.
fn established(writers: &[u8], at_ms: u64) -> ArrivalWatch {
    let mut w = watch();
    let mut t = at_ms - ESTABLISHED_MS;
    while t < at_ms {
        for n in writers {
            w.sample(*n, writer(*n), 5, t);
        }
        t += EVERY_MS;
    }
    for n in writers {
        w.sample(*n, writer(*n), 5, at_ms);
    }
    w
}

#[test]
fn a_new_writer_says_nothing_until_it_is_established() {
    // C3 has just joined: its first samples are their own baseline.
    let mut w = established(&[1], 1_000);
    assert_eq!(w.sample(1, writer(1), 90, 1_010), Some(Arrival::Late));
    assert_eq!(w.sample(3, writer(3), 5, 1_020), None);
    let established_ms = 1_020 + ESTABLISHED_MS;
    assert_eq!(w.sample(3, writer(3), 5, established_ms - EVERY_MS), None);
    // Established: its on-time samples count, and with C1 late each is reported.
    w.sample(1, writer(1), 90, established_ms);
    assert_eq!(
        w.sample(3, writer(3), 5, established_ms + 2 * EVERY_MS),
        Some(Arrival::OnTime)
    );
}

#[test]
fn the_rate_limited_primarys_second_delayed_sample_is_late() {
    let mut w = established(&[1], 1_000);
    let mut t = 1_000 + EVERY_MS;
    let mut verdicts = Vec::new();
    for delay_ms in [4, 12, 3, 7, 5, 23, 79, 148] {
        verdicts.push(w.sample(1, writer(1), delay_ms, t));
        t += EVERY_MS;
    }
    assert_eq!(
        verdicts,
        [
            None,
            None,
            None,
            None,
            None,
            None,
            Some(Arrival::Late),
            None
        ]
    );
    // On time again with the next sample at its usual delay.
    assert_eq!(w.sample(1, writer(1), 6, t), Some(Arrival::OnTime));
}

#[test]
fn while_one_controller_is_late_each_on_time_sample_of_another_is_reported() {
    let mut w = established(&[1, 3], 1_000);
    assert_eq!(w.sample(3, writer(3), 6, 1_010), None);
    assert_eq!(w.sample(1, writer(1), 90, 1_020), Some(Arrival::Late));
    assert_eq!(w.sample(3, writer(3), 5, 1_030), Some(Arrival::OnTime));
    assert_eq!(w.sample(3, writer(3), 5, 1_040), Some(Arrival::OnTime));
    // C1 on time again: C3's samples are news no more.
    assert_eq!(w.sample(1, writer(1), 5, 1_045), Some(Arrival::OnTime));
    assert_eq!(w.sample(3, writer(3), 5, 1_050), None);
}

#[test]
fn a_late_writer_keeps_its_controller_late_beside_a_new_one_on_time() {
    // C1 lowered to 15 (a new writer, on time from its first sample) while samples of its
    // writer at 30 still come out of the starved link's queue.
    let mut w = established(&[1], 1_000);
    assert_eq!(w.sample(1, writer(1), 300, 1_033), Some(Arrival::Late));
    assert_eq!(w.sample(1, writer(7), 250, 1_040), None);
    assert_eq!(w.sample(1, writer(7), 250, 1_073), None);
    // The old writer's queue is empty: a command deadline later the new one, once
    // established, says on time.
    assert_eq!(w.silence(1_133), vec![]);
    let mut t = 1_140;
    while t < 1_040 + ESTABLISHED_MS {
        assert_ne!(
            w.sample(1, writer(7), 250, t),
            Some(Arrival::Late),
            "at {t}"
        );
        t += EVERY_MS;
    }
    assert_eq!(w.sample(1, writer(7), 250, t), Some(Arrival::OnTime));
}

#[test]
fn a_clock_an_hour_off_is_on_time_and_so_is_one_running_a_percent_fast() {
    let mut w = watch();
    let mut t = 0;
    for n in 0..600 {
        // An hour behind: every delay an hour long, by the two clocks.
        assert_ne!(
            w.sample(3, writer(3), 3_600_000 + 5, t),
            Some(Arrival::Late)
        );
        // 1 % fast: its stamps run ahead by 0.33 ms a sample, and its delays shrink.
        let drift = i64::from(n) * i64::try_from(EVERY_MS).unwrap() / 100;
        assert_ne!(w.sample(2, writer(2), 5 - drift, t), Some(Arrival::Late));
        // 1 % slow: its delays grow by as much; the 2 s window keeps the growth at 20 ms.
        assert_ne!(
            w.sample(4, writer(4), 5 + drift, t),
            Some(Arrival::Late),
            "sample {n}"
        );
        t += EVERY_MS;
    }
}

#[test]
fn a_delay_is_judged_against_its_own_writers_baseline() {
    // C1's writer at 20 always takes 60 ms (a slow path); its new writer starts fresh.
    let mut w = watch();
    let mut t = 0;
    while t <= ESTABLISHED_MS + EVERY_MS {
        w.sample(1, writer(1), 60, t);
        t += EVERY_MS;
    }
    assert_eq!(w.reported.get(&1), Some(&Arrival::OnTime));
    let start = t;
    while t <= start + ESTABLISHED_MS + EVERY_MS {
        w.sample(1, writer(9), 5, t);
        t += EVERY_MS;
    }
    assert_eq!(w.sample(1, writer(9), 70, t), Some(Arrival::Late));
}

#[test]
fn commands_that_stop_for_a_deadline_are_unheard() {
    let mut w = established(&[2, 3], 1_000);
    w.sample(3, writer(3), 5, 1_050);
    assert_eq!(w.silence(1_100), vec![]);
    assert_eq!(w.silence(1_101), vec![(2, Arrival::Unheard)]);
    assert_eq!(w.silence(1_151), vec![(3, Arrival::Unheard)]);
    assert_eq!(w.silence(1_200), vec![]);
    // Heard again, within the baseline window: on time.
    assert_eq!(w.sample(2, writer(2), 5, 1_300), Some(Arrival::OnTime));
}

#[test]
fn a_writer_silent_for_the_window_is_forgotten() {
    let mut w = watch();
    w.sample(2, writer(2), 5, 0);
    w.silence(BASELINE_MS + 1);
    assert!(w.writers.is_empty());
}

#[test]
fn stopping_reports_every_controller_heard_as_unheard() {
    let mut w = established(&[1, 3], 1_000);
    w.sample(1, writer(1), 90, 1_010);
    w.sample(3, writer(3), 5, 1_020);
    let mut silent = established(&[1], 1_000);
    silent.silence(1_000 + 2 * BASELINE_MS);
    assert_eq!(w.stop(), vec![(1, Arrival::Unheard), (3, Arrival::Unheard)]);
    assert_eq!(silent.stop(), vec![]);
}
