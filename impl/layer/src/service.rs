//! Running under systemd (`Type=notify`, `WatchdogSec=`): the controller tells the service
//! manager when it is ready (`READY=1`), what it is doing (`STATUS=`), that it is alive
//! (`WATCHDOG=1`) and that it is stopping (`STOPPING=1`), through `sd-notify`. Without
//! `NOTIFY_SOCKET` (run by hand, in tests) every notification is a no-op.
//!
//! A watchdog ping must mean that the controller works, not only that some thread runs. The
//! controller has two loops: the voting thread (runtime.rs) and the application's loop
//! (controller.rs). The voting loop marks a shared [`LoopProgress`] at every iteration; the
//! application loop calls [`Notifier::tick`], which pings only while that mark is recent. So
//! either loop getting stuck stops the pings, and systemd restarts the service after
//! `WatchdogSec`.
//!
//! Both loops can run while nothing reaches the network: RustDDS sends and receives on its
//! own thread, the participant's event loop, which exits on a poll error, and writes still
//! return `Ok` after it has gone. So the pings also require that loop to go round
//! ([`Notifier::watch_dds_loop`], fed by `DomainParticipant::event_loop_iterations`). It goes
//! round at least every 2 s when idle, and at every heartbeat RL writes. This is the loop's
//! own progress, not hearing the peers: a dead network must raise alarms, not restart the
//! controller.
//!
//! Pings go out every half of `WATCHDOG_USEC` (systemd's advice); `WATCHDOG_PID`, when set,
//! must be this process, as for `sd_watchdog_enabled(3)`.

use sd_notify::NotifyState;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};
use tracing::warn;

/// When a loop last went round, as milliseconds since the value was made.
#[derive(Debug)]
pub struct LoopProgress {
    origin: Instant,
    last_ms: AtomicU64,
}

impl Default for LoopProgress {
    fn default() -> LoopProgress {
        LoopProgress::new()
    }
}

impl LoopProgress {
    /// Marked now.
    pub fn new() -> LoopProgress {
        LoopProgress {
            origin: Instant::now(),
            last_ms: AtomicU64::new(0),
        }
    }

    /// The loop went round now.
    pub fn mark(&self) {
        self.mark_at(Instant::now());
    }

    /// The loop went round at `at`.
    pub fn mark_at(&self, at: Instant) {
        let elapsed_ms = at.saturating_duration_since(self.origin).as_millis() as u64;
        self.last_ms.store(elapsed_ms, Ordering::Relaxed);
    }

    /// How long ago the loop last went round, seen at `now`.
    pub fn age_at(&self, now: Instant) -> Duration {
        let last = self.origin + Duration::from_millis(self.last_ms.load(Ordering::Relaxed));
        now.saturating_duration_since(last)
    }
}

/// The watchdog interval systemd asked for, from `WATCHDOG_USEC` and `WATCHDOG_PID`.
pub fn watchdog_from_env() -> Option<Duration> {
    let usec: u64 = std::env::var("WATCHDOG_USEC").ok()?.trim().parse().ok()?;
    if let Ok(pid) = std::env::var("WATCHDOG_PID") {
        if pid.trim().parse::<u32>().ok()? != std::process::id() {
            return None;
        }
    }
    (usec > 0).then(|| Duration::from_micros(usec))
}

/// What [`Notifier::tick`] decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tick {
    /// No watchdog, or the last ping is recent enough.
    Idle,
    /// A ping is due and the voting loop is alive: ping.
    Ping,
    /// A ping is due but the voting loop has not gone round within the ping interval.
    Withheld,
}

/// A loop seen through a counter it increments each time round: progress is the counter
/// having changed.
struct CountedLoop {
    read: Box<dyn Fn() -> u64 + Send>,
    last_count: u64,
    progress: LoopProgress,
}

impl CountedLoop {
    fn observe(&mut self, now: Instant) {
        let count = (self.read)();
        if count != self.last_count {
            self.last_count = count;
            self.progress.mark_at(now);
        }
    }
}

impl std::fmt::Debug for CountedLoop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CountedLoop")
            .field("last_count", &self.last_count)
            .field("progress", &self.progress)
            .finish()
    }
}

