//! The two implementations of the control law against each other: over many sequences of
//! circles, errors and alignments (the coordinates a camera gives, and the extremes of `i32`),
//! they give the same command at every step.

use super::{ControlLaw, FloatPanTilt, PanTiltController};
use proptest::prelude::*;

/// One thing a controller does to its law.
#[derive(Clone, Debug)]
enum Step {
    Circle(i32, i32),
    Errors(i64, i64),
    Align(u16, u16),
}

fn coordinate() -> impl Strategy<Value = i32> {
    prop_oneof![
        8 => -300..600i32,
        1 => any::<i32>(),
        1 => Just(i32::MIN),
        1 => Just(i32::MAX),
    ]
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        8 => (coordinate(), coordinate()).prop_map(|(x, y)| Step::Circle(x, y)),
        2 => (coordinate(), coordinate())
            .prop_map(|(x, y)| Step::Errors(i64::from(x) - 111, i64::from(y) - 126)),
        1 => (0..=1200u16, 0..=1200u16).prop_map(|(pan, tilt)| Step::Align(pan, tilt)),
    ]
}

fn apply(law: &mut dyn ControlLaw, step: &Step) -> super::ServoCommand {
    match *step {
        Step::Circle(x, y) => law.update(x, y),
        Step::Errors(pan, tilt) => law.update_errors(pan, tilt),
        Step::Align(pan, tilt) => {
            law.align(pan, tilt);
            law.command()
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn both_laws_give_the_same_command_at_every_step(
        steps in prop::collection::vec(step(), 1..200),
        frequency in 1..=1000u16,
    ) {
        let mut integer = PanTiltController::new(frequency);
        let mut float = FloatPanTilt::new(frequency);
        for (i, step) in steps.iter().enumerate() {
            let expected = apply(&mut integer, step);
            let got = apply(&mut float, step);
            prop_assert_eq!(got, expected, "step {} ({:?})", i, step);
            prop_assert_eq!(float.step(), integer.step(), "raw step {} ({:?})", i, step);
        }
    }

    /// The raw answer (rl_layer::wire::RawAnswer) is the law's step: two controllers aligned
    /// to different positions give the same one for the same circles, so it is compared
    /// exactly, while a wrong gain gives another.
    #[test]
    fn the_step_depends_on_the_circles_alone_not_on_the_position(
        circles in prop::collection::vec((coordinate(), coordinate()), 2..50),
        (pan, tilt) in (0..=1000u16, 0..=1000u16),
    ) {
        let mut here = PanTiltController::new(60);
        let mut there = PanTiltController::new(60);
        there.align(pan, tilt);
        for (i, (x, y)) in circles.into_iter().enumerate() {
            here.update(x, y);
            there.update(x, y);
            prop_assert_eq!(here.step(), there.step());
            prop_assert_eq!(here.step().is_some(), i > 0);
        }
    }
}

#[test]
fn the_first_circle_has_no_step() {
    let mut law = PanTiltController::new(60);
    assert_eq!(law.step(), None);
    law.update(101, 136);
    assert_eq!(law.step(), None, "the first only records the errors");
    law.update(101, 136);
    assert_eq!(law.step(), Some((2, 3)));
}

#[test]
fn the_float_law_takes_the_hand_computed_steps() {
    // The integer law's hand-computed steps (crate::tracker's tests), negative velocities
    // rounding toward minus infinity included.
    let mut float = FloatPanTilt::new(60);
    let at = |c: super::ServoCommand| (c.pan, c.tilt);
    assert_eq!(at(float.update(111, 126)), (500, 500));
    assert_eq!(at(float.update(101, 136)), (504, 506));
    assert_eq!(at(float.update(101, 136)), (506, 509));
    assert_eq!(at(float.update(111, 126)), (504, 506));
    let mut float = FloatPanTilt::new(60);
    float.update(111, 126);
    assert_eq!(at(float.update(112, 125)), (499, 499));
    let mut float = FloatPanTilt::new(60);
    float.update(i32::MIN, i32::MAX);
    assert_eq!(at(float.update(i32::MAX, i32::MIN)), (0, 0));
    assert_eq!(at(float.update(i32::MIN, i32::MAX)), (1000, 1000));
}
