//! The wire types' unit tests: CDR layouts, round trips, and every malformed field named.

use super::*;
use crate::core::types::{AlarmReason, Assignment, Holder, Phase, Role, Strength, VoteRecord};
use crate::core::Heartbeat;
use rustdds::Keyed;
use rustdds::{
    no_key::{DeserializerAdapter, SerializerAdapter},
    CDRDeserializerAdapter, CDRSerializerAdapter, RepresentationIdentifier,
};
use serde::de::DeserializeOwned;

fn to_cdr<T: Serialize>(value: &T) -> Vec<u8> {
    <CDRSerializerAdapter<T> as SerializerAdapter<T>>::to_bytes(value)
        .unwrap()
        .to_vec()
}

/// What RustDDS's CDR decoder reports for bytes it cannot read.
type CdrError<T> = <CDRDeserializerAdapter<T> as DeserializerAdapter<T>>::Error;

fn from_cdr<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, CdrError<T>> {
    <CDRDeserializerAdapter<T> as DeserializerAdapter<T>>::from_bytes(
        bytes,
        RepresentationIdentifier::CDR_LE,
    )
}

/// Encode, go through CDR bytes, decode.
fn round_trip<S>(value: &S::Value) -> Result<S::Value, WireError>
where
    S: WireSample + Serialize + DeserializeOwned,
{
    let bytes = to_cdr(&S::encode(value));
    from_cdr::<S>(&bytes).unwrap().decode()
}

fn holder(id: u8, incarnation: u64) -> Holder {
    Holder { id, incarnation }
}

fn full_assignment() -> Assignment {
    Assignment::from_ranked([holder(2, 77), holder(1, 5), holder(3, u64::MAX)])
}

fn heartbeat() -> Heartbeat {
    Heartbeat {
        id: 2,
        incarnation: 1_723_000_000_123,
        phase: Phase::Steady,
        role: Some(Role::Primary),
        strength: Some(Strength(30)),
        agreed: Some(full_assignment()),
        vote: Some(Assignment::from_ranked([holder(2, 77), holder(1, 5)])),
        epoch: 4_000_000_007,
        provisional: false,
        established_strength: Some(Strength(20)),
        took_over_from: None,
    }
}

/// A valid heartbeat sample to break one field at a time.
fn heartbeat_sample() -> HeartbeatSample {
    HeartbeatSample::encode(&heartbeat())
}

fn rejected_field<S: WireSample>(sample: S) -> &'static str
where
    S::Value: std::fmt::Debug,
{
    sample.decode().unwrap_err().field
}

#[test]
fn shape_matches_the_idl_layout() {
    let shape = ShapeTypeExtended {
        color: "YELLOW".into(),
        x: 1,
        y: -2,
        shapesize: 30,
        fill_kind: ShapeFillKind::HorizontalHatchFill,
        angle: 1.5,
    };
    let bytes = to_cdr(&shape);
    // string: length 7 incl. NUL, "YELLOW\0", 1 byte padding to 4, then 5 x 4-byte fields.
    let mut expected = vec![7, 0, 0, 0];
    expected.extend_from_slice(b"YELLOW\0\0");
    for field in [1i32, -2, 30, 2] {
        expected.extend_from_slice(&field.to_le_bytes());
    }
    expected.extend_from_slice(&1.5f32.to_le_bytes());
    assert_eq!(bytes, expected);
    assert_eq!(from_cdr::<ShapeTypeExtended>(&bytes).unwrap(), shape);
    assert_eq!(shape.key(), "YELLOW");
}

#[test]
fn unknown_fill_kind_is_a_decode_error_not_a_panic() {
    let mut bytes = to_cdr(&ShapeTypeExtended {
        color: "RED".into(),
        x: 0,
        y: 0,
        shapesize: 0,
        fill_kind: ShapeFillKind::SolidFill,
        angle: 0.0,
    });
    // fill_kind sits after the 8-byte string and three i32.
    bytes[20..24].copy_from_slice(&9u32.to_le_bytes());
    assert!(from_cdr::<ShapeTypeExtended>(&bytes).is_err());
}

#[test]
fn servo_control_is_three_u16() {
    let command = ServoControl {
        pan: 500,
        tilt: 1000,
        frequency: 60,
    };
    let bytes = to_cdr(&command);
    assert_eq!(bytes, [244, 1, 232, 3, 60, 0]);
    assert_eq!(round_trip::<ServoControl>(&command).unwrap(), command);
}

