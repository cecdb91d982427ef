//! Human-readable renderings of states, actions and paths: the explorer UI, counterexamples
//! and trace transcripts all use these, so a reviewer reads names, roles and phases.

use crate::state::{link_bit, Action, Controller, State};
use crate::types::{Life, Phase};
use std::fmt::Write;

/// `C2 up#1 steady Secondary out=20 agreed[P=1 S=2 T=3] vote[P=1 S=2 T=3] sees{1,3} FAILED{} alarms{}`
pub fn controller_line(c: &Controller) -> String {
    let mut line = format!("C{} ", c.id);
    match c.life {
        Life::NotStarted => {
            line.push_str("not started");
            return line;
        }
        Life::Down => {
            let _ = write!(line, "down (incarnation {})", c.incarnation);
            return line;
        }
        Life::Up => {}
        Life::Paused => line.push_str("PAUSED "),
    }
    let _ = write!(line, "up#{} {}", c.incarnation, c.phase.name());
    match c.role {
        Some(role) => {
            let _ = write!(line, " {}", role.name());
        }
        None if c.phase == Phase::Steady => line.push_str(" spare"),
        None => line.push_str(" no-role"),
    }
    match c.output {
        Some(strength) => {
            let _ = write!(line, " out={strength}");
        }
        None => line.push_str(" silent"),
    }
    if let Some(old) = c.retiring {
        let _ = write!(line, " (old writer {old} retiring)");
    }
    if c.undiscovered {
        line.push_str(" (writer undiscovered)");
    }
    if let Some((from, incarnation)) = c.took_over_from {
        let _ = write!(line, " took-over-from-C{from}#{incarnation}");
    }
    if c.provisional {
        line.push_str(" provisional");
    }
    if c.late_joiner {
        line.push_str(" late-joiner");
    }
    if c.phase == Phase::Initializing {
        let _ = write!(line, " quiet={}", c.window_quiet_rounds);
    }
    if let Some(agreed) = c.agreed {
        let _ = write!(line, " agreed[{agreed}]");
        if c.epoch > 0 {
            let _ = write!(line, "@e{}", c.epoch);
        }
    }
    if let Some(vote) = c.vote {
        let _ = write!(line, " vote[{vote}]");
    }
    let ids = |pred: &dyn Fn(&crate::state::Peer) -> bool| -> String {
        let list: Vec<String> = c
            .peers
            .iter()
            .enumerate()
            .filter(|(i, p)| *i + 1 != usize::from(c.id) && pred(p))
            .map(|(i, _)| (i + 1).to_string())
            .collect();
        list.join(",")
    };
    let _ = write!(line, " sees{{{}}}", ids(&|p| p.alive.is_some()));
    let silent = ids(&|p| p.alive.is_some() && p.silent_rounds > 0);
    if !silent.is_empty() {
        let _ = write!(line, " missing{{{silent}}}");
    }
    let failed = ids(&|p| p.failed);
    if !failed.is_empty() {
        let _ = write!(line, " FAILED{{{failed}}}");
    }
    let alarms = ids(&|p| p.alarm);
    if !alarms.is_empty() {
        let _ = write!(line, " alarms{{{alarms}}}");
    }
    line
}

