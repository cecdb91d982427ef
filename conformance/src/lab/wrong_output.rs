//! Wrong outputs: controllers that heartbeat on, and so keep their roles, while the commands
//! they compute are wrong (docs/protocol.md, "Output voting"; docs/faults.md, "Wrong
//! outputs"). A `fault-injection` build of `rl controller` reads `wrong-commands offset N`,
//! `frozen`, `random` and `none` on its stdin (`super::faults::Fault::WrongCommands`); each
//! controller cross-checks its answer to every camera frame with the two others' and leaves
//! (FAILED, exit 75, restarted by the lab as by systemd) once it has been the odd one out of
//! three at N = 2 frames of one life.
//!
//! Each scenario is judged at three readers on the actuator node: `rl servo --json` and the
//! Connext reader (exclusive ownership: they take the strongest writer's commands, whatever
//! they are) and `rl servo --vote --json` (the voting reader: a command only when two
//! controllers agree). Which sample is wrong, and how many reached each reader:
//! [`delivered`]; what each scenario promises: [`verdict`]; the ball's tracking error at the
//! camera: [`tracking`]; the lines they read: [`readings`]; what a run leaves beside the
//! lab's usual output: [`files`]. Under the duplex and the pair the same runs are judged on
//! what those architectures promise instead ([`architectures`]): the voting reader is then
//! only the judges' reference for the right commands.

pub mod architectures;
pub mod delivered;
pub mod files;
pub mod readings;
mod scenarios;
pub mod tracking;
pub mod verdict;

use super::architecture::Architecture;
use super::error::LabError;
use super::expect::GAP_SLACK_MS;
use super::faults::WrongAnswer;
use super::judge::FaultRecord;
use super::observe::{Observations, OwnerSpan};
use super::procs::Life;
use super::session::Camera;
use delivered::{Delivered, Judging};
pub use scenarios::scenarios;
use serde::Serialize;

/// N: the odd-one-out inputs of one life after which a controller leaves, the output model's
/// and the controllers' (`tracker.odd_limit`, which the lab leaves at its default;
/// docs/protocol.md, "K = N = 2").
pub const ODD_LIMIT: usize = rl_layer::cross_check::ODD_LIMIT_DEFAULT as usize;

/// The camera's frame rate (`rl shapes --rate-hz`, its default, which the lab passes): one
/// input of the output model per frame.
pub const CAMERA_RATE_HZ: f64 = 30.0;

/// The dissents after which the voting reader raises its alarm (`--dissent-after`): N. A wrong
/// controller's answers reach the voting reader at N inputs of its life and no more (its N-th
/// odd answer is the last it publishes; its fault starts at the next camera frame), so a
/// reader waiting for more (the servo's default is 3) never names a controller the
/// cross-check takes out, and one waiting for fewer would name a right one that is a frame out
/// of step once.
pub const VOTER_DISSENT_AFTER: u32 = ODD_LIMIT as u32;

/// The largest difference per axis at which two commands agree: the voting reader's and the
/// cross-check's default (`rl servo --vote-tolerance`).
pub const TOLERANCE: u16 = rl_layer::vote_reader::SERVO_TOLERANCE_DEFAULT;

/// One camera period (ms).
pub fn camera_period_ms() -> f64 {
    1000.0 / CAMERA_RATE_HZ
}

/// A wrong output asked of one controller life (lab ms).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Injection {
    pub id: u8,
    /// `C1`, `C1#2`: the life that was asked.
    pub life: String,
    pub wrong: WrongAnswer,
    /// When the line was written to its stdin.
    pub from_ms: f64,
    /// When `wrong-commands none` was written to its controller id's stdin.
    pub healed_ms: Option<f64>,
}

/// Which wrong-output scenario: what its judges promise ([`verdict`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// The Primary's pan off by 300: it leaves within N wrong answers, the exclusive readers
    /// move once to the Secondary.
    WrongPrimary,
    /// The Secondary's: it leaves, and the exclusive readers see nothing.
    WrongSecondary,
    /// The Primary's output frozen: wrong once the ball has moved, then as `WrongPrimary`.
    FrozenPrimary,
    /// The Primary's commands random at every frame.
    RandomPrimary,
    /// Two controllers wrong at once, never agreeing: the voting reader holds, nobody leaves,
    /// the exclusive readers follow the wrong Primary.
    TwoWrong,
    /// The Primary's pan drifting off slowly: wrong once past the tolerance, then as
    /// `WrongPrimary`.
    DriftPrimary,
    /// The Primary reading another camera: its answers are to inputs the group never has,
    /// so no voter compares them; its input congruence takes it out, alarmed by name.
    WrongInputPrimary,
    /// The Primary's law wrong by a gain (its pan steps at [`LAW_GAIN_PERCENT`]): aligned to
    /// the group at every frame, its output agrees within the tolerance, so no voter names
    /// it; its raw answers take it out, alarmed by name.
    WrongLawPrimary,
}