#[test]
fn heartbeat_round_trips_through_cdr() {
    assert_eq!(
        round_trip::<HeartbeatSample>(&heartbeat()).unwrap(),
        heartbeat()
    );
    let quiet = Heartbeat::initial(1, 0);
    assert_eq!(round_trip::<HeartbeatSample>(&quiet).unwrap(), quiet);
    let handover = Heartbeat {
        phase: Phase::Voting,
        strength: Some(Strength(20)),
        agreed: Some(Assignment::default()),
        ..heartbeat()
    };
    assert_eq!(round_trip::<HeartbeatSample>(&handover).unwrap(), handover);
    for phase in Phase::ALL {
        let h = Heartbeat {
            phase,
            strength: None,
            established_strength: None,
            ..heartbeat()
        };
        assert_eq!(round_trip::<HeartbeatSample>(&h).unwrap(), h);
    }
}

#[test]
fn heartbeat_key_is_the_sender() {
    assert_eq!(heartbeat_sample().key(), 2);
}

#[test]
fn malformed_heartbeat_codes_are_named() {
    let cases = [
        (
            HeartbeatSample {
                from_id: 0,
                ..heartbeat_sample()
            },
            "heartbeat.from_id",
        ),
        (
            HeartbeatSample {
                phase: 0,
                ..heartbeat_sample()
            },
            "heartbeat.phase",
        ),
        (
            HeartbeatSample {
                phase: 5,
                ..heartbeat_sample()
            },
            "heartbeat.phase",
        ),
        (
            HeartbeatSample {
                role: 4,
                ..heartbeat_sample()
            },
            "heartbeat.role",
        ),
    ];
    for (sample, field) in cases {
        assert_eq!(rejected_field(sample), field, "{sample:?}");
    }
}

#[test]
fn a_strength_the_role_or_phase_does_not_allow_is_named() {
    let with = |role, strength, phase| HeartbeatSample {
        role,
        strength,
        phase,
        established_strength: strength,
        ..heartbeat_sample()
    };
    for (sample, why) in [
        (with(ROLE_PRIMARY, 25, PHASE_STEADY), "no role's strength"),
        (
            with(ROLE_NONE, 30, PHASE_STEADY),
            "commanding without a role",
        ),
        (
            with(ROLE_TERTIARY, 30, PHASE_STEADY),
            "a Tertiary at the Primary's strength",
        ),
        // A role may command below its own strength (a hand-over), never above.
        (
            with(ROLE_TERTIARY, 20, PHASE_STEADY),
            "a Tertiary one step above its own",
        ),
        (
            with(ROLE_PRIMARY, 30, PHASE_FAILED),
            "a failed controller commanding",
        ),
        (
            with(ROLE_PRIMARY, 30, PHASE_INITIALIZING),
            "commanding while initializing",
        ),
    ] {
        assert_eq!(
            rejected_field(sample),
            "heartbeat.strength",
            "{why}: {sample:?}"
        );
    }
    // The same fields within the rules decode.
    for sample in [
        with(ROLE_PRIMARY, 15, PHASE_STEADY), // PROVISIONAL_PRIMARY_STRENGTH
        with(ROLE_PRIMARY, 20, PHASE_VOTING),
        with(ROLE_SECONDARY, 20, PHASE_STEADY),
        with(ROLE_TERTIARY, 10, PHASE_STEADY),
    ] {
        assert!(sample.decode().is_ok(), "{sample:?}");
    }
}

#[test]
fn malformed_assignments_are_named() {
    let slot = |id, incarnation| HolderSlot { id, incarnation };
    let broken = [
        // Hole before a filled slot.
        WireAssignment {
            slots: [slot(1, 1), slot(0, 0), slot(3, 3)],
        },
        WireAssignment {
            slots: [slot(0, 0), slot(2, 2), slot(0, 0)],
        },
        // Empty slot with an incarnation.
        WireAssignment {
            slots: [slot(1, 1), slot(0, 9), slot(0, 0)],
        },
        // One controller in two roles.
        WireAssignment {
            slots: [slot(1, 1), slot(1, 2), slot(0, 0)],
        },
    ];
    for assignment in broken {
        let agreed = HeartbeatSample {
            agreed: assignment,
            ..heartbeat_sample()
        };
        assert_eq!(rejected_field(agreed), "heartbeat.agreed", "{assignment:?}");
        let vote = HeartbeatSample {
            vote: assignment,
            ..heartbeat_sample()
        };
        assert_eq!(rejected_field(vote), "heartbeat.vote", "{assignment:?}");
        let record = VoteSample {
            from_id: 1,
            incarnation: 1,
            vote_valid: true,
            vote: assignment,
        };
        assert_eq!(rejected_field(record), "vote.vote", "{assignment:?}");
    }
    // Slots filled but marked not valid.
    let stale = HeartbeatSample {
        agreed_valid: false,
        ..heartbeat_sample()
    };
    assert_eq!(rejected_field(stale), "heartbeat.agreed");
}

