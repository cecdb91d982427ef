//! Property tests of every wire type, through real CDR (RustDDS's adapters, both byte
//! orders):
//! - every valid value survives encode, CDR, decode unchanged;
//! - no sample, whatever its field values, and no byte string makes a decoder panic; a
//!   rejection names a field of that type; a sample that is accepted is exactly the encoding
//!   of what it decodes to, so it re-encodes to itself and decodes again to the same value.
//!
//! Case counts are proptest's default (256 per property, a few seconds in all);
//! `PROPTEST_CASES=100000 cargo test --release -p rl-layer --lib wire::proptests` runs longer.
//! The cargo-fuzz target `impl/fuzz` (`wire_decoders`) checks the same byte-level property
//! with coverage guidance.

mod strategies;

use self::strategies::*;
use super::*;
use crate::core::types::{Phase, Role, Strength, TAKEOVER_STRENGTH};
use proptest::collection::vec;
use proptest::prelude::*;
use proptest::sample::{select, Index};
use proptest::test_runner::TestCaseError;
use rustdds::serialization::{deserialize_from_cdr_with_rep_id, to_writer_with_rep_id};
use rustdds::RepresentationIdentifier;
use serde::de::DeserializeOwned;
use std::fmt::Debug;

/// The encodings a reader accepts for these types.
fn representation() -> impl Strategy<Value = RepresentationIdentifier> {
    select(vec![
        RepresentationIdentifier::CDR_LE,
        RepresentationIdentifier::CDR_BE,
    ])
}

fn to_cdr_as<T: Serialize>(value: &T, representation: RepresentationIdentifier) -> Vec<u8> {
    let mut bytes = Vec::new();
    if let Err(error) = to_writer_with_rep_id(&mut bytes, value, representation) {
        panic!("CDR serialization failed: {error}");
    }
    bytes
}

/// What a reader makes of these bytes (`None`: not CDR of an `S`).
fn from_cdr_as<S: DeserializeOwned>(
    bytes: &[u8],
    representation: RepresentationIdentifier,
) -> Option<S> {
    deserialize_from_cdr_with_rep_id::<S>(bytes, representation)
        .ok()
        .map(|(sample, _consumed)| sample)
}

/// The little-endian CDR of a sample: equal bytes are equal samples, NaN angles included.
fn cdr<S: Serialize>(sample: &S) -> Vec<u8> {
    to_cdr_as(sample, RepresentationIdentifier::CDR_LE)
}

/// A wire type under test: its sample, and the fields its decoder may name.
trait Checked: WireSample + Serialize + DeserializeOwned + Clone + Debug {
    const FIELDS: &'static [&'static str];
}

impl Checked for HeartbeatSample {
    const FIELDS: &'static [&'static str] = &[
        "heartbeat.from_id",
        "heartbeat.phase",
        "heartbeat.role",
        "heartbeat.strength",
        "heartbeat.established_strength",
        "heartbeat.agreed",
        "heartbeat.vote",
        "heartbeat.took_over_from",
    ];
}

impl Checked for VoteSample {
    const FIELDS: &'static [&'static str] = &["vote.from_id", "vote.vote"];
}

impl Checked for AlarmSample {
    const FIELDS: &'static [&'static str] = &[
        "alarm.reporter_id",
        "alarm.about_id",
        "alarm.about_incarnation",
        "alarm.reason",
    ];
}

impl Checked for NetworkHeartbeatSample {
    const FIELDS: &'static [&'static str] = &[
        "network_heartbeat.from_id",
        "network_heartbeat.heard_on_a",
        "network_heartbeat.heard_on_b",
    ];
}

impl Checked for NetworkAlarmSample {
    const FIELDS: &'static [&'static str] = &[
        "network_alarm.reporter_id",
        "network_alarm.network",
        "network_alarm.controller_id",
        "network_alarm.certainty",
        "network_alarm.cause",
    ];
}

/// Decoded without a check: any value is acceptable.
impl Checked for ServoControl {
    const FIELDS: &'static [&'static str] = &[];
}

impl Checked for VotedServoControl {
    const FIELDS: &'static [&'static str] = &["voted.from_id"];
}

/// Decoded without a check: any value is acceptable.
impl Checked for ShapeTypeExtended {
    const FIELDS: &'static [&'static str] = &[];
}