impl Kind {
    /// Whether one controller, the Primary, is wrong.
    pub fn primary_alone(self) -> bool {
        matches!(
            self,
            Kind::WrongPrimary
                | Kind::FrozenPrimary
                | Kind::RandomPrimary
                | Kind::DriftPrimary
                | Kind::WrongInputPrimary
                | Kind::WrongLawPrimary
        )
    }

    /// Whether the fault is in the controller's input (judged on input congruence).
    pub fn in_input(self) -> bool {
        self == Kind::WrongInputPrimary
    }

    /// What the controller must say it was odd on and the alarm it must raise about itself,
    /// when the alignment masks the fault in its output (no voter can name it): its input,
    /// or its law.
    pub fn masked(self) -> Option<(&'static str, &'static str)> {
        match self {
            Kind::WrongInputPrimary => Some(("input", "input_disagrees")),
            Kind::WrongLawPrimary => Some(("law", "law_disagrees")),
            _ => None,
        }
    }
}

/// The pan gain of `wrong-law-primary`'s law, in percent of the right one: half again, so
/// that any step of 2 or more differs (integer steps, rounded toward zero), while a step's
/// error stays within the tolerance of 25 for steps below 50 (a ball tracked at the camera's
/// usual 13 px moves the gimbal a few units a frame).
pub const LAW_GAIN_PERCENT: i32 = 150;

/// A controller's odd answers before it leaves on input: [`FOREIGN_LIMIT`] inputs the group
/// never had, in a row (rl_layer::cross_check), where an output fault leaves at N.
pub const FOREIGN_LIMIT: usize = rl_layer::cross_check::FOREIGN_LIMIT;

/// The drift of `drift-primary`, pan per second: past the tolerance 1.25 s after the fault,
/// about a pan unit a frame, so the controller is a little wrong for a few frames first.
pub const DRIFT_PER_S: i32 = 20;

/// What makes a scenario a wrong-output one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct OutputScenario {
    pub kind: Kind,
    pub camera: Camera,
}

/// How far apart the two wrong controllers of `two-wrong` are: each 300 off the right pan,
/// one up and one down, so they never agree (600 apart) and neither agrees with the right one.
pub const OFFSET: i32 = 300;

/// Why a wrong-output scenario is not run under `architecture`, if it is not: both members
/// of a pair wrong at once (`two-wrong`). Each member's compare takes it off the bus at its
/// first wrong frame, so the actuator has no writer until one is restarted and has waited out
/// its initialization window: a silence no gap bound covers. The pair promises a right writer
/// after one failure (the model's pair property), not after two; docs/architectures.md.
///
/// A wrong input (`wrong-input-primary`) is judged under voting only: the duplex compares
/// nothing, and a pair's two implementations read the same input, so its compare passes a
/// wrong one (A2 of docs/findings.md: a fault both share); only three inputs can outvote one.
pub fn not_run_under(scenario: OutputScenario, architecture: Architecture) -> Option<&'static str> {
    if scenario.kind == Kind::WrongLawPrimary && architecture != Architecture::Voting {
        return Some(
            "a wrong law masked by the alignment is caught by comparing raw answers across three controllers: the duplex compares nothing, and a pair member compares its two implementations' outputs, not raw answers",
        );
    }
    if scenario.kind.in_input() && architecture != Architecture::Voting {
        return Some(
            "a wrong input is caught only by comparing inputs across three controllers: the duplex compares nothing, and a pair's two implementations read the same input (A2)",
        );
    }
    (scenario.kind == Kind::TwoWrong && architecture == Architecture::Pair).then_some(
        "both members wrong at once are two failures: both leave the bus, and the actuator has no writer until one is restarted (the pair promises a right writer after one failure)",
    )
}

/// What the wrong-output judges read of a run.
pub struct Recorded<'a> {
    pub architecture: Architecture,
    pub observed: &'a Observations,
    pub lives: &'a [Life],
    pub injections: &'a [Injection],
    pub faults: &'a [FaultRecord],
    pub servo_owners: &'a [OwnerSpan],
    pub connext_owners: Option<&'a [OwnerSpan]>,
    pub judged_from_ms: f64,
    pub end_ms: f64,
}

