//! Test-only fault injection (feature `fault-injection`): heartbeats from the peers named on
//! stdin are dropped on arrival, as if the network lost them one way, each drop logged as a
//! `heartbeat_dropped` event (with `--json-events`); `stall-voting-loop <ms>`
//! blocks the voting loop once for that long, as a hung loop would (the watchdog test);
//! `break-dds-event-loop` makes RustDDS's event loop fail its poll and exit, as it does on a
//! poll error: the process's every participant then sends and receives nothing while writes
//! still succeed (the watchdog test); `wrong-commands offset <n>|frozen|random|none` asks the
//! application to make its commands wrong (crate::api::Redundancy::injected_output_fault: a
//! controller that heartbeats on but computes wrong commands, for the output voting tests and
//! the lab); `wrong-input offset <n>|foreign|none` asks it to read its input wrong
//! (crate::api::Redundancy::injected_input_fault: a miscalibrated sensor, or another camera
//! than the group's); `skew-commands <n>` is `wrong-commands offset <n>`; `delay-commands <ms>` and
//! `hold-commands` make its commands late or missing, as a starved link does
//! (crate::dds::command_link). Under `RL_HOLD_START` the
//! controller waits for `start-voting` before its clock starts ([`hold_until_started`]).

use crate::dds::command_link::CommandLink;
use std::collections::BTreeSet;
use std::io::{BufRead, Write};
use std::sync::Mutex;
use std::time::Duration;

static DROPPED: Mutex<BTreeSet<u8>> = Mutex::new(BTreeSet::new());
static STALL: Mutex<Option<Duration>> = Mutex::new(None);
static OUTPUT_FAULT: Mutex<OutputFault> = Mutex::new(OutputFault::None);
static INPUT_FAULT: Mutex<InputFault> = Mutex::new(InputFault::None);

/// How the application's input is to be wrong (`wrong-input`); the application applies it to
/// what it received, as a miswired or miscalibrated sensor would.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum InputFault {
    /// Right (`wrong-input none`).
    #[default]
    None,
    /// The same inputs, a value off by this much (the tracker: the ball's x, in pixels;
    /// `wrong-input offset <n>`).
    Offset(i32),
    /// Another source's inputs (`wrong-input foreign`): none of them is an input the group
    /// has, and their values differ (the tracker: another camera's frames).
    Foreign,
}

impl InputFault {
    /// The fault a `wrong-input` line's words after the verb name; `None` if they name none.
    pub fn parse<'a>(mut words: impl Iterator<Item = &'a str>) -> Option<InputFault> {
        let fault = match (words.next()?, words.next()) {
            ("none", None) => InputFault::None,
            ("foreign", None) => InputFault::Foreign,
            ("offset", Some(n)) => InputFault::Offset(n.parse().ok()?),
            _ => return None,
        };
        words.next().is_none().then_some(fault)
    }
}

/// The input fault asked for.
pub fn input_fault() -> InputFault {
    *INPUT_FAULT.lock().unwrap_or_else(|e| e.into_inner())
}

/// How the application's commands are to be wrong (`wrong-commands`); the application applies
/// it to what it computed, as a bug in it would.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum OutputFault {
    /// Right (`wrong-commands none`, `skew-commands 0`).
    #[default]
    None,
    /// Pan off by this much, within the servo's range (`wrong-commands offset <n>`).
    Offset(i32),
    /// The command sent when it froze, whatever the input (`wrong-commands frozen`).
    Frozen,
    /// Random pan and tilt at every input (`wrong-commands random`).
    Random,
    /// Pan off by this much more every second from when it was asked (`wrong-commands drift
    /// <n>`): an error growing slowly through the comparison's tolerance, as a drifting
    /// integrator or a sensor bias would.
    Drift(i32),
    /// The law's pan steps at this percent of its own (`wrong-commands gain <percent>`): a
    /// wrong law, which alignment to the group's position masks while each step's error is
    /// within the tolerance; only the raw answers show it (crate::cross_check).
    Gain(i32),
}

impl OutputFault {
    /// The fault a `wrong-commands` line's words after the verb name; `None` if they name none.
    pub fn parse<'a>(mut words: impl Iterator<Item = &'a str>) -> Option<OutputFault> {
        let fault = match (words.next()?, words.next()) {
            ("none", None) => OutputFault::None,
            ("frozen", None) => OutputFault::Frozen,
            ("random", None) => OutputFault::Random,
            ("offset", Some(n)) => OutputFault::Offset(n.parse().ok()?),
            ("drift", Some(n)) => OutputFault::Drift(n.parse().ok()?),
            ("gain", Some(n)) => OutputFault::Gain(n.parse().ok()?),
            _ => return None,
        };
        words.next().is_none().then_some(fault)
    }
}

/// The output fault asked for.
pub fn output_fault() -> OutputFault {
    *OUTPUT_FAULT.lock().unwrap_or_else(|e| e.into_inner())
}