/// Sends the service manager the controller's notifications.
#[derive(Debug)]
pub struct Notifier {
    /// Half the watchdog timeout; `None` without a watchdog.
    ping_interval: Option<Duration>,
    last_ping: Option<Instant>,
    voting: std::sync::Arc<LoopProgress>,
    /// RustDDS's event loop, once [`Notifier::watch_dds_loop`] named it.
    dds: Option<CountedLoop>,
    withheld: bool,
    status: String,
    send_failed: bool,
}

impl Notifier {
    /// A notifier for a process whose watchdog timeout is `watchdog` (see
    /// [`watchdog_from_env`]); `voting` is the voting loop's progress.
    pub fn new(watchdog: Option<Duration>, voting: std::sync::Arc<LoopProgress>) -> Notifier {
        Notifier {
            ping_interval: watchdog.map(|timeout| timeout / 2),
            last_ping: None,
            voting,
            dds: None,
            withheld: false,
            status: String::new(),
            send_failed: false,
        }
    }

    /// Pings also require `iterations` (RustDDS's event loop count,
    /// `DomainParticipant::event_loop_iterations`) to have grown within the ping interval.
    pub fn watch_dds_loop(&mut self, iterations: impl Fn() -> u64 + Send + 'static) {
        let last_count = iterations();
        self.dds = Some(CountedLoop {
            read: Box::new(iterations),
            last_count,
            progress: LoopProgress::new(),
        });
    }

    /// The interval between pings, if systemd watches this process.
    pub fn ping_interval(&self) -> Option<Duration> {
        self.ping_interval
    }

    /// Startup finished: DDS joined, the voting thread runs.
    pub fn ready(&mut self) {
        self.send(&[NotifyState::Ready]);
    }

    /// `systemctl status` shows `text`; sent only when it changes.
    pub fn status(&mut self, text: &str) {
        if self.status != text {
            self.status = text.to_string();
            self.send(&[NotifyState::Status(text)]);
        }
    }

    /// Shutting down. Lets go of RustDDS's event loop counter (and whatever it holds, such as
    /// the participant), so the participant can be closed.
    pub fn stopping(&mut self) {
        self.dds = None;
        self.send(&[NotifyState::Stopping]);
    }

    /// Called from the application loop: pings the watchdog when a ping is due and the voting
    /// loop (and RustDDS's event loop, if watched) went round within the ping interval.
    pub fn tick(&mut self, now: Instant) -> Tick {
        if let Some(dds) = &mut self.dds {
            dds.observe(now);
        }
        let decision = self.decide(now);
        match decision {
            Tick::Ping => {
                self.last_ping = Some(now);
                if self.withheld {
                    self.withheld = false;
                    warn!("the controller's loops run again: watchdog pings resumed");
                }
                self.send(&[NotifyState::Watchdog]);
            }
            Tick::Withheld if !self.withheld => {
                self.withheld = true;
                let (stuck, age) = self.slowest_loop(now);
                warn!(
                    "{stuck} has not run for {} ms: watchdog pings withheld, systemd will \
                     restart the service",
                    age.as_millis()
                );
            }
            Tick::Withheld | Tick::Idle => {}
        }
        decision
    }

    fn decide(&self, now: Instant) -> Tick {
        let Some(interval) = self.ping_interval else {
            return Tick::Idle;
        };
        let due = self
            .last_ping
            .is_none_or(|last| now.saturating_duration_since(last) >= interval);
        if !due {
            Tick::Idle
        } else if self.slowest_loop(now).1 < interval {
            Tick::Ping
        } else {
            Tick::Withheld
        }
    }

    /// The watched loop that went round longest ago, and how long ago.
    fn slowest_loop(&self, now: Instant) -> (&'static str, Duration) {
        let voting = ("the voting loop", self.voting.age_at(now));
        match &self.dds {
            Some(dds) if dds.progress.age_at(now) > voting.1 => {
                ("RustDDS's event loop", dds.progress.age_at(now))
            }
            _ => voting,
        }
    }