/// A wrong life's way out and back (lab ms after its injection).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct OutAndBack {
    pub life: String,
    /// Its odd-one-out decision.
    pub decided_after_ms: Option<f64>,
    /// Its lockstep mismatch (a pair member's: it leaves the bus at once).
    pub mismatch_after_ms: Option<f64>,
    /// The inputs its decision counted that were camera frames taken after the fault (its
    /// wrong answers the voting reader heard), and before it (a right answer of this life
    /// found odd: a glitch the per-life count keeps); `None` without its `odd_one_out` event.
    pub odd_after_fault: Option<usize>,
    pub odd_before_fault: Option<usize>,
    /// Its answers that went out before they could be judged at their next input (its
    /// `odd_one_out` event's `late`): each adds one wrong answer and one camera period to
    /// the bounds (docs/protocol.md, "The cross-check in the controllers").
    pub late: Option<u64>,
    /// Its process's end, and how it ended.
    pub exited_after_ms: Option<f64>,
    pub exit: Option<String>,
    /// The next life of its id first steady in a role: when, which life, which role.
    pub back_after_ms: Option<f64>,
    pub back_life: Option<String>,
    pub back_as: Option<String>,
    /// The voting reader's dissent alarm about its id: raised (after the injection), and
    /// cleared (after that).
    pub dissent_raised_after_ms: Option<f64>,
    pub dissent_cleared_after_ms: Option<f64>,
    /// What its decision says it was odd on (`output`, `input`).
    pub odd_on: Option<String>,
    /// Its `input_disagrees` alarm about itself (input congruence).
    pub input_alarm_after_ms: Option<f64>,
    /// Its `law_disagrees` alarm about itself (raw answers).
    pub law_alarm_after_ms: Option<f64>,
}

/// The voting reader's figures.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct VoterFigures {
    /// Commands it accepted in the judged window.
    pub accepted: usize,
    pub wrong: Delivered,
    /// Its `no_majority` lines in the judged window, and the first after the injections.
    pub no_majority: usize,
    pub first_no_majority_after_ms: Option<f64>,
    /// Its first accepted command after the last heal (ms after it).
    pub accepting_again_after_ms: Option<f64>,
    /// Every dissent alarm raised in the judged window, `C1 at 2.03 s`.
    pub dissents_raised: Vec<String>,
}

/// What the wrong-output judges measured and decided.
#[derive(Clone, Debug, Serialize)]
pub struct OutputReport {
    pub scenario: OutputScenario,
    pub injections: Vec<Injection>,
    pub voter: VoterFigures,
    /// Wrong commands delivered at `rl servo` and at the Connext reader (when it ran).
    pub servo: Delivered,
    pub connext: Option<Delivered>,
    /// The owners at each exclusive reader in the judged window, in order.
    pub servo_owner_path: Vec<String>,
    pub connext_owner_path: Option<Vec<String>>,
    pub out_and_back: Vec<OutAndBack>,
    pub tracking: tracking::Tracking,
    pub failures: Vec<String>,
}

impl OutputReport {
    /// The exclusive readers that ran: each with the wrong commands it took and its owners.
    pub fn exclusive_readers(&self) -> Vec<(&'static str, &Delivered, &[String])> {
        let mut readers = vec![("rl servo", &self.servo, self.servo_owner_path.as_slice())];
        if let (Some(delivered), Some(path)) = (&self.connext, &self.connext_owner_path) {
            readers.push(("Connext", delivered, path.as_slice()));
        }
        readers
    }
}

/// The owners of `spans` in the judged window, in order, each once per span.
pub fn owner_path(spans: &[OwnerSpan], judged_from_ms: f64) -> Vec<String> {
    spans
        .iter()
        .filter(|span| span.to_ms >= judged_from_ms)
        .map(|span| span.owner.clone())
        .collect()
}

