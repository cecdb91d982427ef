//! The peers' commands as the voting thread sees them (F17): taken from the follower reader
//! and measured by [`ArrivalWatch`] only while the core wants arrivals
//! (`Core::watches_arrivals`, the Secondary). A Primary or Tertiary neither wakes on nor
//! reads them: the three command streams would otherwise wake every controller's voting
//! thread about ninety times a second for verdicts no rule of theirs reads.

use super::arrival::ArrivalWatch;
use super::{Voting, COMMANDS};
use crate::core::Input;
use rustdds::mio::Poll;

impl Voting {
    /// Starts or stops measuring as the core's role asks. Starting drops what the reader
    /// holds (a sample read now would carry the time it waited as delay) and begins every
    /// writer's baseline afresh; stopping reports every peer unheard to the core.
    pub(super) fn follow_arrivals(&mut self, poll: &Poll) -> Result<(), crate::Error> {
        let wanted = self.core.watches_arrivals();
        if wanted == self.watching_arrivals {
            return Ok(());
        }
        self.watching_arrivals = wanted;
        let reader = &mut self.endpoints.commands_in;
        if wanted {
            drop(reader.take());
            self.command_wakes
                .on(poll, reader, COMMANDS)
                .map_err(|e| crate::Error::io("registering the command reader", e))
        } else {
            self.command_wakes
                .off(poll, reader)
                .map_err(|e| crate::Error::io("deregistering the command reader", e))?;
            let command_deadline_ms = self.arrival.command_deadline_ms();
            let stopped =
                std::mem::replace(&mut self.arrival, ArrivalWatch::new(command_deadline_ms));
            for (from, arrival) in stopped.stop() {
                self.step(Input::Commands { from, arrival });
            }
            Ok(())
        }
    }

    /// Drains the command reader while measuring: how each peer's commands arrive, and which
    /// stopped.
    pub(super) fn take_commands(&mut self) {
        if !self.watching_arrivals {
            return;
        }
        let now_ms = self.clock.now_ms();
        let arrived = rustdds::Timestamp::now();
        let own_id = self.core.config().id;
        let mut changed = Vec::new();
        for command in self.endpoints.commands_in.take() {
            let Some(written) = command.source_timestamp else {
                continue;
            };
            let participant = crate::dds::participant_key(command.writer);
            let Some(from) = self.identities.speaks_for(participant) else {
                continue;
            };
            if from == own_id {
                continue;
            }
            let delay_ms = crate::delay::delay_ms(arrived, written);
            if let Some(arrival) = self.arrival.sample(from, command.writer, delay_ms, now_ms) {
                changed.push((from, arrival));
            }
        }
        changed.extend(self.arrival.silence(now_ms));
        for (from, arrival) in changed {
            self.step(Input::Commands { from, arrival });
        }
    }
}