#[test]
fn vote_round_trips_and_rejects_id_zero() {
    let record = VoteRecord {
        from: 3,
        incarnation: 42,
        vote: Some(full_assignment()),
    };
    assert_eq!(round_trip::<VoteSample>(&record).unwrap(), record);
    let withdrawn = VoteRecord {
        vote: None,
        ..record
    };
    assert_eq!(round_trip::<VoteSample>(&withdrawn).unwrap(), withdrawn);
    assert_eq!(VoteSample::encode(&record).key(), 3);
    let anonymous = VoteSample {
        from_id: 0,
        ..VoteSample::encode(&record)
    };
    assert_eq!(rejected_field(anonymous), "vote.from_id");
}

#[test]
fn alarm_round_trips_and_rejects_bad_fields() {
    let alarm = ControllerAlarm {
        reporter: 1,
        reporter_incarnation: 10,
        about: 3,
        about_incarnation: Some(30),
        reason: AlarmReason::Lost,
        raised: true,
    };
    assert_eq!(round_trip::<AlarmSample>(&alarm).unwrap(), alarm);
    let cleared = ControllerAlarm {
        about_incarnation: None,
        reason: AlarmReason::Failed,
        raised: false,
        ..alarm
    };
    assert_eq!(round_trip::<AlarmSample>(&cleared).unwrap(), cleared);
    let impostor = ControllerAlarm {
        reason: AlarmReason::Impostor,
        ..alarm
    };
    assert_eq!(round_trip::<AlarmSample>(&impostor).unwrap(), impostor);
    let input = ControllerAlarm {
        reason: AlarmReason::InputDisagrees,
        about: 1,
        ..alarm
    };
    assert_eq!(AlarmSample::encode(&input).reason, 4);
    let stalled = ControllerAlarm {
        reason: AlarmReason::Stalled,
        ..input
    };
    assert_eq!(AlarmSample::encode(&stalled).reason, 5);
    assert_eq!(AlarmSample::encode(&stalled).decode(), Ok(stalled));
    let law = ControllerAlarm {
        reason: AlarmReason::LawDisagrees,
        ..input
    };
    assert_eq!(AlarmSample::encode(&law).reason, 6);
    assert_eq!(AlarmSample::encode(&law).decode(), Ok(law));
    assert_eq!(round_trip::<AlarmSample>(&input).unwrap(), input);

    let good = AlarmSample::encode(&alarm);
    let cases = [
        (
            AlarmSample {
                reporter_id: 0,
                ..good
            },
            "alarm.reporter_id",
        ),
        (
            AlarmSample {
                about_id: 0,
                ..good
            },
            "alarm.about_id",
        ),
        (AlarmSample { reason: 0, ..good }, "alarm.reason"),
        (AlarmSample { reason: 7, ..good }, "alarm.reason"),
        (
            AlarmSample {
                about_incarnation_valid: false,
                ..good
            },
            "alarm.about_incarnation",
        ),
    ];
    for (sample, field) in cases {
        assert_eq!(rejected_field(sample), field, "{sample:?}");
    }
}

#[test]
fn network_alarm_round_trips_and_rejects_bad_fields() {
    use crate::core::network::{AlarmSubject, Network};
    let alarm = NetworkAlarm {
        reporter: 2,
        reporter_incarnation: 77,
        subject: AlarmSubject::Transceiver {
            controller: 3,
            network: Network::B,
        },
        raised: Some(Certainty::Concluded),
        cause: "controller 3's transmitter on B failed".into(),
    };
    assert_eq!(round_trip::<NetworkAlarmSample>(&alarm).unwrap(), alarm);
    let cleared = NetworkAlarm {
        subject: AlarmSubject::Network(Network::A),
        raised: None,
        cause: String::new(),
        ..alarm.clone()
    };
    assert_eq!(round_trip::<NetworkAlarmSample>(&cleared).unwrap(), cleared);
    let good = NetworkAlarmSample::encode(&alarm);
    let cases = [
        (
            NetworkAlarmSample {
                reporter_id: 0,
                ..good.clone()
            },
            "network_alarm.reporter_id",
        ),
        (
            NetworkAlarmSample {
                network: 2,
                ..good.clone()
            },
            "network_alarm.network",
        ),
        (
            NetworkAlarmSample {
                certainty: 9,
                ..good.clone()
            },
            "network_alarm.certainty",
        ),
        (
            NetworkAlarmSample {
                cause: "x".repeat(CAUSE_MAX_BYTES + 1),
                ..good.clone()
            },
            "network_alarm.cause",
        ),
    ];
    for (sample, field) in cases {
        assert_eq!(rejected_field(sample.clone()), field, "{sample:?}");
    }
}

