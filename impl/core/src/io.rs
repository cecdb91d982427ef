//! The core's interface: the inputs it takes, the timers it asks for and the commands it
//! returns. Commands are protocol output only; what a person sees (LEDs, console lines, the
//! status view) is a function of [`crate::Status`] in the adapter.

use crate::report::Heartbeat;
use crate::types::{AlarmReason, Arrival, ControllerId, Role, VoteRecord};

/// The core's timers. When several are due at once they run in this order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Timer {
    /// The round ends: the heartbeats heard are taken in and the controller decides.
    RoundEnd,
    /// The initialization window times out (right after the round end that made it due).
    WindowExpiry,
    /// This controller's heartbeat is due (a quarter period after the round boundary).
    Heartbeat,
}

/// When the core must next be stepped, and with which timer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Deadline {
    /// The instant, on the caller's clock.
    pub at_ms: u64,
    /// The timer that fires then.
    pub timer: Timer,
}

/// An input to the core.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Input {
    /// A peer's heartbeat arrived (kept until the round ends).
    Heartbeat(Heartbeat),
    /// A durable vote record arrived (kept for status; no decision reads it).
    Vote(VoteRecord),
    /// A timer fired (see [`crate::Core::due_timer`]); a timer that is not due does nothing.
    Timer(Timer),
    /// The application detected its own fault: fail now (stop commanding, announce FAILED).
    LocalFault,
    /// How a peer's commands now arrive: when that changed, and each on-time command while
    /// another peer's are late (F17: a Secondary takes over from a Primary whose commands
    /// arrive late when a command of the Tertiary then arrives on time).
    Commands {
        /// The peer whose commands these are.
        from: ControllerId,
        /// How they arrive.
        arrival: Arrival,
    },
}

/// What the caller must do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    /// Publish this heartbeat (best effort).
    PublishHeartbeat(Heartbeat),
    /// Publish (durably) this controller's vote record.
    PublishVote(VoteRecord),
    /// Command with this role's strength from now on; `strength: None` = stop commanding.
    SetOutput {
        /// The role it now holds.
        role: Option<Role>,
        /// The ownership strength to command with.
        strength: Option<u8>,
    },
    /// Raise a controller alarm about a peer.
    RaiseAlarm {
        /// The peer the alarm is about.
        about: ControllerId,
        /// Why.
        reason: AlarmReason,
    },
    /// Clear the alarm about a peer (it came back, or was retired).
    ClearAlarm {
        /// The peer the alarm is about.
        about: ControllerId,
        /// The reason it was raised with.
        reason: AlarmReason,
    },
    /// Start again as a new incarnation, silent until it has heard a round (as after a
    /// stall): a peer took over from this controller, whose commands arrive late (F17).
    StartAgain,
}
