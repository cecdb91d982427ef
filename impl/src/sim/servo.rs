//! `rl servo`: the actuator simulator. It reads the command topic (`pixy/servo_control`) the
//! way the camera's gimbal does, as an EXCLUSIVE-ownership reader, through the layer's one
//! actuator view ([`OwnerFeed`]: the writer trust, each writer's strength from discovery, the
//! arbiter with the command deadline from the configuration, the controller behind each
//! writer from the heartbeats), and reports every sample's fate.
//!
//! Output: by default one human line per ownership change and a summary every few seconds.
//! With `--json`, exactly one JSON object per line on stdout, flushed per line; fields may be
//! added later, never removed or renamed:
//! ```text
//! {"event":"command","t_ms":1234,"writer_guid":"<32 hex>","controller_id":1,"strength":30,
//!  "pan":500,"tilt":480,"frequency":60}
//! {"event":"owner_changed","t_ms":1300,"from_controller_id":1,"to_controller_id":2,
//!  "gap_ms":108,"from_writer_guid":"<32 hex>","to_writer_guid":"<32 hex>","strength":20}
//! {"event":"expired","t_ms":1310,"writer_guid":"<32 hex>","controller_id":1,"late_ms":290,
//!  "lifespan_ms":100}
//! ```
//! A command's `late_ms` is how much later it arrived than its writer's best delay of the last
//! 2 s (`null`: unstamped); a sample later than its writer's lifespan is `expired` and never
//! reaches the arbiter (crate's `owner_feed`: LIFESPAN on the reading side).
//! `t_ms` is milliseconds since the servo started. A `command` line is printed per accepted
//! command; an `owner_changed` line comes just before the first command of a new owner.
//! `controller_id` is `null` while the writer's controller is unknown (no heartbeat heard
//! from its participant yet). At the first owner `from_*` and `gap_ms` are `null`; otherwise
//! `gap_ms` is the time since the previous owner's last accepted command.
//!
//! `--vote` follows the voted command topic instead, as a voting receiver (`vote.rs`: its lines
//! are `voted_command`, `dissent` and `no_majority`).

use crate::Error;
use rl_layer::core::types::{ControllerId, Strength};
use rl_layer::dds::{guid_hex, mio, Session, GUID};
use rl_layer::owner_feed::{Delivery, OwnerFeed};
use rl_layer::trust::CommandTrust;
use rl_layer::wire::ServoControl;
use serde::Serialize;
use std::collections::BTreeSet;
use std::io::{self, Write};
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

pub mod vote;

/// The actuator simulator: an exclusive-ownership reader of the command topic.
#[derive(Clone, Debug, clap::Args)]
pub struct ServoArgs {
    /// Print one JSON object per line (events `command` and `owner_changed`) instead of
    /// human-readable lines.
    #[arg(long)]
    pub json: bool,
    /// Configuration file (rl.toml) for the domain, topic names and command deadline.
    #[arg(long, value_name = "PATH")]
    pub config: Option<PathBuf>,
    /// DDS domain id (overrides the configuration).
    #[arg(long, value_name = "D")]
    pub domain: Option<u16>,
    /// Take commands from any writer, as plain DDS exclusive ownership does. By default only
    /// a controller's writers are obeyed (its participant sends that controller's heartbeats)
    /// and none above the takeover strength (35, a Secondary taking over from a late Primary):
    /// a stray writer at strength 100 cannot take the servo.
    #[arg(long)]
    pub any_writer: bool,
    /// Exit after this many milliseconds (default: run until SIGINT/SIGTERM).
    #[arg(long, value_name = "MS")]
    pub duration_ms: Option<u64>,
    /// Follow the voted command topic (`dds.voted_command_topic`) instead: a command is taken
    /// only when two controllers agree on it, a dissenting controller is alarmed, and without
    /// a majority the servo holds (or goes to `--vote-safe`). With `--json` the lines are
    /// `voted_command`, `dissent` and `no_majority` (docs/architecture.md).
    #[arg(long)]
    pub vote: bool,
    /// With `--vote`: the largest difference per axis (servo units, 0..=1000) at which two
    /// controllers' commands agree.
    #[arg(long, value_name = "N", default_value_t = rl_layer::vote_reader::SERVO_TOLERANCE_DEFAULT, requires = "vote")]
    pub vote_tolerance: u16,
    /// With `--vote`: a controller's dissents (camera frames, in a row or not) that raise its
    /// dissent alarm, and its agreements in a row that clear it.
    #[arg(long, value_name = "N", default_value_t = rl_layer::vote_reader::DISSENT_AFTER_DEFAULT, requires = "vote")]
    pub dissent_after: u32,
    /// With `--vote`: without a majority go to this command (`PAN,TILT`) instead of holding the
    /// last accepted one.
    #[arg(long, value_name = "PAN,TILT", value_parser = vote::parse_safe_position, requires = "vote")]
    pub vote_safe: Option<(u16, u16)>,
}