fn set_output_fault(line: &str, fault: Option<OutputFault>) {
    match fault {
        Some(fault) => {
            *OUTPUT_FAULT.lock().unwrap_or_else(|e| e.into_inner()) = fault;
            tracing::warn!("fault injection: commands wrong: {fault:?}");
        }
        None => tracing::warn!("fault injection: bad output fault in {line:?}"),
    }
}

/// Blocks the calling (voting) thread if a stall was asked for.
pub fn stall() {
    let stall = STALL.lock().unwrap_or_else(|e| e.into_inner()).take();
    if let Some(duration) = stall {
        tracing::warn!("fault injection: voting loop stalled for {duration:?}");
        std::thread::sleep(duration);
    }
}

pub fn dropped(from: u8) -> bool {
    DROPPED
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .contains(&from)
}

/// The thread name (as the kernel keeps it, 15 bytes) of a RustDDS participant's event loop,
/// "RustDDS Participant `<n>` event loop".
const DDS_EVENT_LOOP_COMM: &str = "RustDDS Partici";

/// The epoll descriptor a thread of this process waits on now, if it is blocked in
/// `epoll_wait`/`epoll_pwait`: `/proc/self/task/<tid>/syscall` shows the system call's
/// arguments, the first being the descriptor, which must be an epoll instance.
fn epoll_fd_waited_on_by(task: &std::path::Path) -> Option<i32> {
    let syscall = std::fs::read_to_string(task.join("syscall")).ok()?;
    let first_argument = syscall.split_whitespace().nth(1)?;
    let fd = i32::from_str_radix(first_argument.trim_start_matches("0x"), 16).ok()?;
    let target = std::fs::read_link(format!("/proc/self/fd/{fd}")).ok()?;
    (target.to_string_lossy() == "anon_inode:[eventpoll]").then_some(fd)
}

/// Replaces the epoll descriptor of every RustDDS event loop in this process with
/// `/dev/null`: its next poll fails (`EINVAL`) and the loop exits, as on any poll error.
fn break_dds_event_loops() {
    let mut broken = 0;
    let tasks = std::fs::read_dir("/proc/self/task").into_iter().flatten();
    for task in tasks.flatten() {
        let comm = std::fs::read_to_string(task.path().join("comm")).unwrap_or_default();
        if comm.trim_end() != DDS_EVENT_LOOP_COMM {
            continue;
        }
        // The loop may be between two polls: look again for a moment.
        let fd = (0..200).find_map(|_| {
            epoll_fd_waited_on_by(&task.path()).or_else(|| {
                std::thread::sleep(Duration::from_millis(5));
                None
            })
        });
        let Some(fd) = fd else {
            tracing::warn!("fault injection: no epoll descriptor found for a RustDDS event loop");
            continue;
        };
        // SAFETY: plain system calls on descriptors; `fd` is an epoll instance this process
        // owns, replaced in place so the number stays taken.
        let replaced = unsafe {
            let null = libc::open(c"/dev/null".as_ptr(), libc::O_RDONLY | libc::O_CLOEXEC);
            let replaced = null >= 0 && libc::dup2(null, fd) == fd;
            if null >= 0 {
                libc::close(null);
            }
            replaced
        };
        if replaced {
            broken += 1;
        }
    }
    tracing::warn!("fault injection: broke {broken} RustDDS event loop(s)");
}

/// Reads `drop-heartbeats-from <id>`, `accept-heartbeats-from <id>`,
/// `stall-voting-loop <ms>`, `wrong-commands ...`, `wrong-input ...`, `skew-commands <offset>`,
/// `delay-commands <ms>`, `hold-commands` and `break-dds-event-loop` lines.
pub fn listen_on_stdin() {
    let _ = std::thread::Builder::new()
        .name("rl-fault-injection".into())
        .spawn(|| {
            for line in std::io::stdin().lock().lines().map_while(Result::ok) {
                obey(&line);
            }
        });
}

/// The line that ends a hold ([`hold_until_started`]).
pub const START_VOTING: &str = "start-voting";

/// Under `RL_HOLD_START` (any value): holds the controller before its clock starts, its DDS
/// endpoints created, until `start-voting` comes on stdin (or stdin closes), printing a
/// `held` event line (with `--json-events`) whenever the count of discovered participants
/// changes. The other control lines are obeyed meanwhile. The DDS-level replay starts every
/// process of a trace this way, so a process that joins in round `k` has been discovered by
/// then and is heard in round `k`, as the model's join is. What the readers take in while it
/// is held is thrown away (`discard`, every few milliseconds): a process started at the
/// release would not have it.
pub fn hold_until_started(
    session: &crate::dds::Session,
    id: crate::core::ControllerId,
    json_events: bool,
    mut discard: impl FnMut(),
) -> bool {
    if std::env::var_os("RL_HOLD_START").is_none() {
        return false;
    }
    let (started, start) = std::sync::mpsc::channel();
    let reading = std::thread::Builder::new()
        .name("rl-held".into())
        .spawn(move || {
            for line in std::io::stdin().lock().lines().map_while(Result::ok) {
                if line.trim() == START_VOTING {
                    break;
                }
                obey(&line);
            }
            let _ = started.send(());
        });
    let Ok(reading) = reading else {
        tracing::warn!("fault injection: no thread to read stdin while held; not holding");
        return false;
    };
    tracing::warn!("fault injection: held until {START_VOTING:?} on stdin");
    let mut shown = None;
    loop {
        // Thrown away as it comes, not at the end: a peer let go a moment earlier sends its
        // first heartbeat at once, and it belongs to this round.
        discard();
        let counts = session.heartbeat_participants_discovered();
        if json_events && shown != Some(counts) {
            shown = Some(counts);
            let line = crate::event::EventLine {
                t_ms: crate::round_clock::RoundClock::start().now_ms(),
                id,
                incarnation: 0,
                event: crate::event::Event::Held {
                    heartbeat_writers: counts.0,
                    heartbeat_readers: counts.1,
                },
            };
            let mut out = std::io::stdout().lock();
            let _ = writeln!(out, "{}", line.to_json());
            let _ = out.flush();
        }
        match start.recv_timeout(Duration::from_millis(HELD_LOOK_MS)) {
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
            _ => break,
        }
    }
    let _ = reading.join();
    true
}

