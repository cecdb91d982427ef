//! `dds-replay-all [TRACE.jsonl ...]`: the DDS-level replay of every trace the plan can time on
//! real processes, not only the curated subset `tests/dds_replay.rs` replays (about 100
//! traces, some 6 minutes), each recording then checked by trace validation
//! (docs/conformance.md, "DDS-level replay"). Given trace file names, only those.
//!
//! A command rather than a test: too long for every test run, and CI runs the ignored tests
//! too. Domain 199, one trace after the other; the `rl` binary with the `fault-injection`
//! feature is built once into `target/fault-injection`, the recordings are kept in
//! `target/tmp/dds-replay-all/NNNN/`. Exit 0: every replayed trace conforms; 1: some did not;
//! 2: the trace set, the configuration or the `rl` build could not be had.

use conformance::dds_plan::{self, CURATED};
use conformance::dds_replay;
use conformance::record::Recording;
use conformance::trace::{self, Trace};
use conformance::validate::{self, Timing};
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

/// The DDS domain the replays run on.
const DOMAIN: u16 = 199;

fn main() -> ExitCode {
    let wanted: Vec<String> = std::env::args().skip(1).collect();
    if wanted.iter().any(|arg| arg.starts_with('-')) {
        eprintln!("usage: dds-replay-all [TRACE.jsonl ...]   (default: every trace)");
        return ExitCode::from(2);
    }
    let setup = dds_replay::timing().and_then(|timing| {
        let exe = dds_replay::fault_injection_rl()?;
        let traces = trace::read_dir(&trace::default_dir()).map_err(|e| e.to_string())?;
        Ok((timing, exe, traces))
    });
    let (timing, exe, traces) = match setup {
        Ok(setup) => setup,
        Err(error) => {
            eprintln!("dds-replay-all: {error}");
            return ExitCode::from(2);
        }
    };
    if let Some(unknown) = wanted
        .iter()
        .find(|w| !traces.iter().any(|t| &&t.file == w))
    {
        eprintln!("dds-replay-all: no trace {unknown} in traces/");
        return ExitCode::from(2);
    }
    let record_root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("target")
        .join("tmp")
        .join("dds-replay-all");
    let started = Instant::now();
    let (mut replayed, mut not_replayable, mut failures) = (0, 0, Vec::new());
    for trace in traces
        .iter()
        .filter(|t| wanted.is_empty() || wanted.contains(&t.file))
    {
        let Ok(plan) = dds_plan::plan(trace, &timing) else {
            not_replayable += 1;
            continue;
        };
        let record_dir = record_root.join(trace.file.trim_end_matches(".jsonl"));
        match replay_and_validate(trace, plan, &exe, &timing, &record_dir) {
            Ok(report) => {
                replayed += 1;
                println!("{report}");
            }
            Err(message) => {
                println!("{} FAILED\n{message}\n", trace.file);
                failures.push(trace.file.clone());
            }
        }
    }
    println!(
        "{replayed} traces replayed over DDS, {} failed, {not_replayable} not replayable on \
         real processes, in {:.0} s",
        failures.len(),
        started.elapsed().as_secs_f64()
    );
    if failures.is_empty() {
        ExitCode::SUCCESS
    } else {
        println!("failed: {}", failures.join(" "));
        ExitCode::from(1)
    }
}

/// Replays one trace on real processes and validates the recording; the line to print, or
/// why it does not conform.
fn replay_and_validate(
    trace: &Trace,
    plan: dds_plan::Plan,
    exe: &Path,
    timing: &Timing,
    record_dir: &Path,
) -> Result<String, String> {
    let selected = dds_plan::Selected {
        curated: CURATED[0],
        trace: trace.clone(),
        plan,
    };
    let done = dds_replay::replay(&selected, exe, DOMAIN, record_dir)?;
    let recording = Recording::read_dir(record_dir).map_err(|e| e.to_string())?;
    let accepted = validate::validate(&recording, timing)
        .map_err(|rejection| format!("{}: recording rejected:\n{rejection}", trace.file))?;
    Ok(format!(
        "{} conforms ({}, attempt {}); its recording: {accepted}",
        trace.file, trace.purpose, done.attempts
    ))
}
