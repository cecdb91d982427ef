//! A real stop of this test process: SIGSTOP from a child, SIGCONT from the same child a
//! command deadline later, and a SIGCONT to the running process, seen by the stall clock
//! (`rl_layer::stall`). In a test binary of its own: a SIGCONT reaches every clock of the
//! process, and the stop stops every thread (so it is one test: the steps must not overlap).

use rl_layer::stall::LoopClock;
use std::time::Duration;

#[test]
fn continued_stops_past_the_command_deadline_are_stalls_and_others_are_none() {
    let clock = LoopClock::new(10_000, 100);
    assert_eq!(clock.mark(), None);
    // A SIGCONT to a running process, whose loop marks as it runs: no stall.
    signal_self(libc::SIGCONT);
    for _ in 0..15 {
        std::thread::sleep(Duration::from_millis(10));
        assert_eq!(clock.mark(), None, "a SIGCONT to a running loop is no stop");
    }
    clock.wrote(false);
    assert!(!clock.stalled_for_writer(clock.restarts()));
    // Stopped for 150 ms by a child, continued by it.
    assert_eq!(clock.mark(), None);
    stop_self_for(Duration::from_millis(150));
    assert!(
        clock.stalled_for_writer(clock.restarts()),
        "the writer, back first, waits for the loop and writes nothing"
    );
    let gap = clock.mark().expect("a continued stop of 150 ms is a stall");
    assert!(gap >= Duration::from_millis(100), "{gap:?}");
    assert!(
        clock.stalled_for_writer(clock.restarts()),
        "still, until the loop has restarted"
    );
    clock.resumed();
    assert_eq!(clock.mark(), None, "the SIGCONT was taken by the stall");
    clock.wrote(false);
    assert!(!clock.stalled_for_writer(clock.restarts()));
    // A stop shorter than the command deadline: nobody noticed.
    stop_self_for(Duration::from_millis(20));
    assert_eq!(clock.mark(), None, "20 ms: the actuator did not notice");
}

fn signal_self(signal: libc::c_int) {
    // SAFETY: kill(2) on this process with a valid signal number.
    let sent = unsafe { libc::kill(libc::getpid(), signal) };
    assert_eq!(sent, 0, "kill({signal})");
}

/// Stops this process for `stop` from a child process (a stopped process cannot continue
/// itself); returns once the child has continued it.
fn stop_self_for(stop: Duration) {
    let pid = std::process::id();
    let script = format!(
        "kill -STOP {pid}; sleep {}; kill -CONT {pid}",
        stop.as_secs_f64()
    );
    let status = std::process::Command::new("sh")
        .args(["-c", &script])
        .status()
        .expect("running sh");
    assert!(status.success(), "{status}");
}
