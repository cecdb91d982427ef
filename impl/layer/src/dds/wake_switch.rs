//! Turning a reader's wake-ups on and off. A RustDDS reader signals a mio 0.6 poll through a
//! channel that can be registered with a poll once only ("receiver already registered"):
//! after the first registration, waking is switched off by deregistering (an empty interest)
//! and on again by reregistering. The voting thread watches the command reader only while
//! its controller is the Secondary (crate::runtime), which a controller can become many
//! times in one life.

use rustdds::mio::{Evented, Poll, PollOpt, Ready, Token};
use std::io;

/// Whether a source wakes a poll, and whether it was ever registered with it.
#[derive(Debug, Default)]
pub struct WakeSwitch {
    registered: bool,
    on: bool,
}

impl WakeSwitch {
    /// Off, and never registered.
    pub fn new() -> WakeSwitch {
        WakeSwitch::default()
    }

    /// Whether `source` wakes the poll now.
    pub fn is_on(&self) -> bool {
        self.on
    }

    /// From now on `source` wakes `poll` with `token` when readable (edge-triggered).
    pub fn on(&mut self, poll: &Poll, source: &dyn Evented, token: Token) -> io::Result<()> {
        if self.on {
            return Ok(());
        }
        if self.registered {
            poll.reregister(source, token, Ready::readable(), PollOpt::edge())?;
        } else {
            poll.register(source, token, Ready::readable(), PollOpt::edge())?;
            self.registered = true;
        }
        self.on = true;
        Ok(())
    }

    /// From now on `source` does not wake `poll`; its samples wait in the reader.
    pub fn off(&mut self, poll: &Poll, source: &dyn Evented) -> io::Result<()> {
        if !self.on {
            return Ok(());
        }
        poll.deregister(source)?;
        self.on = false;
        Ok(())
    }
}
