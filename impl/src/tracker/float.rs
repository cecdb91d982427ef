//! The tracker's control law written a second time, apart from the first: the same
//! specification (the module header of crate::tracker) computed in binary floating point,
//! with the positions, errors and gains as `f64`. Running it on one controller beside the
//! integer law on the others is the paper's diverse implementation: a bug in one
//! implementation shows as a command the others do not give.
//!
//! It is exact, not approximate. Every quantity is an integer far below 2^53 (an error is at
//! most about 2^32 camera units, a gain at most 350), so each product and sum is exact in
//! `f64`, a division by 1024 only moves the binary point, and `floor` gives what the arithmetic
//! shift gives. The two implementations therefore agree on every input; the property test in
//! crate::tracker says so over many inputs.

use super::{ControlLaw, ServoCommand};

/// One axis: its gains, where it is and the error it saw last.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Axis {
    proportional: f64,
    derivative: f64,
    position: f64,
    previous_error: Option<f64>,
    /// The last step's velocity, before the clamp.
    velocity: Option<f64>,
}

/// The gimbal's servos move between these positions and start in the middle.
const LOWEST: f64 = 0.0;
const HIGHEST: f64 = 1000.0;
const MIDDLE: f64 = 500.0;
/// The gains are in 1024ths.
const GAIN_UNIT: f64 = 1024.0;

impl Axis {
    fn new(proportional: f64, derivative: f64) -> Axis {
        Axis {
            proportional,
            derivative,
            position: MIDDLE,
            previous_error: None,
            velocity: None,
        }
    }

    fn step(&mut self, error: f64) {
        if let Some(previous) = self.previous_error {
            let push = error * self.proportional + (error - previous) * self.derivative;
            let velocity = (push / GAIN_UNIT).floor();
            self.velocity = Some(velocity);
            self.position = (self.position + velocity).clamp(LOWEST, HIGHEST);
        }
        self.previous_error = Some(error);
    }

    /// The last velocity as the integer it is (a whole number far below 2^53).
    fn last_velocity(&self) -> Option<i64> {
        self.velocity.map(|velocity| velocity as i64)
    }

    fn servo(&self) -> u16 {
        // Whole numbers in 0..=1000 only: the clamp and the floor keep it so.
        self.position as u16
    }
}

/// Pan and tilt in floating point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloatPanTilt {
    pan: Axis,
    tilt: Axis,
    frequency_hz: u16,
}

impl FloatPanTilt {
    /// Both axes centred, nothing seen yet; every command carries `frequency_hz`.
    pub fn new(frequency_hz: u16) -> FloatPanTilt {
        FloatPanTilt {
            pan: Axis::new(300.0, 200.0),
            tilt: Axis::new(350.0, 300.0),
            frequency_hz,
        }
    }
}

impl ControlLaw for FloatPanTilt {
    fn update(&mut self, x: i32, y: i32) -> ServoCommand {
        // The frame's centre is (111, 126): pan turns toward a ball left of it, tilt toward
        // one below it.
        self.pan.step(111.0 - f64::from(x));
        self.tilt.step(f64::from(y) - 126.0);
        self.command()
    }

    fn update_errors(&mut self, pan_error: i64, tilt_error: i64) -> ServoCommand {
        // An error from a camera coordinate is within ±2^33: exact as an f64.
        self.pan.step(pan_error as f64);
        self.tilt.step(tilt_error as f64);
        self.command()
    }

    fn align(&mut self, pan: u16, tilt: u16) {
        self.pan.position = f64::from(pan).clamp(LOWEST, HIGHEST);
        self.tilt.position = f64::from(tilt).clamp(LOWEST, HIGHEST);
    }

    fn command(&self) -> ServoCommand {
        ServoCommand {
            pan: self.pan.servo(),
            tilt: self.tilt.servo(),
            frequency: self.frequency_hz,
        }
    }

    fn step(&self) -> Option<(i64, i64)> {
        self.pan.last_velocity().zip(self.tilt.last_velocity())
    }
}