/// One line of `--json` output (the documented interface; tools parse it with this type).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum ServoEvent {
    Command {
        t_ms: u64,
        writer_guid: String,
        controller_id: Option<ControllerId>,
        strength: Strength,
        pan: u16,
        tilt: u16,
        frequency: u16,
        /// Absent in lines of earlier versions.
        #[serde(default)]
        late_ms: Option<i64>,
    },
    Expired {
        t_ms: u64,
        writer_guid: String,
        controller_id: Option<ControllerId>,
        late_ms: i64,
        lifespan_ms: u64,
    },
    OwnerChanged {
        t_ms: u64,
        from_controller_id: Option<ControllerId>,
        to_controller_id: Option<ControllerId>,
        gap_ms: Option<u64>,
        from_writer_guid: Option<String>,
        to_writer_guid: String,
        strength: Strength,
    },
}

impl ServoEvent {
    /// Milliseconds since the servo started, when the line was printed.
    pub fn t_ms(&self) -> u64 {
        match self {
            ServoEvent::Command { t_ms, .. }
            | ServoEvent::Expired { t_ms, .. }
            | ServoEvent::OwnerChanged { t_ms, .. } => *t_ms,
        }
    }
}

/// Poll timeout: bounds how late a sample, a stop request or the end of `--duration-ms` is
/// noticed. RustDDS's readiness events for unkeyed readers do not reliably wake the poll
/// (measured: command times quantized to this timeout), so the servo also wakes every
/// millisecond; its times, and the gaps it reports, are then accurate to about 1 ms.
const POLL_TIMEOUT_MS: u64 = 1;
/// Period of the human-readable summary line.
const SUMMARY_PERIOD_MS: u64 = 5_000;

const COMMANDS: mio::Token = mio::Token(0);
const HEARTBEATS: mio::Token = mio::Token(1);

fn dds_error(error: rl_layer::dds::DdsError) -> Error {
    Error::dds(error)
}

/// Writes lines to stdout, flushing each; a closed pipe ends the run quietly.
struct Output {
    json: bool,
}

impl Output {
    /// `Ok(false)` when stdout is gone (the consumer exited).
    fn line(&self, text: &str) -> Result<bool, Error> {
        let mut stdout = io::stdout().lock();
        match writeln!(stdout, "{text}").and_then(|()| stdout.flush()) {
            Ok(()) => Ok(true),
            Err(e) if e.kind() == io::ErrorKind::BrokenPipe => Ok(false),
            Err(e) => Err(Error::io("writing to stdout", e)),
        }
    }

    fn event(&self, event: &ServoEvent) -> Result<bool, Error> {
        let text = serde_json::to_string(event)
            .map_err(|e| Error::runtime(format!("encoding a servo event: {e}")))?;
        self.line(&text)
    }
}

/// Runs the servo simulator until SIGINT/SIGTERM or `--duration-ms`.
pub fn run(args: ServoArgs) -> Result<(), Error> {
    let config = crate::cli::load_config(args.config.as_deref(), args.domain)?;
    let stop = crate::cli::stop_on_signals()?;
    let keystore = rl_layer::security::keystore_of(&config)?;
    let session = Session::with_keystore(&config.dds, &config.timing, false, keystore.as_ref())
        .map_err(dds_error)?;
    let output = Output { json: args.json };
    if args.vote {
        let options = vote::VoteOptions {
            tolerance: args.vote_tolerance,
            dissent_after: args.dissent_after,
            safe: args.vote_safe.map(|(pan, tilt)| ServoControl {
                pan,
                tilt,
                frequency: config.tracker.servo_frequency_hz,
            }),
        };
        return vote::run(&session, options, &output, &stop, args.duration_ms);
    }
    let deadline_ms = config.timing.command_deadline_ms;
    if !output.json {
        output.line(&format!(
            "servo: reading {} on domain {} (exclusive ownership, deadline {deadline_ms} ms)",
            config.dds.command_topic, config.dds.domain
        ))?;
    }
    let trust = CommandTrust::new(config.timing.peer_deadline_ms, args.any_writer);
    let mut servo = Servo::open(&session, output, deadline_ms, trust)?;
    while !stop.load(Ordering::Relaxed) {
        if args
            .duration_ms
            .is_some_and(|limit| servo.now_ms() >= limit)
        {
            break;
        }
        if !servo.wait_for_samples()? {
            continue;
        }
        if !servo.take_samples(&session)? || !servo.maybe_summarize()? {
            // stdout is gone: the consumer exited.
            return Ok(());
        }
    }
    Ok(())
}

