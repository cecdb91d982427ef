//! The wrong-output scenarios by name (`lab list`), each with the fault it asks for 2 s into
//! judging and what its judges hold it to ([`super::Kind`]).

use super::{Kind, OutputScenario, DRIFT_PER_S, LAW_GAIN_PERCENT, OFFSET};
use crate::lab::faults::{Fault, Target, WrongAnswer};
use crate::lab::scenario::{Scenario, Step};
use crate::lab::session::Camera;

fn scenario(name: &str, about: &str, output: OutputScenario, steps: Vec<Step>) -> Scenario {
    Scenario {
        name: name.into(),
        about: about.into(),
        steps,
        in_ci: false,
        network: None,
        output: Some(output),
    }
}

/// The wrong outputs at 2 s into judging, as every named scenario applies its fault.
fn wrong(target: Target, wrong: WrongAnswer, lasts_s: f64) -> Step {
    Step {
        at_ms: 2000,
        fault: Fault::WrongCommands(target, wrong),
        lasts_ms: (lasts_s * 1000.0) as u64,
    }
}

/// The wrong-output scenarios (`lab list`): not in `matrix --ci`.
pub fn scenarios() -> Vec<Scenario> {
    let (p, s) = (Target::Primary, Target::Secondary);
    let exclusive = |kind| OutputScenario {
        kind,
        camera: Camera::Exclusive,
    };
    let offset = WrongAnswer::Offset(OFFSET);
    vec![
        scenario(
            "wrong-primary",
            "the Primary's pan 300 off, 3 s: it leaves within N = 2 wrong frames, voting reader takes none",
            exclusive(Kind::WrongPrimary),
            vec![wrong(p, offset, 3.0)],
        ),
        scenario(
            "wrong-primary-vote-camera",
            "wrong-primary with the camera's gimbal following the vote (rl shapes --vote)",
            OutputScenario {
                kind: Kind::WrongPrimary,
                camera: Camera::Vote,
            },
            vec![wrong(p, offset, 3.0)],
        ),
        scenario(
            "wrong-secondary",
            "the Secondary's pan 300 off, 3 s: it leaves, nothing changes at the exclusive readers",
            exclusive(Kind::WrongSecondary),
            vec![wrong(s, offset, 3.0)],
        ),
        // Longer: wrong only once the ball has moved the tolerance away from where it froze.
        scenario(
            "frozen-primary",
            "the Primary's output frozen, 5 s: it leaves once the ball has moved away",
            exclusive(Kind::FrozenPrimary),
            vec![wrong(p, WrongAnswer::Frozen, 5.0)],
        ),
        // Past the tolerance after 1.25 s; 4 s leaves room for the decision.
        scenario(
            "drift-primary",
            "the Primary's pan drifting 20 a second, 4 s: it leaves once past the tolerance, at N = 2 odd frames",
            exclusive(Kind::DriftPrimary),
            vec![wrong(p, WrongAnswer::Drift(DRIFT_PER_S), 4.0)],
        ),
        scenario(
            "wrong-input-primary",
            "the Primary reading another camera, 3 s: no voter compares its answers; it leaves on input within 5 frames, alarmed by name",
            exclusive(Kind::WrongInputPrimary),
            vec![wrong(p, WrongAnswer::ForeignInput, 3.0)],
        ),
        scenario(
            "wrong-law-primary",
            "the Primary's law at 150% of its pan gain, 3 s: its output agrees within the tolerance, no voter names it; it leaves on its raw answers at N = 2, alarmed by name",
            exclusive(Kind::WrongLawPrimary),
            vec![wrong(p, WrongAnswer::Gain(LAW_GAIN_PERCENT), 3.0)],
        ),
        scenario(
            "random-primary",
            "the Primary's commands random at every frame, 3 s",
            exclusive(Kind::RandomPrimary),
            vec![wrong(p, WrongAnswer::Random, 3.0)],
        ),
        // The camera follows the vote: the plant is then driven by the reader that must fail
        // safe. Following the exclusive topic it follows the wrong Primary, the ball leaves
        // the view and no controller answers a frame again, so nothing could be healed. Brief:
        // while the vote holds the gimbal, the ball drifts off centre and the right pan runs
        // to the servo's end within about a second, where the Primary's +300, clamped, is
        // right again (C1 and C3 then agree, rightly, and C2 is the odd one out).
        scenario(
            "two-wrong",
            "the Primary's pan 300 up and the Secondary's 300 down, 0.6 s, the camera following the vote: the voting reader holds, nobody leaves",
            OutputScenario {
                kind: Kind::TwoWrong,
                camera: Camera::Vote,
            },
            vec![
                wrong(p, offset, 0.6),
                wrong(s, WrongAnswer::Offset(-OFFSET), 0.6),
            ],
        ),
    ]
}
