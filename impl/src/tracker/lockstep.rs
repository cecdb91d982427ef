//! The lockstep pair's comparison (`architecture = "pair"`, the paper's custom hardware duplex
//! in software): the controller runs its control law twice, in the two diverse
//! implementations (`tracker.law` and the other one), and compares their outputs for every
//! camera frame before anything is written. Outputs further apart than the voting rule's
//! per-axis tolerance (rl_layer::vote_reader::ServoRule, the bound the diverse-law property
//! test measures) are a mismatch: the controller reports a local fault and leaves the bus.
//! Writing only after comparing is the model's rule (`architectures::pair`); writing first is
//! its `write_before_compare` mutation, which lets a wrong output through.

use super::{control_law, ControlLaw, ServoCommand};
use rl_layer::vote_reader::{ServoRule, VoteRule};
use rl_layer::wire::ServoControl;

/// The second implementation, kept in step with the first.
pub struct Lockstep {
    second: Box<dyn ControlLaw>,
    rule: ServoRule,
}

/// Two implementations disagreed on one frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mismatch {
    /// The frame (camera sample timestamp) both answered.
    pub frame: u64,
    /// The output about to be written (the first implementation's).
    pub first: ServoControl,
    /// The second implementation's.
    pub second: ServoControl,
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "lockstep mismatch at frame {}: pan {} tilt {} against the second \
             implementation's pan {} tilt {}",
            self.frame, self.first.pan, self.first.tilt, self.second.pan, self.second.tilt
        )
    }
}

impl Lockstep {
    /// The implementation `law` is not, centred, beside a first one of `law`.
    pub fn beside(law: rl_layer::config::ControlLaw, frequency_hz: u16) -> Lockstep {
        let other = match law {
            rl_layer::config::ControlLaw::Integer => rl_layer::config::ControlLaw::Float,
            rl_layer::config::ControlLaw::Float => rl_layer::config::ControlLaw::Integer,
        };
        Lockstep {
            second: control_law(other, frequency_hz),
            rule: ServoRule::default(),
        }
    }

    /// The second implementation's answer to the circle at `(x, y)`.
    pub fn update(&mut self, x: i32, y: i32) -> ServoCommand {
        self.second.update(x, y)
    }

    /// Takes the actuator's position, as the first implementation did.
    pub fn align(&mut self, pan: u16, tilt: u16) {
        self.second.align(pan, tilt);
    }

    /// Compares what is about to be written for `frame` with the second implementation's
    /// answer to it.
    pub fn compare(
        &self,
        frame: u64,
        first: ServoControl,
        second: ServoCommand,
    ) -> Result<(), Mismatch> {
        let second = ServoControl {
            pan: second.pan,
            tilt: second.tilt,
            frequency: second.frequency,
        };
        if self.rule.agree(&first, &second) {
            Ok(())
        } else {
            Err(Mismatch {
                frame,
                first,
                second,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rl_layer::config::ControlLaw as Law;

    fn sample(command: ServoCommand) -> ServoControl {
        ServoControl {
            pan: command.pan,
            tilt: command.tilt,
            frequency: command.frequency,
        }
    }

    #[test]
    fn the_two_implementations_agree_along_a_path_and_a_wrong_pan_is_a_mismatch() {
        let mut first = control_law(Law::Integer, 50);
        let mut lockstep = Lockstep::beside(Law::Integer, 50);
        for step in 0..400 {
            let (x, y) = (111 + (step % 90) - 45, 126 + (step % 70) - 35);
            let (a, b) = (first.update(x, y), lockstep.update(x, y));
            assert_eq!(lockstep.compare(step as u64, sample(a), b), Ok(()));
            if step == 200 {
                first.align(300, 700);
                lockstep.align(300, 700);
            }
        }
        let (a, b) = (first.update(100, 100), lockstep.update(100, 100));
        let wrong = ServoControl {
            pan: a.pan.saturating_add(ServoRule::default().pan_tolerance + 1),
            ..sample(a)
        };
        let mismatch = lockstep.compare(7, wrong, b).expect_err("a wrong pan");
        assert_eq!(mismatch.frame, 7);
        assert!(mismatch
            .to_string()
            .starts_with("lockstep mismatch at frame 7: pan"));
    }
}
