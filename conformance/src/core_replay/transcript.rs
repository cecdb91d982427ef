//! Readable transcripts of a replay: the golden files (`tests/snapshots/`) a reviewer reads
//! when a trace or the implementation changes.
//!
//! One block per step: the action in words; what each core did (every timer that fired and
//! every input that made it emit something, with the commands it returned); then, from each
//! core's own status, every controller's life and incarnation (the model's small numbers),
//! phase, role, command strength, FAILED marks and alarms, and the actuator's owner. No
//! timestamps or process stamps, so a transcript depends only on the trace and the
//! implementation's behaviour, and a change of behaviour changes it.

use super::network::{Cause, Emitted, StepLog};
use crate::abstraction::{self, IncarnationNumbers};
use crate::diff::controller_line;
use crate::trace::Trace;
use model::traces::AbstractState;
use rl_layer::core::{Assignment, Command, ControllerId, Timer};
use std::fmt::Write;

/// The insta snapshot name of a trace's transcript (`trace_0005-late-joiner`).
pub fn snapshot_name(trace_file: &str) -> String {
    format!("trace_{}", trace_file.trim_end_matches(".jsonl"))
}

/// The transcript committed for a trace (`tests/snapshots/core_replay__<name>.snap`, the
/// content after insta's header), if there is one: what the mutation check compares against.
pub fn committed(snapshot_dir: &std::path::Path, trace_file: &str) -> Option<String> {
    let path = snapshot_dir.join(format!("core_replay__{}.snap", snapshot_name(trace_file)));
    let text = std::fs::read_to_string(path).ok()?;
    // `---`, the header's fields, `---`, then the content.
    let body = text.splitn(3, "---\n").nth(2)?;
    Some(body.trim_end().to_string())
}

/// The transcript's opening lines: which trace, why it exists, the scope it came from.
pub fn header(trace: &Trace) -> String {
    format!(
        "trace {}: {}\nscope: {}\n",
        trace.file,
        trace.purpose,
        trace.config.summary()
    )
}

/// Appends one block: a title line, one line per controller, the actuator's owner.
pub fn push_state(out: &mut String, title: &str, state: &AbstractState) {
    let _ = writeln!(out, "\n{title}");
    push_controllers(out, state);
}

/// One line per controller and the actuator's owner.
fn push_controllers(out: &mut String, state: &AbstractState) {
    for c in &state.controllers {
        let _ = writeln!(out, "  {}", controller_line(c));
    }
    let owner = state
        .actuator_owner
        .map_or("none".to_string(), |id| format!("C{id}"));
    let _ = writeln!(out, "  actuator owner: {owner}");
}

/// Appends one step: its title, what each core did, then the state block.
pub fn push_step(
    out: &mut String,
    title: &str,
    log: &StepLog,
    state: &AbstractState,
    numbers: &IncarnationNumbers,
) {
    let _ = writeln!(out, "\n{title}");
    for (&id, emitted) in log {
        for Emitted { cause, commands } in emitted {
            let done: Vec<String> = commands
                .iter()
                .map(|command| command_text(id, command, numbers))
                .collect();
            let done = if done.is_empty() {
                "-".to_string()
            } else {
                done.join("; ")
            };
            let _ = writeln!(out, "  | C{id} {}: {done}", cause_text(*cause));
        }
    }
    push_controllers(out, state);
}

fn cause_text(cause: Cause) -> String {
    match cause {
        Cause::Timer(Timer::RoundEnd) => "round end".to_string(),
        Cause::Timer(Timer::WindowExpiry) => "window expiry".to_string(),
        Cause::Timer(Timer::Heartbeat) => "heartbeat due".to_string(),
        Cause::Timer(Timer::Exit) => "exit due".to_string(),
        Cause::HeartbeatFrom(from) => format!("heartbeat from C{from}"),
        Cause::Started => "started".to_string(),
        Cause::Arrival(from, arrival) => format!("C{from}'s commands {arrival:?}"),
    }
}

/// A command in the model's words (incarnations as the model's small numbers).
fn command_text(id: ControllerId, command: &Command, numbers: &IncarnationNumbers) -> String {
    let assignment = |a: Option<Assignment>| match abstraction::render_assignment(id, a, numbers) {
        Ok(Some(text)) => text,
        Ok(None) => "-".to_string(),
        Err(error) => format!("? ({error})"),
    };
    match command {
        Command::PublishHeartbeat(h) => format!(
            "send heartbeat {} {} {} established={} agreed[{}]@e{}{} vote[{}]{}",
            h.phase,
            h.role.map_or("no-role".to_string(), |r| r.to_string()),
            h.strength
                .map_or("silent".to_string(), |s| format!("out={s}")),
            h.established_strength
                .map_or("none".to_string(), |s| s.to_string()),
            assignment(h.agreed),
            h.epoch,
            if h.provisional { " provisional" } else { "" },
            assignment(h.vote),
            h.took_over_from.map_or(String::new(), |from| format!(
                " took-over-from[{}]",
                numbers.number(from.id, from.incarnation).map_or_else(
                    || format!("C{}#?", from.id),
                    |n| format!("C{}#{n}", from.id)
                )
            ))
        ),
        Command::PublishVote(record) => match record.vote {
            Some(vote) => format!("publish vote [{}]", assignment(Some(vote))),
            None => "withdraw vote".to_string(),
        },
        Command::SetOutput { role, strength } => format!(
            "set output {} {}",
            role.map_or("no-role".to_string(), |r| r.to_string()),
            strength.map_or("silent".to_string(), |s| s.to_string())
        ),
        Command::RaiseAlarm { about, reason } => format!("raise alarm C{about} {reason:?}"),
        Command::ClearAlarm { about, reason } => format!("clear alarm C{about} {reason:?}"),
        Command::RoundEndsMissed { rounds } => format!("{rounds} round ends missed"),
        Command::StartAgain => "start again as a new incarnation".to_string(),
        Command::NewLife { cause } => format!("new life ({cause:?})"),
        Command::MoveClock { by_ms, following } => {
            format!("move the clock {by_ms} ms to follow C{following}")
        }
        Command::Failed { failure, .. } => format!("failed itself: {failure}"),
        Command::Exit(_) => "exit".to_string(),
    }
}
