//! # rl-core: RL's voting protocol as a pure state machine
//!
//! No I/O, no clock, no threads (this crate depends on serde only, so the compiler keeps it
//! that way): the caller passes every input with the current time and performs the commands
//! it gets back, like raft-rs's `RawNode` or openraft's `Engine`.
//!
//! ```text
//!   Input::Heartbeat ────────┐                      ┌─▶ PublishHeartbeat, PublishVote
//!   Input::HeartbeatArrival ─┤                      ├─▶ SetOutput { role, strength }
//!   Input::Vote ─────────────┤   ┌──────────────┐   ├─▶ RaiseAlarm / ClearAlarm
//!   Input::Timer(t) ─────────┼──▶│  Core::step  │───┼─▶ MoveClock (follow the Primary's phase)
//!   Input::Commands ─────────┤   └──────────────┘   ├─▶ Failed, Exit (leave to be restarted)
//!   Input::LocalFault ───────┤                      └─▶ StartAgain, NewLife
//!   Input::StartAgain ───────┘   Core::status() ───▶ (adapter) LEDs, console line, status view
//! ```
//!
//! Time is divided into rounds of one heartbeat period, aligned to multiples of the period on
//! the caller's clock (controllers whose clocks agree then share round boundaries, which is
//! the model's synchronous round). Heartbeats heard during a round are kept (the latest per
//! peer); at the round's end ([`Timer::RoundEnd`]) the controller takes them in and decides,
//! and a quarter period later ([`Timer::Heartbeat`]) it publishes its heartbeat carrying what
//! it decided, so the heartbeat lands inside every peer's same round even with some clock skew.
//! The model delivers a heartbeat in the round it was sent or never, so a heartbeat sent
//! before the round now running ([`Core::sent_before_this_round`]: one that waited in a
//! queue on a starved link) is dropped by the adapter as lost, never counted late.
//!
//! The adapter's loop:
//!
//! ```
//! # use rl_core::{Core, CoreConfig, Input, Rounds};
//! # let rounds = Rounds { dead_after_rounds: 2, window_rounds: 2 };
//! # let mut core = Core::new(CoreConfig::new(1, 7, 250, rounds), 0);
//! # let now_ms = 1_000;
//! while let Some(timer) = core.due_timer(now_ms) {
//!     for command in core.step(Input::Timer(timer), now_ms) {
//!         // perform it: publish, change the command strength, raise an alarm ...
//! #       let _ = command;
//!     }
//! }
//! // ... and `core.step(Input::Heartbeat(heartbeat), now_ms)` for every heartbeat received;
//! // sleep until `core.next_deadline().at_ms`.
//! ```
//!
//! [`architectures`] holds the paper's two other architectures (the simple duplex and the
//! lockstep pair) as other round-end rules of the same core.
//!
//! Modules: [`types`] (the vocabulary, shared with the model by meaning, never by code),
//! [`state`] (what one controller knows), [`report`] (the self-report sent as heartbeat and
//! shown as status), [`io`] (inputs, timers, commands), [`config`] (its own id and its timing
//! in rounds), [`phase`] (whose round phase to follow), [`failure`] (why a controller failed
//! itself, and when it leaves), [`identity`] (which participant speaks for which id), and
//! `mutation` (deliberately broken rules, feature `mutation` only).
//! [`network`] is the network alarm participant, a second pure state machine of the same
//! shape that watches both networks between the like controllers. Private to the crate:
//! `rules` (the model's rules, one function each), `epochs` (which of two agreed results wins
//! a merge), `strength` (the command strength a role earns, and when to move there) and
//! `invariants` (the state's invariants, asserted in debug builds after every step).

#![deny(missing_docs)]

pub mod architectures;
pub mod config;
mod epochs;
pub mod failure;
pub mod identity;
mod invariants;
pub mod io;
#[cfg(feature = "mutation")]
pub mod mutation;
pub mod network;
pub mod phase;
pub mod report;
mod rules;
pub mod state;
mod strength;
pub mod types;

