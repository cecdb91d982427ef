//! Recorded runs: the JSON event lines `rl controller --json-events` prints, grouped into the
//! lives of the controllers, and what each life reported of itself at every round boundary.
//!
//! A recording is what `rl demo --record DIR` and the DDS-level replay leave behind: one log
//! per process (`C1.log`, `C3#1.log`, ...) whose controller events are `started`, `status`,
//! `output`, `vote`, `alarm`, `leds`, `stopped`, `heartbeat_late` (and `heartbeat_dropped` from a
//! fault-injection build), each with `t_ms` (the controller's round
//! clock: wall-clock milliseconds, rounds are multiples of the heartbeat period), `id` and
//! `incarnation` (docs/architecture.md). Other lines (servo and camera events, log text, and
//! a fault-injection build's `held` lines, printed before the process has a life) are
//! skipped. Both the DDS-level replay and trace validation read a controller's state from here,
//! so they agree on what was observed.
//!
//! What a life reports: a `status` event whenever its phase, role, strength, agreed result,
//! vote or membership (peers alive and not FAILED) changes, and an `alarm` event whenever an
//! alarm is raised or cleared. The state at a boundary is therefore the last status at or
//! before it with the later alarm events applied. One change is not reported: a peer already
//! marked FAILED that is then lost leaves the membership unchanged, so `sees` and `failed`
//! of the last status may still name it (trace validation allows exactly that).

use rl_layer::core::{ControllerId, Incarnation, Status};
use rl_layer::event::{Event, EventLine};
use std::collections::BTreeMap;
use std::path::Path;

/// The round a controller-clock time falls in: round `r` spans `[r * period, (r + 1) * period)`.
pub fn round_of(t_ms: u64, period_ms: u64) -> u64 {
    t_ms / period_ms.max(1)
}

/// What a controller reports before its first status event: it starts initializing, knowing
/// nobody (the core's initial state).
pub fn initial_status(id: ControllerId, incarnation: Incarnation) -> Status {
    Status::initial(id, incarnation)
}

/// One process's events, in the order it printed them.
#[derive(Clone, Debug)]
pub struct LifeLog {
    pub id: ControllerId,
    pub incarnation: Incarnation,
    /// Where the events came from (`C1.log`), for messages.
    pub source: String,
    pub events: Vec<EventLine>,
}

impl LifeLog {
    /// When it started: its `started` event, else its first event.
    pub fn started_ms(&self) -> Option<u64> {
        self.events
            .iter()
            .find(|e| e.event == Event::Started)
            .or(self.events.first())
            .map(|e| e.t_ms)
    }

    /// When it last printed anything (it was alive then).
    pub fn last_event_ms(&self) -> Option<u64> {
        self.events.iter().map(|e| e.t_ms).max()
    }

    /// When it stopped cleanly (its `stopped` event), if it did.
    pub fn stopped_ms(&self) -> Option<u64> {
        self.events
            .iter()
            .find(|e| matches!(e.event, Event::Stopped { .. }))
            .map(|e| e.t_ms)
    }

    /// What it reported of itself after every event stamped before `until_ms`: the last
    /// status, with the alarm events after it applied.
    pub fn status_before(&self, until_ms: u64) -> Status {
        let mut status = initial_status(self.id, self.incarnation);
        for event in self.events.iter().filter(|e| e.t_ms < until_ms) {
            apply_event(&mut status, event);
        }
        status
    }

    /// What it reported at the boundary that starts round `round`: every event stamped in an
    /// earlier round or in this one (decisions are taken, and reported, at the boundary).
    pub fn status_at_boundary(&self, round: u64, period_ms: u64) -> Status {
        self.status_before((round + 1) * period_ms.max(1))
    }
}

/// Folds one event into the reported state.
pub fn apply_event(status: &mut Status, event: &EventLine) {
    match &event.event {
        Event::Status { status: reported } => *status = (**reported).clone(),
        Event::Alarm {
            about,
            reason,
            raised,
        } => {
            status.alarms.retain(|(who, _)| who != about);
            if *raised {
                status.alarms.push((*about, *reason));
            }
        }
        _ => {}
    }
}

/// Every life of a recorded run, grouped by controller id, each id's lives in start order.
#[derive(Clone, Debug, Default)]
pub struct Recording {
    pub lives: BTreeMap<ControllerId, Vec<LifeLog>>,
    /// Lines that were not controller events (servo, camera, log text), for the summary.
    pub skipped_lines: usize,
}

