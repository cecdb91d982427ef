//! The lines the wrong-output judges read, on the lab clock: the voting reader's decisions
//! (`rl servo --vote --json`: `voted_command`, `dissent`, `no_majority`), the camera's frames
//! (`rl shapes --json`: where the ball was seen, how far off centre) and each controller life's
//! odd-one-out decision (its `odd_one_out` event, or the stderr line that says `odd one out`),
//! or, in a lockstep pair, its mismatch (the stderr line that says `lockstep mismatch`).
//! Kept apart from `super::super::observe`, which reads what every scenario reads.

use crate::lab::clock::LabClock;
use crate::lab::procs::{Life, Line};
use rl::procs::VotedServoEvent;
use rl::sim::shapes::CameraFrame;
use serde::Serialize;
use std::collections::BTreeSet;

/// The voting reader's helper name (its lines' source).
pub const VOTER: &str = "voter";
/// The camera's helper name.
pub const CAMERA: &str = "camera";

/// What a lockstep pair member logs when its two implementations disagree
/// (`rl::tracker::lockstep::Mismatch`, logged as it leaves the bus).
const LOCKSTEP_MISMATCH: &str = "lockstep mismatch";

/// The camera frames a steady voting reader has decided in a second, at least: half the
/// camera's rate, so a reader that heard only the first few frames is not yet steady.
const MIN_STEADY_FRAMES: usize = 15;

/// A command the voting reader accepted.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Accepted {
    pub at_ms: f64,
    /// The camera frame it answers (the frame's source timestamp, as DDS ticks).
    pub input: u64,
    /// When that frame was taken (lab ms).
    pub input_at_ms: f64,
    /// The controllers whose answers agreed.
    pub agreeing: Vec<u8>,
    pub pan: u16,
    pub tilt: u16,
}

/// A dissent alarm raised or cleared at the voting reader.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DissentChange {
    pub at_ms: f64,
    pub id: u8,
    pub raised: bool,
}

/// The voting reader found no two fresh controllers agreeing.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NoMajority {
    pub at_ms: f64,
    /// The controllers fresh at that moment.
    pub fresh: Vec<u8>,
    /// It held its last command (`false`: went to its safe command).
    pub hold: bool,
}

/// One camera frame: how far off centre the ball was (`None`: not in view).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Frame {
    pub at_ms: f64,
    pub error_px: Option<f64>,
}

/// A controller life's decision that it is the odd one out (it leaves).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OddOneOut {
    /// `C1`, `C1#2`.
    pub life: String,
    pub at_ms: f64,
    /// The inputs at which it was the odd one out, when its JSON event says.
    pub inputs: Vec<u64>,
    /// When those camera frames were taken (lab ms): the camera stamps each with its wall
    /// clock, which is the lab's.
    pub inputs_at_ms: Vec<f64>,
    /// N, when its JSON event says.
    pub odd_limit: Option<u64>,
    /// Its answers that went out before they could be judged at their next input (the
    /// timing assumption broken), when its JSON event says.
    pub late: Option<u64>,
    /// What it was odd on (`output`, `input`), when its JSON event says.
    pub on: Option<String>,
}

/// Everything the wrong-output judges read.
#[derive(Clone, Debug, Default)]
pub struct Readings {
    pub accepted: Vec<Accepted>,
    pub dissents: Vec<DissentChange>,
    pub no_majority: Vec<NoMajority>,
    pub frames: Vec<Frame>,
    pub odd_one_out: Vec<OddOneOut>,
    /// A lockstep pair member's mismatches between its two implementations (it leaves the
    /// bus at its first): the life and when its log line was read.
    pub mismatches: Vec<(String, f64)>,
    /// The `input_disagrees` alarms controller lives raised about themselves (input
    /// congruence): the life and when (its event's time).
    pub input_alarms: Vec<(String, f64)>,
    /// The `law_disagrees` alarms controller lives raised about themselves (raw answers).
    pub law_alarms: Vec<(String, f64)>,
    /// Each helper's clock origin on the lab clock: the smallest read time minus its own time
    /// (its lines carry milliseconds since it started).
    voter_origin_ms: Option<f64>,
    camera_origin_ms: Option<f64>,
}

