//! # Network monitoring: the Network Alarm Participant (NAP), pure
//!
//! Each controller runs one monitor for its like peers (ids 1..=3) on both networks (the
//! paper's "Detect Network Failures - Alarm and Clear"). Every period it publishes a network
//! heartbeat (RLNHB) on each network, carrying its own row of the link matrix: whom it hears,
//! on which network. A monitor therefore sees all twelve directed links, even with one network
//! dead, as long as the other carries the reports. From that matrix it concludes which
//! component failed (a network, a controller's transmitter or receiver on one network, a
//! controller) and raises or clears network alarms with hysteresis.
//!
//! ```text
//!   NapInput::Heartbeat ─┐  ┌────────────────────────────────────────────┐  ┌▶ PublishHeartbeat{A|B}
//!   NapInput::Timer(t) ──┴─▶│ observe ─▶ matrix ─▶ conclude ─▶ alarms    │──┼▶ RaiseAlarm{subject, cause}
//!                           └────────────────────────────────────────────┘  └▶ ClearAlarm{subject}
//! ```
//!
//! Like the voting core, it is pure: the caller passes each input with the time and performs
//! the commands. The adapter's loop:
//!
//! ```
//! # use rl_core::network::{Nap, NapConfig, NapInput};
//! let mut nap = Nap::new(NapConfig::new(1), 0);
//! let now_ms = 250;
//! while let Some(timer) = nap.due_timer(now_ms) {
//!     for command in nap.step(NapInput::Timer(timer), now_ms) {
//!         // publish on the network it names, or raise / clear the alarm
//! #       let _ = command;
//!     }
//! }
//! // `nap.step(NapInput::Heartbeat { received_on, heartbeat }, now_ms)` for each heartbeat
//! // read; sleep until `nap.next_deadline().at_ms`.
//! ```
//!
//! Modules: [`links`] (networks, links, the matrix, the heartbeat), [`observe`] (per-link
//! deadlines), [`mod@conclude`] (the table as a minimum explanation), [`alarms`] (what is alarmed,
//! and when), [`nap`] (the participant that ties them together).

pub mod alarms;
pub mod conclude;
pub mod links;
pub mod nap;
pub mod observe;

pub use alarms::{AlarmBook, AlarmCause, AlarmChange, AlarmSubject, AlarmTiming};
pub use conclude::{
    conclude, findings, links_failed_by, Conclusion, Fault, Finding, Part, Verdict,
    MAX_EXPLANATION_FAULTS,
};
pub use links::{
    Hearing, Link, LinkMatrix, LinkSet, LinkState, Members, Network, NetworkHeartbeat,
    NAP_CONTROLLERS,
};
pub use nap::{Nap, NapCommand, NapConfig, NapDeadline, NapInput, NapTimer};
pub use observe::Observer;

#[cfg(test)]
mod tests;