/// Measures and judges a wrong-output run.
pub fn judge(recorded: &Recorded, scenario: OutputScenario) -> OutputReport {
    let observed = recorded.observed;
    let judging = Judging::new(
        &observed.outputs.accepted,
        recorded.injections,
        recorded.lives,
    );
    let life_of =
        |participant: &str, at_ms: f64| observed.owner_name(participant, at_ms, recorded.lives);
    let in_window = |at_ms: f64| at_ms >= recorded.judged_from_ms && at_ms <= recorded.end_ms;
    let exclusive = |samples: &[super::observe::ActuatorSample]| {
        let judged: Vec<_> = samples
            .iter()
            .filter(|s| in_window(s.at_ms))
            .cloned()
            .collect();
        judging.exclusive(&judged, life_of)
    };
    let servo = exclusive(&observed.servo_commands);
    let connext = recorded
        .connext_owners
        .map(|_| exclusive(&observed.connext));
    let voter = voter_figures(recorded, &judging);
    let out_and_back = recorded
        .injections
        .iter()
        .map(|injection| out_and_back(recorded, injection))
        .collect();
    let tracking = tracking::measure(
        &observed.outputs.frames,
        recorded.faults,
        recorded.judged_from_ms,
        recorded.end_ms,
        scenario.camera,
    );
    let mut report = OutputReport {
        scenario,
        injections: recorded.injections.to_vec(),
        voter,
        servo,
        connext,
        servo_owner_path: owner_path(recorded.servo_owners, recorded.judged_from_ms),
        connext_owner_path: recorded
            .connext_owners
            .map(|spans| owner_path(spans, recorded.judged_from_ms)),
        out_and_back,
        tracking,
        failures: Vec::new(),
    };
    report.failures = match recorded.architecture {
        Architecture::Voting => verdict::failures(&report, recorded),
        other => architectures::failures(other, &report, recorded),
    };
    report
}

/// The voting reader's figures in the judged window.
fn voter_figures(recorded: &Recorded, judging: &Judging) -> VoterFigures {
    let outputs = &recorded.observed.outputs;
    let from = recorded.judged_from_ms;
    let in_window = |at_ms: f64| at_ms >= from && at_ms <= recorded.end_ms;
    let accepted: Vec<_> = outputs
        .accepted
        .iter()
        .filter(|a| in_window(a.at_ms))
        .cloned()
        .collect();
    let first_injection = recorded
        .injections
        .iter()
        .map(|i| i.from_ms)
        .fold(f64::INFINITY, f64::min);
    let last_heal = recorded
        .injections
        .iter()
        .filter_map(|i| i.healed_ms)
        .fold(f64::NEG_INFINITY, f64::max);
    let no_majority: Vec<f64> = outputs
        .no_majority
        .iter()
        .map(|n| n.at_ms)
        .filter(|at| in_window(*at))
        .collect();
    VoterFigures {
        accepted: accepted.len(),
        wrong: judging.voter(&accepted),
        no_majority: no_majority.len(),
        first_no_majority_after_ms: no_majority
            .iter()
            .find(|at| **at >= first_injection)
            .map(|at| at - first_injection),
        accepting_again_after_ms: accepted
            .iter()
            .find(|a| a.at_ms > last_heal)
            .map(|a| a.at_ms - last_heal),
        dissents_raised: outputs
            .dissents
            .iter()
            .filter(|d| d.raised && in_window(d.at_ms))
            .map(|d| format!("C{} at {:.2} s", d.id, d.at_ms / 1000.0))
            .collect(),
    }
}

/// How the life `injection` asked went out and came back.
fn out_and_back(recorded: &Recorded, injection: &Injection) -> OutAndBack {
    let from = injection.from_ms;
    let after = |at_ms: f64| at_ms - from;
    let life = recorded.lives.iter().find(|l| l.label() == injection.life);
    let next = recorded
        .lives
        .iter()
        .find(|l| l.id == injection.id && l.started_ms > from);
    let back = next.and_then(|next| {
        let label = next.label();
        recorded
            .observed
            .controller
            .iter()
            .filter(|e| e.life == label)
            .find_map(|e| {
                let status = e.line.status()?;
                let role = status.report.role?;
                (status.report.phase == rl_layer::core::Phase::Steady)
                    .then(|| (e.at_ms, label.clone(), role.name().to_string()))
            })
    });
    let decision = recorded.observed.outputs.odd_one_out_of(&injection.life);
    // A frame taken just before the asking may reach the controller after it: the slack.
    let fault_frames_from = from - GAP_SLACK_MS;
    let odd_counts = decision.filter(|d| !d.inputs_at_ms.is_empty()).map(|d| {
        let after = d
            .inputs_at_ms
            .iter()
            .filter(|at| **at >= fault_frames_from)
            .count();
        (after, d.inputs_at_ms.len() - after)
    });
    let dissents = &recorded.observed.outputs.dissents;
    let raised = dissents
        .iter()
        .find(|d| d.id == injection.id && d.raised && d.at_ms >= from);
    let cleared = raised.and_then(|raised| {
        dissents
            .iter()
            .find(|d| d.id == injection.id && !d.raised && d.at_ms > raised.at_ms)
    });
    OutAndBack {
        life: injection.life.clone(),
        decided_after_ms: decision.map(|o| after(o.at_ms)),
        mismatch_after_ms: recorded
            .observed
            .outputs
            .mismatch_of(&injection.life)
            .map(after),
        odd_after_fault: odd_counts.map(|(after, _)| after),
        odd_before_fault: odd_counts.map(|(_, before)| before),
        late: decision.and_then(|o| o.late),
        exited_after_ms: life.and_then(|l| l.ended_ms).map(after),
        exit: life.and_then(|l| l.exit.clone()),
        back_after_ms: back.as_ref().map(|(at, ..)| after(*at)),
        back_life: back.as_ref().map(|(_, life, _)| life.clone()),
        back_as: back.map(|(.., role)| role),
        dissent_raised_after_ms: raised.map(|d| after(d.at_ms)),
        dissent_cleared_after_ms: cleared.map(|d| after(d.at_ms)),
        odd_on: decision.and_then(|o| o.on.clone()),
        input_alarm_after_ms: recorded
            .observed
            .outputs
            .input_alarm_of(&injection.life)
            .map(after),
        law_alarm_after_ms: recorded
            .observed
            .outputs
            .law_alarm_of(&injection.life)
            .map(after),
    }
}