#[test]
fn network_heartbeat_round_trips_and_rejects_bad_fields() {
    use crate::core::network::{Hearing, LinkState, Network, NetworkHeartbeat};
    let mut hearing = Hearing::default();
    hearing.set(2, Network::A, LinkState::Good);
    hearing.set(2, Network::B, LinkState::Fail);
    hearing.set(3, Network::B, LinkState::Good);
    let heartbeat = NetworkHeartbeat { from: 1, hearing };
    assert_eq!(
        round_trip::<NetworkHeartbeatSample>(&heartbeat).unwrap(),
        heartbeat
    );
    let good = NetworkHeartbeatSample::encode(&heartbeat);
    assert_eq!(good.heard_on_a, [LINK_UNKNOWN, LINK_GOOD, LINK_UNKNOWN]);
    assert_eq!(good.heard_on_b, [LINK_UNKNOWN, LINK_FAIL, LINK_GOOD]);
    let cases = [
        (
            NetworkHeartbeatSample { from_id: 0, ..good },
            "network_heartbeat.from_id",
        ),
        (
            NetworkHeartbeatSample {
                heard_on_a: [0, 3, 0],
                ..good
            },
            "network_heartbeat.heard_on_a",
        ),
        (
            NetworkHeartbeatSample {
                heard_on_b: [7, 0, 0],
                ..good
            },
            "network_heartbeat.heard_on_b",
        ),
    ];
    for (sample, field) in cases {
        assert_eq!(rejected_field(sample), field, "{sample:?}");
    }
}

#[test]
fn truncated_or_garbage_bytes_are_errors_not_panics() {
    let bytes = to_cdr(&heartbeat_sample());
    for len in 0..bytes.len() {
        assert!(from_cdr::<HeartbeatSample>(&bytes[..len]).is_err(), "{len}");
    }
    // A boolean flag that is neither 0 nor 1.
    let mut flipped = bytes.clone();
    let agreed_valid_offset = 1 + 7 + 8 + 3; // from_id, pad, incarnation, phase/role/strength
    assert_eq!(flipped[agreed_valid_offset], 1);
    flipped[agreed_valid_offset] = 7;
    assert!(from_cdr::<HeartbeatSample>(&flipped).is_err());
    // Random bytes never panic (they may decode; then validation judges them).
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    for _ in 0..2000 {
        let noise: Vec<u8> = (0..bytes.len())
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state & 0xff) as u8
            })
            .collect();
        if let Ok(sample) = from_cdr::<HeartbeatSample>(&noise) {
            let _ = sample.decode();
        }
    }
}

#[test]
fn an_established_strength_above_the_commanded_one_or_outside_the_rules_is_named() {
    let with = |strength, established_strength| HeartbeatSample {
        strength,
        established_strength,
        ..heartbeat_sample()
    };
    for (sample, why) in [
        (
            with(20, 30),
            "established above the strength it commands with",
        ),
        (with(STRENGTH_NONE, 10), "established while silent"),
        (with(30, 25), "no role's strength"),
    ] {
        assert_eq!(
            rejected_field(sample),
            "heartbeat.established_strength",
            "{why}: {sample:?}"
        );
    }
    // A raise reports the old writer's strength until the new one is established; a
    // lowering reports none for that round.
    for sample in [with(30, 20), with(30, STRENGTH_NONE), with(20, 20)] {
        assert!(sample.decode().is_ok(), "{sample:?}");
    }
}

#[test]
fn a_long_cause_is_cut_to_fit_the_wire_at_a_character_boundary() {
    for short in ["", "network A failed", &"x".repeat(CAUSE_MAX_BYTES)] {
        assert_eq!(fit_cause(short), short);
    }
    for long in [
        "x".repeat(CAUSE_MAX_BYTES + 1),
        "é".repeat(CAUSE_MAX_BYTES),
        format!("x{}", "€".repeat(CAUSE_MAX_BYTES)),
    ] {
        let cut = fit_cause(&long);
        assert!(cut.len() <= CAUSE_MAX_BYTES, "{} bytes", cut.len());
        // Within a character of the limit: nothing more is dropped than needs to be.
        assert!(cut.len() > CAUSE_MAX_BYTES - 4, "{} bytes", cut.len());
        let kept = cut.strip_suffix('…').unwrap();
        assert!(long.starts_with(kept));
        let alarm = NetworkAlarm {
            reporter: 1,
            reporter_incarnation: 1,
            subject: crate::core::network::AlarmSubject::Network(crate::core::network::Network::A),
            raised: Some(Certainty::Suspected),
            cause: cut,
        };
        assert_eq!(round_trip::<NetworkAlarmSample>(&alarm).unwrap(), alarm);
    }
}

mod takeover;
mod voted;