    fn send(&mut self, states: &[NotifyState]) {
        if let Err(error) = sd_notify::notify(false, states) {
            // Once: a missing socket would otherwise repeat at every ping.
            if !self.send_failed {
                self.send_failed = true;
                warn!("cannot notify the service manager: {error}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn no_watchdog_never_pings() {
        let notifier = Notifier::new(None, Arc::new(LoopProgress::new()));
        assert_eq!(notifier.decide(Instant::now()), Tick::Idle);
        assert_eq!(notifier.ping_interval(), None);
    }

    #[test]
    fn pings_every_half_timeout_while_the_voting_loop_runs() {
        let voting = Arc::new(LoopProgress::new());
        let mut notifier = Notifier::new(Some(Duration::from_secs(2)), Arc::clone(&voting));
        assert_eq!(notifier.ping_interval(), Some(Duration::from_secs(1)));
        let start = voting.origin;
        assert_eq!(notifier.decide(start), Tick::Ping);
        notifier.last_ping = Some(start);
        assert_eq!(notifier.decide(start + ms(999)), Tick::Idle);
        // The voting loop went round 200 ms before the next ping is due: ping.
        voting.mark_at(start + ms(800));
        assert_eq!(notifier.decide(start + ms(1000)), Tick::Ping);
        notifier.last_ping = Some(start + ms(1000));
        assert_eq!(notifier.decide(start + ms(1500)), Tick::Idle);
    }

    #[test]
    fn a_stuck_voting_loop_withholds_pings_until_it_runs_again() {
        let voting = Arc::new(LoopProgress::new());
        let mut notifier = Notifier::new(Some(Duration::from_secs(2)), Arc::clone(&voting));
        let start = voting.origin;
        notifier.last_ping = Some(start);
        // Not gone round for a whole ping interval: no ping, however long it lasts.
        assert_eq!(notifier.decide(start + ms(1000)), Tick::Withheld);
        assert_eq!(notifier.decide(start + ms(5000)), Tick::Withheld);
        voting.mark_at(start + ms(5100));
        assert_eq!(notifier.decide(start + ms(5100)), Tick::Ping);
    }

    #[test]
    fn a_dds_event_loop_that_stops_counting_withholds_pings() {
        use std::sync::atomic::{AtomicU64, Ordering};
        let voting = Arc::new(LoopProgress::new());
        let mut notifier = Notifier::new(Some(Duration::from_secs(2)), Arc::clone(&voting));
        let iterations = Arc::new(AtomicU64::new(0));
        let count = Arc::clone(&iterations);
        notifier.watch_dds_loop(move || count.load(Ordering::Relaxed));
        let start = notifier.dds.as_ref().unwrap().progress.origin;
        notifier.last_ping = Some(start);
        // Both loops go round: ping.
        voting.mark_at(start + ms(900));
        iterations.store(5, Ordering::Relaxed);
        notifier.dds.as_mut().unwrap().observe(start + ms(900));
        assert_eq!(notifier.decide(start + ms(1000)), Tick::Ping);
        notifier.last_ping = Some(start + ms(1000));
        // The voting loop goes on, the event loop's count stands still: no ping.
        voting.mark_at(start + ms(1950));
        notifier.dds.as_mut().unwrap().observe(start + ms(1950));
        assert_eq!(notifier.decide(start + ms(2000)), Tick::Withheld);
        assert_eq!(
            notifier.slowest_loop(start + ms(2000)).0,
            "RustDDS's event loop"
        );
        // It counts again: ping.
        iterations.store(6, Ordering::Relaxed);
        notifier.dds.as_mut().unwrap().observe(start + ms(2100));
        voting.mark_at(start + ms(2100));
        assert_eq!(notifier.decide(start + ms(2100)), Tick::Ping);
    }

    fn ms(value: u64) -> Duration {
        Duration::from_millis(value)
    }

    #[test]
    fn watchdog_env_is_read_as_systemd_sets_it() {
        // One test owns these variables: no other test in this binary reads them.
        std::env::set_var("WATCHDOG_USEC", "3000000");
        std::env::remove_var("WATCHDOG_PID");
        assert_eq!(watchdog_from_env(), Some(Duration::from_secs(3)));
        std::env::set_var("WATCHDOG_PID", std::process::id().to_string());
        assert_eq!(watchdog_from_env(), Some(Duration::from_secs(3)));
        std::env::set_var("WATCHDOG_PID", "1");
        assert_eq!(watchdog_from_env(), None, "another process's watchdog");
        std::env::remove_var("WATCHDOG_PID");
        std::env::set_var("WATCHDOG_USEC", "0");
        assert_eq!(watchdog_from_env(), None);
        std::env::set_var("WATCHDOG_USEC", "soon");
        assert_eq!(watchdog_from_env(), None);
        std::env::remove_var("WATCHDOG_USEC");
        assert_eq!(watchdog_from_env(), None);
    }
}
