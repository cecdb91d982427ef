//! The model's actions: every environment and timer event, which is also the trace
//! vocabulary, with their kinds (the transition classes the trace set covers) and how each
//! reads in a trace.

use crate::types::Id;
use serde::{Deserialize, Serialize};
use std::fmt;

/// One environment or timer event. This enum is also the trace vocabulary.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Action {
    /// The heartbeat `from` sends to `to` in the current round is lost (one-way).
    LoseHeartbeat { from: Id, to: Id },
    /// The round ends: every heartbeat of the round not lost is delivered, then every live
    /// controller runs its dead-man check and its timers.
    Tick,
    /// A controller's initialization window times out (no new peer for the window).
    ExpireWindow { controller: Id },
    /// The latest durable votes not yet received by `to` reach it, as one batch.
    DeliverVotes { to: Id },
    /// A controller's process dies; its durable vote disappears with it.
    Crash { controller: Id },
    /// A crashed or FAILED controller starts again as a new incarnation.
    Restart { controller: Id },
    /// A controller that never ran starts.
    Join { controller: Id },
    /// A controller's process stops (SIGSTOP, a stall) with its memory intact.
    Pause { controller: Id },
    /// A paused controller runs again: its round clock jumped.
    Resume { controller: Id },
    /// A controller is cut off from its peers (every heartbeat to and from it lost) while the
    /// actuator still hears it.
    Isolate { controller: Id },
    /// A controller's own links all go down (a pulled cable, a dead switch port): cut off
    /// from its peers and from the actuator. It sees its carrier go and starts again as a new
    /// incarnation at once, as after a stall (impl/layer/src/link_watch.rs; F16).
    Unplug { controller: Id },
    /// A controller's links are starved (rate-limited): they still carry some of its
    /// datagrams, late, and its carrier stays up. The actuator may miss its commands' deadline
    /// and then receive a late one ([`Action::Lag`], [`Action::CatchUp`]); its peers see its
    /// commands arrive late while the others' arrive on time (F17).
    Starve { controller: Id },
    /// A controller's process is slowed (starved of CPU, throttled): it runs, but late. Its
    /// links are fine; its heartbeats may miss the round's end in any round and the actuator
    /// may miss its commands' deadline ([`Action::Lag`]) until it heals. Its samples are
    /// stamped when written, so its peers do not see them arrive late (no F17 takeover).
    Slow { controller: Id },
    /// A slowed controller's heartbeat of this round misses every peer's round end: one
    /// multicast sample, sent late (a gap that one peer's round sees and another's does not
    /// is a lost heartbeat, budgeted apart).
    LateHeartbeat { from: Id },
    /// A slowed controller's loop takes this round's heartbeats in after its round's end:
    /// every peer's heartbeat of the round is lost to it (a slowed receiver; budgeted with
    /// the late heartbeats).
    HearLate { to: Id },
    /// The round ends while a slowed controller's loop sleeps through it: it ends no round
    /// at this tick (its dead-man counts no miss) and sends no heartbeat in it; its next
    /// round end is one round end for all it missed, as the implementation's loop that fell
    /// behind runs (budgeted with the late heartbeats).
    Oversleep { controller: Id },
    /// A paused controller runs again without noticing it stopped (no signal, no clock jump
    /// it trusts), within its peers' dead-man deadline: it goes on with its memory (F18).
    Thaw { controller: Id },
    /// The actuator misses a starved or slowed controller's command deadline: its writer
    /// counts as silent until a late sample arrives.
    Lag { controller: Id },
    /// A late sample of a starved controller reaches the actuator: its writer counts again.
    CatchUp { controller: Id },
    /// The cut-off, unplugged or starved controller's links work again.
    Heal { controller: Id },
    /// The actuator discovers a controller's newest command writer.
    DiscoverWriter { controller: Id },
    /// Two writers tie at the top strength and DDS's GUID order (which no controller
    /// chooses) hands the actuator to this controller.
    TieBreak { to: Id },
}

/// The action kinds, for transition coverage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionKind {
    LoseHeartbeat,
    Tick,
    ExpireWindow,
    DeliverVotes,
    Crash,
    Restart,
    Join,
    Pause,
    Resume,
    Isolate,
    Unplug,
    Starve,
    Slow,
    LateHeartbeat,
    HearLate,
    Oversleep,
    Thaw,
    Lag,
    CatchUp,
    Heal,
    DiscoverWriter,
    TieBreak,
}

impl ActionKind {
    pub const ALL: [ActionKind; 22] = [
        ActionKind::LoseHeartbeat,
        ActionKind::Tick,
        ActionKind::ExpireWindow,
        ActionKind::DeliverVotes,
        ActionKind::Crash,
        ActionKind::Restart,
        ActionKind::Join,
        ActionKind::Pause,
        ActionKind::Resume,
        ActionKind::Isolate,
        ActionKind::Unplug,
        ActionKind::Starve,
        ActionKind::Slow,
        ActionKind::LateHeartbeat,
        ActionKind::HearLate,
        ActionKind::Oversleep,
        ActionKind::Thaw,
        ActionKind::Lag,
        ActionKind::CatchUp,
        ActionKind::Heal,
        ActionKind::DiscoverWriter,
        ActionKind::TieBreak,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ActionKind::LoseHeartbeat => "lose_heartbeat",
            ActionKind::Tick => "tick",
            ActionKind::ExpireWindow => "expire_window",
            ActionKind::DeliverVotes => "deliver_votes",
            ActionKind::Crash => "crash",
            ActionKind::Restart => "restart",
            ActionKind::Join => "join",
            ActionKind::Pause => "pause",
            ActionKind::Resume => "resume",
            ActionKind::Isolate => "isolate",
            ActionKind::Unplug => "unplug",
            ActionKind::Starve => "starve",
            ActionKind::Slow => "slow",
            ActionKind::LateHeartbeat => "late_heartbeat",
            ActionKind::HearLate => "hear_late",
            ActionKind::Oversleep => "oversleep",
            ActionKind::Thaw => "thaw",
            ActionKind::Lag => "lag",
            ActionKind::CatchUp => "catch_up",
            ActionKind::Heal => "heal",
            ActionKind::DiscoverWriter => "discover_writer",
            ActionKind::TieBreak => "tie_break",
        }
    }
}