/// The running simulator: the actuator view, its poll and what it has counted.
struct Servo {
    feed: OwnerFeed<ServoControl>,
    poll: mio::Poll,
    events: mio::Events,
    output: Output,
    /// Writers already reported as of unknown strength (warned once each).
    unknown_warned: BTreeSet<GUID>,
    start: Instant,
    accepted_count: u64,
    rejected_count: u64,
    expired_count: u64,
    last_summary_ms: u64,
    last_command: Option<ServoControl>,
}

impl Servo {
    /// Creates the actuator view and registers its readers with a poll.
    fn open(
        session: &Session,
        output: Output,
        deadline_ms: u64,
        trust: CommandTrust,
    ) -> Result<Servo, Error> {
        let commands = session.command_reader().map_err(dds_error)?;
        let feed =
            OwnerFeed::open_trusting(session, commands, deadline_ms, trust).map_err(dds_error)?;
        let poll = mio::Poll::new().map_err(|e| Error::io("creating a poll", e))?;
        for (reader, token) in feed.readers().into_iter().zip([COMMANDS, HEARTBEATS]) {
            poll.register(reader, token, mio::Ready::readable(), mio::PollOpt::edge())
                .map_err(|e| Error::io("registering a DDS reader", e))?;
        }
        Ok(Servo {
            feed,
            poll,
            events: mio::Events::with_capacity(16),
            output,
            unknown_warned: BTreeSet::new(),
            start: Instant::now(),
            accepted_count: 0,
            rejected_count: 0,
            expired_count: 0,
            last_summary_ms: 0,
            last_command: None,
        })
    }

    /// Milliseconds since the servo started.
    fn now_ms(&self) -> u64 {
        u64::try_from(self.start.elapsed().as_millis()).unwrap_or(u64::MAX)
    }

    /// Waits for samples, at most [`POLL_TIMEOUT_MS`]; `false` when a signal interrupted it.
    fn wait_for_samples(&mut self) -> Result<bool, Error> {
        let timeout = Some(Duration::from_millis(POLL_TIMEOUT_MS));
        match self.poll.poll(&mut self.events, timeout) {
            Ok(_) => Ok(true),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(false),
            Err(e) => Err(Error::io("waiting for DDS", e)),
        }
    }

