//! What a run observed, on the lab clock: every controller life's JSON events (its network
//! alarm and conclusion lines apart, `super::network_alarms`), the servo's
//! accepted commands and owner changes, the Connext reader's samples, every stderr line, and
//! what the wrong-output judges read (`super::wrong_output::readings`: the voting reader, the
//! camera's frames, odd-one-out decisions).
//! Owners are named by controller life (`C1`, `C1#2`): a writer's participant (the first 12
//! bytes of its GUID) is one process, across the writers it re-creates at new strengths; which
//! controller it is comes from the servo (which learns it from heartbeats), which life from
//! the processes started with that id.

use super::clock::LabClock;
use super::network_alarms::{self, NapRecord};
use super::procs::{Life, Line};
use super::wrong_output::readings::{self, Readings};
use rl::procs::ServoEvent;
use rl_layer::event::EventLine;
use std::collections::BTreeMap;

/// A controller event on the lab clock.
#[derive(Clone, Debug)]
pub struct ControllerEvent {
    /// `C1#2`.
    pub life: String,
    pub at_ms: f64,
    pub line: EventLine,
}

/// A command the actuator accepted, or an owner change it reported, on the lab clock.
#[derive(Clone, Debug)]
pub struct ActuatorSample {
    pub at_ms: f64,
    pub participant: String,
    /// The writer's entity id (its GUID's last 8 hex digits): a controller's writers at
    /// different strengths differ here.
    pub writer_entity: String,
    /// The servo's own time (ms since it started), for exact gaps.
    pub own_ms: f64,
    /// The command's pan and tilt (0..=1000), where the reader printed them.
    pub pan_tilt: Option<(u16, u16)>,
}

/// Everything a run observed.
#[derive(Default)]
pub struct Observations {
    pub controller: Vec<ControllerEvent>,
    /// The controllers' network alarm and conclusion lines.
    pub network: Vec<NapRecord>,
    /// Each life's JSON lines as printed (the recording trace validation reads).
    pub controller_lines: BTreeMap<String, Vec<String>>,
    /// Accepted commands at `rl servo`.
    pub servo_commands: Vec<ActuatorSample>,
    /// Commands `rl servo` dropped as older than their writer's lifespan, with how late each
    /// came (ms).
    pub servo_expired: Vec<(ActuatorSample, i64)>,
    /// Samples at the Connext reader.
    pub connext: Vec<ActuatorSample>,
    /// The controller id of each participant, as the servo learned it.
    pub participant_ids: BTreeMap<String, u8>,
    /// stderr lines, `(source, text)`.
    pub stderr: Vec<(String, String)>,
    /// The voting reader, the camera's frames and odd-one-out decisions.
    pub outputs: Readings,
    /// The servo's clock origin on the lab clock (the smallest read time minus servo time).
    servo_origin_ms: Option<f64>,
}

/// The participant of a writer: its GUID's first 12 bytes (24 hex digits).
pub fn participant_of(guid_hex: &str) -> String {
    guid_hex.chars().take(24).collect()
}

/// The entity id of a writer: its GUID's last 4 bytes (8 hex digits).
pub fn entity_of(guid_hex: &str) -> String {
    guid_hex.chars().skip(24).collect()
}

impl Observations {
    /// Takes in one line; `lives` gives a controller life's clock error.
    pub fn ingest(&mut self, line: Line, clock: &LabClock, lives: &[Life]) {
        if let Some(source) = line.source.strip_suffix('!') {
            if source.starts_with('C') {
                self.outputs
                    .ingest_controller(source, &line, true, clock, lives);
            }
            self.stderr.push((source.to_string(), line.text));
            return;
        }
        match line.source.as_str() {
            "servo" => self.ingest_servo(&line),
            "connext" => self.ingest_connext(&line, clock),
            readings::VOTER => self.outputs.ingest_voter(&line, clock),
            readings::CAMERA => self.outputs.ingest_camera(&line),
            source if source.starts_with('C') => {
                self.outputs
                    .ingest_controller(source, &line, false, clock, lives);
                let Some(event) = EventLine::parse(&line.text) else {
                    return;
                };
                let offset_ms = lives
                    .iter()
                    .find(|l| l.label() == source)
                    .map_or(0.0, |l| l.round_clock_correction_ms(event.t_ms) as f64);
                if let Some(nap) = network_alarms::nap_event(&event.event) {
                    self.network.push(NapRecord {
                        life: source.to_string(),
                        id: event.id,
                        at_ms: clock.of_wall_ms(event.t_ms as f64 - offset_ms),
                        event: nap,
                    });
                    return;
                }
                self.controller.push(ControllerEvent {
                    life: source.to_string(),
                    at_ms: clock.of_wall_ms(event.t_ms as f64 - offset_ms),
                    line: event,
                });
                let lines = self.controller_lines.entry(source.to_string()).or_default();
                lines.push(line.text);
            }
            _ => {}
        }
    }