/// Encode, CDR in `representation`, decode: the value must come back.
fn round_trip<S: Checked>(
    value: &S::Value,
    representation: RepresentationIdentifier,
) -> Result<(), TestCaseError>
where
    S::Value: Debug,
{
    let sample = S::encode(value);
    let bytes = to_cdr_as(&sample, representation);
    let Some(read) = from_cdr_as::<S>(&bytes, representation) else {
        return Err(TestCaseError::fail(format!(
            "{sample:?} does not read back from its own CDR {bytes:?}"
        )));
    };
    match read.decode() {
        // Compared by encoding, so a NaN angle equals itself.
        Ok(decoded) => prop_assert_eq!(
            cdr(&S::encode(&decoded).unstamped()),
            cdr(&sample.unstamped())
        ),
        Err(error) => {
            return Err(TestCaseError::fail(format!(
                "{value:?} encodes to {sample:?}, which is rejected: {error}"
            )))
        }
    }
    Ok(())
}

/// Whatever its fields: decoding does not panic, a rejection names a field of the type, and
/// an accepted sample is the encoding of its value, which decodes again to the same value.
fn check_sample<S: Checked>(sample: S) -> Result<(), TestCaseError> {
    match sample.clone().decode() {
        Ok(value) => {
            let reencoded = S::encode(&value);
            let unstamped = sample.clone().unstamped();
            prop_assert_eq!(
                cdr(&reencoded.clone().unstamped()),
                cdr(&unstamped),
                "accepted {:?}",
                sample
            );
            match reencoded.decode() {
                Ok(again) => prop_assert_eq!(cdr(&S::encode(&again).unstamped()), cdr(&unstamped)),
                Err(error) => {
                    return Err(TestCaseError::fail(format!(
                        "{sample:?} is accepted but its re-encoding is not: {error}"
                    )))
                }
            }
        }
        Err(error) => {
            prop_assert!(
                S::FIELDS.contains(&error.field),
                "{:?} rejected naming {:?}, not one of {:?}",
                sample,
                error.field,
                S::FIELDS
            );
            prop_assert!(!error.reason.is_empty());
        }
    }
    Ok(())
}

/// Bytes from the network: the CDR reader errs or yields a sample, which `check_sample`
/// judges.
fn check_bytes<S: Checked>(
    bytes: &[u8],
    representation: RepresentationIdentifier,
) -> Result<(), TestCaseError> {
    match from_cdr_as::<S>(bytes, representation) {
        Some(sample) => check_sample(sample),
        None => Ok(()),
    }
}

/// A valid sample's bytes with a few bytes overwritten and perhaps cut short: mostly the
/// same layout, so the decoder, not only the CDR reader, sees the damage.
fn damaged(mut bytes: Vec<u8>, edits: &[(Index, u8)], cut: Option<Index>) -> Vec<u8> {
    if !bytes.is_empty() {
        for (at, byte) in edits {
            let at = at.index(bytes.len());
            bytes[at] = *byte;
        }
    }
    if let Some(cut) = cut {
        bytes.truncate(cut.index(bytes.len() + 1));
    }
    bytes
}

fn edits() -> impl Strategy<Value = Vec<(Index, u8)>> {
    vec((any::<Index>(), any::<u8>()), 0..4)
}

/// Round trips of valid values, checks of any field values, of any bytes and of damaged
/// valid bytes, for one wire type.
macro_rules! wire_properties {
    ($module:ident, $sample:ty, values: $values:expr, samples: $samples:expr) => {
        mod $module {
            use super::*;

            proptest! {
                #[test]
                fn every_valid_value_round_trips(value in $values, rep in representation()) {
                    round_trip::<$sample>(&value, rep)?;
                }

                #[test]
                fn any_fields_decode_without_panic_and_re_encode(sample in $samples) {
                    check_sample::<$sample>(sample)?;
                }

                #[test]
                fn any_bytes_decode_without_panic_and_re_encode(
                    bytes in vec(any::<u8>(), 0..96),
                    rep in representation(),
                ) {
                    check_bytes::<$sample>(&bytes, rep)?;
                }

                #[test]
                fn damaged_bytes_decode_without_panic_and_re_encode(
                    value in $values,
                    rep in representation(),
                    edits in edits(),
                    cut in proptest::option::of(any::<Index>()),
                ) {
                    let bytes = damaged(to_cdr_as(&<$sample>::encode(&value), rep), &edits, cut);
                    check_bytes::<$sample>(&bytes, rep)?;
                }
            }
        }
    };
}

