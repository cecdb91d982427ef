//! The voting loop's clock: milliseconds on the wall clock at start, advanced by the
//! monotonic clock and moved by the phase corrections the core asks for (rl-core's `phase`
//! module decides which peer to follow and by how much, `Command::MoveClock`). It never runs
//! backwards: a correction backwards holds it still instead.
//!
//! Why the rounds must follow a peer's phase at all: a Raspberry Pi has no real-time clock,
//! a ship's LAN may have no time server, and two crystals drift apart by up to about 100 ppm,
//! a quarter period in well under an hour (docs/faults.md, "Clocks").

use std::cell::Cell;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

/// Milliseconds on the wall clock at start, advanced by the monotonic clock and moved by the
/// phase corrections. It never runs backwards: a correction backwards holds it still instead.
#[derive(Clone, Debug)]
pub struct RoundClock {
    started: Instant,
    started_wall_ms: u64,
    /// The sum of the corrections so far.
    moved_ms: i64,
    /// The latest time it returned: what it must not go below.
    latest_ms: Cell<u64>,
}

impl RoundClock {
    /// A clock that reads the wall clock now (0 ms before 1970), with no correction yet.
    pub fn start() -> RoundClock {
        let started_wall_ms = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map(|d| d.as_millis() as u64)
            .unwrap_or(0);
        RoundClock {
            started: Instant::now(),
            started_wall_ms,
            moved_ms: 0,
            latest_ms: Cell::new(started_wall_ms),
        }
    }

    /// The time (ms) with the corrections applied, never below what it last returned.
    pub fn now_ms(&self) -> u64 {
        let latest_ms = self.latest_ms.get().max(self.unheld_ms());
        self.latest_ms.set(latest_ms);
        latest_ms
    }

    /// The time with every correction applied, also while the clock holds still after a move
    /// backwards: where the round boundaries will be, so where phases are measured.
    pub fn unheld_ms(&self) -> u64 {
        let elapsed_ms = self.started.elapsed().as_millis() as u64;
        (self.started_wall_ms + elapsed_ms).saturating_add_signed(self.moved_ms)
    }

    /// Moves the clock by `by_ms` (forward: the round ends sooner; backward: the clock holds
    /// still until the monotonic clock has caught up).
    pub fn shift(&mut self, by_ms: i64) {
        self.moved_ms += by_ms;
    }

    /// The sum of the corrections so far.
    pub fn moved_ms(&self) -> i64 {
        self.moved_ms
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_never_runs_backwards() {
        let mut clock = RoundClock::start();
        let before_ms = clock.now_ms();
        clock.shift(-200);
        let after_ms = clock.now_ms();
        assert!(after_ms >= before_ms, "{after_ms} < {before_ms}");
        assert!(
            clock.unheld_ms() + 150 <= after_ms,
            "the unheld time shows the move"
        );
        clock.shift(300);
        assert!(clock.now_ms() >= before_ms + 100);
        assert_eq!(clock.moved_ms(), 100);
    }
}