/// A recording that cannot be read.
pub type RecordError = crate::trace::FileError;

impl Recording {
    /// Reads every file of a recording directory (`*.log`, `*.jsonl`), in name order.
    pub fn read_dir(dir: &Path) -> Result<Recording, RecordError> {
        let error = |message: String| RecordError {
            path: dir.to_path_buf(),
            line: None,
            message,
        };
        let mut paths = Vec::new();
        for entry in std::fs::read_dir(dir).map_err(|e| error(e.to_string()))? {
            let path = entry.map_err(|e| error(e.to_string()))?.path();
            let readable = path
                .extension()
                .is_some_and(|ext| ext == "log" || ext == "jsonl");
            if path.is_file() && readable {
                paths.push(path);
            }
        }
        paths.sort();
        let mut recording = Recording::default();
        for path in &paths {
            let text = std::fs::read_to_string(path).map_err(|e| RecordError {
                path: path.clone(),
                line: None,
                message: e.to_string(),
            })?;
            let source = path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            recording
                .add_lines(&source, text.lines())
                .map_err(|(line, message)| RecordError {
                    path: path.clone(),
                    line: Some(line),
                    message,
                })?;
        }
        recording.finish();
        if recording.lives.is_empty() {
            return Err(error(format!(
                "no controller events in {} file(s) (*.log, *.jsonl)",
                paths.len()
            )));
        }
        Ok(recording)
    }

    /// Builds a recording from lines already in memory, `(source, line)`; an error names the
    /// source as its path.
    pub fn from_lines<'a>(
        lines: impl IntoIterator<Item = (&'a str, &'a str)>,
    ) -> Result<Recording, RecordError> {
        let mut recording = Recording::default();
        for (source, line) in lines {
            recording
                .add_lines(source, std::iter::once(line))
                .map_err(|(_, message)| RecordError {
                    path: source.into(),
                    line: None,
                    message,
                })?;
        }
        recording.finish();
        Ok(recording)
    }

    /// Takes in the lines of one source; a line that looks like a controller event but does
    /// not parse is an error `(1-based line, message)`.
    fn add_lines<'a>(
        &mut self,
        source: &str,
        lines: impl Iterator<Item = &'a str>,
    ) -> Result<(), (usize, String)> {
        for (index, line) in lines.enumerate() {
            let Ok(serde_json::Value::Object(object)) =
                serde_json::from_str::<serde_json::Value>(line)
            else {
                self.skipped_lines += 1;
                continue;
            };
            let is_controller_event = ["event", "id", "incarnation", "t_ms"]
                .iter()
                .all(|key| object.contains_key(*key));
            if !is_controller_event {
                self.skipped_lines += 1;
                continue;
            }
            let event: EventLine = serde_json::from_value(serde_json::Value::Object(object))
                .map_err(|e| {
                    (
                        index + 1,
                        format!("a controller event that does not parse: {e}"),
                    )
                })?;
            // Held before it votes (the DDS-level replay's start): not yet a life.
            if matches!(event.event, Event::Held { .. }) {
                self.skipped_lines += 1;
                continue;
            }
            let lives = self.lives.entry(event.id).or_default();
            match lives
                .iter_mut()
                .find(|life| life.incarnation == event.incarnation)
            {
                Some(life) => life.events.push(event),
                None => lives.push(LifeLog {
                    id: event.id,
                    incarnation: event.incarnation,
                    source: source.to_string(),
                    events: vec![event],
                }),
            }
        }
        Ok(())
    }

    /// Orders each life's events by time (stable: a process prints in order) and each id's
    /// lives by start.
    fn finish(&mut self) {
        for lives in self.lives.values_mut() {
            for life in lives.iter_mut() {
                life.events.sort_by_key(|e| e.t_ms);
            }
            lives.sort_by_key(|life| (life.started_ms(), life.incarnation));
        }
    }

    /// The model's number of every life: 0, 1, 2, ... per id in start order.
    pub fn incarnation_numbers(&self) -> crate::abstraction::IncarnationNumbers {
        let mut numbers = crate::abstraction::IncarnationNumbers::new();
        for (id, lives) in &self.lives {
            for life in lives {
                numbers.started(*id, life.incarnation);
            }
        }
        numbers
    }

    /// The highest controller id recorded.
    pub fn max_id(&self) -> ControllerId {
        self.lives.keys().copied().max().unwrap_or(0)
    }

    /// Every event of every life, by time: `(life's source, event)`.
    pub fn events_by_time(&self) -> Vec<(&str, &EventLine)> {
        let mut all: Vec<(&str, &EventLine)> = self
            .lives
            .values()
            .flatten()
            .flat_map(|life| life.events.iter().map(move |e| (life.source.as_str(), e)))
            .collect();
        all.sort_by_key(|(_, e)| (e.t_ms, e.id));
        all
    }
}

