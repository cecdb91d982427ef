//! `rl controller` under a service manager: a real controller process with a fake systemd
//! notify socket (a Unix datagram socket this test binds, named by `NOTIFY_SOCKET`) and
//! `WATCHDOG_USEC`. It must say `READY=1`, ping `WATCHDOG=1` every half watchdog interval,
//! stop pinging when it stops (SIGSTOP: what systemd acts on after `WatchdogSec`), resume on
//! SIGCONT, and say `STOPPING=1` on SIGTERM. With the `fault-injection` feature, a stalled
//! voting loop alone must stop the pings while the process runs on, and so must RustDDS's
//! event loop exiting. DDS domains 181-183 and 152.

mod support;

use std::io::Read;
use std::os::unix::net::UnixDatagram;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};
use support::tempdir::Dir;

/// 1 s watchdog: pings every 500 ms.
const WATCHDOG_USEC: &str = "1000000";

struct Service {
    child: Child,
    messages: Receiver<(Instant, String)>,
    seen: Vec<(Instant, String)>,
    dir: Dir,
}

impl Service {
    /// Starts controller 1 on `domain` with a notify socket and, if given, a watchdog.
    fn start(tag: &str, domain: u16, watchdog_usec: Option<&str>) -> Service {
        Service::start_with(tag, domain, watchdog_usec, false)
    }

    /// Like [`Service::start`]; `journal_stream` sets `JOURNAL_STREAM` to the stderr file, as
    /// systemd does when the journal holds stderr.
    fn start_with(
        tag: &str,
        domain: u16,
        watchdog_usec: Option<&str>,
        journal_stream: bool,
    ) -> Service {
        let dir = Dir::new(tag);
        let socket_path = dir.0.join("notify.sock");
        let socket = UnixDatagram::bind(&socket_path).unwrap();
        let config = support::test_config(&dir.0, "");
        let stderr = std::fs::File::create(dir.0.join("stderr.txt")).unwrap();
        let mut command = Command::new(support::rl());
        if journal_stream {
            use std::os::unix::fs::MetadataExt;
            let file = stderr.metadata().unwrap();
            command.env("JOURNAL_STREAM", format!("{}:{}", file.dev(), file.ino()));
        } else {
            command.env_remove("JOURNAL_STREAM");
        }
        command
            .args(["controller", "--id", "1", "--domain", &domain.to_string()])
            .arg("--config")
            .arg(&config)
            .env("NOTIFY_SOCKET", &socket_path)
            .env_remove("WATCHDOG_USEC")
            .env_remove("WATCHDOG_PID")
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(stderr);
        if let Some(usec) = watchdog_usec {
            command.env("WATCHDOG_USEC", usec);
        }
        let child = command.spawn().expect("start rl controller");
        let (to, messages) = mpsc::channel();
        std::thread::spawn(move || {
            let mut buffer = [0u8; 4096];
            while let Ok(length) = socket.recv(&mut buffer) {
                let text = String::from_utf8_lossy(&buffer[..length]).into_owned();
                for line in text.lines() {
                    if to.send((Instant::now(), line.to_string())).is_err() {
                        return;
                    }
                }
            }
        });
        Service {
            child,
            messages,
            seen: Vec::new(),
            dir,
        }
    }

