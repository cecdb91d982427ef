//! The time a thread was held: neither on a CPU nor waiting for one. The kernel keeps, for
//! every thread, the nanoseconds it ran and the nanoseconds it waited runnable on a run queue
//! (`/proc/thread-self/schedstat`: "run wait slices"); what a gap between two readings has
//! beyond those two the thread spent off every run queue: sleeping in its own waits, blocked,
//! stopped by a signal, or frozen (a freezer cgroup, a paused virtual machine, an I/O stall).
//!
//! That tells a stop from a loaded host, which a gap of the loop alone cannot: on a loaded
//! host a lapsed loop was runnable and waited for a CPU (its gap is run-queue wait), where a
//! stopped one was held for the whole gap. The voting loop's own waits are held time too, but
//! they are bounded (`Voting::wait_max_ms`, at most half a command deadline).
//!
//! A CPU-quota throttle (a cgroup's `cpu.cfs_quota_us`) keeps the thread runnable, so it shows
//! as run-queue wait, as load does: starvation is no stop by this reading.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::time::{Duration, Instant};

/// The scheduler's account of the thread that opened it, and the reading it was last at.
#[derive(Debug)]
pub(super) struct HeldClock {
    /// `/proc/thread-self/schedstat` as opened by the thread measured: the file stays that
    /// thread's whoever reads it.
    account: File,
    /// When it was last read, and the run and wait time it showed (ns).
    last: Option<(Instant, u64)>,
}

impl HeldClock {
    /// The calling thread's account; `None` where the kernel has none (no procfs, a kernel
    /// without schedstats): then only gaps and SIGCONT tell a stop.
    pub(super) fn for_this_thread() -> Option<HeldClock> {
        match File::open("/proc/thread-self/schedstat") {
            Ok(account) => Some(HeldClock {
                account,
                last: None,
            }),
            Err(error) => {
                tracing::warn!(
                    "no scheduler account of the voting thread \
                     (/proc/thread-self/schedstat: {error}): a stop without a SIGCONT \
                     shorter than the peer deadline is not noticed"
                );
                None
            }
        }
    }

    /// How long the thread was held between the last reading and `now` (`None` at the first
    /// reading, or if the account cannot be read); the reading at `now` becomes the last.
    pub(super) fn held_since_last(&mut self, now: Instant) -> Option<Duration> {
        let Some(busy_ns) = self.busy_ns() else {
            self.last = None;
            return None;
        };
        let previous = self.last.replace((now, busy_ns));
        let (then, busy_then_ns) = previous?;
        let gap = now.saturating_duration_since(then);
        let busy = Duration::from_nanos(busy_ns.saturating_sub(busy_then_ns));
        Some(gap.saturating_sub(busy))
    }

    /// Run time plus run-queue wait, ns, as the account says now.
    fn busy_ns(&self) -> Option<u64> {
        let mut text = [0u8; 96];
        let read = self.account.read_at(&mut text, 0).ok()?;
        parse_busy_ns(text.get(..read)?)
    }
}

/// "run wait slices" → run + wait (ns); `None` for anything else.
fn parse_busy_ns(text: &[u8]) -> Option<u64> {
    let text = std::str::from_utf8(text).ok()?;
    let mut fields = text.split_ascii_whitespace();
    let run: u64 = fields.next()?.parse().ok()?;
    let wait: u64 = fields.next()?.parse().ok()?;
    run.checked_add(wait)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_account_is_run_plus_wait() {
        assert_eq!(parse_busy_ns(b"1057947 59494 3\n"), Some(1_117_441));
        assert_eq!(parse_busy_ns(b""), None);
        assert_eq!(parse_busy_ns(b"12"), None);
        assert_eq!(parse_busy_ns(b"x 1 2"), None);
        assert_eq!(parse_busy_ns(b"18446744073709551615 1 0"), None);
    }

    #[test]
    fn a_sleep_is_held_and_a_spin_is_not() {
        let Some(mut clock) = HeldClock::for_this_thread() else {
            return;
        };
        assert_eq!(clock.held_since_last(Instant::now()), None, "first reading");
        std::thread::sleep(Duration::from_millis(60));
        let held = clock.held_since_last(Instant::now()).expect("a reading");
        assert!(
            held >= Duration::from_millis(50),
            "slept 60 ms, held {held:?}"
        );
        let until = Instant::now() + Duration::from_millis(60);
        while Instant::now() < until {
            std::hint::spin_loop();
        }
        let held = clock.held_since_last(Instant::now()).expect("a reading");
        assert!(
            held < Duration::from_millis(30),
            "spun 60 ms, held {held:?}"
        );
    }
}
