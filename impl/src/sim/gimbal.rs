//! The camera's world: a ball moving in front of a pan-tilt gimbal, and what the camera on the
//! gimbal sees of it. Pure: positions and times in, positions out.
//!
//! The gimbal's axes take the tracker's servo positions (0..=1000, 500 centred). A servo moves
//! toward its commanded position at most [`SERVO_RATE_PER_S`] units a second (a hobby servo
//! sweeps its range in about half a second) and holds it. Angles are in servo units: the
//! ball's place is where the gimbal would have to point to centre it. The camera sees the ball
//! at the frame centre (111, 126) plus [`PIXELS_PER_UNIT`] times the angle between the ball and
//! where the gimbal points, inside the shapes application's frame (0..=222 × 0..=252), or not
//! at all.
//!
//! Directions follow the tracker's law (crate::tracker): a ball right of centre (x > 111) makes
//! the pan error negative and the pan position fall, so a falling pan position turns the
//! camera right; a ball below centre (y > 126) makes the tilt position rise, so a rising tilt
//! position turns the camera down.

use crate::sim::shapes::{X_MAX, Y_MAX};
use crate::tracker::{POSITION_CENTRE, POSITION_MAX, POSITION_MIN, SET_POINT_X, SET_POINT_Y};
use std::f64::consts::TAU;

/// How far the servos move per second at most (servo units).
pub const SERVO_RATE_PER_S: f64 = 2000.0;
/// Pixels in the camera frame per servo unit of angle (the Pixy's 75° field over 320 pixels,
/// on a gimbal whose 1000 units span 180°, scaled to the shapes frame).
pub const PIXELS_PER_UNIT: f64 = 0.5;

/// Where the ball is at `t_s`: pan and tilt angles from the centre, in servo units. A 3:2
/// Lissajous figure every 24 s (a ball moved by hand), ±180 units in pan and ±200 in tilt:
/// seen from the centred gimbal it stays in the frame (±90 and ±100 pixels).
pub fn ball(t_s: f64) -> (f64, f64) {
    (
        180.0 * (TAU * t_s / 8.0).sin(),
        200.0 * (TAU * t_s / 12.0 + 0.5).sin(),
    )
}

/// The gimbal: where each axis is and where it was told to go.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gimbal {
    pub pan: f64,
    pub tilt: f64,
    target: (f64, f64),
}

impl Default for Gimbal {
    fn default() -> Gimbal {
        let centre = f64::from(POSITION_CENTRE);
        Gimbal {
            pan: centre,
            tilt: centre,
            target: (centre, centre),
        }
    }
}

impl Gimbal {
    /// A new command: the servos head there from now on.
    pub fn command(&mut self, pan: u16, tilt: u16) {
        let clamp = |p: u16| f64::from(p).clamp(f64::from(POSITION_MIN), f64::from(POSITION_MAX));
        self.target = (clamp(pan), clamp(tilt));
    }

    /// `dt_s` seconds of servo motion toward the target.
    pub fn advance(&mut self, dt_s: f64) {
        let step = SERVO_RATE_PER_S * dt_s.max(0.0);
        let toward = |at: f64, target: f64| at + (target - at).clamp(-step, step);
        self.pan = toward(self.pan, self.target.0);
        self.tilt = toward(self.tilt, self.target.1);
    }

    /// Where the camera points, as angles from the centre in servo units.
    fn pointing(&self) -> (f64, f64) {
        let centre = f64::from(POSITION_CENTRE);
        (centre - self.pan, self.tilt - centre)
    }

    /// Where the camera sees a ball at angles `ball` (frame pixels, unrounded); may lie
    /// outside the frame.
    pub fn view(&self, ball: (f64, f64)) -> (f64, f64) {
        let (pan, tilt) = self.pointing();
        (
            f64::from(SET_POINT_X) + PIXELS_PER_UNIT * (ball.0 - pan),
            f64::from(SET_POINT_Y) + PIXELS_PER_UNIT * (ball.1 - tilt),
        )
    }

    /// The ball in the frame, rounded, or `None` if the camera does not see it.
    pub fn sees(&self, ball: (f64, f64)) -> Option<(i32, i32)> {
        let (x, y) = self.view(ball);
        let inside = (0.0..=f64::from(X_MAX)).contains(&x) && (0.0..=f64::from(Y_MAX)).contains(&y);
        inside.then(|| (x.round() as i32, y.round() as i32))
    }
}

/// How far from the frame centre a seen ball is, in pixels.
pub fn error_px(seen: (i32, i32)) -> f64 {
    let dx = f64::from(seen.0 - SET_POINT_X);
    let dy = f64::from(seen.1 - SET_POINT_Y);
    dx.hypot(dy)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::PanTiltController;

    #[test]
    fn a_centred_gimbal_sees_the_ball_everywhere_on_its_path() {
        let gimbal = Gimbal::default();
        for step in 0..2400 {
            let t_s = f64::from(step) * 0.01;
            assert!(gimbal.sees(ball(t_s)).is_some(), "lost at {t_s} s");
        }
    }

    #[test]
    fn the_servos_are_rate_limited() {
        let mut gimbal = Gimbal::default();
        gimbal.command(1000, 0);
        gimbal.advance(0.1);
        assert_eq!((gimbal.pan, gimbal.tilt), (700.0, 300.0));
        gimbal.advance(1.0);
        assert_eq!((gimbal.pan, gimbal.tilt), (1000.0, 0.0));
    }

    /// The paper's tracker in the loop, at the camera's 30 Hz and one frame of delay: the
    /// ball stays near the centre; with the camera fixed (the gimbal ignored) it would not.
    #[test]
    fn the_tracker_keeps_the_ball_near_the_centre_in_closed_loop() {
        let frame_s = 1.0 / 30.0;
        let mut gimbal = Gimbal::default();
        let mut tracker = PanTiltController::new(60);
        let mut errors = Vec::new();
        for frame in 0..1800 {
            let t_s = f64::from(frame) * frame_s;
            let seen = gimbal.sees(ball(t_s)).expect("the ball stays in view");
            let command = tracker.update(seen.0, seen.1);
            gimbal.command(command.pan, command.tilt);
            gimbal.advance(frame_s);
            if t_s > 2.0 {
                errors.push(error_px(seen));
            }
        }
        errors.sort_by(f64::total_cmp);
        let median = errors[errors.len() / 2];
        let worst = errors[errors.len() - 1];
        println!("closed loop: median {median:.1} px, worst {worst:.1} px");
        assert!(
            median < 15.0 && worst < 30.0,
            "median {median} px, worst {worst} px"
        );
        // Open loop, the same path is up to 134 px off centre.
        let fixed = Gimbal::default();
        let open_worst = (0..900)
            .chain(900..1800)
            .filter_map(|f| fixed.sees(ball(f64::from(f) * frame_s)))
            .map(error_px)
            .fold(0.0, f64::max);
        assert!(open_worst > 100.0, "{open_worst}");
    }
}
