//! Stall detection: a controller whose voting loop did not run for a peer deadline (SIGSTOP, a
//! frozen virtual machine, a starved CPU), or that was stopped and continued after its
//! commands lapsed, comes back knowing nothing current.
//!
//! While it stood still its peers declared it lost and the Secondary took over; the actuator
//! followed the Secondary after the command deadline. If it went on where it stopped, it would
//! command at its old strength and vote from its old result: the actuator would switch back
//! and the peers would hand it the Primary role again (failback). So it starts again as a new
//! incarnation: silent, it hears a round and joins below the controllers that kept the system
//! running (the model's rule F12, docs/protocol.md).
//!
//! A stop shorter than the peer deadline is no stall to its peers, but one longer than the
//! command deadline is one to the actuator, which has moved to the Secondary's commands
//! meanwhile: going on as it was would move it back, two owner changes for one fault. A gap
//! of the loop alone cannot tell that stop from a loaded host (the loop waits up to 100 ms for
//! samples, and on a busy machine every controller's loop lapses for that long at once), so
//! the clock also listens for SIGCONT, which only a stopped process is sent by whoever
//! stopped it (a shell's `fg`, a debugger, the fault lab): a SIGCONT after a gap of at least
//! the command deadline is a stop the actuator noticed, and the controller starts again as
//! after a stall. A stop without a signal (a frozen virtual machine, a frozen cgroup) is
//! seen only once it reaches the peer deadline.
//!
//! The voting loop marks the [`LoopClock`] at every iteration and restarts the core when the
//! gap since the last mark is a stall. The command writer, which runs in the application's
//! thread and may wake first after a stop, checks the same clock
//! ([`LoopClock::stalled_for_writer`]) and writes nothing while the loop has not run for a
//! peer deadline, or for a command deadline with a SIGCONT since, and after a stall until the
//! loop has put the new, silent core's status in place ([`LoopClock::resumed`]): in between the status still says what the
//! controller was before it stopped.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long the loop waits for a SIGCONT after finding itself still for a command deadline.
/// All threads wake at SIGCONT and its handler runs in whichever dequeues it first, which on a
/// busy machine may be scheduled a few milliseconds after the loop.
const SIGCONT_SETTLE: Duration = Duration::from_millis(30);
/// How long a writer back from a command deadline of standing still waits for the loop to
/// decide whether it was a stop: the loop's settling and a margin.
const WRITER_WAIT: Duration = Duration::from_millis(50);
/// The step of both waits.
const WAIT_STEP: Duration = Duration::from_millis(1);

/// When the voting loop last ran, shared by the loop and the command writer.
#[derive(Debug)]
pub struct LoopClock {
    state: Mutex<Marks>,
    /// A gap this long is a stall: the peer deadline.
    stall_after: Duration,
    /// A gap this long with a SIGCONT since is a stop the actuator noticed: the command
    /// deadline.
    noticed_after: Duration,
    /// Set by SIGCONT, taken by the loop's next mark.
    continued: Arc<AtomicBool>,
    /// The SIGCONT handler's registration, removed with the clock (`None`: it could not be
    /// installed, and only gaps of a peer deadline are seen).
    sigcont: Option<signal_hook::SigId>,
}

#[derive(Debug)]
struct Marks {
    last_mark: Instant,
    /// This controller's last command written (any writer of its group); `None`: none yet.
    last_write: Option<Instant>,
    /// The loop found itself still for a command deadline and waits for a SIGCONT.
    settling: bool,
    /// The loop found a stall and restarts the core: stalled until [`LoopClock::resumed`].
    restarting: bool,
}

impl Marks {
    fn since_mark(&self, now: Instant) -> Duration {
        now.saturating_duration_since(self.last_mark)
    }
}

impl LoopClock {
    /// A clock marked now, for which a gap of `stall_after_ms` (the peer deadline, ms) is a
    /// stall, and so is a gap of `noticed_after_ms` (the command deadline) with a SIGCONT
    /// since. The voting loop must mark it more often than every `noticed_after_ms` while it
    /// runs.
    pub fn new(stall_after_ms: u64, noticed_after_ms: u64) -> LoopClock {
        let continued = Arc::new(AtomicBool::new(false));
        let sigcont =
            signal_hook::flag::register(signal_hook::consts::SIGCONT, Arc::clone(&continued));
        let sigcont = match sigcont {
            Ok(id) => Some(id),
            Err(error) => {
                tracing::warn!(
                    "no SIGCONT handler ({error}): a stop shorter than the peer deadline is \
                     not noticed, and the actuator may switch back at the continue"
                );
                None
            }
        };
        LoopClock {
            state: Mutex::new(Marks {
                last_mark: Instant::now(),
                last_write: None,
                settling: false,
                restarting: false,
            }),
            stall_after: Duration::from_millis(stall_after_ms),
            noticed_after: Duration::from_millis(noticed_after_ms),
            continued,
            sigcont,
        }
    }