    /// Every command's fate, printed; `Ok(false)` when stdout is gone.
    fn take_samples(&mut self, session: &Session) -> Result<bool, Error> {
        let now = self.now_ms();
        for delivery in self.feed.deliveries(session, now) {
            if !self.report(delivery, now)? {
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// Prints what became of one command; `Ok(false)` when stdout is gone.
    fn report(&mut self, delivery: Delivery<ServoControl>, now: u64) -> Result<bool, Error> {
        let (command, writer, strength, late_ms, decision) = match delivery {
            Delivery::Refused { writer, refusal } => {
                if self.feed.first_refusal(writer) {
                    tracing::warn!(
                        writer = %guid_hex(writer),
                        "command refused: {refusal} (rl servo --any-writer takes every writer)"
                    );
                }
                self.rejected_count += 1;
                return Ok(true);
            }
            Delivery::Expired {
                writer,
                late_ms,
                lifespan_ms,
            } => {
                self.expired_count += 1;
                if !self.output.json {
                    return Ok(true);
                }
                return self.output.event(&ServoEvent::Expired {
                    t_ms: now,
                    writer_guid: guid_hex(writer),
                    controller_id: self.feed.controller_of(writer),
                    late_ms,
                    lifespan_ms,
                });
            }
            Delivery::Offered {
                value,
                writer,
                strength,
                strength_known,
                late_ms,
                decision,
            } => {
                if !strength_known && self.unknown_warned.insert(writer) {
                    tracing::warn!(
                        writer = %guid_hex(writer),
                        "command from a writer not yet discovered: strength 0 until it is"
                    );
                }
                (value, writer, strength, late_ms, decision)
            }
        };
        if let Some(change) = decision.owner_changed {
            let event = ServoEvent::OwnerChanged {
                t_ms: now,
                from_controller_id: change.from.and_then(|w| self.feed.controller_of(w)),
                to_controller_id: self.feed.controller_of(change.to),
                gap_ms: change.gap_ms,
                from_writer_guid: change.from.map(guid_hex),
                to_writer_guid: guid_hex(change.to),
                strength,
            };
            let printed = if self.output.json {
                self.output.event(&event)?
            } else {
                self.output.line(&describe_change(&event))?
            };
            if !printed {
                return Ok(false);
            }
        }
        if !decision.accepted {
            self.rejected_count += 1;
            return Ok(true);
        }
        self.accepted_count += 1;
        self.last_command = Some(command);
        if !self.output.json {
            return Ok(true);
        }
        self.output.event(&ServoEvent::Command {
            t_ms: now,
            writer_guid: guid_hex(writer),
            controller_id: self.feed.controller_of(writer),
            strength,
            pan: command.pan,
            tilt: command.tilt,
            frequency: command.frequency,
            late_ms,
        })
    }

    /// The human summary line every [`SUMMARY_PERIOD_MS`] (not with `--json`); `Ok(false)`
    /// when stdout is gone.
    fn maybe_summarize(&mut self) -> Result<bool, Error> {
        let now = self.now_ms();
        if self.output.json || now.saturating_sub(self.last_summary_ms) < SUMMARY_PERIOD_MS {
            return Ok(true);
        }
        self.last_summary_ms = now;
        let owner = match self.feed.owner(now) {
            Some(writer) => format!(
                "{} at strength {}",
                controller_name(self.feed.controller_of(writer), writer),
                self.feed.strength_of(writer).unwrap_or_default()
            ),
            None => "none".to_string(),
        };
        let position = match self.last_command {
            Some(c) => format!("pan {} tilt {}", c.pan, c.tilt),
            None => "no command yet".to_string(),
        };
        self.output.line(&format!(
            "servo: owner {owner}; {position}; {} commands accepted, {} ignored (weaker writers), \
             {} expired (older than their writer's lifespan)",
            self.accepted_count, self.rejected_count, self.expired_count
        ))
    }
}

fn controller_name(controller: Option<ControllerId>, writer: GUID) -> String {
    match controller {
        Some(id) => format!("controller {id}"),
        None => format!("writer {}", guid_hex(writer)),
    }
}

fn describe_change(event: &ServoEvent) -> String {
    let ServoEvent::OwnerChanged {
        t_ms,
        from_controller_id,
        to_controller_id,
        gap_ms,
        from_writer_guid,
        to_writer_guid,
        strength,
    } = event
    else {
        return String::new();
    };
    let name = |id: &Option<ControllerId>, guid: &str| match id {
        Some(id) => format!("controller {id}"),
        None => format!("writer {guid}"),
    };
    let to = name(to_controller_id, to_writer_guid);
    match (from_writer_guid, gap_ms) {
        (Some(from_guid), Some(gap_ms)) => format!(
            "servo: {t_ms} ms: owner {} -> {to} (strength {strength}), {gap_ms} ms without commands",
            name(from_controller_id, from_guid)
        ),
        _ => format!("servo: {t_ms} ms: first owner {to} (strength {strength})"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_lines_have_the_documented_shape() {
        let command = ServoEvent::Command {
            t_ms: 12,
            writer_guid: "00".repeat(16),
            controller_id: Some(1),
            strength: rl_layer::core::Strength(30),
            pan: 500,
            tilt: 400,
            frequency: 60,
            late_ms: Some(3),
        };
        assert_eq!(
            serde_json::to_string(&command).unwrap(),
            format!(
                r#"{{"event":"command","t_ms":12,"writer_guid":"{}","controller_id":1,"strength":30,"pan":500,"tilt":400,"frequency":60,"late_ms":3}}"#,
                "00".repeat(16)
            )
        );
        let first = ServoEvent::OwnerChanged {
            t_ms: 5,
            from_controller_id: None,
            to_controller_id: None,
            gap_ms: None,
            from_writer_guid: None,
            to_writer_guid: "ab".into(),
            strength: rl_layer::core::Strength(20),
        };
        assert_eq!(
            serde_json::to_string(&first).unwrap(),
            r#"{"event":"owner_changed","t_ms":5,"from_controller_id":null,"to_controller_id":null,"gap_ms":null,"from_writer_guid":null,"to_writer_guid":"ab","strength":20}"#
        );
    }

    #[test]
    fn human_line_names_controllers_and_gap() {
        let change = ServoEvent::OwnerChanged {
            t_ms: 900,
            from_controller_id: Some(1),
            to_controller_id: Some(2),
            gap_ms: Some(108),
            from_writer_guid: Some("aa".into()),
            to_writer_guid: "bb".into(),
            strength: rl_layer::core::Strength(20),
        };
        assert_eq!(
            describe_change(&change),
            "servo: 900 ms: owner controller 1 -> controller 2 (strength 20), 108 ms without commands"
        );
    }
}