impl Action {
    pub fn kind(&self) -> ActionKind {
        match self {
            Action::LoseHeartbeat { .. } => ActionKind::LoseHeartbeat,
            Action::Tick => ActionKind::Tick,
            Action::ExpireWindow { .. } => ActionKind::ExpireWindow,
            Action::DeliverVotes { .. } => ActionKind::DeliverVotes,
            Action::Crash { .. } => ActionKind::Crash,
            Action::Restart { .. } => ActionKind::Restart,
            Action::Join { .. } => ActionKind::Join,
            Action::Pause { .. } => ActionKind::Pause,
            Action::Resume { .. } => ActionKind::Resume,
            Action::Isolate { .. } => ActionKind::Isolate,
            Action::Unplug { .. } => ActionKind::Unplug,
            Action::Starve { .. } => ActionKind::Starve,
            Action::Slow { .. } => ActionKind::Slow,
            Action::LateHeartbeat { .. } => ActionKind::LateHeartbeat,
            Action::HearLate { .. } => ActionKind::HearLate,
            Action::Oversleep { .. } => ActionKind::Oversleep,
            Action::Thaw { .. } => ActionKind::Thaw,
            Action::Lag { .. } => ActionKind::Lag,
            Action::CatchUp { .. } => ActionKind::CatchUp,
            Action::Heal { .. } => ActionKind::Heal,
            Action::DiscoverWriter { .. } => ActionKind::DiscoverWriter,
            Action::TieBreak { .. } => ActionKind::TieBreak,
        }
    }

    /// The controller whose state the action changes first (the receiver for messages);
    /// `None` for the tick, which acts on every controller.
    pub fn actor(&self) -> Option<Id> {
        match *self {
            Action::LoseHeartbeat { from, .. } | Action::LateHeartbeat { from } => Some(from),
            Action::Tick => None,
            Action::ExpireWindow { controller }
            | Action::Crash { controller }
            | Action::Restart { controller }
            | Action::Join { controller }
            | Action::Pause { controller }
            | Action::Resume { controller }
            | Action::Isolate { controller }
            | Action::Unplug { controller }
            | Action::Starve { controller }
            | Action::Slow { controller }
            | Action::Oversleep { controller }
            | Action::Thaw { controller }
            | Action::Lag { controller }
            | Action::CatchUp { controller }
            | Action::Heal { controller }
            | Action::DiscoverWriter { controller } => Some(controller),
            Action::DeliverVotes { to } | Action::TieBreak { to } | Action::HearLate { to } => {
                Some(to)
            }
        }
    }
}

impl fmt::Display for Action {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Action::LoseHeartbeat { from, to } => {
                write!(f, "heartbeat C{from} -> C{to} lost")
            }
            Action::LateHeartbeat { from } => {
                write!(f, "C{from}'s heartbeat late for every peer's round end")
            }
            Action::HearLate { to } => {
                write!(f, "every heartbeat to C{to} late for its round's end")
            }
            Action::Oversleep { controller } => write!(
                f,
                "round ends while C{controller}'s loop sleeps through it (no round end, no heartbeat)"
            ),
            Action::Tick => write!(f, "round ends (heartbeats delivered, dead-man check)"),
            Action::ExpireWindow { controller } => {
                write!(f, "C{controller}: initialization window expires")
            }
            Action::DeliverVotes { to } => write!(f, "pending votes delivered to C{to}"),
            Action::Crash { controller } => write!(f, "C{controller} crashes"),
            Action::Restart { controller } => write!(f, "C{controller} restarts"),
            Action::Join { controller } => write!(f, "C{controller} joins"),
            Action::Pause { controller } => write!(f, "C{controller} pauses"),
            Action::Resume { controller } => write!(f, "C{controller} resumes"),
            Action::Isolate { controller } => {
                write!(
                    f,
                    "C{controller} cut off from its peers (not from the actuator)"
                )
            }
            Action::Unplug { controller } => write!(
                f,
                "C{controller}'s cable pulled (cut off from its peers and the actuator)"
            ),
            Action::Starve { controller } => write!(
                f,
                "C{controller}'s links starved (its datagrams delayed, some dropped)"
            ),
            Action::Slow { controller } => write!(
                f,
                "C{controller}'s process slowed (starved of CPU: it runs, late)"
            ),
            Action::Thaw { controller } => {
                write!(f, "C{controller} runs again without noticing it stopped")
            }
            Action::Lag { controller } => {
                write!(f, "actuator misses C{controller}'s command deadline")
            }
            Action::CatchUp { controller } => {
                write!(f, "a late command of C{controller} reaches the actuator")
            }
            Action::Heal { controller } => write!(f, "C{controller} reconnected to its peers"),
            Action::DiscoverWriter { controller } => {
                write!(f, "actuator discovers C{controller}'s new command writer")
            }
            Action::TieBreak { to } => write!(f, "tie at the top strength broken to C{to}"),
        }
    }
}
