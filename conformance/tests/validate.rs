//! Trace validation (docs/conformance.md, "Trace validation"): recorded runs of real
//! controllers checked to be behaviours the model allows.
//!
//! - `tests/fixtures/demo-run/`: a committed recording of `rl demo` (three controllers, the
//!   Primary killed and restarted twice), accepted deterministically;
//! - `tests/fixtures/demo-run-secondary-promotes-itself/`: the same recording with one line
//!   added, the Secondary reporting itself Primary while the Primary is alive, which must be
//!   rejected with a readable message;
//! - `tests/fixtures/lab-restart-within-a-round/`: a fault-lab recording in which C3 stopped and
//!   its next life started within one heartbeat period, after C1 had heard the old life in
//!   that round; accepted (tolerance 3 of `conformance::validate`);
//! - `tests/fixtures/lab-takeover-stale-heartbeat/`: a fault-lab recording of a takeover from a
//!   starved Primary (F17) in which the taker heard the deposed Primary's heartbeat a round
//!   late; accepted (tolerance 4);
//! - a fresh `rl demo --record` run on DDS domain 198, validated as it comes.
//!
//! The DDS-level replays validate their own recordings (tests/dds_replay.rs).

use conformance::dds_replay;
use conformance::record::Recording;
use conformance::validate::{self, describe_lives};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("fixtures")
        .join(name)
}

fn check(dir: &Path) -> Result<validate::Accepted, Box<validate::Rejection>> {
    let (timing, source) = validate::run_timing(dir, None).unwrap_or_else(|e| panic!("{e}"));
    let recording = Recording::read_dir(dir).unwrap_or_else(|e| panic!("{e}"));
    println!(
        "{}: period {} ms, dead after {} rounds, window {} rounds (from {source})\n{}",
        dir.display(),
        timing.period_ms,
        timing.dead_after_rounds,
        timing.window_rounds,
        describe_lives(&recording, timing.period_ms)
    );
    validate::validate(&recording, &timing)
}

#[test]
fn the_recorded_demo_run_is_a_behaviour_of_the_model() {
    let accepted = check(&fixture("demo-run")).unwrap_or_else(|r| panic!("{r}"));
    println!("{accepted}");
    assert_eq!(accepted.controllers, 3);
    assert_eq!(accepted.lives, 5, "three controllers, two restarts");
    assert!(accepted.rounds_checked > 30, "{accepted}");
    assert_eq!(
        accepted.strict_rejection_round, None,
        "accepted without the lag tolerance"
    );
}

#[test]
fn a_secondary_that_promotes_itself_is_rejected() {
    let rejection = check(&fixture("demo-run-secondary-promotes-itself"))
        .expect_err("a Secondary cannot take Primary while the Primary is alive");
    let message = rejection.to_string();
    println!("{message}");
    assert!(
        message.starts_with("the run is not a behaviour of the model: at round boundary"),
        "{message}"
    );
    assert!(
        message.contains("C2 (life #0) reported at this boundary"),
        "{message}"
    );
    let marked: Vec<&str> = message
        .lines()
        .filter(|line| line.trim_start().starts_with(">>"))
        .collect();
    assert!(
        marked.iter().any(|line| line.contains("role")
            && line.contains("secondary")
            && line.contains("primary")),
        "the diff shows the role: {marked:?}"
    );
    assert!(
        marked
            .iter()
            .any(|line| line.contains("strength") && line.contains("20") && line.contains("30")),
        "the diff shows the strength: {marked:?}"
    );
    // The unmodified recording is accepted: the one added line is what is rejected.
    let good = Recording::read_dir(&fixture("demo-run")).expect("readable");
    let bad =
        Recording::read_dir(&fixture("demo-run-secondary-promotes-itself")).expect("readable");
    let events = |r: &Recording| {
        r.lives
            .values()
            .flatten()
            .map(|l| l.events.len())
            .sum::<usize>()
    };
    assert_eq!(events(&bad), events(&good) + 1);
}

#[test]
fn a_restart_within_one_round_is_a_behaviour_of_the_model() {
    // `lab run random --seed 4`: C3's life with its clock an hour back stopped 164 ms into a
    // round and the next (the right clock) started 37 ms later; the old life had sent that
    // round's heartbeat, so C1 saw C3 missing a round later than a restart at the round's
    // start would make it, and voted for the new life a round later. Rejected at round 32
    // without tolerance 3.
    let accepted = check(&fixture("lab-restart-within-a-round")).unwrap_or_else(|r| panic!("{r}"));
    println!("{accepted}");
    assert_eq!(accepted.controllers, 3);
    assert_eq!(accepted.lives, 6, "C1, C2 and four lives of C3");
    assert!(accepted.rounds_checked > 100, "{accepted}");
}