pub use architectures::Architecture;
pub use config::{CoreConfig, Rounds};
pub use io::{Command, Deadline, Input, Restart, Timer};
pub use report::{Heartbeat, SelfReport, Status};
pub use state::{ControllerState, Peer};
pub use types::*;

use std::collections::{BTreeMap, BTreeSet};

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
    /// Heartbeats that named this controller's id with another incarnation (misconfiguration).
    duplicate_id_heartbeats: u64,
    /// Whose round phase it follows, and by how much its clock must move (crate::phase).
    phase: phase::PhaseFollower,
    /// Set when it failed itself and a delay is configured: when it leaves.
    exit: Option<failure::PendingExit>,
    /// A new life follows no round phase before this instant (crate::Core::follows_phase_at).
    phase_held_until_ms: Option<u64>,
    /// A life begun after a stall holds its `Stalled` alarm about itself until this instant
    /// ([`STALL_ALARM_ROUNDS`] rounds on).
    stall_alarm_until_ms: Option<u64>,
}

/// Rounds a life begun after a stall keeps its `Stalled` alarm about itself: the model's
/// settle bound ("settles after faults stop"), after which a life that did not stall again
/// has settled below the others. An operator sees the alarm for at least that long, and
/// again with every further stall.
pub const STALL_ALARM_ROUNDS: u64 = 10;

impl Core {
    /// A controller starting at `now_ms`. Its first heartbeat is due at once.
    pub fn new(config: CoreConfig, now_ms: u64) -> Core {
        let period_ms = config.heartbeat_period_ms.max(1);
        Core {
            config,
            state: ControllerState::new(config.id, config.incarnation),
            inbox: BTreeMap::new(),
            durable_votes: BTreeMap::new(),
            round_end_ms: next_boundary(now_ms, period_ms),
            heartbeat_due_ms: now_ms,
            window_due_ms: None,
            duplicate_id_heartbeats: 0,
            phase: phase::PhaseFollower::new(period_ms, config.heartbeat_offset_ms()),
            exit: None,
            phase_held_until_ms: None,
            stall_alarm_until_ms: None,
        }
    }

    /// A controller starting again at `now_ms` as a new life of the same process, after a peer
    /// took over from it (F17), which it learns at a round's end: its first heartbeat goes at
    /// the round's heartbeat slot rather than at once, so a peer whose round ends at the same
    /// instant counts it in the next round, as the model's restart at a round's end has it.
    pub(crate) fn start_again(config: CoreConfig, now_ms: u64) -> Core {
        let mut core = Core::new(config, now_ms);
        let period_ms = config.heartbeat_period_ms.max(1);
        let round_start_ms = now_ms / period_ms * period_ms;
        core.heartbeat_due_ms = (round_start_ms + config.heartbeat_offset_ms()).max(now_ms);
        core
    }

    /// Its identity and timing.
    pub fn config(&self) -> &CoreConfig {
        &self.config
    }

    /// The protocol state (read-only): what the conformance abstraction maps to the model.
    pub fn state(&self) -> &ControllerState {
        &self.state
    }

    /// Whether the adapter should measure how its peers' commands arrive
    /// ([`Input::Commands`]): only a Secondary can take over from a starved Primary (F17), so
    /// only a Secondary needs them. A controller that stops measuring reports every peer
    /// unheard, so no verdict outlives the measurement behind it.
    pub fn watches_arrivals(&self) -> bool {
        self.config.architecture == Architecture::Voting && self.state.role == Some(Role::Secondary)
    }

    /// Whether a heartbeat sent at `sent_ms` (on the caller's clock) was sent before the round
    /// now running began: it is late, and the caller drops it as lost. The model's rounds are
    /// synchronous (a heartbeat arrives in its own round or never), and a late heartbeat says
    /// what its sender decided rounds ago: counting it would decide on a stale state.
    pub fn sent_before_this_round(&self, sent_ms: u64) -> bool {
        let period_ms = self.config.heartbeat_period_ms.max(1);
        sent_ms < self.round_end_ms.saturating_sub(period_ms)
    }

