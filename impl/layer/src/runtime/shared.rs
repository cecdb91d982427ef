//! What the voting thread and the application share: the options the application starts the
//! layer with, and the state both sides read and write while it runs (crate::api wraps it).

use crate::core::types::{AlarmReason, ControllerId};
use crate::core::Status;
use crate::event::EventLine;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex, MutexGuard};

/// How the redundancy layer reports what it does.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Print one JSON event per line on stdout (status, outputs, alarms) instead of console
    /// lines: the record that tools and the conformance suite read.
    pub json_events: bool,
    /// Show LEDs on the console (the default LED bank). LEDs on GPIO (`leds.backend =
    /// "gpio"`) are driven either way.
    pub console_leds: bool,
    /// Marked at every iteration of the voting loop, for a watchdog that must stop when the
    /// loop is stuck (crate::service).
    pub voting_progress: Option<Arc<crate::service::LoopProgress>>,
}

/// What the voting thread shares with the application.
#[derive(Debug)]
pub(crate) struct Shared {
    pub status: Mutex<Status>,
    pub alarms: Mutex<Vec<(ControllerId, AlarmReason)>>,
    pub fault: AtomicBool,
    /// The application reported a fault: nothing more goes out in this life, from the moment
    /// it reported it (the voting loop fails the controller at its next turn).
    pub silenced: AtomicBool,
    /// Why, when its cross-check found it the odd one out (crate::cross_check): the voting loop
    /// reports it with the fault.
    pub odd_one_out: Mutex<Option<crate::cross_check::OddOneOut>>,
    pub stop: AtomicBool,
    /// When the voting loop last ran: a stalled loop (crate::stall) lets no command out.
    pub loop_clock: crate::stall::LoopClock,
    /// The application's subscriptions to the event lines (crate::api::Redundancy::events);
    /// one whose receiver is gone is dropped at the next event.
    pub subscribers: Mutex<Vec<Sender<EventLine>>>,
    /// The deliberately broken rule `RL_MUTATION` names (a `mutation` build only), for the
    /// application's own rules (crate::api::Redundancy::mutation).
    #[cfg(feature = "mutation")]
    pub mutation: Option<crate::core::mutation::Mutation>,
}

impl Shared {
    pub fn status(&self) -> MutexGuard<'_, Status> {
        // A poisoned lock only means the other thread panicked mid-update; the value is
        // still the last complete status.
        self.status.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn subscribers(&self) -> MutexGuard<'_, Vec<Sender<EventLine>>> {
        self.subscribers.lock().unwrap_or_else(|e| e.into_inner())
    }
}
