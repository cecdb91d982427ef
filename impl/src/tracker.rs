//! The paper's application: the pan/tilt law that turns the camera's circle position into a
//! gimbal command. Pure arithmetic, no DDS: the controller feeds it circles and publishes what
//! it returns, so every role holder computes the same command from the same samples.
//!
//! It is the original Pixytracker's proportional-derivative loop, kept bit for bit so a
//! redundant tracker moves the gimbal exactly as the original did. Per axis:
//!
//! ```text
//! velocity = (error * P + (error - previous_error) * D) >> 10
//! position = clamp(position + velocity, 0, 1000)
//! ```
//!
//! with pan error = 111 − x and tilt error = y − 126 (the centre of the shapes application's
//! 0..222 × 0..252 range), gains pan P 300 D 200 and tilt P 350 D 300, positions starting at
//! 500. `>>` is an arithmetic shift, as C's `>>` on a signed `int` is on every compiler the
//! original ran on: negative velocities round toward −∞ (−500 >> 10 = −1, not 0). The first
//! sample only records the error: there is no previous error to differentiate.

#[cfg(test)]
mod diverse_tests;
mod float;
pub mod lockstep;

pub use float::FloatPanTilt;

/// A control law as a controller uses it: feed it every circle (or the errors of one), publish
/// what it returns. [`PanTiltController`] is the original's; [`FloatPanTilt`] the same law
/// written apart from it, for diverse implementations (`tracker.law`).
pub trait ControlLaw: Send {
    /// One circle at `(x, y)`: one step of both axes (the first only records the errors).
    fn update(&mut self, x: i32, y: i32) -> ServoCommand;
    /// The same step from the errors [`errors_of`] gives.
    fn update_errors(&mut self, pan_error: i64, tilt_error: i64) -> ServoCommand;
    /// Takes the actuator's position as its own (bumpless transfer; see
    /// [`PanTiltController::align`]).
    fn align(&mut self, pan: u16, tilt: u16);
    /// The current command without a new sample.
    fn command(&self) -> ServoCommand;
    /// The law's own step at the last sample, pan and tilt, before the clamp and whatever
    /// position it was aligned to: the velocity, a function of that sample's errors and the
    /// previous sample's alone (none before a second sample). Controllers compare it exactly
    /// (their raw answers, rl_layer::wire::RawAnswer).
    fn step(&self) -> Option<(i64, i64)>;
}

/// The implementation `tracker.law` names, centred, with `frequency_hz` in every command.
pub fn control_law(law: rl_layer::config::ControlLaw, frequency_hz: u16) -> Box<dyn ControlLaw> {
    match law {
        rl_layer::config::ControlLaw::Integer => Box::new(PanTiltController::new(frequency_hz)),
        rl_layer::config::ControlLaw::Float => Box::new(FloatPanTilt::new(frequency_hz)),
    }
}

/// The set-point: the centre of the camera frame as the shapes application scales it.
pub const SET_POINT_X: i32 = 111;
pub const SET_POINT_Y: i32 = 126;

/// Servo positions the gimbal accepts, and where both axes start.
pub const POSITION_MIN: i32 = 0;
pub const POSITION_MAX: i32 = 1000;
pub const POSITION_CENTRE: i32 = 500;

/// The gains are fixed-point with 10 fractional bits: velocity is the sum shifted right by 10.
pub const GAIN_SHIFT: u32 = 10;

/// Proportional and derivative gain of one axis (fixed point, see [`GAIN_SHIFT`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisGains {
    pub proportional: i32,
    pub derivative: i32,
}

pub const PAN_GAINS: AxisGains = AxisGains {
    proportional: 300,
    derivative: 200,
};

pub const TILT_GAINS: AxisGains = AxisGains {
    proportional: 350,
    derivative: 300,
};

/// One gimbal command, as the tracker computes it (the DDS sample type lives in `wire`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ServoCommand {
    /// Pan servo position, 0..=1000.
    pub pan: u16,
    /// Tilt servo position, 0..=1000.
    pub tilt: u16,
    /// Servo PWM frequency in Hz.
    pub frequency: u16,
}

/// One axis of the PD loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct AxisLoop {
    gains: AxisGains,
    position: i32,
    /// `None` until the first sample.
    previous_error: Option<i64>,
    /// The velocity of the last step, before the clamp (`None` until a second sample).
    velocity: Option<i64>,
}

impl AxisLoop {
    fn new(gains: AxisGains) -> AxisLoop {
        AxisLoop {
            gains,
            position: POSITION_CENTRE,
            previous_error: None,
            velocity: None,
        }
    }

