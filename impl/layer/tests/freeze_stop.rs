//! A real stop of this test process without a signal: a child puts it in a freezer cgroup
//! (cgroups v1), freezes it for a while and thaws it, as a paused virtual machine or a
//! blocked disk would stop it. The stall clock (`rl_layer::stall`) must see a freeze past the
//! command deadline as a stop, and a shorter one as none. In a test binary of its own: the
//! freeze stops every thread of the process.

use rl_layer::stall::LoopClock;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

const FREEZER: &str = "/sys/fs/cgroup/freezer";

#[test]
#[ignore = "needs root and the cgroup v1 freezer (/sys/fs/cgroup/freezer); CI runs it"]
fn freezes_past_the_command_deadline_are_stalls_and_shorter_ones_are_none() {
    assert!(
        Path::new(FREEZER).join("cgroup.procs").exists(),
        "no cgroup v1 freezer at {FREEZER}"
    );
    let clock = Arc::new(LoopClock::new(10_000, 100));
    let (stalls, stalled) = mpsc::channel();
    let (resume, resumed) = mpsc::channel::<()>();
    let stop = Arc::new(AtomicBool::new(false));
    // The voting loop: marks every 10 ms; after a stall it waits for the test to let it
    // resume, as the real loop restarts its core before it resumes.
    let voting = {
        let (clock, stop) = (Arc::clone(&clock), Arc::clone(&stop));
        std::thread::spawn(move || {
            while !stop.load(Ordering::SeqCst) {
                if let Some(gap) = clock.mark() {
                    let _ = stalls.send(gap);
                    let _ = resumed.recv();
                    clock.resumed();
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        })
    };
    std::thread::sleep(Duration::from_millis(50));
    clock.wrote(false);
    freeze_self_for(Duration::from_millis(150));
    assert!(
        clock.stalled_for_writer(clock.restarts()),
        "the writer, back, waits for the loop's decision and writes nothing"
    );
    let gap = stalled
        .recv_timeout(Duration::from_secs(1))
        .expect("a freeze of 150 ms is a stall");
    assert!(gap >= Duration::from_millis(100), "{gap:?}");
    resume.send(()).expect("the loop waits");
    std::thread::sleep(Duration::from_millis(50));
    clock.wrote(false);
    assert!(!clock.stalled_for_writer(clock.restarts()), "running again");
    freeze_self_for(Duration::from_millis(20));
    std::thread::sleep(Duration::from_millis(50));
    assert!(!clock.stalled_for_writer(clock.restarts()));
    assert_eq!(
        stalled.try_recv().ok(),
        None,
        "20 ms: the actuator did not notice"
    );
    stop.store(true, Ordering::SeqCst);
    drop(resume);
    voting.join().expect("the loop thread");
}

/// Freezes this process for `freeze` from a child, which moves it into a freezer group of its
/// own and back out; returns once thawed.
fn freeze_self_for(freeze: Duration) {
    let pid = std::process::id();
    let group = format!("{FREEZER}/rl-freeze-test-{pid}");
    let script = format!(
        "mkdir -p {group} && echo {pid} > {group}/cgroup.procs && \
         echo FROZEN > {group}/freezer.state && sleep {s} && \
         echo THAWED > {group}/freezer.state && echo {pid} > {FREEZER}/cgroup.procs && \
         rmdir {group}",
        s = freeze.as_secs_f64()
    );
    let status = std::process::Command::new("sh")
        .args(["-c", &script])
        .status()
        .expect("running sh");
    assert!(status.success(), "{status}");
}
