//! Test-only fault injection (feature `fault-injection`): heartbeats from the peers named on
//! stdin are dropped on arrival, as if the network lost them one way, each drop logged as a
//! `heartbeat_dropped` event (with `--json-events`); `stall-voting-loop <ms>`
//! blocks the voting loop once for that long, as a hung loop would (the watchdog test);
//! `break-dds-event-loop` makes RustDDS's event loop fail its poll and exit, as it does on a
//! poll error: the process's every participant then sends and receives nothing while writes
//! still succeed (the watchdog test); `skew-commands <offset>` asks the application to make
//! its commands wrong by `offset` on pan (crate::api::Redundancy::injected_command_skew: the
//! voted output test, a controller that heartbeats on but computes wrong commands).

use std::collections::BTreeSet;
use std::io::BufRead;
use std::sync::atomic::{AtomicI32, Ordering};
use std::sync::Mutex;
use std::time::Duration;

static DROPPED: Mutex<BTreeSet<u8>> = Mutex::new(BTreeSet::new());
static STALL: Mutex<Option<Duration>> = Mutex::new(None);
static COMMAND_SKEW: AtomicI32 = AtomicI32::new(0);

/// The pan offset asked for with `skew-commands`.
pub fn command_skew() -> i32 {
    COMMAND_SKEW.load(Ordering::Relaxed)
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
/// "RustDDS Participant <n> event loop".
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
/// `stall-voting-loop <ms>`, `skew-commands <offset>` and `break-dds-event-loop` lines.
pub fn listen_on_stdin() {
    let _ = std::thread::Builder::new()
        .name("rl-fault-injection".into())
        .spawn(|| {
            for line in std::io::stdin().lock().lines().map_while(Result::ok) {
                if line.trim() == "break-dds-event-loop" {
                    break_dds_event_loops();
                    continue;
                }
                let mut words = line.split_whitespace();
                let (Some(verb), Some(id)) = (words.next(), words.next()) else {
                    continue;
                };
                if verb == "skew-commands" {
                    match id.parse::<i32>() {
                        Ok(offset) => {
                            COMMAND_SKEW.store(offset, Ordering::Relaxed);
                            tracing::warn!("fault injection: commands skewed by {offset} on pan");
                        }
                        Err(_) => tracing::warn!("fault injection: bad offset in {line:?}"),
                    }
                    continue;
                }
                if verb == "stall-voting-loop" {
                    match id.parse::<u64>() {
                        Ok(ms) => {
                            *STALL.lock().unwrap_or_else(|e| e.into_inner()) =
                                Some(Duration::from_millis(ms));
                        }
                        Err(_) => tracing::warn!("fault injection: bad duration in {line:?}"),
                    }
                    continue;
                }
                let Ok(id) = id.parse::<u8>() else {
                    tracing::warn!("fault injection: bad id in {line:?}");
                    continue;
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
        });
}
