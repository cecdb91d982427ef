//! How long each peer's heartbeat waited on the way, and dropping the ones that arrive a round
//! late.
//!
//! A heartbeat carries when it was written, on its sender's monotonic clock
//! ([`crate::wire::sender_clock_ms`]). The receiver does not know that clock's offset from
//! its own, so it learns it: per peer life, the smallest difference between arrival (on its
//! own monotonic clock) and stamp seen so far is the offset plus the fastest delivery, and
//! whatever a heartbeat takes beyond that is how long it waited (a queue on a rate-limited
//! link, a stalled sender). The smallest difference creeps up by [`CREEP_MS_PER_S`], so two
//! clocks that run at different rates never make on-time heartbeats look late.
//!
//! The core decides what a wait means ([`crate::core::Core::sent_before_this_round`]): a
//! heartbeat sent before the round now running is lost, as in the model, whose rounds are
//! synchronous. Both monotonic clocks ignore wall-clock steps and the round phase's moves,
//! so neither can make a heartbeat look late.

use super::Voting;
use crate::core::{ControllerId, Heartbeat, Incarnation};
use crate::dds::Received;
use crate::event::Event;
use crate::wire::sender_clock_ms;
use std::collections::BTreeMap;
use tracing::debug;

/// How fast the learnt offset may grow, in ms per second: twice the fault lab's fastest
/// clock (1 % fast), two hundred times a crystal's error. A heartbeat queued on a starved
/// link for the whole fault still looks late: the offset grows 20 ms a second, and a
/// heartbeat is late only once it waits past the end of its round (188 ms after its slot).
pub const CREEP_MS_PER_S: u64 = 20;

/// Per peer: the life it heard last, and the smallest arrival-minus-stamp difference.
#[derive(Debug, Default)]
pub struct HeartbeatDelays {
    peers: BTreeMap<ControllerId, PeerClock>,
}

#[derive(Debug)]
struct PeerClock {
    incarnation: Incarnation,
    /// Arrival minus stamp of the fastest delivery (crept up since), in ms.
    fastest_difference_ms: i128,
    /// When it was last measured, on this receiver's clock.
    measured_at_ms: u64,
}

impl HeartbeatDelays {
    /// How long a heartbeat of life (`id`, `incarnation`) stamped `sent_ms` and arriving at
    /// `arrived_ms` (this receiver's [`sender_clock_ms`]) waited beyond the fastest delivery
    /// from that life. The first heartbeat of a life waited 0 by definition.
    pub fn waited_ms(
        &mut self,
        id: ControllerId,
        incarnation: Incarnation,
        sent_ms: u64,
        arrived_ms: u64,
    ) -> u64 {
        let difference_ms = i128::from(arrived_ms) - i128::from(sent_ms);
        let peer = self.peers.entry(id).or_insert(PeerClock {
            incarnation,
            fastest_difference_ms: difference_ms,
            measured_at_ms: arrived_ms,
        });
        if peer.incarnation != incarnation {
            *peer = PeerClock {
                incarnation,
                fastest_difference_ms: difference_ms,
                measured_at_ms: arrived_ms,
            };
        }
        let elapsed_ms = arrived_ms.saturating_sub(peer.measured_at_ms);
        let crept_ms = i128::from(elapsed_ms) * i128::from(CREEP_MS_PER_S) / 1000;
        peer.fastest_difference_ms = (peer.fastest_difference_ms + crept_ms).min(difference_ms);
        peer.measured_at_ms = arrived_ms;
        u64::try_from(difference_ms - peer.fastest_difference_ms).unwrap_or(u64::MAX)
    }
}

impl Voting {
    /// Places an admitted heartbeat in the round it was sent for; whether the core takes it:
    /// one sent before the round now running is dropped as lost ([`Voting::arrived_late`]),
    /// and one sent after it should have ended first ends the rounds due by then
    /// ([`Voting::end_rounds_due_before`]).
    pub(super) fn place_in_its_round(&mut self, heartbeat: &Received<Heartbeat>) -> bool {
        let sent_ms = self.sent_on_round_clock_ms(heartbeat);
        if self.arrived_late(heartbeat, sent_ms) {
            return false;
        }
        self.end_rounds_due_before(sent_ms);
        true
    }