/// `network: lost C1->C2 | overdue votes C3->C4 | actuator owner C1 | losses 1 crashes 0 ...`
pub fn network_line(s: &State) -> String {
    let n = s.controllers.len() as u8;
    let links = |mask: u16| -> Vec<String> {
        let mut out = Vec::new();
        for from in 1..=n {
            for to in 1..=n {
                if from != to && mask & link_bit(from, to) != 0 {
                    out.push(format!("C{from}->C{to}"));
                }
            }
        }
        out
    };
    let mut line = String::from("network:");
    let lost = links(s.lost_links);
    if !lost.is_empty() {
        let _ = write!(line, " lost heartbeats {} |", lost.join(" "));
    }
    let overdue = links(s.overdue_votes);
    if !overdue.is_empty() {
        let _ = write!(line, " overdue votes {} |", overdue.join(" "));
    }
    match s.actuator_owner() {
        Some(owner) => {
            let _ = write!(line, " actuator owner C{owner} |");
        }
        None => line.push_str(" actuator idle |"),
    }
    if s.isolated != 0 {
        let cut: Vec<String> = (1..=n)
            .filter(|id| s.isolated & (1 << (id - 1)) != 0)
            .map(|id| format!("C{id}"))
            .collect();
        let _ = write!(line, " cut off {} |", cut.join(" "));
    }
    for (mask, label) in [
        (s.starved, "starved"),
        (s.slowed, "slowed"),
        (s.lagging, "deadline missed"),
    ] {
        if mask != 0 {
            let ids: Vec<String> = (1..=n)
                .filter(|id| mask & (1 << (id - 1)) != 0)
                .map(|id| format!("C{id}"))
                .collect();
            let _ = write!(line, " {label} {} |", ids.join(" "));
        }
    }
    let h = &s.history;
    let _ = write!(
        line,
        " faults: losses {} crashes {} restarts {} pauses {} cuts {}, owner changes {}, \
         quiet rounds {}",
        h.losses, h.crashes, h.restarts, h.pauses, h.isolations, h.owner_changes, h.quiet_rounds
    );
    if h.starvations > 0 {
        let _ = write!(line, ", starved links {}", h.starvations);
    }
    if h.slowdowns > 0 {
        let _ = write!(line, ", slowed processes {}", h.slowdowns);
    }
    line
}

/// The explorer's name for an initial state: which controllers are up at the start and which
/// may join later, e.g. `C1, C2 start; C3 may join later` (stateright's UI says `Init 1`).
pub fn initial_state_name(s: &State) -> String {
    let ids = |pred: fn(Life) -> bool| -> Vec<String> {
        s.controllers
            .iter()
            .filter(|c| pred(c.life))
            .map(|c| format!("C{}", c.id))
            .collect()
    };
    let started = ids(|life| matches!(life, Life::Up | Life::Paused));
    let joining = ids(|life| life == Life::NotStarted);
    let down = ids(|life| life == Life::Down);
    let mut parts = Vec::new();
    for (list, one, many) in [
        (started, "starts", "start"),
        (joining, "may join later", "may join later"),
        (down, "is down", "are down"),
    ] {
        if !list.is_empty() {
            let verb = if list.len() == 1 { one } else { many };
            parts.push(format!("{} {verb}", list.join(", ")));
        }
    }
    if parts.is_empty() {
        return "no controllers".to_string();
    }
    parts.join("; ")
}

/// What changed between two states, one line per changed controller.
pub fn diff(before: &State, after: &State) -> String {
    let mut out = String::new();
    for (b, a) in before.controllers.iter().zip(&after.controllers) {
        if b != a {
            let _ = writeln!(out, "{}", controller_line(a));
        }
    }
    if before.actuator_owner() != after.actuator_owner() {
        let _ = writeln!(
            out,
            "actuator owner: {} -> {}",
            owner(before.actuator_owner()),
            owner(after.actuator_owner())
        );
    }
    if out.is_empty() {
        out.push_str("(no controller changed)\n");
    }
    out
}

fn owner(id: Option<u8>) -> String {
    id.map_or_else(|| "none".to_string(), |id| format!("C{id}"))
}

/// A path as numbered steps: the action, then the controllers it changed.
pub fn numbered_steps(init: &State, steps: &[(Action, State)]) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "  0. initial state");
    for line in format!("{init:?}").lines() {
        let _ = writeln!(out, "       {line}");
    }
    let mut before = init;
    for (index, (action, after)) in steps.iter().enumerate() {
        let _ = writeln!(out, "{:>3}. {action}", index + 1);
        for line in diff(before, after).lines() {
            let _ = writeln!(out, "       {line}");
        }
        before = after;
    }
    out
}