    /// One PD step. The error is i64 so that any i32 camera coordinate is safe: the original's
    /// i32 arithmetic is reproduced exactly wherever it did not overflow.
    fn update(&mut self, error: i64) {
        if let Some(previous_error) = self.previous_error {
            let sum = error * i64::from(self.gains.proportional)
                + (error - previous_error) * i64::from(self.gains.derivative);
            let velocity = sum >> GAIN_SHIFT;
            self.velocity = Some(velocity);
            let position = (i64::from(self.position) + velocity)
                .clamp(i64::from(POSITION_MIN), i64::from(POSITION_MAX));
            // Clamped to 0..=1000 just above, so it fits.
            self.position = i32::try_from(position).unwrap_or(POSITION_CENTRE);
        }
        self.previous_error = Some(error);
    }

    /// The position as a servo value; always within 0..=1000.
    fn servo_position(&self) -> u16 {
        u16::try_from(self.position).unwrap_or(0)
    }
}

/// The pan and tilt errors of a circle at `(x, y)`: how far the set-point is from it, pan
/// `111 − x`, tilt `y − 126`.
pub fn errors_of(x: i32, y: i32) -> (i64, i64) {
    (
        i64::from(SET_POINT_X) - i64::from(x),
        i64::from(y) - i64::from(SET_POINT_Y),
    )
}

/// The pan/tilt controller: feed it every circle, publish what it returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PanTiltController {
    pan: AxisLoop,
    tilt: AxisLoop,
    frequency_hz: u16,
}

impl PanTiltController {
    /// Both axes centred, no previous sample; every command carries `frequency_hz`
    /// (`tracker.servo_frequency_hz`, 60 by default).
    pub fn new(frequency_hz: u16) -> PanTiltController {
        PanTiltController {
            pan: AxisLoop::new(PAN_GAINS),
            tilt: AxisLoop::new(TILT_GAINS),
            frequency_hz,
        }
    }

    /// One circle at `(x, y)` in the shapes application's coordinates: moves both axes one PD
    /// step (the first sample only records the errors) and returns the new command.
    pub fn update(&mut self, x: i32, y: i32) -> ServoCommand {
        let (pan_error, tilt_error) = errors_of(x, y);
        self.update_errors(pan_error, tilt_error)
    }

    /// The same step from the errors [`errors_of`] gives: the chain's actuator controllers
    /// (crate::chain) get them from the navigation controllers instead of a circle.
    pub fn update_errors(&mut self, pan_error: i64, tilt_error: i64) -> ServoCommand {
        self.pan.update(pan_error);
        self.tilt.update(tilt_error);
        self.command()
    }

    /// Takes the actuator's position as its own, keeping the derivative's memory: a standby
    /// controller follows the commanding controller's commands, so that when it takes over the
    /// gimbal continues from where it is (bumpless transfer). The law itself is incremental
    /// (position += velocity), so without this a controller restarted later carries an offset
    /// from the owner's position forever, and the gimbal jumps by it at the failover.
    pub fn align(&mut self, pan: u16, tilt: u16) {
        let within = |p: u16| i32::from(p).clamp(POSITION_MIN, POSITION_MAX);
        self.pan.position = within(pan);
        self.tilt.position = within(tilt);
    }

    /// The current command without a new sample (for re-publishing while the camera is quiet).
    pub fn command(&self) -> ServoCommand {
        ServoCommand {
            pan: self.pan.servo_position(),
            tilt: self.tilt.servo_position(),
            frequency: self.frequency_hz,
        }
    }

    /// The velocity of the last step per axis, before the clamp ([`ControlLaw::step`]).
    pub fn step(&self) -> Option<(i64, i64)> {
        self.pan.velocity.zip(self.tilt.velocity)
    }

    /// Back to the centre with no previous sample, as at start.
    pub fn reset(&mut self) {
        *self = PanTiltController::new(self.frequency_hz);
    }
}

impl ControlLaw for PanTiltController {
    fn update(&mut self, x: i32, y: i32) -> ServoCommand {
        PanTiltController::update(self, x, y)
    }

    fn update_errors(&mut self, pan_error: i64, tilt_error: i64) -> ServoCommand {
        PanTiltController::update_errors(self, pan_error, tilt_error)
    }

    fn align(&mut self, pan: u16, tilt: u16) {
        PanTiltController::align(self, pan, tilt)
    }

    fn command(&self) -> ServoCommand {
        PanTiltController::command(self)
    }

