//! The RL API: the one small surface an application uses.
//!
//! ```no_run
//! # fn main() -> Result<(), rl_layer::Error> {
//! let config = rl_layer::config::Config::default();
//! let rl = rl_layer::api::Redundancy::start(&config, 1, rl_layer::api::Options::default())?;
//! let mut commands = rl.command_writer()?;
//! loop {
//!     // ... compute a command from the application's inputs ...
//!     let command = rl_layer::wire::ServoControl { pan: 500, tilt: 500, frequency: 60 };
//!     commands.write(command)?; // written only while this controller holds a role,
//!                               // at its role's ownership strength
//!     if rl.status().report.phase == rl_layer::core::Phase::Failed { break; }
//! #   break;
//! }
//! # Ok(()) }
//! ```
//!
//! [`Redundancy::start`] joins DDS and runs the voting core in its own thread (heartbeats,
//! votes, alarms, LEDs, console, the ROS 2 status topic). The application reads the current
//! role and state ([`Redundancy::status`], [`Redundancy::role`]), the raised alarms, reports
//! its own faults ([`Redundancy::report_fault`]), and writes commands through a
//! [`CommandWriter`] whose ownership strength always follows the role.
//!
//! A controller that votes itself FAILED stays FAILED for the rest of its life, so the layer
//! stops by itself `timing.failed_exit_delay_ms` after it failed ([`Redundancy::is_finished`]
//! turns true, [`Redundancy::stop`] returns [`crate::Error::Failed`]); the application should
//! then exit with [`crate::Error::exit_code`] to be restarted (crate::failed_exit).

use crate::config::{AperiodicPolicy, Config};
use crate::core::types::{AlarmReason, ControllerId, Role};
use crate::core::Status;
use crate::dds::{self, DdsError, Session};
pub use crate::runtime::Options;
use crate::runtime::{self, Shared};
use crate::wire::ServoControl;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::thread::JoinHandle;

/// A running redundancy layer: one controller of the voting group.
pub struct Redundancy {
    shared: Arc<Shared>,
    session: Arc<Session>,
    config: Config,
    thread: Option<JoinHandle<Result<(), crate::Error>>>,
}

impl Redundancy {
    /// Joins the configured DDS domain as controller `id` and starts voting.
    pub fn start(
        config: &Config,
        id: ControllerId,
        options: Options,
    ) -> Result<Redundancy, crate::Error> {
        // On two networks every datagram goes out on both, so losing one loses nothing.
        // With a keystore, secured (checked first: a bad file is named, exit status 2).
        let session = Arc::new(Session::for_config(config)?);
        let (shared, thread) = runtime::spawn(Arc::clone(&session), config.clone(), id, options)?;
        Ok(Redundancy {
            shared,
            session,
            config: config.clone(),
            thread: Some(thread),
        })
    }

    /// The current protocol state: phase, role, strength, agreed result, vote, view, alarms.
    pub fn status(&self) -> Status {
        self.shared.status().clone()
    }

    /// The role this controller holds now.
    pub fn role(&self) -> Option<Role> {
        self.shared.status().report.role
    }

    /// The ownership strength its commands carry now (`None`: it must not command).
    pub fn strength(&self) -> Option<u8> {
        self.shared.status().report.strength
    }

    /// Controller alarms this controller has raised and not cleared.
    pub fn alarms(&self) -> Vec<(ControllerId, AlarmReason)> {
        self.shared
            .alarms
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }

    /// The application detected its own fault: the controller fails itself (stops commanding,
    /// announces FAILED so the others re-vote).
    pub fn report_fault(&self) {
        self.shared.fault.store(true, Ordering::SeqCst);
    }

    /// The DDS session (to create the application's own readers on the same participant).
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// A writer of the command topic that carries this controller's role strength.
    pub fn command_writer(&self) -> Result<CommandWriter, crate::Error> {
        let writer = self
            .session
            .command_writer(None)
            .map_err(|e| crate::Error::Dds(e.to_string()))?;
        Ok(CommandWriter {
            shared: Arc::clone(&self.shared),
            writer,
            policy: self.config.tracker.aperiodic,
        })
    }

    /// The voting thread ended (an error, `stop`, or the controller failed itself and its
    /// `timing.failed_exit_delay_ms` is over).
    pub fn is_finished(&self) -> bool {
        self.thread.as_ref().is_none_or(JoinHandle::is_finished)
    }

    /// Stops the voting thread and returns how it ended: [`crate::Error::Failed`] if it
    /// stopped because the controller failed itself.
    pub fn stop(mut self) -> Result<(), crate::Error> {
        self.shared.stop.store(true, Ordering::SeqCst);
        match self.thread.take() {
            Some(thread) => thread.join().unwrap_or_else(|_| {
                Err(crate::Error::Runtime("the voting thread panicked".into()))
            }),
            None => Ok(()),
        }
    }
}

impl Drop for Redundancy {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Writes commands at the strength of the controller's current role; writes nothing while it
/// holds none. The DDS writer is re-created when the strength changes (RustDDS fixes a
/// writer's ownership strength at creation).
pub struct CommandWriter {
    shared: Arc<Shared>,
    writer: dds::CommandWriter,
    policy: AperiodicPolicy,
}

impl CommandWriter {
    /// Writes `command` if this controller may command now; returns whether it was written.
    pub fn write(&mut self, command: ServoControl) -> Result<bool, DdsError> {
        let (role, strength) = {
            let status = self.shared.status();
            (status.report.role, status.report.strength)
        };
        let allowed = match self.policy {
            AperiodicPolicy::Republish => strength,
            AperiodicPolicy::PrimaryOnly => strength.filter(|_| role == Some(Role::Primary)),
        };
        // Back from a stop before the voting loop has noticed: what the status says is stale
        // (a new Primary commands meanwhile), so the writer goes and nothing is written.
        let allowed = allowed.filter(|_| !self.shared.loop_clock.stalled());
        self.writer.set_strength(allowed.map(i32::from))?;
        self.writer.write(command)
    }

    /// The strength of the DDS writer now (`None`: no writer).
    pub fn strength(&self) -> Option<i32> {
        self.writer.strength()
    }
}
