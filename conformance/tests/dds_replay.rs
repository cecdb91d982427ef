//! The DDS-level replay (docs/conformance.md, "DDS-level replay"): a curated subset of the
//! model's traces, every fault kind at least once, replayed against real
//! `rl controller --json-events` processes over DDS on loopback, with real faults (`kill -9`,
//! new processes, heartbeats dropped by the fault-injection control). Each run's recorded
//! events are then checked by trace validation.
//!
//! The subset is `conformance::dds_plan::CURATED`, resolved by purpose from
//! `traces/index.json`; each test has its own DDS domain (190-197, in that table) and the
//! tests take turns (they are timed on the wall clock, and this machine has 2 cores). The
//! `rl` binary with the `fault-injection` feature is built once into
//! `target/fault-injection`; the recordings are kept in `target/tmp/dds-replay/NNNN/`.
//!
//! Every replayable trace, not only this subset, is a command, not a test (about 6 minutes):
//! `cargo run --release -p conformance --bin dds-replay-all`.

use conformance::dds_plan::{self, CURATED};
use conformance::dds_replay;
use conformance::record::Recording;
use conformance::trace;
use conformance::validate;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

/// One replay at a time.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

fn replay_curated(name: &str) {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let curated = CURATED
        .iter()
        .find(|c| c.name == name)
        .unwrap_or_else(|| panic!("no curated entry {name:?}"));
    let timing = dds_replay::timing().unwrap_or_else(|e| panic!("replay configuration: {e}"));
    let selected =
        dds_plan::select(&trace::default_dir(), curated, &timing).unwrap_or_else(|e| panic!("{e}"));
    let exe = dds_replay::fault_injection_rl().unwrap_or_else(|e| panic!("{e}"));
    let stem = selected.plan.file.trim_end_matches(".jsonl").to_string();
    let record_dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("dds-replay")
        .join(&stem);
    let started = Instant::now();
    let replayed = dds_replay::replay(&selected, &exe, curated.domain, &record_dir)
        .unwrap_or_else(|e| panic!("{e}"));
    println!(
        "{}: traces/{} ({}) conforms over DDS on domain {}: lockstep boundaries {}, real \
         rounds {}, attempt {}, {:.1} s",
        curated.name,
        replayed.file,
        selected.plan.purpose,
        curated.domain,
        replayed.lockstep_boundaries,
        replayed.rounds,
        replayed.attempts,
        started.elapsed().as_secs_f64()
    );
    let recording = Recording::read_dir(&record_dir).unwrap_or_else(|e| panic!("{e}"));
    let (timing, _) = validate::run_timing(&record_dir, None).unwrap_or_else(|e| panic!("{e}"));
    let validated = Instant::now();
    match validate::validate(&recording, &timing) {
        Ok(accepted) => println!(
            "  its recording ({}) is a behaviour of the model: {accepted} in {:.2} s",
            record_dir.display(),
            validated.elapsed().as_secs_f64()
        ),
        Err(rejection) => panic!(
            "the recording of the replay of traces/{} ({}) is not a behaviour of the model:\n{rejection}",
            replayed.file,
            record_dir.display()
        ),
    }
}

#[test]
fn the_curated_subset_shows_every_fault_kind() {
    let timing = dds_replay::timing().expect("the replay configuration is valid");
    println!("{:<24} {:<12} {:<6} why", "fault", "trace", "domain");
    for curated in CURATED {
        let selected = dds_plan::select(&trace::default_dir(), curated, &timing)
            .unwrap_or_else(|e| panic!("{e}"));
        println!(
            "{:<24} {:<12} {:<6} {} [{}]",
            curated.name,
            selected.plan.file,
            curated.domain,
            curated.why,
            selected.plan.describe()
        );
    }
}

/// A suite that cannot fail proves nothing: the Primary-crash replay with the `kill -9` left
/// out must fail at the first boundary where the model has the Primary down, with a diff.
/// Domain 199.
#[test]
fn a_replay_that_departs_from_the_trace_fails_with_a_diff() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let timing = dds_replay::timing().expect("the replay configuration is valid");
    let curated = CURATED
        .iter()
        .find(|c| c.need == dds_plan::Need::CrashOf(model::Role::Primary))
        .expect("the subset has a crash of the Primary");
    let mut selected =
        dds_plan::select(&trace::default_dir(), curated, &timing).unwrap_or_else(|e| panic!("{e}"));
    let crash_round = selected
        .plan
        .rounds
        .iter()
        .position(|r| !r.lifecycle.is_empty())
        .expect("the trace crashes a controller");
    selected.plan.rounds[crash_round].lifecycle.clear();
    let exe = dds_replay::fault_injection_rl().unwrap_or_else(|e| panic!("{e}"));
    let record_dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("dds-replay")
        .join("departing");
    let message = dds_replay::replay(&selected, &exe, 199, &record_dir)
        .expect_err("the processes keep the Primary alive; the model has it killed");
    println!("{message}");
    let expected_row = format!("boundary {} of", crash_round + 1);
    assert!(
        message.contains(&expected_row),
        "fails right after the missing crash: {message}"
    );
    assert!(
        message.lines().any(|line| {
            let row: Vec<&str> = line.split_whitespace().collect();
            row == [">>", "life", "down", "up"]
        }),
        "the diff shows C1 up where the model has it down: {message}"
    );
}

// Domain 190.
#[test]
fn crash_of_the_primary() {
    replay_curated("crash of the Primary");
}

// Domain 191.
#[test]
fn crash_of_the_secondary() {
    replay_curated("crash of the Secondary");
}

// Domain 192.
#[test]
fn crash_of_the_tertiary() {
    replay_curated("crash of the Tertiary");
}

// Domain 193.
#[test]
fn restart() {
    replay_curated("restart");
}

// Domain 194.
#[test]
fn late_join() {
    replay_curated("late join");
}

// Domain 195.
#[test]
fn fourth_controller() {
    replay_curated("fourth controller");
}

// Domain 196.
#[test]
fn one_way_heartbeat_loss() {
    replay_curated("one-way heartbeat loss");
}

// Domain 197.
#[test]
fn minority_vote() {
    replay_curated("minority vote");
}