    /// Whether a heartbeat sent at `sent_ms` (on the caller's clock) was sent after the round
    /// now running should have ended: it is the next round's, and a caller that fell behind (a
    /// starved or stalled loop, which takes the next round's heartbeats before its overdue
    /// round end) ends this round first ([`Core::due_timer`] at `sent_ms`). Deciding this
    /// round with it would act on what the model's controller hears only a round later.
    pub fn sent_after_this_round(&self, sent_ms: u64) -> bool {
        sent_ms >= self.round_end_ms
    }

    /// Whether a heartbeat arriving at `now_ms` may set this controller's round phase
    /// ([`Input::HeartbeatArrival`]). A new life ([`Input::StartAgain`]) follows no phase
    /// before the next round boundary: the datagrams the kernel kept while the process stood
    /// still (or its starved links queued) arrive in a burst, off their place in the round.
    ///
    /// What they say is another matter: a new life hears at once, as the model's resumed,
    /// unplugged or deposed controller hears the round it comes back in. A heartbeat that
    /// waited from an earlier round is dropped one by one by its send time
    /// ([`Core::sent_before_this_round`]).
    pub fn follows_phase_at(&self, now_ms: u64) -> bool {
        self.phase_held_until_ms
            .is_none_or(|until_ms| now_ms >= until_ms)
    }

    /// Durable vote records received, by peer id.
    pub fn durable_votes(&self) -> &BTreeMap<ControllerId, VoteRecord> {
        &self.durable_votes
    }

    /// The timer that runs at `now_ms`, if any is due; when several are, the round end first,
    /// then the window, then the heartbeat (a caller that fell behind decides before it
    /// speaks).
    pub fn due_timer(&self, now_ms: u64) -> Option<Timer> {
        if now_ms >= self.round_end_ms {
            Some(Timer::RoundEnd)
        } else if self.window_due_ms.is_some_and(|due| now_ms >= due) {
            Some(Timer::WindowExpiry)
        } else if now_ms >= self.heartbeat_due_ms {
            Some(Timer::Heartbeat)
        } else if self.exit_due_ms().is_some_and(|due| now_ms >= due) {
            Some(Timer::Exit)
        } else {
            None
        }
    }

    /// When it leaves, once it failed itself and announced it.
    fn exit_due_ms(&self) -> Option<u64> {
        self.exit.as_ref().and_then(failure::PendingExit::due_at_ms)
    }

    /// When the core must next be stepped with a timer, and which.
    pub fn next_deadline(&self) -> Deadline {
        let at_ms = self
            .window_due_ms
            .into_iter()
            .chain(self.exit_due_ms())
            .chain([self.round_end_ms, self.heartbeat_due_ms])
            .min()
            .unwrap_or(self.round_end_ms);
        let timer = self.due_timer(at_ms).unwrap_or(Timer::RoundEnd);
        Deadline { at_ms, timer }
    }

    /// What this controller says of itself now (the heartbeat it sends).
    pub fn report(&self) -> SelfReport {
        let c = &self.state;
        SelfReport {
            id: c.id,
            incarnation: c.incarnation,
            phase: c.phase,
            role: c.role,
            strength: c.output,
            agreed: c.agreed,
            vote: c.vote,
            epoch: c.epoch,
            provisional: c.provisional,
            established_strength: c.established_strength(),
            took_over_from: c.took_over_from,
        }
    }

    /// Its status: the self-report and its view of the peers.
    pub fn status(&self) -> Status {
        let c = &self.state;
        Status {
            report: self.report(),
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
            duplicate_id_heartbeats: self.duplicate_id_heartbeats,
        }
    }

