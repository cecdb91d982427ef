//! The voted sample: its CDR layout as docs/rl.idl declares `rl::VotedServoControl`, its key,
//! a round trip, and the refused id 0.

use super::*;

#[test]
fn a_voted_servo_command_matches_the_idl_layout_and_is_keyed_by_its_controller() {
    let voted = Voted {
        from: 3,
        input: 0x0102_0304_0506_0708,
        input_digest: 0x1112_1314_1516_1718,
        raw: RawAnswer {
            after: 0x2122_2324_2526_2728,
            digest: 0x3132_3334_3536_3738,
        },
        value: ServoControl {
            pan: 500,
            tilt: 1000,
            frequency: 60,
        },
    };
    let sample = VotedServoControl::encode(&voted);
    assert_eq!(sample.key(), 3);
    let bytes = to_cdr(&sample);
    // octet from_id, 7 bytes of padding to the 8-aligned input, the input, its digest, the
    // raw answer's input before and digest, three u16.
    let mut expected = vec![3, 0, 0, 0, 0, 0, 0, 0];
    expected.extend_from_slice(&0x0102_0304_0506_0708u64.to_le_bytes());
    expected.extend_from_slice(&0x1112_1314_1516_1718u64.to_le_bytes());
    expected.extend_from_slice(&0x2122_2324_2526_2728u64.to_le_bytes());
    expected.extend_from_slice(&0x3132_3334_3536_3738u64.to_le_bytes());
    expected.extend_from_slice(&[244, 1, 232, 3, 60, 0]);
    assert_eq!(bytes, expected);
    assert_eq!(round_trip::<VotedServoControl>(&voted), Ok(voted));
}

#[test]
fn a_voted_sample_from_controller_zero_is_named() {
    let sample = VotedServoControl {
        from_id: 0,
        input: 1,
        input_digest: 0,
        raw_after: 0,
        raw_digest: 0,
        value: ServoControl::default(),
    };
    assert_eq!(rejected_field(sample), "voted.from_id");
}

#[test]
fn an_input_digest_is_fnv_1a_and_never_zero() {
    // FNV-1a 64's published test vectors.
    assert_eq!(input_digest(b""), 0xcbf2_9ce4_8422_2325);
    assert_eq!(input_digest(b"a"), 0xaf63_dc4c_8601_ec8c);
    assert_eq!(input_digest(b"foobar"), 0x8594_4171_f739_67e8);
    assert_ne!(input_digest(&[1, 2]), input_digest(&[2, 1]), "order counts");
}
