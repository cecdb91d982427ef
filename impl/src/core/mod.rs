//! The voting core: RL's protocol as a pure state machine.
//!
//! No I/O, no clock, no threads: the caller passes every input with the current time and
//! performs the commands it gets back (publish a heartbeat, change the command strength,
//! raise an alarm, ...), like raft-rs's `RawNode` or openraft's `Engine`.
//!
//! ```text
//!   heartbeats, votes ──▶ ┌──────────────┐ ──▶ PublishHeartbeat, PublishVote
//!   timer (next_deadline) │ Core::step   │ ──▶ SetOutput { role, strength }
//!   local fault ────────▶ └──────────────┘ ──▶ RaiseAlarm / ClearAlarm, Leds, Console
//! ```
//!
//! Time is divided into rounds of one heartbeat period, aligned to multiples of the period on
//! the caller's clock (controllers whose clocks agree then share round boundaries, which is
//! the model's synchronous round). Heartbeats heard during a round are kept (the latest per
//! peer); at the round's end the controller takes them in and decides (`rules::end_round`),
//! and a quarter period later it publishes its heartbeat carrying what it decided, so the
//! heartbeat lands inside every peer's same round even with some clock skew.
//!
//! The adapter's loop: `while core.next_deadline_ms() <= now { core.step(Input::Timer, now) }`,
//! and `core.step(Input::Heartbeat(..), now)` for every heartbeat received.

#[cfg(feature = "mutation")]
pub mod mutation;
pub mod rules;
pub mod state;
pub mod types;

pub use rules::Rounds;
pub use state::{ControllerState, Peer};
pub use types::*;

use std::collections::BTreeMap;

/// What the core needs to know about itself and its timing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoreConfig {
    pub id: ControllerId,
    /// A new value at every start of the process (e.g. the start time in ms).
    pub incarnation: Incarnation,
    /// One round.
    pub heartbeat_period_ms: u64,
    pub rounds: Rounds,
}

impl CoreConfig {
    /// The heartbeat goes out this long after the round boundary.
    pub fn heartbeat_offset_ms(&self) -> u64 {
        self.heartbeat_period_ms / 4
    }
}

/// An input to the core.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Input {
    /// A peer's heartbeat arrived (kept until the round ends).
    Heartbeat(Heartbeat),
    /// A durable vote record arrived (kept for status; no decision reads it).
    Vote(VoteRecord),
    /// `next_deadline_ms()` has passed: runs the earliest due timer.
    Timer,
    /// The application detected its own fault: fail now (stop commanding, announce FAILED).
    LocalFault,
}

/// What the caller must do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    PublishHeartbeat(Heartbeat),
    /// Publish (durably) this controller's vote record.
    PublishVote(VoteRecord),
    /// Command with this role's strength from now on; `strength: None` = stop commanding.
    SetOutput {
        role: Option<Role>,
        strength: Option<u8>,
    },
    RaiseAlarm {
        about: ControllerId,
        reason: AlarmReason,
    },
    ClearAlarm {
        about: ControllerId,
    },
    /// The protocol state changed (phase, role, agreed result or vote): show it.
    Status(Status),
    /// The status LEDs to show (paper, "LED Operation").
    Leds(crate::leds::LedPattern),
    /// A line for the console (paper, "LED Operation": relative number and the Primary).
    Console(String),
}

/// A summary of a controller's protocol state, for consoles, LEDs and status topics.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Status {
    pub id: ControllerId,
    pub incarnation: Incarnation,
    pub phase: Phase,
    pub role: Option<Role>,
    pub strength: Option<u8>,
    pub agreed: Option<Assignment>,
    pub vote: Option<Assignment>,
    /// Peers believed alive (FAILED ones included).
    pub sees: Vec<ControllerId>,
    /// Peers marked FAILED.
    pub failed: Vec<ControllerId>,
    /// Peers with a raised controller alarm.
    pub alarms: Vec<(ControllerId, AlarmReason)>,
}

/// The voting core of one controller.
#[derive(Clone, Debug)]
pub struct Core {
    config: CoreConfig,
    state: ControllerState,
    /// Heartbeats heard in the current round, the latest per peer id.
    inbox: BTreeMap<ControllerId, Heartbeat>,
    /// Latest durable vote record per peer (status only).
    durable_votes: BTreeMap<ControllerId, VoteRecord>,
    round_end_ms: u64,
    heartbeat_due_ms: u64,
    /// The window times out at this instant (right after the round end that made it due).
    window_due_ms: Option<u64>,
    /// The LEDs last shown.
    leds: crate::leds::LedPattern,
    /// Heartbeats that named this controller's id with another incarnation (misconfiguration).
    pub duplicate_id_heartbeats: u64,
}