/// How often a held controller looks at what discovery found.
const HELD_LOOK_MS: u64 = 10;

/// One control line.
fn obey(line: &str) {
    if line.trim() == "break-dds-event-loop" {
        break_dds_event_loops();
        return;
    }
    if line.trim() == "hold-commands" {
        crate::dds::command_link::set(CommandLink::Held);
        return;
    }
    let mut words = line.split_whitespace();
    let (Some(verb), Some(id)) = (words.next(), words.next()) else {
        return;
    };
    if verb == "wrong-commands" {
        let words = line.split_whitespace().skip(1);
        set_output_fault(line, OutputFault::parse(words));
        return;
    }
    if verb == "wrong-input" {
        match InputFault::parse(line.split_whitespace().skip(1)) {
            Some(fault) => {
                *INPUT_FAULT.lock().unwrap_or_else(|e| e.into_inner()) = fault;
                tracing::warn!("fault injection: input wrong: {fault:?}");
            }
            None => tracing::warn!("fault injection: bad input fault in {line:?}"),
        }
        return;
    }
    if verb == "skew-commands" {
        let fault = id.parse().ok().map(|offset| match offset {
            0 => OutputFault::None,
            offset => OutputFault::Offset(offset),
        });
        set_output_fault(line, fault);
        return;
    }
    if verb == "delay-commands" {
        match id.parse::<u64>() {
            Ok(0) => crate::dds::command_link::set(CommandLink::OnTime),
            Ok(ms) => crate::dds::command_link::set(CommandLink::Delayed(ms)),
            Err(_) => tracing::warn!("fault injection: bad delay in {line:?}"),
        }
        return;
    }
    if verb == "stall-voting-loop" {
        match id.parse::<u64>() {
            Ok(ms) => {
                *STALL.lock().unwrap_or_else(|e| e.into_inner()) = Some(Duration::from_millis(ms));
            }
            Err(_) => tracing::warn!("fault injection: bad duration in {line:?}"),
        }
        return;
    }
    let Ok(id) = id.parse::<u8>() else {
        tracing::warn!("fault injection: bad id in {line:?}");
        return;
    };
    let mut dropped = DROPPED.lock().unwrap_or_else(|e| e.into_inner());
    match verb {
        "drop-heartbeats-from" => {
            dropped.insert(id);
        }
        "accept-heartbeats-from" => {
            dropped.remove(&id);
        }
        _ => tracing::warn!("fault injection: unknown command {line:?}"),
    }
    tracing::info!("fault injection: dropping heartbeats from {dropped:?}");
}

#[cfg(test)]
mod tests {
    use super::{InputFault, OutputFault};

    #[test]
    fn input_faults_parse_from_their_words() {
        let parse = |line: &str| InputFault::parse(line.split_whitespace());
        assert_eq!(parse("none"), Some(InputFault::None));
        assert_eq!(parse("foreign"), Some(InputFault::Foreign));
        assert_eq!(parse("offset 40"), Some(InputFault::Offset(40)));
        for bad in ["", "offset", "offset x", "foreign 2", "offset 3 4"] {
            assert_eq!(parse(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn output_faults_parse_from_their_words() {
        let parse = |line: &str| OutputFault::parse(line.split_whitespace());
        assert_eq!(parse("none"), Some(OutputFault::None));
        assert_eq!(parse("frozen"), Some(OutputFault::Frozen));
        assert_eq!(parse("random"), Some(OutputFault::Random));
        assert_eq!(parse("offset -300"), Some(OutputFault::Offset(-300)));
        assert_eq!(parse("drift 20"), Some(OutputFault::Drift(20)));
        assert_eq!(parse("gain 130"), Some(OutputFault::Gain(130)));
        for bad in [
            "",
            "offset",
            "offset x",
            "frozen now",
            "sideways",
            "offset 3 4",
        ] {
            assert_eq!(parse(bad), None, "{bad:?}");
        }
    }
}