#[test]
fn a_takeover_that_hears_a_round_old_heartbeat_is_a_behaviour_of_the_model() {
    // `lab run tbf-primary --seed 1`: C2 took over from the starved C1 at 35, then lost it;
    // the heartbeat of C1 it heard next had waited a round in the link's queue and said 30,
    // where C1 had lowered to 15, so C2 held 35 a round longer. Rejected at round 18 without
    // tolerance 4.
    let accepted =
        check(&fixture("lab-takeover-stale-heartbeat")).unwrap_or_else(|r| panic!("{r}"));
    println!("{accepted}");
    assert_eq!(accepted.controllers, 3);
    assert_eq!(accepted.lives, 3);
    assert!(accepted.rounds_checked > 80, "{accepted}");
}

/// `rl demo --record` on domain 198: three controllers, camera and servo, the Primary killed
/// and restarted twice; the recording is validated. Bounded: the first kill must come within
/// 20 s (the demo kills 3 s after formation), the whole run within 60 s.
#[test]
fn a_fresh_demo_run_is_a_behaviour_of_the_model() {
    let exe = dds_replay::fault_injection_rl().unwrap_or_else(|e| panic!("{e}"));
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("validate-demo-run");
    if dir.exists() {
        std::fs::remove_dir_all(&dir).expect("empty the recording directory");
    }
    let started = Instant::now();
    let mut demo = Command::new(&exe)
        .args([
            "demo",
            "--domain",
            "198",
            "--kill-every-s",
            "3",
            "--down-s",
            "2",
        ])
        .args(["--cycles", "2", "--record"])
        .arg(&dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start rl demo");
    // What the demo says went wrong (a child that exited, and its last words) goes to stderr.
    let complaints = std::sync::Arc::new(std::sync::Mutex::new(Vec::<String>::new()));
    if let Some(stderr) = demo.stderr.take() {
        let complaints = std::sync::Arc::clone(&complaints);
        std::thread::spawn(move || {
            use std::io::BufRead;
            for line in std::io::BufReader::new(stderr)
                .lines()
                .map_while(Result::ok)
            {
                complaints
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push(line);
            }
        });
    }
    // The demo's timeline, line by line.
    let (lines, timeline) = std::sync::mpsc::channel::<String>();
    if let Some(stdout) = demo.stdout.take() {
        std::thread::spawn(move || {
            use std::io::BufRead;
            for line in std::io::BufReader::new(stdout)
                .lines()
                .map_while(Result::ok)
            {
                if lines.send(line).is_err() {
                    break;
                }
            }
        });
    }
    let mut printed: Vec<String> = Vec::new();
    let stop_with = |demo: &mut std::process::Child, printed: &[String], why: String| -> ! {
        // SIGTERM lets the demo stop its children; then make sure, the demo and its children.
        let children = children_of(demo.id());
        let _ = rl::procs::signal(demo.id(), libc::SIGTERM);
        std::thread::sleep(Duration::from_secs(3));
        let _ = demo.kill();
        let _ = demo.wait();
        for child in children {
            let _ = rl::procs::signal(child, libc::SIGKILL);
        }
        panic!("{why}; rl demo printed:\n{}", printed.join("\n"));
    };
    let status = loop {
        while let Ok(line) = timeline.try_recv() {
            printed.push(line);
        }
        if let Some(status) = demo.try_wait().expect("wait for rl demo") {
            break status;
        }
        let elapsed = started.elapsed();
        let killed = printed.iter().any(|line| line.contains("kill -9"));
        if !killed && elapsed > Duration::from_secs(20) {
            stop_with(
                &mut demo,
                &printed,
                "rl demo killed no Primary within 20 s".into(),
            );
        }
        if elapsed > Duration::from_secs(60) {
            stop_with(
                &mut demo,
                &printed,
                "rl demo did not finish its 2 cycles within 60 s".into(),
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    if !status.success() {
        std::thread::sleep(Duration::from_millis(200));
        while let Ok(line) = timeline.try_recv() {
            printed.push(line);
        }
        let complaints = complaints
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .join("\n");
        panic!(
            "rl demo exited with {status}; it printed:\n{}\nand on stderr:\n{complaints}",
            printed.join("\n")
        );
    }
    println!("rl demo ran for {:.1} s", started.elapsed().as_secs_f64());
    let validated = Instant::now();
    let accepted = check(&dir).unwrap_or_else(|r| panic!("{r}\nthe recording: {}", dir.display()));
    println!("{accepted} in {:.2} s", validated.elapsed().as_secs_f64());
    assert_eq!(accepted.lives, 5, "three controllers, two restarts");
}

/// The pids whose parent is `pid` (from /proc; empty where there is none).
fn children_of(pid: u32) -> Vec<u32> {
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    entries
        .filter_map(Result::ok)
        .filter_map(|entry| entry.file_name().to_str()?.parse::<u32>().ok())
        .filter(|candidate| {
            std::fs::read_to_string(format!("/proc/{candidate}/stat"))
                .ok()
                .and_then(|stat| {
                    // pid (comm) state ppid ...: the comm may hold spaces, so split after ')'.
                    let rest = stat.rsplit_once(')')?.1;
                    rest.split_whitespace().nth(1)?.parse::<u32>().ok()
                })
                == Some(pid)
        })
        .collect()
}
