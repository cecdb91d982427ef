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
//! after a stall. A stop without a signal (a frozen virtual machine, a frozen cgroup, a write
//! blocked on a full disk) is told from load by the kernel's account of the voting thread
//! (`stall::held`): a gap of a command deadline in which the thread was held (neither running nor
//! waiting for a CPU) for a command deadline is a stop the actuator noticed too. A loaded
//! host's lapse is run-queue wait, and restarts nobody.
//!
//! A starved process can run its loop on time while its commands reach the wire late, each
//! gap past the actuator's deadline and each late command at the Primary's strength taking the
//! actuator back: so the Primary's writer doubts itself ([`LoopClock::owner_lapsed`]) when its
//! own commands lapsed for half a command deadline, writes nothing more, and the loop starts
//! again. The writing thread cannot see all of it: the DDS event loop that sends falls behind
//! it, and a thread held back between its look at the clock and its write writes late. So
//! the thread that sends decides too: a voting Primary's DDS writer stops for good when, about
//! to send, it finds its last send longer ago than the deadline less a period (RustDDS fix 20,
//! crate::dds::qos::command_max_send_gap_ms), before any reader can have moved to the next
//! writer, and the writer then doubts itself the same way ([`LoopClock::owner_stopped`]).
//!
//! The voting loop marks the [`LoopClock`] at every iteration and restarts the core when the
//! gap since the last mark is a stall. The command writer, which runs in the application's
//! thread and may wake first after a stop, checks the same clock
//! ([`LoopClock::stalled_for_writer`]) and writes nothing while the loop has not run for a
//! peer deadline, or for a command deadline with a SIGCONT since, and after a stall until the
//! loop has put the new, silent core's status in place ([`LoopClock::resumed`]): in between the status still says what the
//! controller was before it stopped. A writer reads the status before it checks the clock, so
//! it takes the clock's count of restarts first ([`LoopClock::restarts`]) and is stalled when
//! that count moved: the loop can restart, publish the new status and resume between two of the
//! writer's looks at the clock, and the status it read is the last life's (measured: a
//! Primary frozen 300 ms wrote one fresh command at 30 after its restart, and the actuator
//! went back to it for a moment, 2 runs in 6 of `lab run freeze-primary`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

mod held;

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
    /// Its last command written as the actuator's owner, with no write in another role since
    /// (`None`: none in this life): what [`LoopClock::owner_lapsed`] measures from, so a
    /// Secondary's old write is no lapse of the Primary it becomes.
    last_owner_write: Option<Instant>,
    /// The loop found itself still for a command deadline and waits for a SIGCONT.
    settling: bool,
    /// The loop found a stall and restarts the core: stalled until [`LoopClock::resumed`].
    restarting: bool,
    /// How many times the loop has started again (each stall or doubt once).
    restarts: u64,
    /// The writer found its commands as the owner lapsed this long ([`LoopClock::owner_lapsed`]):
    /// the loop restarts at its next mark.
    doubted: Option<Duration>,
    /// The voting thread's held time, opened at its first mark (`None` before, or where the
    /// kernel keeps no account).
    held: Option<held::HeldClock>,
    /// Whether the loop's thread has tried to open `held`.
    held_opened: bool,
}

impl Marks {
    /// The loop restarts the core: counted once per stall, however many marks see it.
    fn start_again(&mut self) {
        if !self.restarting {
            self.restarts += 1;
        }
        self.restarting = true;
    }

    fn since_mark(&self, now: Instant) -> Duration {
        now.saturating_duration_since(self.last_mark)
    }