/// A camera frame's tag as Unix ms: its DDS source timestamp as ticks, whole seconds in the
/// high 32 bits and the fraction in the low (RustDDS's `Timestamp::to_ticks`).
pub fn wall_ms_of_ticks(ticks: u64) -> f64 {
    let seconds = (ticks >> 32) as f64;
    let fraction = (ticks & 0xffff_ffff) as f64 / 4_294_967_296.0;
    (seconds + fraction) * 1000.0
}

/// The origin `origin` moved to a line read at `read_ms` that says `own_ms`: a line is read
/// after it was printed, never before, so the smallest difference is the truest.
fn earliest_origin(origin: &mut Option<f64>, read_ms: f64, own_ms: f64) -> f64 {
    let candidate = read_ms - own_ms;
    let origin = origin.get_or_insert(candidate);
    *origin = origin.min(candidate);
    *origin
}

impl Readings {
    /// A line of the voting reader.
    pub fn ingest_voter(&mut self, line: &Line, clock: &LabClock) {
        let Some(event) = rl::procs::parse_voted_servo_event(&line.text) else {
            return;
        };
        match event {
            VotedServoEvent::VotedCommand {
                t_ms,
                input,
                agreeing,
                pan,
                tilt,
                ..
            } => {
                let at_ms = earliest_origin(&mut self.voter_origin_ms, line.at_ms, t_ms as f64)
                    + t_ms as f64;
                self.accepted.push(Accepted {
                    at_ms,
                    input,
                    input_at_ms: clock.of_wall_ms(wall_ms_of_ticks(input)),
                    agreeing,
                    pan,
                    tilt,
                });
            }
            VotedServoEvent::Dissent {
                t_ms,
                controller_id,
                raised,
                ..
            } => {
                let at_ms = earliest_origin(&mut self.voter_origin_ms, line.at_ms, t_ms as f64)
                    + t_ms as f64;
                self.dissents.push(DissentChange {
                    at_ms,
                    id: controller_id,
                    raised,
                });
            }
            VotedServoEvent::NoMajority {
                t_ms,
                fresh,
                action,
                ..
            } => {
                let at_ms = earliest_origin(&mut self.voter_origin_ms, line.at_ms, t_ms as f64)
                    + t_ms as f64;
                self.no_majority.push(NoMajority {
                    at_ms,
                    fresh,
                    hold: action == rl::sim::servo::vote::NoMajorityAction::Hold,
                });
            }
        }
    }

    /// A line of the camera (`--json`: one per frame).
    pub fn ingest_camera(&mut self, line: &Line) {
        let Ok(frame) = serde_json::from_str::<CameraFrame>(&line.text) else {
            return;
        };
        let own_ms = frame.t_ms as f64;
        let at_ms = earliest_origin(&mut self.camera_origin_ms, line.at_ms, own_ms) + own_ms;
        self.frames.push(Frame {
            at_ms,
            error_px: frame.error_px,
        });
    }

