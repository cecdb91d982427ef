//! `rl servo --vote`: the actuator simulator as a voting receiver. It reads the voted command
//! topic (`dds.voted_command_topic`, every controller's own answer to each camera frame)
//! through the library's vote (rl_layer::vote_feed, rl_layer::vote_reader: a command is taken
//! only when two fresh controllers agree, per axis within `--vote-tolerance`, as the median of
//! the agreeing; a dissenting controller is alarmed; without a majority it holds or goes to
//! `--vote-safe`), and reports what the vote decides.
//!
//! With `--json`, one JSON object per line on stdout, flushed per line (a stable interface,
//! docs/architecture.md; fields may be added, never removed or renamed):
//! ```text
//! {"event":"voted_command","t_ms":1234,"input":…,"agreeing":[1,2,3],"pan":500,"tilt":480,"frequency":60}
//! {"event":"dissent","t_ms":1300,"controller_id":1,"raised":true,"input":…,"pan":800,"tilt":480,"frequency":60}
//! {"event":"no_majority","t_ms":1400,"input":null,"fresh":[2],"action":"hold","pan":500,"tilt":480,"frequency":60}
//! ```

use super::Output;
use crate::Error;
use rl_layer::core::types::ControllerId;
use rl_layer::dds::{mio, Session};
use rl_layer::vote_feed::VoteFeed;
use rl_layer::vote_reader::{Fallback, ServoRule, VoteEvent, VoteSettings};
use rl_layer::wire::ServoControl;
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// What the receiver does without a majority, in the JSON line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoMajorityAction {
    /// It keeps the last accepted command.
    Hold,
    /// It goes to the safe command (`--vote-safe`).
    Safe,
}

/// One line of `rl servo --vote --json` (the documented interface; tools parse it with this
/// type).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum VotedServoEvent {
    /// A command the vote accepted: the median of the agreeing controllers' answers to
    /// `input` (again when a late answer joins them).
    VotedCommand {
        t_ms: u64,
        input: u64,
        agreeing: Vec<ControllerId>,
        pan: u16,
        tilt: u16,
        frequency: u16,
    },
    /// The dissent alarm about `controller_id` raised or cleared, with its answer to `input`.
    Dissent {
        t_ms: u64,
        controller_id: ControllerId,
        raised: bool,
        input: u64,
        pan: u16,
        tilt: u16,
        frequency: u16,
    },
    /// No two fresh controllers agree: the servo holds or goes to the safe command (the
    /// command it keeps; `null` when holding before any was accepted).
    NoMajority {
        t_ms: u64,
        input: Option<u64>,
        fresh: Vec<ControllerId>,
        action: NoMajorityAction,
        pan: Option<u16>,
        tilt: Option<u16>,
        frequency: Option<u16>,
    },
}

impl VotedServoEvent {
    /// The line of one decision of the vote at `t_ms`.
    pub fn of(event: VoteEvent<ServoControl>, t_ms: u64) -> VotedServoEvent {
        match event {
            VoteEvent::Accepted {
                input,
                value,
                agreeing,
            } => VotedServoEvent::VotedCommand {
                t_ms,
                input,
                agreeing,
                pan: value.pan,
                tilt: value.tilt,
                frequency: value.frequency,
            },
            VoteEvent::Dissent {
                source,
                raised,
                input,
                value,
            } => VotedServoEvent::Dissent {
                t_ms,
                controller_id: source,
                raised,
                input,
                pan: value.pan,
                tilt: value.tilt,
                frequency: value.frequency,
            },
            VoteEvent::NoMajority {
                input,
                fresh,
                fallback,
                value,
            } => VotedServoEvent::NoMajority {
                t_ms,
                input,
                fresh,
                action: match fallback {
                    Fallback::Hold => NoMajorityAction::Hold,
                    Fallback::Safe(_) => NoMajorityAction::Safe,
                },
                pan: value.map(|v| v.pan),
                tilt: value.map(|v| v.tilt),
                frequency: value.map(|v| v.frequency),
            },
        }
    }

    /// The line for a person.
    pub fn describe(&self) -> String {
        match self {
            VotedServoEvent::VotedCommand { .. } => String::new(),
            VotedServoEvent::Dissent {
                t_ms,
                controller_id,
                raised: true,
                pan,
                tilt,
                ..
            } => format!(
                "servo: {t_ms} ms: controller {controller_id} dissents (pan {pan} tilt {tilt}): its commands are refused"
            ),
            VotedServoEvent::Dissent {
                t_ms,
                controller_id,
                ..
            } => format!("servo: {t_ms} ms: controller {controller_id} agrees again"),
            VotedServoEvent::NoMajority {
                t_ms, fresh, action, ..
            } => format!(
                "servo: {t_ms} ms: no two controllers agree (fresh: {fresh:?}): {}",
                match action {
                    NoMajorityAction::Hold => "holding the last command",
                    NoMajorityAction::Safe => "going to the safe command",
                }
            ),
        }
    }
}