    /// When a heartbeat was sent, on this controller's round clock: now less how long it
    /// waited beyond the fastest delivery from its sender's life (a queue on the way, or this
    /// loop running late). `None` for a heartbeat without a stamp, which cannot be placed.
    fn sent_on_round_clock_ms(&mut self, heartbeat: &Received<Heartbeat>) -> Option<u64> {
        let sent_ms = heartbeat.sent_ms?;
        let waited_ms = self.delays.waited_ms(
            heartbeat.value.id,
            heartbeat.value.incarnation,
            sent_ms,
            sender_clock_ms(),
        );
        Some(self.clock.now_ms().saturating_sub(waited_ms))
    }

    /// Whether a heartbeat sent at `sent_ms` ([`Voting::sent_on_round_clock_ms`]) was sent
    /// before the round now running (it waited in a queue): then it is dropped as lost, with a
    /// `heartbeat_late` event. A heartbeat without a stamp cannot be judged and is taken.
    fn arrived_late(&mut self, heartbeat: &Received<Heartbeat>, sent_ms: Option<u64>) -> bool {
        let Some(sent_ms) = sent_ms else {
            return false;
        };
        if !self.core.sent_before_this_round(sent_ms) {
            return false;
        }
        let from = heartbeat.value.id;
        let waited_ms = self.clock.now_ms().saturating_sub(sent_ms);
        debug!("dropped a heartbeat of C{from} that waited {waited_ms} ms: sent a round before");
        self.event(Event::HeartbeatLate { from, waited_ms });
        true
    }

    /// A heartbeat sent at `sent_ms` after the round now running should have ended is the
    /// next round's: this loop fell behind (starved, stalled), so the rounds due by then end
    /// first, as they would have had it run on time.
    fn end_rounds_due_before(&mut self, sent_ms: Option<u64>) {
        let Some(sent_ms) = sent_ms else {
            return;
        };
        if !self.core.sent_after_this_round(sent_ms) {
            return;
        }
        while let Some(timer) = self.core.due_timer(sent_ms) {
            self.step(crate::core::Input::Timer(timer));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fastest_delivery_sets_the_offset_and_a_queued_heartbeat_has_waited() {
        let mut delays = HeartbeatDelays::default();
        // The sender's clock is 10 s behind; deliveries take 2 ms, then 1 ms.
        assert_eq!(delays.waited_ms(2, 7, 0, 10_002), 0);
        assert_eq!(
            delays.waited_ms(2, 7, 250, 10_251),
            0,
            "faster: the new offset"
        );
        // 3 ms of jitter is within what the offset may creep in a round (5 ms).
        assert_eq!(delays.waited_ms(2, 7, 500, 10_504), 0);
        // Two rounds in a queue: 547 ms over the 10,004 learnt, less 797 ms of creep.
        assert_eq!(delays.waited_ms(2, 7, 750, 11_301), 547 - 15);
    }

    #[test]
    fn a_new_life_is_measured_afresh() {
        let mut delays = HeartbeatDelays::default();
        assert_eq!(delays.waited_ms(2, 7, 0, 10_000), 0);
        // Restarted: its clock starts at 0 again, 5 s later.
        assert_eq!(delays.waited_ms(2, 8, 0, 15_000), 0);
        assert_eq!(delays.waited_ms(2, 8, 250, 15_250), 0);
        // Another peer's offset is its own.
        assert_eq!(delays.waited_ms(3, 1, 40_000, 15_300), 0);
    }

    #[test]
    fn a_slower_sender_clock_is_followed_by_the_creep() {
        let mut delays = HeartbeatDelays::default();
        // The sender's clock runs 1 % slow: each 250 ms round its stamps fall 2.5 ms behind,
        // while the offset may creep 5 ms a round.
        let mut worst_ms = 0;
        for round in 0..400u64 {
            let arrived_ms = 1_000 + round * 250;
            let sent_ms = round * 250 * 99 / 100;
            worst_ms = worst_ms.max(delays.waited_ms(2, 7, sent_ms, arrived_ms));
        }
        assert!(worst_ms <= 3, "on-time heartbeats waited {worst_ms} ms");
    }

    #[test]
    fn an_absurd_stamp_saturates_instead_of_overflowing() {
        let mut delays = HeartbeatDelays::default();
        assert_eq!(delays.waited_ms(2, 7, u64::MAX, 0), 0);
        assert_eq!(delays.waited_ms(2, 7, 0, u64::MAX), u64::MAX);
    }
}