    /// The loop runs at `now` and the next gap starts: how long its thread was held since
    /// the last mark (`None`: no account, or no reading at the last mark).
    fn mark_at(&mut self, now: Instant) -> Option<Duration> {
        if !self.held_opened {
            self.held_opened = true;
            self.held = held::HeldClock::for_this_thread();
        }
        self.last_mark = now;
        self.held.as_mut()?.held_since_last(now)
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
                last_owner_write: None,
                settling: false,
                restarting: false,
                restarts: 0,
                doubted: None,
                held: None,
                held_opened: false,
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
    /// since or with the loop's thread held as long. Only the voting loop's thread may mark:
    /// the first mark opens that thread's account. After a gap of the command deadline
    /// without either it waits up to
    /// 30 ms for the SIGCONT's handler to run (only then: a running loop marks
    /// more often). After a stall the clock stays stalled until [`LoopClock::resumed`].
    pub fn mark(&self) -> Option<Duration> {
        // Taken first: a SIGCONT after this mark belongs to the next gap, and one to a
        // running controller is dropped here.
        let continued = self.continued.swap(false, Ordering::SeqCst);
        let now = Instant::now();
        let gap = {
            let mut marks = self.marks();
            if let Some(lapse) = marks.doubted.take() {
                marks.start_again();
                return Some(lapse);
            }
            let gap = marks.since_mark(now);
            if marks.restarting
                || gap >= self.stall_after
                || (continued && gap >= self.noticed_after)
            {
                marks.start_again();
                return Some(gap);
            }
            let held = marks.mark_at(now);
            if gap < self.noticed_after {
                return None;
            }
            if held.is_some_and(|held| held >= self.noticed_after) {
                // Held, not starved, for a command deadline: stopped without a signal.
                marks.start_again();
                return Some(gap);
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
            marks.start_again();
            return Some(gap);
        }
        marks.mark_at(Instant::now());
        None
    }

    /// The voting loop has started again after a stall and published its new status:
    /// commands may follow that status from now on.
    pub fn resumed(&self) {
        let mut marks = self.marks();
        marks.mark_at(Instant::now());
        marks.restarting = false;
        // The new life has written nothing: the last life's lapse is not its own.
        marks.last_write = None;
        marks.last_owner_write = None;
    }

    /// A command of this controller was written now, as the actuator's owner beside weaker
    /// writers (`as_owner`) or not (another role, or another topic: the voted one). Only
    /// [`LoopClock::not_the_owner`] and a new life forget the owner's last write: the voted
    /// writer beside the owner's writes too, and must not hide the owner's lapse.
    pub fn wrote(&self, as_owner: bool) {
        let mut marks = self.marks();
        let now = Instant::now();
        marks.last_write = Some(now);
        if as_owner {
            marks.last_owner_write = Some(now);
        }
    }

    /// This controller holds no role now, so writes nothing: a gap in its commands from here
    /// is no lapse of a writer (a silent life that is given the Primary role later must not
    /// doubt itself for the silence).
    pub fn holds_no_role(&self) {
        let mut marks = self.marks();
        marks.last_write = None;
        marks.last_owner_write = None;
    }

    /// This controller is not the actuator's owner now (a Secondary or Tertiary, or a Primary
    /// with no weaker writer beside it): a gap in its commands from here is no owner's lapse.
    pub fn not_the_owner(&self) {
        self.marks().last_owner_write = None;
    }

    /// Whether this controller, about to command as the actuator's owner (the Primary, with
    /// weaker writers beside it), let its commands lapse for `bound`
    /// ([`owner_lapse_bound`]): its reader has taken, or is about to take, the next writer's
    /// commands, and one more at the owner's strength would take them back (a starved or
    /// stalled process, whatever its loop saw). It doubts itself then: it writes nothing more
    /// in this life, and the voting loop starts again at its next mark, as after a stall.
    pub fn owner_lapsed(&self, bound: Duration) -> bool {
        let mut marks = self.marks();
        if marks.doubted.is_some() {
            return true;
        }
        let lapse = marks.last_owner_write.map(|wrote| wrote.elapsed());
        match lapse {
            Some(lapse) if lapse >= bound => {
                marks.doubted = Some(lapse);
                true
            }
            _ => false,
        }
    }

    /// The owner's DDS writer stopped after a gap in its sends
    /// (crate::dds::StrengthWriter::set_max_send_gap): a lapse its participant saw, at the
    /// moment it would have sent, that the writing thread may not have (a starved process's
    /// event loop falls behind while its writer keeps writing). It doubts itself as
    /// [`LoopClock::owner_lapsed`] does, the lapse counted from its last write (at least
    /// `bound`). Returns true.
    pub fn owner_stopped(&self, bound: Duration) -> bool {
        let mut marks = self.marks();
        if marks.doubted.is_none() {
            let lapse = marks
                .last_owner_write
                .map_or(bound, |wrote| wrote.elapsed());
            marks.doubted = Some(lapse.max(bound));
        }
        true
    }

    /// How many times the loop has started again: a writer takes it before it reads the
    /// status, and passes it to [`LoopClock::stalled_for_writer`].
    pub fn restarts(&self) -> u64 {
        self.marks().restarts
    }

    /// Whether the loop is past a stall (restarting, restarted since the writer's
    /// `restarts_seen`, or still for a peer deadline), or still for a command deadline with a
    /// SIGCONT since.
    fn past_a_stall(&self, continued: bool, restarts_seen: u64) -> bool {
        let marks = self.marks();
        let gap = marks.since_mark(Instant::now());
        marks.restarting
            || marks.restarts != restarts_seen
            || marks.doubted.is_some()
            || gap >= self.stall_after
            || (continued && (marks.settling || gap >= self.noticed_after))
    }

    /// Whether a writer must write nothing now: the loop has not run for a stall (it is
    /// stopped, or has just resumed and not yet noticed, or is restarting), or it has started
    /// again since the writer took `restarts_seen` ([`LoopClock::restarts`], taken before the
    /// status it writes by: that status is the last life's). A writer whose
    /// commands have lapsed for a command deadline while the loop stood still as long (the
    /// whole process was, or a loaded host starved both) waits up to 50 ms for the
    /// loop to tell a stop from a slow start; one that wrote within the command deadline
    /// cannot have been stopped that long, and never waits.
    pub fn stalled_for_writer(&self, restarts_seen: u64) -> bool {
        if self.past_a_stall(self.continued(), restarts_seen) {
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
            if self.past_a_stall(self.continued(), restarts_seen) {
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
        self.past_a_stall(self.continued(), restarts_seen)
    }

    /// [`LoopClock::stalled_for_writer`] without waiting, for a writer that has just looked
    /// at the restarts, for tests.
    #[cfg(test)]
    fn stalled(&self) -> bool {
        self.past_a_stall(self.continued(), self.restarts())
    }
}

impl Drop for LoopClock {
    fn drop(&mut self) {
        if let Some(id) = self.sigcont.take() {
            signal_hook::low_level::unregister(id);
        }
    }
}

/// How long the owner's commands may lapse, between two of its writes, before it doubts itself
/// ([`LoopClock::owner_lapsed`]): the command deadline, or, where RL republishes the owner's
/// last command every `republish` (`AperiodicPolicy::Republish`), half of it, and never less
/// than two republish periods.
///
/// Why half: what the reader sees is the gap between the commands that reach the wire, and in
/// a starved process the DDS event loop that sends them runs as late as the writing thread
/// does. A CPU quota lets every thread of the process run about once per scheduling period
/// (100 ms by default, 2 ms of it at a 2 % quota): writes about 100 ms apart, each sent in the
/// next window or the one after, so that the reader's gaps reach twice the writes'. Measured
/// with the command deadline as the bound (`lab run starve-primary`, 100 ms deadline at `rl
/// servo`): the owner's writes stayed just under 100 ms apart for 1.4 s while `rl servo` saw
/// gaps of 100-200 ms, 3 to 5 owner changes in 4 runs of 6. A lapse of half the deadline is
/// five missed republications, and twice the lateness bound at which a Secondary takes over
/// from a late Primary (F17). Only the owner doubts itself, so a loaded host restarts at most
/// the controller the actuator follows, once (docs/findings.md, the gray process faults).
/// An application that writes at its own rate (`Periodic`) keeps the deadline, and so does the
/// pair (`RoleWriter`). The duplex doubts at half too: its restarted Primary dwells below the
/// Standby before it takes the actuator back (docs/findings.md, A4); without the dwell the
/// half-deadline doubt made a starved Primary restart and retake the actuator again and again
/// (24 owner changes in 8 s).
pub fn owner_lapse_bound(command_deadline: Duration, republish: Option<Duration>) -> Duration {
    match republish {
        Some(republish) => (command_deadline / 2)
            .max(republish.saturating_mul(2))
            .min(command_deadline),
        None => command_deadline,
    }
}

/// A new incarnation number: the time in milliseconds with the pid, as at start, so a restart
/// in the same process is told apart from the life before it.
pub fn incarnation(now_ms: u64) -> u64 {
    now_ms << 16 | u64::from(std::process::id() & 0xffff)
}

#[cfg(test)]
mod tests;