/// How the servo votes (from its command line).
pub(super) struct VoteOptions {
    /// Largest difference per axis that agrees.
    pub tolerance: u16,
    /// Dissents that raise a dissent alarm, agreements in a row that clear it.
    pub dissent_after: u32,
    /// The safe command without a majority (`None`: hold).
    pub safe: Option<ServoControl>,
}

/// Poll timeout: the vote is re-taken at least this often, so a lapsed majority is reported
/// within about a millisecond of its deadline.
const POLL_TIMEOUT_MS: u64 = 1;

/// Runs the voting servo until `stop` or `duration_ms`.
pub(super) fn run(
    session: &Session,
    options: VoteOptions,
    output: &Output,
    stop: &AtomicBool,
    duration_ms: Option<u64>,
) -> Result<(), Error> {
    let deadline_ms = session.timing().command_deadline_ms;
    let rule = ServoRule {
        pan_tolerance: options.tolerance,
        tilt_tolerance: options.tolerance,
    };
    let settings = VoteSettings {
        freshness_ms: deadline_ms,
        dissent_after: options.dissent_after,
        fallback: options.safe.map_or(Fallback::Hold, Fallback::Safe),
    };
    let feed = VoteFeed::servo_commands(session, rule, settings).map_err(Error::dds)?;
    let mut feed = crate::sim::vote_mutated(feed)?;
    let poll = mio::Poll::new().map_err(|e| Error::io("creating a poll", e))?;
    for (token, reader) in feed.readers().into_iter().enumerate() {
        poll.register(
            reader,
            mio::Token(token),
            mio::Ready::readable(),
            mio::PollOpt::edge(),
        )
        .map_err(|e| Error::io("registering a DDS reader", e))?;
    }
    if !output.json {
        output.line(&format!(
            "servo: voting on {} (two controllers must agree within {} per axis; freshness {deadline_ms} ms)",
            session.config().voted_topic_name(),
            options.tolerance
        ))?;
    }
    let mut events = mio::Events::with_capacity(16);
    let start = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        let now_ms = u64::try_from(start.elapsed().as_millis()).unwrap_or(u64::MAX);
        if duration_ms.is_some_and(|limit| now_ms >= limit) {
            break;
        }
        match poll.poll(&mut events, Some(Duration::from_millis(POLL_TIMEOUT_MS))) {
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(Error::io("waiting for DDS", e)),
        }
        for decision in feed.take(now_ms) {
            if !report(output, VotedServoEvent::of(decision, now_ms))? {
                return Ok(());
            }
        }
    }
    Ok(())
}

/// Prints one decision; `Ok(false)` when stdout is gone.
fn report(output: &Output, event: VotedServoEvent) -> Result<bool, Error> {
    if output.json {
        let text = serde_json::to_string(&event)
            .map_err(|e| Error::runtime(format!("encoding a servo event: {e}")))?;
        return output.line(&text);
    }
    match event.describe() {
        line if line.is_empty() => Ok(true),
        line => output.line(&line),
    }
}

/// Parses `--vote-safe PAN,TILT`.
pub fn parse_safe_position(text: &str) -> Result<(u16, u16), SafePositionError> {
    let error = || SafePositionError(text.to_string());
    let (pan, tilt) = text.split_once(',').ok_or_else(error)?;
    let axis = |value: &str| {
        value
            .trim()
            .parse::<u16>()
            .ok()
            .filter(|v| *v <= 1000)
            .ok_or_else(error)
    };
    Ok((axis(pan)?, axis(tilt)?))
}

/// A `--vote-safe` that is not two servo positions.
#[derive(Debug, thiserror::Error)]
#[error("expected PAN,TILT, each 0..=1000, got {0:?}")]
pub struct SafePositionError(String);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn voted_lines_have_the_documented_shape() {
        let accepted = VoteEvent::Accepted {
            input: 9,
            value: ServoControl {
                pan: 500,
                tilt: 480,
                frequency: 60,
            },
            agreeing: vec![1, 2],
        };
        assert_eq!(
            serde_json::to_string(&VotedServoEvent::of(accepted, 12)).unwrap(),
            r#"{"event":"voted_command","t_ms":12,"input":9,"agreeing":[1,2],"pan":500,"tilt":480,"frequency":60}"#
        );
        let lost = VoteEvent::NoMajority {
            input: None,
            fresh: vec![2],
            fallback: Fallback::Hold,
            value: None,
        };
        assert_eq!(
            serde_json::to_string(&VotedServoEvent::of(lost, 13)).unwrap(),
            r#"{"event":"no_majority","t_ms":13,"input":null,"fresh":[2],"action":"hold","pan":null,"tilt":null,"frequency":null}"#
        );
    }

    #[test]
    fn a_safe_position_is_two_servo_positions() {
        assert_eq!(parse_safe_position("500, 1000").unwrap(), (500, 1000));
        assert!(parse_safe_position("500").is_err());
        assert!(parse_safe_position("500,1001").is_err());
    }
}
