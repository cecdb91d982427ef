//! The heartbeat's takeover field (F17): a takeover round-trips, and every combination of
//! strength and `took_over_from` the rules forbid is named.

use super::*;

#[test]
fn a_takeover_round_trips_and_its_rules_are_named() {
    // C2, Secondary, took over from C1's life 77 at 35; its writer at 20 is still the
    // established one in the round of the takeover.
    let taker = Heartbeat {
        role: Some(Role::Secondary),
        strength: Some(Strength(35)),
        established_strength: Some(Strength(20)),
        took_over_from: Some(holder(1, 77)),
        ..heartbeat()
    };
    let sample = HeartbeatSample::encode(&taker);
    assert_eq!(
        sample.took_over_from,
        HolderSlot {
            id: 1,
            incarnation: 77
        }
    );
    assert_eq!(sample.decode(), Ok(taker));
    // Released: Primary at 30 while the takeover writer still retires at 35.
    let released = Heartbeat {
        strength: Some(Strength(30)),
        established_strength: Some(Strength(35)),
        took_over_from: None,
        ..heartbeat()
    };
    assert_eq!(HeartbeatSample::encode(&released).decode(), Ok(released));
    let with = |strength, established_strength, took_over_from| HeartbeatSample {
        strength,
        established_strength,
        took_over_from,
        ..HeartbeatSample::encode(&taker)
    };
    let c1 = HolderSlot {
        id: 1,
        incarnation: 77,
    };
    for (sample, field, why) in [
        (
            with(35, 20, HolderSlot::default()),
            "heartbeat.strength",
            "35 without a takeover",
        ),
        (
            with(20, 20, c1),
            "heartbeat.took_over_from",
            "a takeover commanding at 20",
        ),
        (
            with(0, 0, c1),
            "heartbeat.took_over_from",
            "a takeover commanding nothing",
        ),
        (
            with(
                35,
                20,
                HolderSlot {
                    id: 2,
                    incarnation: 1,
                },
            ),
            "heartbeat.took_over_from",
            "a takeover from itself",
        ),
        (
            with(
                35,
                20,
                HolderSlot {
                    id: 0,
                    incarnation: 5,
                },
            ),
            "heartbeat.took_over_from",
            "an empty slot with an incarnation",
        ),
    ] {
        assert_eq!(rejected_field(sample), field, "{why}: {sample:?}");
    }
}