    /// Takes in every message that arrives within `wait`.
    fn collect_for(&mut self, wait: Duration) -> Vec<(Instant, String)> {
        let deadline = Instant::now() + wait;
        let mut got = Vec::new();
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match self.messages.recv_timeout(left) {
                Ok(message) => got.push(message),
                Err(_) => break,
            }
        }
        self.seen.extend(got.iter().cloned());
        got
    }

    /// Waits up to `timeout` for a new message equal to (or, ending in `*`, starting with)
    /// `want`.
    fn wait_for(&mut self, want: &str, timeout: Duration) -> Instant {
        self.wait_for_from(want, timeout, self.seen.len())
    }

    /// Like [`Service::wait_for`], but a message already taken in counts too.
    fn saw_or_wait_for(&mut self, want: &str, timeout: Duration) -> Instant {
        self.wait_for_from(want, timeout, 0)
    }

    fn wait_for_from(&mut self, want: &str, timeout: Duration, from: usize) -> Instant {
        let deadline = Instant::now() + timeout;
        let matches = |text: &str| match want.strip_suffix('*') {
            Some(prefix) => text.starts_with(prefix),
            None => text == want,
        };
        if let Some((at, _)) = self.seen[from..].iter().find(|(_, text)| matches(text)) {
            return *at;
        }
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            if let Ok((at, text)) = self.messages.recv_timeout(left) {
                self.seen.push((at, text.clone()));
                if matches(&text) {
                    return at;
                }
            }
        }
        panic!(
            "no {want:?} within {timeout:?}; saw {:?}\nstderr:\n{}",
            self.seen.iter().map(|(_, t)| t).collect::<Vec<_>>(),
            self.stderr()
        );
    }

    fn stderr(&self) -> String {
        let mut text = String::new();
        if let Ok(mut file) = std::fs::File::open(self.dir.0.join("stderr.txt")) {
            let _ = file.read_to_string(&mut text);
        }
        text
    }

    fn signal(&self, signal: i32) {
        rl::procs::signal(self.child.id(), signal).unwrap();
    }
}

