//! The duplex's state and actions: two controllers with configured roles, what each writes to
//! the actuator and knows of its partner, the heartbeats lost this round, the actuator's
//! owner, and the ghost counts the properties read.
//!
//! Time is rounds of one heartbeat period, as in the role model: within a round crashes,
//! restarts and lost heartbeats come in any order; `Tick` ends it, delivering every heartbeat
//! that was not lost and running each controller's deadline check.

use crate::types::{Id, Life, Role};
use serde::{Deserialize, Serialize};
use std::fmt;

/// The duplex's two controllers: C1 is configured Primary, C2 Standby.
pub const CONTROLLERS: usize = 2;

/// Rounds without a partner's heartbeat after which a controller takes it for failed (the
/// heartbeat deadline, two periods as in the role model).
pub const DEADLINE_ROUNDS: u8 = 2;

/// The strength a controller writes at while it does not command: below both configured
/// strengths (30 and 20), so it never takes the actuator from a partner that commands, and
/// still the actuator's writer at once if that partner dies.
pub const YIELDED_STRENGTH: u8 = 10;

/// Round ends a preempting Primary that started again in place after a lapse of its own loop
/// must run on time, hearing its partner, before it takes its configured strength back (the
/// dwell against oscillation, finding A4): more than [`SICK_GAP_ROUNDS`].
pub const DWELL_ROUNDS: u8 = 2;

/// The scope's timing assumption on a sick controller: while its episode lasts it lapses again
/// before more than this many round ends have run on time (a starved or stalling loop is
/// late at nearly every round end; docs/findings.md, A4, argues the figures of `rl`).
pub const SICK_GAP_ROUNDS: u8 = 1;

/// What a controller writes to the actuator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Writing {
    /// Nothing: it is down (or, mutation `SilentStandby`, a standby that does not write).
    Silent,
    /// At [`YIELDED_STRENGTH`]: back from a restart without preemption, until it has heard
    /// whether its partner commands; then for as long as a weaker partner commands.
    Yielded,
    /// At its configured role's strength (Primary 30, Standby 20).
    Configured,
}

/// What a controller knows of its partner from heartbeats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PartnerView {
    /// Not heard since this controller started.
    Unknown,
    /// Heard within the deadline.
    Heard,
    /// Not heard for the deadline: taken for failed, its alarm raised.
    Lost,
}

/// One controller of the duplex.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct DuplexController {
    pub id: Id,
    /// Its configured role: Primary (30) or Secondary, the Standby (20).
    pub role: Role,
    pub life: Life,
    pub writing: Writing,
    pub view: PartnerView,
    /// Rounds in a row without the partner's heartbeat (saturating at the deadline).
    pub missed: u8,
    /// Its alarm that the partner failed.
    pub alarm: bool,
    /// Ghost: it has restarted at least once.
    pub restarted: bool,
    /// Ghost: rounds ended since it started (saturating at the deadline).
    pub up_rounds: u8,
    /// Ghost: rounds ended since it crashed (saturating at the deadline).
    pub down_rounds: u8,
    /// Ghost: since it last heard its partner, the partner crashed or one of its heartbeats
    /// to this controller was lost.
    pub partner_missed: bool,
    /// Round ends on time it must still run before it takes its configured strength back
    /// (0: no dwell): set when it starts again in place after a lapse, with preemption.
    pub dwell: u8,
    /// Ghost: a gray fault's episode holds (its loop starved or stalling).
    pub sick: bool,
    /// Ghost: round ends run on time since its last lapse in this episode (saturating).
    pub on_time_rounds: u8,
    /// Ghost: it has started again in place after a lapse at least once.
    pub lapsed: bool,
}

impl DuplexController {
    /// A controller that has run with its partner for longer than the deadline.
    pub fn settled(id: Id, role: Role) -> DuplexController {
        DuplexController {
            id,
            role,
            life: Life::Up,
            writing: Writing::Configured,
            view: PartnerView::Heard,
            missed: 0,
            alarm: false,
            restarted: false,
            up_rounds: DEADLINE_ROUNDS,
            down_rounds: 0,
            partner_missed: false,
            dwell: 0,
            sick: false,
            on_time_rounds: 0,
            lapsed: false,
        }
    }

    pub fn is_up(&self) -> bool {
        self.life == Life::Up
    }

    /// The ownership strength it writes at, if it writes.
    pub fn strength(&self) -> Option<u8> {
        match (self.life, self.writing) {
            (Life::Up, Writing::Configured) => Some(self.role.strength()),
            (Life::Up, Writing::Yielded) => Some(YIELDED_STRENGTH),
            _ => None,
        }
    }

    /// The duplex's name for its configured role.
    pub fn role_name(&self) -> &'static str {
        match self.role {
            Role::Primary => "Primary",
            _ => "Standby",
        }
    }
}

/// The whole state (its `Debug` is the readable lines of [`state_lines`]).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct DuplexState {
    pub controllers: [DuplexController; CONTROLLERS],
    /// The heartbeat of controller i (index id - 1) is lost this round.
    pub lost: [bool; CONTROLLERS],
    /// ... and was lost the round before (a loss then continues the same episode).
    pub lost_before: [bool; CONTROLLERS],
    /// The controller whose samples the actuator takes: DDS exclusive ownership, the
    /// strongest live writer.
    pub owner: Option<Id>,
    pub crashes: u8,
    pub lost_heartbeats: u8,
    /// Gray-fault episodes begun and lapses so far (budgets `max_sick_episodes`,
    /// `max_lapses`).
    pub sick_episodes: u8,
    pub lapses: u8,
    /// Ghost: faults so far, each crash, each episode of lost heartbeats on one link and each
    /// gray-fault episode.
    pub faults: u8,
    /// Ghost: times the actuator moved from one controller to the other.
    pub owner_changes: u8,
}