    fn ingest_servo(&mut self, line: &Line) {
        let Some(event) = rl::procs::parse_servo_event(&line.text) else {
            return;
        };
        let own_ms = event.t_ms() as f64;
        let origin = self
            .servo_origin_ms
            .map_or(line.at_ms - own_ms, |o| o.min(line.at_ms - own_ms));
        self.servo_origin_ms = Some(origin);
        if let ServoEvent::Expired {
            writer_guid,
            late_ms,
            ..
        } = &event
        {
            let sample = ActuatorSample {
                at_ms: origin + own_ms,
                participant: participant_of(writer_guid),
                writer_entity: entity_of(writer_guid),
                own_ms,
                pan_tilt: None,
            };
            self.servo_expired.push((sample, *late_ms));
        }
        if let ServoEvent::Command {
            writer_guid,
            controller_id,
            pan,
            tilt,
            ..
        } = event
        {
            let participant = participant_of(&writer_guid);
            let writer_entity = entity_of(&writer_guid);
            if let Some(id) = controller_id {
                self.participant_ids.insert(participant.clone(), id);
            }
            self.servo_commands.push(ActuatorSample {
                at_ms: origin + own_ms,
                participant,
                writer_entity,
                own_ms,
                pan_tilt: Some((pan, tilt)),
            });
        }
    }

    fn ingest_connext(&mut self, line: &Line, clock: &LabClock) {
        let Ok(value) = serde_json::from_str::<serde_json::Value>(&line.text) else {
            return;
        };
        if let (Some(t_ms), Some(guid)) = (reception_ms(&value), value["writer_guid"].as_str()) {
            self.connext.push(ActuatorSample {
                at_ms: clock.of_wall_ms(t_ms),
                participant: participant_of(guid),
                writer_entity: entity_of(guid),
                own_ms: t_ms,
                pan_tilt: pan_tilt(&value),
            });
        }
    }

    /// The controller life a participant is: the life of its controller id that ran when the
    /// actuator first heard it; `?` and the participant when its id is unknown.
    pub fn owner_name(&self, participant: &str, first_heard_ms: f64, lives: &[Life]) -> String {
        let Some(id) = self.participant_ids.get(participant) else {
            return format!("?{participant}");
        };
        lives
            .iter()
            .rfind(|l| l.id == *id && l.started_ms <= first_heard_ms)
            .map_or_else(|| format!("C{id}"), Life::label)
    }
}

/// An owner span at one actuator: from `from_ms` to `to_ms`, `owner` (a life's name).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct OwnerSpan {
    pub from_ms: f64,
    pub to_ms: f64,
    pub owner: String,
}

/// The owner spans of a sample sequence: a new span whenever the participant changes.
pub fn owner_spans(
    samples: &[ActuatorSample],
    name: impl Fn(&str, f64) -> String,
) -> Vec<OwnerSpan> {
    let mut spans: Vec<(OwnerSpan, String)> = Vec::new();
    for sample in samples {
        match spans.last_mut() {
            Some((span, participant)) if *participant == sample.participant => {
                span.to_ms = sample.at_ms
            }
            _ => spans.push((
                OwnerSpan {
                    from_ms: sample.at_ms,
                    to_ms: sample.at_ms,
                    owner: name(&sample.participant, sample.at_ms),
                },
                sample.participant.clone(),
            )),
        }
    }
    spans.into_iter().map(|(span, _)| span).collect()
}