wire_properties!(heartbeat, HeartbeatSample, values: heartbeat(), samples: heartbeat_sample());
wire_properties!(vote, VoteSample, values: vote_record(), samples: vote_sample());
wire_properties!(alarm, AlarmSample, values: controller_alarm(), samples: alarm_sample());
wire_properties!(
    network_heartbeat,
    NetworkHeartbeatSample,
    values: network_heartbeat(),
    samples: network_heartbeat_sample()
);
wire_properties!(
    network_alarm,
    NetworkAlarmSample,
    values: network_alarm(),
    samples: network_alarm_sample()
);
wire_properties!(
    servo_control,
    ServoControl,
    values: servo_control(),
    samples: servo_control()
);
wire_properties!(shape, ShapeTypeExtended, values: shape(), samples: shape());
wire_properties!(
    voted_servo_control,
    VotedServoControl,
    values: voted_servo_control(),
    samples: voted_servo_control_sample()
);

proptest! {
    /// The keys of keyed topics arrive on their own (dispose, unregister): reading them never
    /// panics either.
    #[test]
    fn any_key_bytes_read_without_panic(bytes in vec(any::<u8>(), 0..8), rep in representation()) {
        let _ = from_cdr_as::<u8>(&bytes, rep);
        let _ = from_cdr_as::<NetworkAlarmKey>(&bytes, rep);
        let _ = from_cdr_as::<String>(&bytes, rep);
    }
}

/// The heartbeat generator covers exactly what the decoder accepts: every phase, role,
/// strength and established-strength code, all 4 x 4 x 256 x 256 of them, without a takeover
/// and with one, decode iff the generator's rule allows them.
#[test]
fn the_strength_rule_of_the_generator_is_the_decoders() {
    let base = HeartbeatSample::encode(&crate::core::Heartbeat::initial(1, 1));
    let mut accepted = 0usize;
    let took_over = HolderSlot {
        id: 2,
        incarnation: 7,
    };
    for (took_over_from, phase) in [HolderSlot::default(), took_over]
        .into_iter()
        .flat_map(|slot| Phase::ALL.map(|phase| (slot, phase)))
    {
        for role in [
            None,
            Some(Role::Primary),
            Some(Role::Secondary),
            Some(Role::Tertiary),
        ] {
            let (strengths_ok, established_ok) = if took_over_from.id == 0 {
                let allowed = strengths_allowed(role, phase);
                (allowed.clone(), allowed)
            } else {
                strengths_allowed_taking_over(role, phase)
            };
            for strength in 0..=u8::MAX {
                for established_strength in 0..=u8::MAX {
                    let sample = HeartbeatSample {
                        phase: phase_code(phase),
                        role: role_code(role),
                        strength,
                        established_strength,
                        took_over_from,
                        ..base
                    };
                    let as_option =
                        |code| (code != STRENGTH_NONE).then_some(Strength(i32::from(code)));
                    let (strength, established) =
                        (as_option(strength), as_option(established_strength));
                    // The takeover writer retires above the strength it hands over to.
                    let handing_over = took_over_from.id == 0
                        && strength.is_some()
                        && established == Some(TAKEOVER_STRENGTH);
                    let expected = strengths_ok.contains(&strength)
                        && (handing_over
                            || established_ok.contains(&established) && established <= strength);
                    assert_eq!(sample.decode().is_ok(), expected, "{sample:?}");
                    accepted += usize::from(expected);
                }
            }
        }
    }
    // Initializing and failed: (none, none) for each of the 4 roles. Voting and steady: the
    // ordered pairs e <= s of none and the role's strengths: 1 without a role, 15 for the
    // Primary (none, 10, 15, 20, 30), 10 for the Secondary (none, 10, 15, 20), 3 for the
    // Tertiary (none, 10); and each strength a role commands with beside an established 35
    // (a released takeover's writer retiring): 4 for the Primary, 3 for the Secondary, 1 for
    // the Tertiary. With a takeover, voting and steady only: commanding at 35, the
    // established writer none, 35, or a strength the role allows: 2 without a role, 6 for
    // the Primary, 5 for the Secondary, 3 for the Tertiary.
    assert_eq!(
        accepted,
        2 * 4 + 2 * (1 + 15 + 10 + 3) + 2 * (4 + 3 + 1) + 2 * (2 + 6 + 5 + 3)
    );
}