    fn step(&self) -> Option<(i64, i64)> {
        PanTiltController::step(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn command(pan: u16, tilt: u16) -> ServoCommand {
        ServoCommand {
            pan,
            tilt,
            frequency: 60,
        }
    }

    #[test]
    fn starts_centred_and_first_sample_does_not_move() {
        let mut tracker = PanTiltController::new(60);
        assert_eq!(tracker.command(), command(500, 500));
        // Far off the set-point, but there is no previous error yet.
        assert_eq!(tracker.update(0, 252), command(500, 500));
    }

    #[test]
    fn hand_computed_steps() {
        let mut tracker = PanTiltController::new(60);
        // On the set-point: errors 0, 0 recorded, no move.
        assert_eq!(tracker.update(111, 126), command(500, 500));
        // pan error 111-101 = 10:  (10*300 + (10-0)*200) >> 10 = 5000 >> 10 = 4   -> 504
        // tilt error 136-126 = 10: (10*350 + (10-0)*300) >> 10 = 6500 >> 10 = 6   -> 506
        assert_eq!(tracker.update(101, 136), command(504, 506));
        // Same errors again, no derivative:
        // pan:  (10*300 + 0*200) >> 10 = 3000 >> 10 = 2                           -> 506
        // tilt: (10*350 + 0*300) >> 10 = 3500 >> 10 = 3                           -> 509
        assert_eq!(tracker.update(101, 136), command(506, 509));
        // Back on the set-point: errors 0, derivative -10:
        // pan:  (0*300 + (0-10)*200) >> 10 = -2000 >> 10 = -2 (floor of -1.95)     -> 504
        // tilt: (0*350 + (0-10)*300) >> 10 = -3000 >> 10 = -3 (floor of -2.93)     -> 506
        assert_eq!(tracker.update(111, 126), command(504, 506));
        // command() repeats the last result without stepping.
        assert_eq!(tracker.command(), command(504, 506));
    }

    #[test]
    fn negative_velocity_rounds_toward_minus_infinity() {
        let mut tracker = PanTiltController::new(60);
        tracker.update(111, 126);
        // pan error 111-121 = -10:  (-3000 + -2000) >> 10 = -5000 >> 10 = -5, not -4 -> 495
        // tilt error 116-126 = -10: (-3500 + -3000) >> 10 = -6500 >> 10 = -7, not -6 -> 493
        assert_eq!(tracker.update(121, 116), command(495, 493));

        let mut tracker = PanTiltController::new(60);
        tracker.update(111, 126);
        // Error -1: (-300 + -200) >> 10 = -500 >> 10 = -1 (truncation would give 0) -> 499
        //           (-350 + -300) >> 10 = -650 >> 10 = -1                           -> 499
        assert_eq!(tracker.update(112, 125), command(499, 499));

        let mut tracker = PanTiltController::new(60);
        tracker.update(111, 126);
        // Error +1: (300 + 200) >> 10 = 500 >> 10 = 0; (350 + 300) >> 10 = 0: no move.
        assert_eq!(tracker.update(110, 127), command(500, 500));
    }

    #[test]
    fn clamps_at_both_ends() {
        let mut tracker = PanTiltController::new(60);
        tracker.update(111, 126);
        // pan error 111-(-10000) = 10111: (10111*300 + 10111*200) >> 10
        //   = 5055500 >> 10 = 4937; 500 + 4937 = 5437 -> clamped to 1000
        // tilt error -10000-126 = -10126: (-3544100 + -3037800) >> 10
        //   = -6581900 >> 10 = -6428 (floor of -6427.6); 500 - 6428 -> clamped to 0
        assert_eq!(tracker.update(-10_000, -10_000), command(1000, 0));
        // The other way: pan error 111-10000 = -9889, previous 10111:
        //   (-9889*300 + (-9889-10111)*200) >> 10 = (-2966700 - 4000000) >> 10
        //   = -6966700 >> 10 = -6804 (floor of -6803.4); 1000 - 6804 -> clamped to 0
        // tilt error 10000-126 = 9874, previous -10126:
        //   (9874*350 + (9874+10126)*300) >> 10 = (3455900 + 6000000) >> 10
        //   = 9455900 >> 10 = 9234; 0 + 9234 -> clamped to 1000
        assert_eq!(tracker.update(10_000, 10_000), command(0, 1000));
        // Clamped positions stay put while pushed further the same way.
        // pan error -9889 again: (-2966700 + 0) >> 10 = -2898 -> 0
        // tilt error 9874 again: (3455900 + 0) >> 10 = 3374 -> 1000
        assert_eq!(tracker.update(10_000, 10_000), command(0, 1000));
    }

    #[test]
    fn extreme_coordinates_do_not_overflow() {
        let mut tracker = PanTiltController::new(60);
        tracker.update(i32::MIN, i32::MAX);
        assert_eq!(tracker.update(i32::MAX, i32::MIN), command(0, 0));
        assert_eq!(tracker.update(i32::MIN, i32::MAX), command(1000, 1000));
    }

    #[test]
    fn frequency_comes_from_the_configuration() {
        let mut tracker = PanTiltController::new(50);
        assert_eq!(tracker.update(0, 0).frequency, 50);
        assert_eq!(tracker.command().frequency, 50);
    }

    #[test]
    fn reset_returns_to_the_start() {
        let mut tracker = PanTiltController::new(60);
        tracker.update(111, 126);
        tracker.update(101, 136);
        assert_ne!(tracker.command(), command(500, 500));
        tracker.reset();
        assert_eq!(tracker, PanTiltController::new(60));
        // The next sample is a first sample again.
        assert_eq!(tracker.update(0, 0), command(500, 500));
    }
}
