//! Readable transcripts of a replay: the golden files (`tests/snapshots/`) a reviewer reads
//! when a trace or the implementation changes.
//!
//! One block per step: the action in words, then every controller's life and incarnation (the
//! model's small numbers), phase, role, command strength, FAILED marks and alarms, and the
//! actuator's owner. No timestamps or process stamps, so a transcript depends only on the
//! trace and the implementation's behaviour.

use crate::coverage::id_set;
use crate::trace::Trace;
use model::traces::{AbstractController, AbstractState};
use model::Life;
use std::fmt::Write;

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
    for c in &state.controllers {
        let _ = writeln!(out, "  {}", controller_line(c));
    }
    let owner = state
        .actuator_owner
        .map_or("none".to_string(), |id| format!("C{id}"));
    let _ = writeln!(out, "  actuator owner: {owner}");
}

/// `C2 up#0  steady        secondary  out=20  alarms{1}`
pub fn controller_line(c: &AbstractController) -> String {
    match c.life {
        Life::NotStarted => return format!("C{} not started", c.id),
        Life::Down => return format!("C{} down (incarnation {})", c.id, c.incarnation),
        Life::Up => {}
    }
    let phase = c.phase.map_or("-", |p| p.name());
    let role = match (c.role, c.phase) {
        (Some(role), _) => role.name().to_lowercase(),
        (None, Some(model::Phase::Steady)) => "spare".to_string(),
        (None, _) => "no-role".to_string(),
    };
    let strength = c
        .strength
        .map_or("silent".to_string(), |s| format!("out={s}"));
    let mut line = format!(
        "C{} up#{:<2} {phase:<13} {role:<10} {strength:<7}",
        c.id, c.incarnation
    );
    if !c.failed.is_empty() {
        let _ = write!(line, " FAILED{}", id_set(&c.failed));
    }
    let _ = write!(line, " alarms{}", id_set(&c.alarms));
    line
}