    /// Feeds one input at time `now_ms`; returns the commands to perform, in order.
    pub fn step(&mut self, input: Input, now_ms: u64) -> Vec<Command> {
        let before = self.state.clone();
        let mut commands = Vec::new();
        let local_fault = input == Input::LocalFault;
        match input {
            Input::Heartbeat(heartbeat) => self.hear(heartbeat),
            Input::HeartbeatArrival(heartbeat) => {
                let phase = self.follows_phase_at(now_ms).then_some(&mut self.phase);
                if let Some(by_ms) =
                    phase.and_then(|phase| phase.on_heartbeat(&self.state, &heartbeat, now_ms))
                {
                    commands.push(Command::MoveClock {
                        by_ms,
                        following: heartbeat.id,
                    });
                }
            }
            Input::StartAgain { cause, incarnation } => {
                return self.start_new_life(cause, incarnation, now_ms);
            }
            Input::Vote(record) => {
                if record.from != self.state.id {
                    self.durable_votes.insert(record.from, record);
                }
            }
            Input::Timer(timer) => {
                if self.due_timer(now_ms) == Some(timer) {
                    self.fire(timer, now_ms, &mut commands);
                }
            }
            Input::LocalFault => {
                if self.state.phase != Phase::Failed {
                    rules::fail_self(&mut self.state);
                }
            }
            Input::Commands { .. } if self.config.architecture != Architecture::Voting => {}
            Input::Commands { from, arrival } => {
                if let Some(peer) = self.state.peers.get_mut(&from) {
                    peer.commands = arrival;
                    if arrival == Arrival::OnTime {
                        rules::take_over_from_late(&mut self.state, from);
                    }
                }
            }
        }
        changes(&before, &self.state, &mut commands);
        if before.phase != Phase::Failed && self.state.phase == Phase::Failed {
            self.failed(before.vote, local_fault, now_ms, &mut commands);
        }
        match self.config.architecture {
            Architecture::Voting if !self.config.is_mutated() => {
                invariants::debug_check(&self.state)
            }
            Architecture::Voting => {}
            other => architectures::debug_check(&other, &self.state),
        }
        if self
            .stall_alarm_until_ms
            .is_some_and(|until| now_ms >= until)
        {
            self.stall_alarm_until_ms = None;
            commands.push(Command::ClearAlarm {
                about: self.state.id,
                reason: AlarmReason::Stalled,
            });
        }
        commands
    }

    /// It has just failed itself: the failure goes out, and with a delay configured, the
    /// leaving is scheduled (due once a heartbeat has announced FAILED).
    fn failed(
        &mut self,
        own_vote: Option<Assignment>,
        local_fault: bool,
        now_ms: u64,
        commands: &mut Vec<Command>,
    ) {
        let failure = failure::Failure::observe(&self.state, own_vote, local_fault);
        let exit_in_ms = self.config.failed_exit_delay_ms;
        if let Some(delay_ms) = exit_in_ms {
            self.exit = Some(failure::PendingExit {
                failure: failure.clone(),
                exit_at_ms: now_ms.saturating_add(delay_ms),
                announced: false,
            });
        }
        commands.push(Command::Failed {
            failure,
            exit_in_ms,
        });
    }

    /// A new life of this process ([`Input::StartAgain`]), which hears from the next round
    /// boundary on.
    fn start_new_life(
        &mut self,
        cause: Restart,
        incarnation: Incarnation,
        now_ms: u64,
    ) -> Vec<Command> {
        if cause == Restart::Detached && !self.config.restarts_when_unplugged() {
            return Vec::new();
        }
        if matches!(cause, Restart::Stalled { .. }) && !self.config.restarts_when_resumed() {
            return Vec::new();
        }
        let config = CoreConfig {
            incarnation,
            ..self.config
        };
        *self = match cause {
            Restart::Deposed => Core::start_again(config, now_ms),
            Restart::Stalled { .. } | Restart::Detached => Core::new(config, now_ms),
        };
        let period_ms = config.heartbeat_period_ms.max(1);
        self.phase_held_until_ms = Some(next_boundary(now_ms, period_ms));
        let mut commands = vec![Command::NewLife { cause }];
        if let (Restart::Stalled { .. }, Architecture::Duplex(duplex)) =
            (cause, &self.config.architecture)
        {
            if duplex.preempt {
                self.state.dwell_rounds_left = architectures::DUPLEX_DWELL_ROUNDS;
            }
        }
        if matches!(cause, Restart::Stalled { .. }) {
            // Named by itself: its peers may never have lost it (a stop shorter than their
            // dead-man deadline), yet the actuator left it (F12, F18).
            self.stall_alarm_until_ms = Some(now_ms + STALL_ALARM_ROUNDS * period_ms);
            commands.push(Command::RaiseAlarm {
                about: self.state.id,
                reason: AlarmReason::Stalled,
            });
        }
        commands
    }