/// A sequence diagram of a path for the explorer: one lane per controller, one row per step.
pub fn svg(init: &State, steps: &[(Action, State)]) -> String {
    let lanes = init.controllers.len();
    let lane_x = |id: u8| 80 + (usize::from(id) - 1) * 170;
    let row_h = 22;
    let height = 50 + (steps.len() + 1) * row_h;
    let width = 80 + lanes * 170 + 40;
    let mut out = format!(
        "<svg version='1.1' baseProfile='full' width='{width}' height='{height}' \
         viewbox='0 0 {width} {height}' xmlns='http://www.w3.org/2000/svg'>"
    );
    for c in &init.controllers {
        let x = lane_x(c.id);
        let _ = write!(
            out,
            "<text x='{x}' y='20' text-anchor='middle' font-weight='bold'>C{}</text>\
             <line x1='{x}' y1='28' x2='{x}' y2='{height}' stroke='#999'/>",
            c.id
        );
    }
    for (index, (action, after)) in steps.iter().enumerate() {
        let y = 45 + index * row_h;
        if let Action::LoseHeartbeat { from, to } = *action {
            // A lost heartbeat: a red arrow from sender to receiver.
            let _ = write!(
                out,
                "<line x1='{}' y1='{y}' x2='{}' y2='{}' stroke='red' marker-end='url(#a)'/>",
                lane_x(from),
                lane_x(to),
                y + 6
            );
        }
        let label = match action.actor() {
            Some(id) => (lane_x(id), short(action)),
            None => (10, "tick".to_string()),
        };
        let _ = write!(
            out,
            "<text x='{}' y='{}' font-size='11' text-anchor='start'>{}</text>",
            label.0 + 4,
            y + 4,
            label.1
        );
        let roles: Vec<String> = after
            .controllers
            .iter()
            .map(|c| match (c.life, c.role) {
                (Life::Up, Some(role)) => format!("C{}:{}", c.id, &role.name()[..1]),
                (Life::Up, None) => format!("C{}:{}", c.id, &c.phase.name()[..4]),
                _ => format!("C{}:-", c.id),
            })
            .collect();
        let _ = write!(
            out,
            "<text x='{}' y='{}' font-size='10' fill='#555'>{}</text>",
            width - 30,
            y + 4,
            roles.join(" ")
        );
    }
    out.push_str(
        "<defs><marker id='a' markerWidth='8' markerHeight='8' refX='6' refY='3' orient='auto'>\
         <path d='M0,0 L0,6 L6,3 z'/></marker></defs></svg>",
    );
    out
}

fn short(action: &Action) -> String {
    match action {
        Action::LoseHeartbeat { .. } => "hb lost".into(),
        Action::Tick => "tick".into(),
        Action::ExpireWindow { .. } => "window expires".into(),
        Action::DeliverVotes { .. } => "votes in".into(),
        Action::Crash { .. } => "crash".into(),
        Action::Restart { .. } => "restart".into(),
        Action::Join { .. } => "join".into(),
        Action::Pause { .. } => "pause".into(),
        Action::Resume { .. } => "resume".into(),
        Action::Isolate { .. } => "cut off".into(),
        Action::Unplug { .. } => "cable pulled".into(),
        Action::Starve { .. } => "starved".into(),
        Action::Slow { .. } => "slowed".into(),
        Action::LateHeartbeat { .. } => "hb late".into(),
        Action::HearLate { .. } => "hears late".into(),
        Action::Oversleep { .. } => "tick, asleep".into(),
        Action::Thaw { .. } => "runs again".into(),
        Action::Lag { .. } => "deadline missed".into(),
        Action::CatchUp { .. } => "late sample".into(),
        Action::Heal { .. } => "reconnected".into(),
        Action::DiscoverWriter { .. } => "writer found".into(),
        Action::TieBreak { .. } => "tie broken".into(),
    }
}