impl Core {
    /// A controller starting at `now_ms`. Its first heartbeat is due at once.
    pub fn new(config: CoreConfig, now_ms: u64) -> Core {
        let period = config.heartbeat_period_ms.max(1);
        Core {
            config,
            state: ControllerState::new(config.id, config.incarnation),
            inbox: BTreeMap::new(),
            durable_votes: BTreeMap::new(),
            round_end_ms: next_boundary(now_ms, period),
            heartbeat_due_ms: now_ms,
            window_due_ms: None,
            leds: crate::leds::LedPattern::ALL_OFF,
            duplicate_id_heartbeats: 0,
        }
    }

    pub fn config(&self) -> &CoreConfig {
        &self.config
    }

    /// The protocol state (read-only): what the conformance abstraction maps to the model.
    pub fn state(&self) -> &ControllerState {
        &self.state
    }

    /// Durable vote records received, by peer id.
    pub fn durable_votes(&self) -> &BTreeMap<ControllerId, VoteRecord> {
        &self.durable_votes
    }

    /// When `step(Input::Timer, ..)` must next be called.
    pub fn next_deadline_ms(&self) -> u64 {
        let mut due = self.round_end_ms.min(self.heartbeat_due_ms);
        if let Some(window) = self.window_due_ms {
            due = due.min(window);
        }
        due
    }

    /// The heartbeat this controller sends now.
    pub fn heartbeat(&self) -> Heartbeat {
        let c = &self.state;
        Heartbeat {
            from: c.id,
            incarnation: c.incarnation,
            phase: c.phase,
            role: c.role,
            strength: c.output,
            agreed: c.agreed,
            vote: c.vote,
        }
    }

    pub fn status(&self) -> Status {
        let c = &self.state;
        Status {
            id: c.id,
            incarnation: c.incarnation,
            phase: c.phase,
            role: c.role,
            strength: c.output,
            agreed: c.agreed,
            vote: c.vote,
            sees: c.live_peers().map(|(id, _)| id).collect(),
            failed: c
                .peers
                .iter()
                .filter(|(_, p)| p.failed)
                .map(|(&id, _)| id)
                .collect(),
            alarms: c
                .peers
                .iter()
                .filter_map(|(&id, p)| p.alarm.map(|reason| (id, reason)))
                .collect(),
        }
    }

    /// Feeds one input at time `now_ms`; returns the commands to perform, in order.
    pub fn step(&mut self, input: Input, now_ms: u64) -> Vec<Command> {
        let before = self.state.clone();
        let mut commands = Vec::new();
        match input {
            Input::Heartbeat(heartbeat) => {
                if heartbeat.from == self.state.id {
                    if heartbeat.incarnation != self.state.incarnation {
                        self.duplicate_id_heartbeats += 1;
                        commands.push(Command::Console(format!(
                            "C{}: another controller is using id {} (ignored; check --id)",
                            self.state.id, heartbeat.from
                        )));
                    }
                } else {
                    self.inbox.insert(heartbeat.from, heartbeat);
                }
            }
            Input::Vote(record) => {
                if record.from != self.state.id {
                    self.durable_votes.insert(record.from, record);
                }
            }
            Input::Timer => self.fire_timer(now_ms, &mut commands),
            Input::LocalFault => {
                if self.state.phase != Phase::Failed {
                    rules::fail_self(&mut self.state);
                }
            }
        }
        self.changes(&before, &mut commands);
        commands
    }

    /// The LEDs for the current state: own role green, a failed unit's role red, own health.
    fn leds_now(&self) -> crate::leds::LedPattern {
        let c = &self.state;
        let alarmed: Vec<ControllerId> = c
            .peers
            .iter()
            .filter(|(_, p)| p.alarm.is_some())
            .map(|(&id, _)| id)
            .collect();
        crate::leds::pattern(&crate::leds::LedInputs {
            phase: c.phase,
            own_role: c.role,
            failed_roles: crate::leds::failed_roles(c.agreed.as_ref(), &alarmed),
            own_fault: false,
        })
    }