    /// A heartbeat is kept for the round's end; one with this controller's own id and another
    /// incarnation is counted (another process is configured with the same id).
    fn hear(&mut self, heartbeat: Heartbeat) {
        if heartbeat.id != self.state.id {
            self.inbox.insert(heartbeat.id, heartbeat);
        } else if heartbeat.incarnation != self.state.incarnation {
            self.duplicate_id_heartbeats += 1;
        }
    }

    fn fire(&mut self, timer: Timer, now_ms: u64, commands: &mut Vec<Command>) {
        let period_ms = self.config.heartbeat_period_ms.max(1);
        match timer {
            Timer::RoundEnd => {
                let heard: Vec<Heartbeat> = std::mem::take(&mut self.inbox).into_values().collect();
                self.state.establish_writers();
                match &self.config.architecture {
                    Architecture::Voting => rules::end_round(&self.config, &mut self.state, &heard),
                    Architecture::Duplex(duplex) => architectures::duplex_round_end(
                        &self.config,
                        duplex,
                        &mut self.state,
                        &heard,
                        now_ms.saturating_sub(self.round_end_ms),
                    ),
                    Architecture::Pair(pair) => {
                        architectures::pair_round_end(&self.config, pair, &mut self.state, &heard)
                    }
                }
                // A caller that fell behind (a stopped process) runs one round end, not every
                // missed one: it cannot know what it did not hear.
                let missed = now_ms.saturating_sub(self.round_end_ms) / period_ms;
                if missed > 0 {
                    commands.push(Command::RoundEndsMissed { rounds: missed });
                }
                self.round_end_ms = next_boundary(now_ms, period_ms);
                self.heartbeat_due_ms =
                    (self.round_end_ms - period_ms + self.config.heartbeat_offset_ms()).max(now_ms);
                if rules::window_can_expire(&self.config, &self.state) {
                    self.window_due_ms = Some(now_ms);
                }
            }
            Timer::WindowExpiry => {
                self.window_due_ms = None;
                if rules::window_can_expire(&self.config, &self.state) {
                    rules::close_window(&self.config, &mut self.state);
                }
            }
            Timer::Heartbeat => {
                commands.push(Command::PublishHeartbeat(self.report()));
                self.heartbeat_due_ms = self.round_end_ms + self.config.heartbeat_offset_ms();
                if self.state.phase == Phase::Failed {
                    if let Some(exit) = &mut self.exit {
                        exit.announced = true;
                    }
                }
            }
            Timer::Exit => {
                if let Some(exit) = self.exit.take() {
                    commands.push(Command::Exit(exit.failure));
                }
            }
        }
    }
}

/// The commands that follow from a state change.
fn changes(before: &ControllerState, after: &ControllerState, commands: &mut Vec<Command>) {
    if after.deposed && !before.deposed {
        commands.push(Command::StartAgain);
    }
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
    let ids: BTreeSet<ControllerId> = before
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
            (Some(reason), None) => commands.push(Command::ClearAlarm { about: id, reason }),
            _ => {}
        }
    }
}

/// The next multiple of `period_ms` strictly after `now_ms`.
fn next_boundary(now_ms: u64, period_ms: u64) -> u64 {
    (now_ms / period_ms + 1) * period_ms
}

#[cfg(test)]
mod tests;