/// The largest time without a sample in the judged window `from_ms..to_ms` (lab clock), with
/// when it ended: from the window's start to the first sample, between consecutive samples
/// (measured on the samples' own clock), and from the last sample to the window's end. A
/// reader that received nothing in the window went the whole window without a command; one
/// that stopped receiving went from its last sample to the end.
pub fn largest_gap(samples: &[ActuatorSample], from_ms: f64, to_ms: f64) -> (f64, f64) {
    let judged: Vec<&ActuatorSample> = samples
        .iter()
        .filter(|s| s.at_ms >= from_ms && s.at_ms <= to_ms)
        .collect();
    let (Some(first), Some(last)) = (judged.first(), judged.last()) else {
        return (to_ms - from_ms, to_ms);
    };
    let head = (first.at_ms - from_ms, first.at_ms);
    let tail = (to_ms - last.at_ms, to_ms);
    judged
        .windows(2)
        .map(|w| (w[1].own_ms - w[0].own_ms, w[1].at_ms))
        .chain([tail])
        .fold(
            head,
            |largest, gap| if gap.0 > largest.0 { gap } else { largest },
        )
}

/// A Connext sample's pan and tilt, when it printed both as servo positions.
fn pan_tilt(value: &serde_json::Value) -> Option<(u16, u16)> {
    let axis = |name: &str| value[name].as_u64().and_then(|v| u16::try_from(v).ok());
    Some((axis("pan")?, axis("tilt")?))
}

/// When the Connext reader received a sample: the reception time Connext recorded (`rx_ms`),
/// or, from a reader that does not print it, when the script handled it (`t_ms`, which adds
/// the Python process's scheduling, up to 10 ms on an idle machine).
fn reception_ms(value: &serde_json::Value) -> Option<f64> {
    value["rx_ms"].as_f64().or_else(|| value["t_ms"].as_f64())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(at_ms: f64, participant: &str) -> ActuatorSample {
        ActuatorSample {
            at_ms,
            participant: participant.into(),
            writer_entity: String::new(),
            own_ms: at_ms,
            pan_tilt: None,
        }
    }

    #[test]
    fn spans_change_with_the_participant() {
        let samples = [
            sample(0.0, "a"),
            sample(10.0, "a"),
            sample(20.0, "b"),
            sample(30.0, "a"),
        ];
        let spans = owner_spans(&samples, |p, _| p.to_uppercase());
        let owners: Vec<&str> = spans.iter().map(|s| s.owner.as_str()).collect();
        assert_eq!(owners, ["A", "B", "A"]);
        assert_eq!((spans[0].from_ms, spans[0].to_ms), (0.0, 10.0));
    }

    #[test]
    fn the_largest_gap_counts_from_the_judged_start() {
        let samples = [
            sample(0.0, "a"),
            sample(500.0, "a"),
            sample(600.0, "b"),
            sample(810.0, "b"),
        ];
        assert_eq!(largest_gap(&samples, 0.0, 820.0), (500.0, 500.0));
        assert_eq!(largest_gap(&samples, 400.0, 820.0), (210.0, 810.0));
        // From the window's start to the first sample in it.
        assert_eq!(largest_gap(&samples, 250.0, 820.0), (250.0, 500.0));
    }

    #[test]
    fn the_connext_reader_is_timed_by_its_reception_time() {
        let line = |text: &str| serde_json::from_str::<serde_json::Value>(text).unwrap();
        let both = line(r#"{"t_ms": 1000.9, "rx_ms": 1000.2, "writer_guid": "ab"}"#);
        assert_eq!(reception_ms(&both), Some(1000.2));
        let older = line(r#"{"t_ms": 1000.9, "writer_guid": "ab"}"#);
        assert_eq!(reception_ms(&older), Some(1000.9));
        assert_eq!(reception_ms(&line(r#"{"writer_guid": "ab"}"#)), None);
    }

    #[test]
    fn a_reader_that_stops_or_hears_nothing_has_a_gap_to_the_end() {
        let samples = [sample(0.0, "a"), sample(10.0, "a"), sample(20.0, "a")];
        // Silent from 20 ms to the end of the run at 3 s.
        assert_eq!(largest_gap(&samples, 0.0, 3_000.0), (2_980.0, 3_000.0));
        // Nothing at all in the window: the whole window.
        assert_eq!(largest_gap(&[], 1_000.0, 3_000.0), (2_000.0, 3_000.0));
        assert_eq!(largest_gap(&samples, 100.0, 3_000.0), (2_900.0, 3_000.0));
    }
}