    /// Runs the earliest due timer: the round end, then the window expiry, then the heartbeat.
    fn fire_timer(&mut self, now_ms: u64, commands: &mut Vec<Command>) {
        let period = self.config.heartbeat_period_ms.max(1);
        if now_ms >= self.round_end_ms {
            let heard: Vec<Heartbeat> = std::mem::take(&mut self.inbox).into_values().collect();
            rules::end_round(&self.config.rounds, &mut self.state, &heard);
            // A caller that fell behind (a stopped process) runs one round end, not every
            // missed one: it cannot know what it did not hear.
            self.round_end_ms = next_boundary(now_ms, period);
            self.heartbeat_due_ms = self.round_end_ms - period + self.config.heartbeat_offset_ms();
            if self.heartbeat_due_ms <= now_ms {
                self.heartbeat_due_ms = now_ms;
            }
            if rules::window_can_expire(&self.config.rounds, &self.state) {
                self.window_due_ms = Some(now_ms);
            }
        } else if self.window_due_ms.is_some_and(|due| now_ms >= due) {
            self.window_due_ms = None;
            if rules::window_can_expire(&self.config.rounds, &self.state) {
                rules::close_window(&mut self.state);
            }
        } else if now_ms >= self.heartbeat_due_ms {
            commands.push(Command::PublishHeartbeat(self.heartbeat()));
            self.heartbeat_due_ms = self.round_end_ms + self.config.heartbeat_offset_ms();
        }
    }

    /// The commands that follow from a state change.
    fn changes(&mut self, before: &ControllerState, commands: &mut Vec<Command>) {
        let after = &self.state;
        if before.vote != after.vote {
            commands.push(Command::PublishVote(VoteRecord {
                from: after.id,
                incarnation: after.incarnation,
                vote: after.vote,
            }));
        }
        if before.output != after.output || before.role != after.role {
            commands.push(Command::SetOutput {
                role: after.role,
                strength: after.output,
            });
        }
        let ids: std::collections::BTreeSet<ControllerId> = before
            .peers
            .keys()
            .chain(after.peers.keys())
            .copied()
            .collect();
        for id in ids {
            let was = before.peers.get(&id).and_then(|p| p.alarm);
            let is = after.peers.get(&id).and_then(|p| p.alarm);
            match (was, is) {
                (None, Some(reason)) => commands.push(Command::RaiseAlarm { about: id, reason }),
                (Some(_), None) => commands.push(Command::ClearAlarm { about: id }),
                _ => {}
            }
        }
        let leds = self.leds_now();
        if leds != self.leds {
            self.leds = leds;
            commands.push(Command::Leds(leds));
        }
        let shown = |c: &ControllerState| (c.phase, c.role, c.output, c.agreed, c.vote);
        // The view as `Status` reports it: who is heard, who is FAILED, who is alarmed.
        let view = |c: &ControllerState| -> Vec<(ControllerId, bool, bool, bool)> {
            c.peers
                .iter()
                .map(|(&id, p)| (id, p.alive.is_some(), p.failed, p.alarm.is_some()))
                .collect()
        };
        if shown(before) != shown(after) || view(before) != view(after) {
            let status = self.status();
            commands.push(Command::Console(console_line(&status)));
            commands.push(Command::Status(status));
        }
    }
}

/// The next multiple of `period_ms` strictly after `now_ms`.
fn next_boundary(now_ms: u64, period_ms: u64) -> u64 {
    (now_ms / period_ms + 1) * period_ms
}

/// The paper's console line: this controller's relative number (its role) and the Primary.
pub fn console_line(status: &Status) -> String {
    let role = match (status.phase, status.role) {
        (Phase::Failed, _) => "FAILED".to_string(),
        (_, Some(role)) => format!("{role} ({})", status.strength.unwrap_or(0)),
        (Phase::Steady, None) => "spare (no role)".to_string(),
        (_, None) => "no role yet".to_string(),
    };
    let primary = status
        .agreed
        .and_then(|a| a.holder(Role::Primary))
        .map(|id| format!("C{id}"))
        .unwrap_or_else(|| "none".to_string());
    let agreed = status
        .agreed
        .map(|a| a.to_string())
        .unwrap_or_else(|| "-".to_string());
    format!(
        "C{} {:<12} {:<16} Primary: {:<4} agreed [{}]",
        status.id,
        status.phase.name(),
        role,
        primary,
        agreed
    )
}

#[cfg(test)]
mod tests;
