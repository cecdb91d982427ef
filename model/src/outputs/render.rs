//! Readable states, steps and paths of the output model: the explorer, counterexamples and
//! the report use these, so a reviewer reads roles, faults, commands and alarms.

use super::state::{Command, Controller, OutputAction, OutputState};
use crate::types::Phase;
use std::fmt::{self, Write};

/// `C1 Primary correct sent v0 odd=0`, `C2 FAILED (left as Primary) frozen at v1`.
pub fn controller_line(c: &Controller) -> String {
    let mut line = format!("C{} ", c.id);
    match (c.phase, c.role) {
        (Phase::Failed, _) => {
            line.push_str("FAILED (local fault alarm");
            if let Some(role) = c.left_as {
                let _ = write!(line, ", left as {}", role.name());
            }
            line.push(')');
        }
        (_, Some(role)) => line.push_str(role.name()),
        (_, None) => line.push_str("no role"),
    }
    match c.fault {
        Some(fault) => {
            let _ = write!(line, " WRONG: {fault}");
        }
        None => line.push_str(" correct"),
    }
    match c.command {
        Command::NoInstance => {}
        Command::Pending => line.push_str(" answering"),
        Command::Sent(value) => {
            let _ = write!(line, " sent {value}");
        }
        Command::Missing => line.push_str(" sent nothing"),
    }
    if c.phase != Phase::Failed {
        let _ = write!(line, " odd={}", c.odd_count);
    }
    if c.restarted {
        line.push_str(" (restarted)");
    }
    line
}

/// `voting receiver: accepted v0, dissent{C2}, HOLD alarm`.
pub fn voting_line(state: &OutputState) -> String {
    let mut line = String::from("voting receiver: ");
    match state.voting.accepted {
        Some(value) => {
            let _ = write!(line, "accepted {value}");
        }
        None => line.push_str("nothing accepted"),
    }
    let dissenters: Vec<String> = state
        .controllers
        .iter()
        .zip(state.voting.dissent)
        .filter(|(_, alarm)| *alarm)
        .map(|(c, _)| format!("C{}", c.id))
        .collect();
    if !dissenters.is_empty() {
        let _ = write!(line, ", dissent alarm{{{}}}", dissenters.join(","));
    }
    if state.voting.hold_alarm {
        line.push_str(", HOLD alarm");
    }
    line
}

/// `exclusive receiver: owner C1, took v0`.
pub fn exclusive_line(state: &OutputState) -> String {
    let owner = state
        .exclusive
        .owner
        .map_or_else(|| "none".to_string(), |id| format!("C{id}"));
    match state.exclusive.taken {
        Some(value) => format!("exclusive receiver: owner {owner}, took {value}"),
        None => format!("exclusive receiver: owner {owner}"),
    }
}

/// Every line of a state: the input, the controllers, the two receivers.
pub fn state_lines(state: &OutputState) -> Vec<String> {
    let mut lines = vec![format!("input: right command {}", state.right)];
    lines.extend(state.controllers.iter().map(controller_line));
    lines.push(voting_line(state));
    lines.push(exclusive_line(state));
    lines
}

impl fmt::Debug for OutputState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for line in state_lines(self) {
            writeln!(f, "{line}")?;
        }
        Ok(())
    }
}

/// The lines of `after` that differ from `before`.
pub fn diff(before: &OutputState, after: &OutputState) -> String {
    let mut out = String::new();
    for (old, new) in state_lines(before).iter().zip(state_lines(after)) {
        if *old != new {
            let _ = writeln!(out, "{new}");
        }
    }
    if out.is_empty() {
        out.push_str("(nothing changed)\n");
    }
    out
}

/// A path as numbered steps: the action, then what it changed. Inputs are numbered along
/// the path (the state holds only the current one).
pub fn numbered_steps(init: &OutputState, steps: &[(OutputAction, OutputState)]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "  0. initial state (input 1 open)");
    for line in state_lines(init) {
        let _ = writeln!(out, "       {line}");
    }
    let mut before = init;
    let mut input = 1;
    for (index, (action, after)) in steps.iter().enumerate() {
        if let OutputAction::NextInput { .. } = action {
            input += 1;
            let _ = writeln!(out, "{:>3}. input {input}: {action}", index + 1);
        } else {
            let _ = writeln!(out, "{:>3}. {action}", index + 1);
        }
        for line in diff(before, after).lines() {
            let _ = writeln!(out, "       {line}");
        }
        before = after;
    }
    out
}

/// The explorer's name of the initial state.
pub fn initial_state_name(state: &OutputState) -> String {
    let roles: Vec<String> = state
        .controllers
        .iter()
        .filter_map(|c| c.role.map(|role| format!("C{} {}", c.id, role.name())))
        .collect();
    format!(
        "{}; input 1 (right command {})",
        roles.join(", "),
        state.right
    )
}