impl Drop for Service {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn pings(messages: &[(Instant, String)]) -> Vec<Instant> {
    messages
        .iter()
        .filter(|(_, text)| text == "WATCHDOG=1")
        .map(|(at, _)| *at)
        .collect()
}

/// The longest time between consecutive instants (and from `from` to the first).
fn longest_gap(from: Instant, times: &[Instant]) -> Duration {
    let mut last = from;
    let mut longest = Duration::ZERO;
    for &at in times {
        longest = longest.max(at.saturating_duration_since(last));
        last = at;
    }
    longest
}

#[test]
fn ready_then_watchdog_pings_that_stop_with_the_process_and_stopping_on_sigterm() {
    let mut service = Service::start("watchdog", 181, Some(WATCHDOG_USEC));
    let ready = service.wait_for("READY=1", Duration::from_secs(20));
    assert!(
        pings(&service.seen).is_empty(),
        "a watchdog ping before READY=1: {:?}",
        service.seen
    );

    // Half the 1 s watchdog: a ping about every 500 ms.
    let window = service.collect_for(Duration::from_secs(3));
    let running = pings(&window);
    assert!(
        running.len() >= 4,
        "{} pings in 3 s: {:?}",
        running.len(),
        window
    );
    let gap = longest_gap(ready, &running);
    assert!(gap < Duration::from_millis(800), "pings {gap:?} apart");

    // The controller reports its state; alone, it is Primary after the 1 s window.
    service.saw_or_wait_for(
        // Alone, its result is provisional (docs/protocol.md, epochs).
        "STATUS=C1 steady provisional primary (strength 15)",
        Duration::from_secs(15),
    );

    // A stopped process pings no more, for longer than the watchdog: systemd would restart it.
    service.signal(libc::SIGSTOP);
    let stopped_at = Instant::now();
    let window = service.collect_for(Duration::from_millis(2500));
    let late: Vec<Instant> = pings(&window)
        .into_iter()
        .filter(|at| at.duration_since(stopped_at) > Duration::from_millis(100))
        .collect();
    assert!(late.is_empty(), "pings while stopped: {late:?}");

    // Continued, it pings again within one interval.
    service.signal(libc::SIGCONT);
    let continued_at = Instant::now();
    let resumed = service.wait_for("WATCHDOG=1", Duration::from_millis(1500));
    assert!(resumed.duration_since(continued_at) < Duration::from_millis(1000));

    service.signal(libc::SIGTERM);
    service.wait_for("STOPPING=1", Duration::from_secs(5));
    let status = service.child.wait().unwrap();
    assert!(status.success(), "exit {status:?}\n{}", service.stderr());
}

/// Also: with `JOURNAL_STREAM` naming its stderr but no journald to talk to (as on a build
/// machine without systemd), the log records still reach stderr, which the journal would hold.
#[test]
fn without_a_watchdog_it_says_ready_and_never_pings() {
    let mut service = Service::start_with("nowatchdog", 182, None, true);
    service.wait_for("READY=1", Duration::from_secs(20));
    let window = service.collect_for(Duration::from_secs(2));
    assert!(pings(&window).is_empty(), "{window:?}");
    if !Path::new("/run/systemd/journal/socket").exists() {
        assert!(
            service.stderr().contains("controller started"),
            "{}",
            service.stderr()
        );
    }
    service.signal(libc::SIGTERM);
    service.wait_for("STOPPING=1", Duration::from_secs(5));
    assert!(service.child.wait().unwrap().success());
}

/// A wedged voting loop (the controller's other loop still running) stops the pings.
#[cfg(feature = "fault-injection")]
#[test]
fn a_stalled_voting_loop_alone_stops_the_pings() {
    use std::io::Write;
    let mut service = Service::start("stall", 183, Some(WATCHDOG_USEC));
    service.wait_for("READY=1", Duration::from_secs(20));
    service.wait_for("WATCHDOG=1", Duration::from_secs(2));
    let stdin = service.child.stdin.as_mut().unwrap();
    writeln!(stdin, "stall-voting-loop 3000").unwrap();
    stdin.flush().unwrap();
    let stalled_at = Instant::now();
    let window = service.collect_for(Duration::from_millis(2500));
    // The last ping may come up to one interval after the stall began; then silence for
    // longer than the 1 s watchdog.
    let after_grace: Vec<Instant> = pings(&window)
        .into_iter()
        .filter(|at| at.duration_since(stalled_at) > Duration::from_millis(1100))
        .collect();
    assert!(
        after_grace.is_empty(),
        "pings while the voting loop was stuck: {after_grace:?}"
    );
    assert!(
        service.child.try_wait().unwrap().is_none(),
        "the process must still run"
    );
    assert!(
        service.stderr().contains("watchdog pings withheld"),
        "{}",
        service.stderr()
    );
    // The stall ends after 3 s: pings resume.
    service.wait_for("WATCHDOG=1", Duration::from_secs(3));
    service.signal(libc::SIGTERM);
    assert!(service.child.wait().unwrap().success());
}

/// RustDDS's event loop gone (its poll failed; the controller's own loops still run and its
/// writes still succeed): nothing reaches the network, so the pings stop.
#[cfg(feature = "fault-injection")]
#[test]
fn a_dead_dds_event_loop_stops_the_pings() {
    use std::io::Write;
    let mut service = Service::start("ddsloop", 152, Some(WATCHDOG_USEC));
    service.wait_for("READY=1", Duration::from_secs(20));
    // Formed first: the command writer exists. (Creating a writer without the event loop
    // hangs inside RustDDS, which stops the pings too, but not by the check under test.)
    service.saw_or_wait_for(
        "STATUS=C1 steady provisional primary (strength 15)",
        Duration::from_secs(15),
    );
    service.wait_for("WATCHDOG=1", Duration::from_secs(2));
    let stdin = service.child.stdin.as_mut().unwrap();
    writeln!(stdin, "break-dds-event-loop").unwrap();
    stdin.flush().unwrap();
    let broken_at = Instant::now();
    let window = service.collect_for(Duration::from_millis(3000));
    let after_grace: Vec<Instant> = pings(&window)
        .into_iter()
        .filter(|at| at.duration_since(broken_at) > Duration::from_millis(1100))
        .collect();
    assert!(
        after_grace.is_empty(),
        "pings without RustDDS's event loop: {after_grace:?}\nstderr:\n{}",
        service.stderr()
    );
    assert!(
        service.child.try_wait().unwrap().is_none(),
        "the process must still run"
    );
    let stderr = service.stderr();
    assert!(
        stderr.contains("broke 1 RustDDS event loop"),
        "the fault was not injected:\n{stderr}"
    );
    assert!(
        stderr.contains("RustDDS's event loop has not run")
            && stderr.contains("watchdog pings withheld"),
        "{stderr}"
    );
    service.signal(libc::SIGTERM);
    let _ = service.child.wait();
}