impl DuplexState {
    pub fn controller(&self, id: Id) -> &DuplexController {
        &self.controllers[usize::from(id) - 1]
    }

    pub fn controller_mut(&mut self, id: Id) -> &mut DuplexController {
        &mut self.controllers[usize::from(id) - 1]
    }

    pub fn partner(&self, id: Id) -> &DuplexController {
        self.controller(partner_of(id))
    }

    /// The live writer with the highest strength.
    pub fn strongest_writer(&self) -> Option<Id> {
        self.controllers
            .iter()
            .filter_map(|c| c.strength().map(|strength| (strength, c.id)))
            .max()
            .map(|(_, id)| id)
    }
}

/// The other controller of the two.
pub fn partner_of(id: Id) -> Id {
    3 - id
}

/// One event of the duplex.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum DuplexAction {
    Crash {
        controller: Id,
    },
    /// A crashed controller starts again (once its partner, if up, has noticed the crash).
    Restart {
        controller: Id,
    },
    /// This round's heartbeat from `from` to its partner is lost.
    LoseHeartbeat {
        from: Id,
    },
    /// The round ends: heartbeats not lost are delivered, deadlines are checked.
    Tick,
    /// A gray fault's episode begins at the Primary: its loop is starved or stalls, for as
    /// long as the episode lasts.
    Sicken {
        controller: Id,
    },
    /// The sick controller's loop lapses: commanding, its writer stops (the actuator moves
    /// at the command deadline) and it starts again in place; otherwise its round end ran
    /// late, which its dwell counts as not healthy.
    Lapse {
        controller: Id,
    },
    /// The episode ends: its loop runs on time again.
    Recover {
        controller: Id,
    },
}

impl fmt::Display for DuplexAction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            DuplexAction::Crash { controller } => write!(f, "C{controller} crashes"),
            DuplexAction::Restart { controller } => write!(f, "C{controller} restarts"),
            DuplexAction::LoseHeartbeat { from } => {
                write!(f, "C{from}'s heartbeat to C{} is lost", partner_of(from))
            }
            DuplexAction::Tick => write!(f, "round ends (heartbeats delivered, deadlines checked)"),
            DuplexAction::Sicken { controller } => write!(f, "C{controller}'s loop is starved"),
            DuplexAction::Lapse { controller } => write!(f, "C{controller}'s loop lapses"),
            DuplexAction::Recover { controller } => {
                write!(f, "C{controller}'s loop runs on time again")
            }
        }
    }
}

/// `C1 Primary up, writes at 30, hears C2`, `C2 Standby up, writes at 20, LOST C1, alarm`.
pub fn controller_line(c: &DuplexController) -> String {
    let mut line = format!("C{} {}", c.id, c.role_name());
    if !c.is_up() {
        line.push_str(" down");
        return line;
    }
    match (c.writing, c.strength()) {
        (Writing::Configured, Some(strength)) => {
            line.push_str(&format!(" up, writes at {strength}"))
        }
        (Writing::Yielded, Some(strength)) => line.push_str(&format!(" up, yields at {strength}")),
        _ => line.push_str(" up, writes nothing"),
    }
    let partner = partner_of(c.id);
    let silent_for = match c.missed {
        1 => "1 round".to_string(),
        n => format!("{n} rounds"),
    };
    match (c.view, c.missed) {
        (PartnerView::Heard, 0) => line.push_str(&format!(", hears C{partner}")),
        (PartnerView::Heard, _) => line.push_str(&format!(", C{partner} silent for {silent_for}")),
        (PartnerView::Unknown, 0) => line.push_str(&format!(", has not heard C{partner} yet")),
        (PartnerView::Unknown, _) => {
            line.push_str(&format!(", has not heard C{partner} yet ({silent_for})"))
        }
        (PartnerView::Lost, _) => line.push_str(&format!(", LOST C{partner}")),
    }
    if c.alarm {
        line.push_str(&format!(", alarm: C{partner} failed"));
    }
    if c.dwell > 0 {
        line.push_str(&format!(", dwells {} more round(s)", c.dwell));
    }
    if c.sick {
        line.push_str(", SICK");
    }
    line
}

/// Every line of a state: the controllers, the actuator, the faults.
pub fn state_lines(state: &DuplexState) -> Vec<String> {
    let mut lines: Vec<String> = state.controllers.iter().map(controller_line).collect();
    lines.push(match state.owner {
        Some(owner) => format!(
            "actuator follows C{owner} at {}",
            state.controller(owner).strength().unwrap_or(0)
        ),
        None => "actuator: no writer".to_string(),
    });
    let lost: Vec<String> = state
        .controllers
        .iter()
        .filter(|c| state.lost[usize::from(c.id) - 1])
        .map(|c| format!("C{}->C{}", c.id, partner_of(c.id)))
        .collect();
    let mut faults = format!(
        "faults {} (crashes {}, lost heartbeats {}), owner changes {}",
        state.faults, state.crashes, state.lost_heartbeats, state.owner_changes
    );
    if state.sick_episodes > 0 {
        faults.push_str(&format!(
            "; sick episodes {}, lapses {}",
            state.sick_episodes, state.lapses
        ));
    }
    if !lost.is_empty() {
        faults.push_str(&format!("; lost this round: {}", lost.join(", ")));
    }
    lines.push(faults);
    lines
}

impl fmt::Debug for DuplexState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for line in state_lines(self) {
            writeln!(f, "{line}")?;
        }
        Ok(())
    }
}
