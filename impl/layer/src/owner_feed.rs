//! The commands a simulated actuator obeys: `pixy/servo_control` read through the ownership
//! arbiter (rl_layer::arbiter, DDS exclusive ownership on the reading side) and the command trust
//! (crate::sim::command_trust: only a live controller's writers, at most at the takeover strength 35). The
//! camera simulator's gimbal follows it, as the real pan-tilt follows the owner's commands.

use crate::sim::command_trust::CommandTrust;
use rl_layer::arbiter::Arbiter;
use rl_layer::dds::{DdsError, Reader, Session, GUID};
use rl_layer::wire::{HeartbeatSample, ServoControl};
use std::collections::BTreeMap;

/// How often discovery is re-read for writers' strengths.
const STRENGTH_REFRESH_MS: u64 = 100;

/// The owner's commands, as they arrive.
pub struct CommandFeed {
    commands: Reader<ServoControl>,
    heartbeats: Reader<HeartbeatSample>,
    arbiter: Arbiter<GUID>,
    trust: CommandTrust,
    strengths: BTreeMap<GUID, i32>,
    last_refresh_ms: Option<u64>,
}

impl CommandFeed {
    /// The owner's commands from `commands` (an actuator's [`Session::command_reader`], or a
    /// standing-by controller's best-effort [`Session::command_follower_reader`]), with a
    /// heartbeat reader on `session`; `deadline_ms` is the command deadline,
    /// `peer_deadline_ms` how long a controller's participant stays trusted after its last
    /// heartbeat.
    pub fn open(
        session: &Session,
        commands: Reader<ServoControl>,
        deadline_ms: u64,
        peer_deadline_ms: u64,
    ) -> Result<CommandFeed, DdsError> {
        Ok(CommandFeed {
            commands,
            heartbeats: session.heartbeat_reader()?,
            arbiter: Arbiter::new(deadline_ms),
            trust: CommandTrust::new(peer_deadline_ms, false),
            strengths: BTreeMap::new(),
            last_refresh_ms: None,
        })
    }

    fn refresh(&mut self, session: &Session, now_ms: u64) {
        let current = session.command_writer_strengths();
        for gone in self.strengths.keys().filter(|w| !current.contains_key(w)) {
            self.arbiter.writer_lost(*gone);
        }
        self.strengths = current;
        self.last_refresh_ms = Some(now_ms);
    }

    /// The newest command the owner sent since the last call, if any, with its writer.
    pub fn take(&mut self, session: &Session, now_ms: u64) -> Option<(ServoControl, GUID)> {
        for heartbeat in self.heartbeats.take() {
            self.trust.heartbeat(&heartbeat, now_ms);
        }
        if self
            .last_refresh_ms
            .is_none_or(|last| now_ms.saturating_sub(last) >= STRENGTH_REFRESH_MS)
        {
            self.refresh(session, now_ms);
        }
        let mut batch = Vec::new();
        for command in self.commands.take() {
            // A writer not yet in discovery: look again, at most every 10 ms.
            if !self.strengths.contains_key(&command.writer)
                && self
                    .last_refresh_ms
                    .is_none_or(|last| now_ms.saturating_sub(last) >= 10)
            {
                self.refresh(session, now_ms);
            }
            let strength = self.strengths.get(&command.writer).copied().unwrap_or(0);
            batch.push((strength, command));
        }
        // A burst goes strongest first, as at `rl servo` (crate::sim::servo).
        batch.sort_by_key(|(strength, _)| std::cmp::Reverse(*strength));
        let mut newest = None;
        for (strength, command) in batch {
            let writer = command.writer;
            if self.trust.admit(writer, strength).is_err() {
                continue;
            }
            if self.arbiter.offer(writer, strength, now_ms).accepted {
                newest = Some((command.value, writer));
            }
        }
        newest
    }
}