/// An error unless every life asked for wrong commands said on stderr (`(source, text)`)
/// that it took them: a PASS of a run whose controllers ignored the fault would say nothing.
pub fn require_acknowledged(
    injections: &[Injection],
    stderr: &[(String, String)],
    rl: &std::path::Path,
) -> Result<(), LabError> {
    let silent: Vec<&str> = injections
        .iter()
        .filter(|i| {
            !stderr
                .iter()
                .any(|(source, text)| *source == i.life && text.contains(i.wrong.acknowledgement()))
        })
        .map(|i| i.life.as_str())
        .collect();
    if silent.is_empty() {
        return Ok(());
    }
    Err(LabError::InjectionIgnored {
        rl: rl.to_path_buf(),
        lives: silent.join(", "),
    })
}

/// The report's figures for the run's summary, one line each.
pub fn summary(report: &OutputReport) -> String {
    let ms = |v: Option<f64>| v.map_or("never".into(), |v| format!("{v:.0} ms"));
    let mut text = format!(
        "  voting reader: {} accepted, {} wrong; no majority {} times (first {} after the fault); accepting again {} after the last heal; dissents raised: {}\n",
        report.voter.accepted,
        report.voter.wrong.samples,
        report.voter.no_majority,
        ms(report.voter.first_no_majority_after_ms),
        ms(report.voter.accepting_again_after_ms),
        if report.voter.dissents_raised.is_empty() {
            "none".into()
        } else {
            report.voter.dissents_raised.join(", ")
        },
    );
    for (reader, delivered, path) in [
        (
            "rl servo",
            Some(&report.servo),
            Some(&report.servo_owner_path),
        ),
        (
            "Connext",
            report.connext.as_ref(),
            report.connext_owner_path.as_ref(),
        ),
    ] {
        if let (Some(d), Some(path)) = (delivered, path) {
            text.push_str(&format!(
                "  {reader}: {} wrong samples ({} distinct commands) over {}; owners {}\n",
                d.samples,
                d.distinct,
                ms(d.span_ms()),
                path.join(" -> ")
            ));
        }
    }
    for o in &report.out_and_back {
        let exited_and_back = format!(
            "exited {} ({}), back {} ({} {})",
            ms(o.exited_after_ms),
            o.exit.as_deref().unwrap_or("running"),
            ms(o.back_after_ms),
            o.back_life.as_deref().unwrap_or("-"),
            o.back_as.as_deref().unwrap_or("-"),
        );
        // A lockstep pair's member leaves on its own compare: no cross-check, no dissent.
        if o.mismatch_after_ms.is_some() {
            text.push_str(&format!(
                "  {}: lockstep mismatch {} after the fault, {exited_and_back}\n",
                o.life,
                ms(o.mismatch_after_ms)
            ));
            continue;
        }
        text.push_str(&format!(
            "  {}: odd one out on {} {} after the fault ({} odd inputs after it, {} before, {} late), input alarm {}, law alarm {}, {exited_and_back}; dissent raised {}, cleared {}\n",
            o.life,
            o.odd_on.as_deref().unwrap_or("?"),
            ms(o.decided_after_ms),
            o.odd_after_fault.map_or("?".into(), |n| n.to_string()),
            o.odd_before_fault.map_or("?".into(), |n| n.to_string()),
            o.late.map_or("?".into(), |n| n.to_string()),
            ms(o.input_alarm_after_ms),
            ms(o.law_alarm_after_ms),
            ms(o.dissent_raised_after_ms),
            ms(o.dissent_cleared_after_ms),
        ));
    }
    text.push_str(&tracking::summary(&report.tracking));
    text
}

#[cfg(test)]
mod input_tests;
#[cfg(test)]
mod tests;
