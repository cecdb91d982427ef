//! The voted sample: its CDR layout as docs/rl.idl declares `rl::VotedServoControl`, its key,
//! a round trip, and the refused id 0.

use super::*;

#[test]
fn a_voted_servo_command_matches_the_idl_layout_and_is_keyed_by_its_controller() {
    let voted = Voted {
        from: 3,
        input: 0x0102_0304_0506_0708,
        value: ServoControl {
            pan: 500,
            tilt: 1000,
            frequency: 60,
        },
    };
    let sample = VotedServoControl::encode(&voted);
    assert_eq!(sample.key(), 3);
    let bytes = to_cdr(&sample);
    // octet from_id, 7 bytes of padding to the 8-aligned input, the input, three u16.
    let mut expected = vec![3, 0, 0, 0, 0, 0, 0, 0];
    expected.extend_from_slice(&0x0102_0304_0506_0708u64.to_le_bytes());
    expected.extend_from_slice(&[244, 1, 232, 3, 60, 0]);
    assert_eq!(bytes, expected);
    assert_eq!(round_trip::<VotedServoControl>(&voted), Ok(voted));
}

#[test]
fn a_voted_sample_from_controller_zero_is_named() {
    let sample = VotedServoControl {
        from_id: 0,
        input: 1,
        value: ServoControl::default(),
    };
    assert_eq!(rejected_field(sample), "voted.from_id");
}