/// One event as a short line for transcripts: `C2#1 status steady secondary 20 ...`.
pub fn describe_event(event: &EventLine, number: Option<u8>) -> String {
    let who = match number {
        Some(n) if n > 0 => format!("C{}#{n}", event.id),
        _ => format!("C{}", event.id),
    };
    let detail = match &event.event {
        Event::Status { status: s } => {
            let holders = |a: Option<rl_layer::core::Assignment>| {
                a.map_or("-".to_string(), |a| {
                    a.holders()
                        .map(|h| h.id.to_string())
                        .collect::<Vec<_>>()
                        .join(",")
                })
            };
            format!(
                "{} {} {} agreed[{}] vote[{}] sees{:?} failed{:?}",
                s.report.phase.name(),
                s.report.role.map_or("no-role", |r| r.name()),
                s.report
                    .strength
                    .map_or("silent".to_string(), |v| v.to_string()),
                holders(s.report.agreed),
                holders(s.report.vote),
                s.sees,
                s.failed
            )
        }
        Event::Alarm {
            about,
            reason,
            raised,
        } => format!("about C{about} {reason:?} raised={raised}"),
        Event::Output { role, strength } => format!(
            "{} {}",
            role.map_or("no-role", |r| r.name()),
            strength.map_or("silent".to_string(), |v| v.to_string())
        ),
        Event::HeartbeatDropped { from } => format!("from C{from}"),
        Event::HeartbeatLate { from, waited_ms } => {
            format!("from C{from}, waited {waited_ms} ms")
        }
        Event::RoundEndsMissed { rounds } => format!("one round end for {rounds} more missed"),
        Event::Resumed { stalled_ms } => format!("after a {stalled_ms} ms stall"),
        Event::Held {
            heartbeat_writers,
            heartbeat_readers,
        } => format!(
            "held; discovered {heartbeat_writers} heartbeat writer(s), \
             {heartbeat_readers} reader(s) of others"
        ),
        Event::Detached => "every link without a carrier".to_string(),
        Event::Deposed => "a peer took over from its late commands".to_string(),
        _ => String::new(),
    };
    format!("{who} {} {detail}", event.event.kind())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(t_ms: u64, id: u8, incarnation: u64, rest: &str) -> String {
        format!(r#"{{"t_ms":{t_ms},"id":{id},"incarnation":{incarnation},{rest}}}"#)
    }

    #[test]
    fn lives_are_grouped_and_numbered_in_start_order() {
        let lines = [
            line(1000, 2, 77, r#""event":"started""#),
            line(900, 2, 99, r#""event":"started""#),
            "not json".to_string(),
            r#"{"event":"command","t_ms":5}"#.to_string(),
            line(
                1250,
                2,
                77,
                r#""event":"alarm","about":1,"reason":"lost","raised":true"#,
            ),
        ];
        let recording =
            Recording::from_lines(lines.iter().map(|l| ("C2.log", l.as_str()))).expect("parses");
        let lives = &recording.lives[&2];
        assert_eq!(lives.len(), 2);
        assert_eq!(lives[0].incarnation, 99, "started first");
        assert_eq!(recording.skipped_lines, 2);
        let numbers = recording.incarnation_numbers();
        assert_eq!(numbers.number(2, 99), Some(0));
        assert_eq!(numbers.number(2, 77), Some(1));
        let status = lives[1].status_at_boundary(5, 250);
        assert_eq!(status.alarms, vec![(1, rl_layer::core::AlarmReason::Lost)]);
        assert_eq!(status.report.phase, rl_layer::core::Phase::Initializing);
        assert!(lives[1].status_at_boundary(4, 250).alarms.is_empty());
    }

    #[test]
    fn a_broken_controller_event_is_an_error() {
        let bad = line(
            1000,
            2,
            77,
            r#""event":"status","status":{"phase":"dancing"}"#,
        );
        let error = Recording::from_lines([("C2.log", bad.as_str())]).expect_err("bad status");
        assert!(error.message.contains("does not parse"), "{error}");
        assert_eq!(error.to_string().split(':').next(), Some("C2.log"));
    }
}
