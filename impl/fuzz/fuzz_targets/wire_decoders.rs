//! Fuzzes the decoders of every DDS sample type RL reads, the way a reader meets them: the
//! first byte picks the type (low four bits) and the byte order (top bit), the rest is the
//! serialized payload. The CDR reader may reject it; a sample it yields must decode without
//! panicking, a rejection must name a field, and an accepted sample must be exactly the
//! encoding of its value, which decodes again to the same value.
//!
//! `cargo +nightly fuzz run wire_decoders` (from `impl/`); see docs/conformance.md.

#![no_main]

use libfuzzer_sys::fuzz_target;
use rl_layer::wire::{
    AlarmSample, HeartbeatSample, NetworkAlarmKey, NetworkAlarmSample, NetworkHeartbeatSample,
    ServoControl, ShapeTypeExtended, VoteSample, VotedServoControl, WireSample,
};
use rustdds::serialization::{deserialize_from_cdr_with_rep_id, to_writer_with_rep_id};
use rustdds::RepresentationIdentifier;
use serde::de::DeserializeOwned;
use serde::Serialize;
use std::fmt::Debug;

fuzz_target!(|data: &[u8]| {
    let Some((&tag, payload)) = data.split_first() else {
        return;
    };
    let representation = if tag & 0x80 == 0 {
        RepresentationIdentifier::CDR_LE
    } else {
        RepresentationIdentifier::CDR_BE
    };
    match tag & 0x0f {
        0 => check::<HeartbeatSample>(payload, representation),
        1 => check::<VoteSample>(payload, representation),
        2 => check::<AlarmSample>(payload, representation),
        3 => check::<NetworkHeartbeatSample>(payload, representation),
        4 => check::<NetworkAlarmSample>(payload, representation),
        5 => check::<ServoControl>(payload, representation),
        6 => check::<ShapeTypeExtended>(payload, representation),
        7 => check::<VotedServoControl>(payload, representation),
        // A keyed topic's key arrives alone with a dispose: reading it must not panic.
        _ => {
            let _ = deserialize_from_cdr_with_rep_id::<u8>(payload, representation);
            let _ = deserialize_from_cdr_with_rep_id::<NetworkAlarmKey>(payload, representation);
        }
    }
});

/// The little-endian CDR of a sample: equal bytes are equal samples (NaN angles included).
fn cdr<S: Serialize>(sample: &S) -> Vec<u8> {
    let mut bytes = Vec::new();
    if let Err(error) = to_writer_with_rep_id(&mut bytes, sample, RepresentationIdentifier::CDR_LE)
    {
        panic!("a decoded sample does not serialize: {error}");
    }
    bytes
}

fn check<S>(payload: &[u8], representation: RepresentationIdentifier)
where
    S: WireSample + Serialize + DeserializeOwned + Clone + Debug,
{
    let Ok((sample, _consumed)) = deserialize_from_cdr_with_rep_id::<S>(payload, representation)
    else {
        return;
    };
    match sample.clone().decode() {
        Ok(value) => {
            // The heartbeat's send time is stamped anew by each encoding.
            let reencoded = S::encode(&value);
            let unstamped = cdr(&sample.clone().unstamped());
            assert_eq!(
                cdr(&reencoded.clone().unstamped()),
                unstamped,
                "accepted {sample:?} is not the encoding of its value"
            );
            match reencoded.decode() {
                Ok(again) => assert_eq!(
                    cdr(&S::encode(&again).unstamped()),
                    unstamped,
                    "{sample:?} decodes to another value the second time"
                ),
                Err(error) => panic!("{sample:?} is accepted, its re-encoding is not: {error}"),
            }
        }
        Err(error) => assert!(
            !error.field.is_empty() && !error.reason.is_empty(),
            "{sample:?} rejected without naming a field: {error:?}"
        ),
    }
}
