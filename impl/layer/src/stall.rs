//! Stall detection: a controller whose voting loop did not run for a peer deadline (SIGSTOP, a
//! frozen virtual machine, a starved CPU) comes back knowing nothing current.
//!
//! While it stood still its peers declared it lost and the Secondary took over; the actuator
//! followed the Secondary after the command deadline. If it went on where it stopped, it would
//! command at its old strength and vote from its old result: the actuator would switch back
//! and the peers would hand it the Primary role again (failback). So it starts again as a new
//! incarnation: silent, it hears a round and joins below the controllers that kept the system
//! running (the model's rule F12, docs/protocol.md).
//!
//! The voting loop marks the [`LoopClock`] at every iteration and restarts the core when the
//! gap since the last mark reaches the peer deadline. The command writer, which runs in the
//! application's thread and may wake first after a stop, checks the same clock and writes
//! nothing while the loop has not run for that long, and after a stall until the loop has put
//! the new, silent core's status in place ([`LoopClock::resumed`]): in between the status
//! still says what the controller was before it stopped.

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// When the voting loop last ran, shared by the loop and the command writer.
#[derive(Debug)]
pub struct LoopClock {
    last_mark: Mutex<Instant>,
    /// A gap this long is a stall: the peer deadline.
    stall_after: Duration,
}

impl LoopClock {
    /// A clock marked now, for which a gap of `stall_after_ms` (the peer deadline, ms) is a
    /// stall.
    pub fn new(stall_after_ms: u64) -> LoopClock {
        LoopClock {
            last_mark: Mutex::new(Instant::now()),
            stall_after: Duration::from_millis(stall_after_ms),
        }
    }

    /// The voting loop runs now; returns the stall it comes back from, if the gap since the
    /// last mark reached the peer deadline. After a stall the clock stays stalled until
    /// [`LoopClock::resumed`].
    pub fn mark(&self) -> Option<Duration> {
        let now = Instant::now();
        let mut last = self.last_mark.lock().unwrap_or_else(|e| e.into_inner());
        let gap = now.saturating_duration_since(*last);
        if gap >= self.stall_after {
            return Some(gap);
        }
        *last = now;
        None
    }

    /// The voting loop has started again after a stall and published its new status:
    /// commands may follow that status from now on.
    pub fn resumed(&self) {
        *self.last_mark.lock().unwrap_or_else(|e| e.into_inner()) = Instant::now();
    }

    /// The voting loop has not run for the peer deadline (it is stopped, or has just resumed
    /// and not yet noticed): commands must wait.
    pub fn stalled(&self) -> bool {
        let last = *self.last_mark.lock().unwrap_or_else(|e| e.into_inner());
        Instant::now().saturating_duration_since(last) >= self.stall_after
    }
}

/// A new incarnation number: the time in milliseconds with the pid, as at start, so a restart
/// in the same process is told apart from the life before it.
pub fn incarnation(now_ms: u64) -> u64 {
    now_ms << 16 | u64::from(std::process::id() & 0xffff)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gap_of_the_peer_deadline_is_a_stall_and_a_shorter_one_is_not() {
        let clock = LoopClock::new(40);
        assert_eq!(clock.mark(), None);
        assert!(!clock.stalled());
        std::thread::sleep(Duration::from_millis(10));
        assert_eq!(clock.mark(), None, "10 ms is no stall");
        std::thread::sleep(Duration::from_millis(50));
        assert!(
            clock.stalled(),
            "the writer sees the stall before the loop runs"
        );
        let gap = clock.mark().expect("50 ms is a stall");
        assert!(gap >= Duration::from_millis(40));
        assert!(
            clock.stalled(),
            "still stalled until the loop has restarted the core"
        );
        clock.resumed();
        assert!(!clock.stalled(), "running again");
        assert_eq!(clock.mark(), None);
    }

    #[test]
    fn incarnations_grow_with_time() {
        assert!(incarnation(2) > incarnation(1));
    }
}