    fn marks(&self) -> std::sync::MutexGuard<'_, Marks> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn continued(&self) -> bool {
        self.continued.load(Ordering::SeqCst)
    }

    /// The voting loop runs now; returns the stall it comes back from (the gap since the last
    /// mark), if any: a gap of the peer deadline, or of the command deadline with a SIGCONT
    /// since. After a gap of the command deadline without one it waits up to
    /// 30 ms for the SIGCONT's handler to run (only then: a running loop marks
    /// more often). After a stall the clock stays stalled until [`LoopClock::resumed`].
    pub fn mark(&self) -> Option<Duration> {
        // Taken first: a SIGCONT after this mark belongs to the next gap, and one to a
        // running controller is dropped here.
        let continued = self.continued.swap(false, Ordering::SeqCst);
        let now = Instant::now();
        let gap = {
            let mut marks = self.marks();
            let gap = marks.since_mark(now);
            if marks.restarting
                || gap >= self.stall_after
                || (continued && gap >= self.noticed_after)
            {
                marks.restarting = true;
                return Some(gap);
            }
            if gap < self.noticed_after {
                marks.last_mark = now;
                return None;
            }
            marks.settling = true;
            gap
        };
        // Still for a command deadline: stopped and continued, or a loaded host.
        let until = now + SIGCONT_SETTLE;
        while !self.continued() && Instant::now() < until {
            std::thread::sleep(WAIT_STEP);
        }
        let continued = self.continued.swap(false, Ordering::SeqCst);
        let mut marks = self.marks();
        marks.settling = false;
        if continued {
            marks.restarting = true;
            return Some(gap);
        }
        marks.last_mark = Instant::now();
        None
    }

    /// The voting loop has started again after a stall and published its new status:
    /// commands may follow that status from now on.
    pub fn resumed(&self) {
        let mut marks = self.marks();
        marks.last_mark = Instant::now();
        marks.restarting = false;
    }

    /// A command of this controller was written now.
    pub fn wrote(&self) {
        self.marks().last_write = Some(Instant::now());
    }

    /// Whether the loop is past a stall (restarting, or still for a peer deadline), or still
    /// for a command deadline with a SIGCONT since.
    fn past_a_stall(&self, continued: bool) -> bool {
        let marks = self.marks();
        let gap = marks.since_mark(Instant::now());
        marks.restarting
            || gap >= self.stall_after
            || (continued && (marks.settling || gap >= self.noticed_after))
    }

    /// Whether a writer must write nothing now: the loop has not run for a stall (it is
    /// stopped, or has just resumed and not yet noticed, or is restarting). A writer whose
    /// commands have lapsed for a command deadline while the loop stood still as long (the
    /// whole process was, or a loaded host starved both) waits up to 50 ms for the
    /// loop to tell a stop from a slow start; one that wrote within the command deadline
    /// cannot have been stopped that long, and never waits.
    pub fn stalled_for_writer(&self) -> bool {
        if self.past_a_stall(self.continued()) {
            return true;
        }
        let now = Instant::now();
        let (writes_lapsed, loop_still) = {
            let marks = self.marks();
            let writes_lapsed = marks
                .last_write
                .is_none_or(|w| now.saturating_duration_since(w) >= self.noticed_after);
            let loop_still = marks.settling || marks.since_mark(now) >= self.noticed_after;
            (writes_lapsed, loop_still)
        };
        if !(writes_lapsed && loop_still) {
            return false;
        }
        let until = now + WRITER_WAIT;
        while Instant::now() < until {
            if self.past_a_stall(self.continued()) {
                return true;
            }
            let decided = {
                let marks = self.marks();
                !marks.settling && marks.since_mark(Instant::now()) < self.noticed_after
            };
            if decided {
                return false;
            }
            std::thread::sleep(WAIT_STEP);
        }
        self.past_a_stall(self.continued())
    }

    /// [`LoopClock::stalled_for_writer`] without waiting, for tests.
    #[cfg(test)]
    fn stalled(&self) -> bool {
        self.past_a_stall(self.continued())
    }
}

impl Drop for LoopClock {
    fn drop(&mut self) {
        if let Some(id) = self.sigcont.take() {
            signal_hook::low_level::unregister(id);
        }
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
        let clock = LoopClock::new(40, 20);
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
        assert!(clock.mark().is_some(), "and the loop still sees it");
        clock.resumed();
        assert!(!clock.stalled(), "running again");
        assert_eq!(clock.mark(), None);
    }

    /// (The SIGCONT tests are tests/sigcont_stop.rs: a SIGCONT reaches every clock of the
    /// process, so they run in a process of their own.)
    #[test]
    fn a_slow_loop_without_a_sigcont_is_no_stall() {
        let clock = LoopClock::new(10_000, 20);
        assert_eq!(clock.mark(), None);
        std::thread::sleep(Duration::from_millis(40));
        assert!(!clock.stalled(), "a loaded host's lapse is not a stop");
        clock.wrote();
        assert!(
            !clock.stalled_for_writer(),
            "a writer that wrote within the deadline was not stopped"
        );
        assert_eq!(
            clock.mark(),
            None,
            "after its settling wait, the loop goes on"
        );
        std::thread::sleep(Duration::from_millis(40));
        let started = Instant::now();
        assert!(
            !clock.stalled_for_writer(),
            "a writer that lapsed with the loop writes once the loop has decided"
        );
        assert!(started.elapsed() >= WRITER_WAIT, "it waited for the loop");
    }

    #[test]
    fn incarnations_grow_with_time() {
        assert!(incarnation(2) > incarnation(1));
    }
}
