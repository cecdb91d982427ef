//! The core's interface: the inputs it takes, the timers it asks for and the commands it
//! returns. Commands are protocol output only; what a person sees (LEDs, console lines, the
//! status view) is a function of [`crate::Status`] in the adapter.

use crate::failure::Failure;
use crate::report::Heartbeat;
use crate::types::{AlarmReason, Arrival, ControllerId, Incarnation, Role, Strength, VoteRecord};

/// The core's timers. When several are due at once they run in this order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Timer {
    /// The round ends: the heartbeats heard are taken in and the controller decides.
    RoundEnd,
    /// The initialization window times out (right after the round end that made it due).
    WindowExpiry,
    /// This controller's heartbeat is due (a quarter period after the round boundary).
    Heartbeat,
    /// A controller that failed itself has announced it and waited the configured delay: it
    /// leaves now ([`Command::Exit`]).
    Exit,
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
    /// A heartbeat whose arrival woke the caller arrived now, stepped before its
    /// [`Input::Heartbeat`] with `now` where the round boundaries are (the caller's clock with
    /// every correction applied): the core may answer [`Command::MoveClock`] (crate::phase).
    HeartbeatArrival(Heartbeat),
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
    /// The caller must start a new life: it did not run for a while, or every link lost its
    /// carrier, or it is answering [`Command::StartAgain`]. `incarnation` is the new life's (a
    /// new value, as at a start of the process). The core answers [`Command::NewLife`] when it
    /// started again (always, but for `Detached` under the `StayWhenUnplugged` mutation).
    StartAgain {
        /// Why.
        cause: Restart,
        /// The new life's incarnation.
        incarnation: Incarnation,
    },
}

/// Why a controller starts a new life within the same process.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Restart {
    /// It did not run for this long (stopped or starved; the caller's stall detection). The
    /// model's F12: a resumed controller is a new incarnation.
    Stalled {
        /// How long it stood still.
        stalled_ms: u64,
    },
    /// Every link lost its carrier (a pulled cable, a dead switch port; the model's F16).
    Detached,
    /// A peer took over from this life, whose commands reached it late (F17).
    Deposed,
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
        strength: Option<Strength>,
    },
    /// Raise a controller alarm about a peer (or about itself: `Stalled`, as a life begun
    /// after a stall).
    RaiseAlarm {
        /// The peer the alarm is about.
        about: ControllerId,
        /// Why.
        reason: AlarmReason,
    },
    /// Clear the alarm about a peer (it came back, or was retired), or its own `Stalled` one.
    ClearAlarm {
        /// The peer the alarm is about.
        about: ControllerId,
        /// The reason it was raised with.
        reason: AlarmReason,
    },
    /// The caller fell behind (a starved or stalled loop): the round end just run is the
    /// one for `rounds` more round boundaries that passed unrun. A record; nothing to do.
    RoundEndsMissed {
        /// Round boundaries passed without a round end of their own.
        rounds: u64,
    },
    /// Start again as a new incarnation, silent until it has heard a round (as after a
    /// stall): a peer took over from this controller, whose commands arrive late (F17). The
    /// caller answers with [`Input::StartAgain`] and a new incarnation.
    StartAgain,
    /// A new life began ([`Input::StartAgain`]): silent until it has heard a round, then it
    /// joins below the others. It follows no round phase before the next round boundary
    /// ([`crate::Core::follows_phase_at`]).
    NewLife {
        /// Why.
        cause: Restart,
    },
    /// Move the round clock by `by_ms` (forward: the round ends sooner; backward: hold the
    /// clock still until it has caught up) to follow the phase of `following`'s rounds
    /// (crate::phase). After moving forward, run the timers now due.
    MoveClock {
        /// The correction, in ms.
        by_ms: i64,
        /// The peer whose phase it follows.
        following: ControllerId,
    },
    /// This controller has just failed itself (FAILED for the rest of this life): why, and in
    /// how long it leaves (`None`: the configuration keeps it up).
    Failed {
        /// Why, and whose votes it disagreed with.
        failure: Failure,
        /// The configured delay before it leaves, counted from now.
        exit_in_ms: Option<u64>,
    },
    /// Leave now (stop, to be restarted): FAILED has been announced and the delay is over.
    Exit(Failure),
}