    /// A line of controller life `life` (stdout: its JSON event; stderr: its log), kept when
    /// it says the life is the odd one out or found a lockstep mismatch. The JSON event's time is its own wall clock (the
    /// life's clock correction taken off, as every event's); a log line's is when it was read.
    pub fn ingest_controller(
        &mut self,
        life: &str,
        line: &Line,
        stderr: bool,
        clock: &LabClock,
        lives: &[Life],
    ) {
        if stderr {
            if line.text.contains(LOCKSTEP_MISMATCH) && !self.mismatches.iter().any(|m| m.0 == life)
            {
                self.mismatches.push((life.to_string(), line.at_ms));
            }
            if line.text.contains("odd one out") && !self.odd_one_out.iter().any(|o| o.life == life)
            {
                self.odd_one_out.push(OddOneOut {
                    life: life.to_string(),
                    at_ms: line.at_ms,
                    inputs: Vec::new(),
                    inputs_at_ms: Vec::new(),
                    odd_limit: None,
                    late: None,
                    on: None,
                });
            }
            return;
        }
        let Ok(value) = serde_json::from_str::<serde_json::Value>(&line.text) else {
            return;
        };
        let Some(t_ms) = value["t_ms"].as_u64() else {
            return;
        };
        let correction_ms = lives
            .iter()
            .find(|l| l.label() == life)
            .map_or(0.0, |l| l.round_clock_correction_ms(t_ms) as f64);
        let about_itself = value["about"].as_u64() == value["id"].as_u64();
        if value["event"] == "alarm" && value["raised"] == true && about_itself {
            let alarms = match value["reason"].as_str() {
                Some("input_disagrees") => Some(&mut self.input_alarms),
                Some("law_disagrees") => Some(&mut self.law_alarms),
                _ => None,
            };
            if let Some(alarms) = alarms.filter(|a| !a.iter().any(|(l, _)| l == life)) {
                let at_ms = clock.of_wall_ms(t_ms as f64 - correction_ms);
                alarms.push((life.to_string(), at_ms));
            }
        }
        if value["event"] != "odd_one_out" {
            return;
        }
        let inputs: Vec<u64> = value["inputs"]
            .as_array()
            .map(|inputs| inputs.iter().filter_map(|i| i.as_u64()).collect())
            .unwrap_or_default();
        let decision = OddOneOut {
            life: life.to_string(),
            at_ms: clock.of_wall_ms(t_ms as f64 - correction_ms),
            inputs_at_ms: inputs
                .iter()
                .map(|ticks| clock.of_wall_ms(wall_ms_of_ticks(*ticks)))
                .collect(),
            inputs,
            odd_limit: value["odd_limit"].as_u64(),
            late: value["late"].as_u64(),
            on: value["on"].as_str().map(String::from),
        };
        // The event, when there is one, says when it decided; the log line only when it was
        // read.
        self.odd_one_out.retain(|o| o.life != life);
        self.odd_one_out.push(decision);
    }

    /// Whether the voting reader has been steady for the second before `now_ms`: every camera
    /// frame it decided in that second, but the newest (its last answer may be on its way),
    /// agreed to by all `controllers` (three, two under the duplex and the pair) (over its acceptances of that frame: the whole rule
    /// grows one set; a broken reader of a mutation run, taking each answer alone, names one
    /// controller at a time), and no dissent alarm raised, cleared or up. Judging
    /// starts only then: a controller that began tracking a frame after the others is a frame
    /// out of step until it aligns, and the reader may name it for that at formation.
    pub fn voter_steady(&self, now_ms: f64, controllers: usize) -> bool {
        let recent = |at_ms: f64| at_ms >= now_ms - 1000.0;
        let mut agreeing_by_input: std::collections::BTreeMap<u64, BTreeSet<u8>> =
            Default::default();
        for a in self.accepted.iter().filter(|a| recent(a.at_ms)) {
            let agreeing = agreeing_by_input.entry(a.input).or_default();
            agreeing.extend(a.agreeing.iter().copied());
        }
        agreeing_by_input.pop_last();
        let all_agree = agreeing_by_input.len() >= MIN_STEADY_FRAMES
            && agreeing_by_input
                .values()
                .all(|ids| ids.len() == controllers);
        let changing = self.dissents.iter().any(|d| recent(d.at_ms));
        let mut up = std::collections::BTreeSet::new();
        for change in &self.dissents {
            if change.raised {
                up.insert(change.id);
            } else {
                up.remove(&change.id);
            }
        }
        all_agree && !changing && up.is_empty()
    }

    /// When life `life` logged a lockstep mismatch, if it did.
    pub fn mismatch_of(&self, life: &str) -> Option<f64> {
        self.mismatches.iter().find(|m| m.0 == life).map(|m| m.1)
    }

    /// When life `life` raised its `input_disagrees` alarm about itself, if it did.
    pub fn input_alarm_of(&self, life: &str) -> Option<f64> {
        self.input_alarms.iter().find(|a| a.0 == life).map(|a| a.1)
    }

    /// When life `life` raised its `law_disagrees` alarm about itself, if it did.
    pub fn law_alarm_of(&self, life: &str) -> Option<f64> {
        self.law_alarms.iter().find(|a| a.0 == life).map(|a| a.1)
    }

    /// When life `life` decided it was the odd one out, if it did.
    pub fn odd_one_out_of(&self, life: &str) -> Option<&OddOneOut> {
        self.odd_one_out.iter().find(|o| o.life == life)
    }
}
