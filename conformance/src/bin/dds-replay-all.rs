//! `dds-replay-all [--mutation NAME] [TRACE.jsonl ...]`: the DDS-level replay of every trace
//! the plan can time on real processes, not only the curated subset `tests/dds_replay.rs`
//! replays (174 of the 350 traces, several minutes), each recording then validated strictly
//! (docs/conformance.md, "DDS-level replay"). Given trace file names, only those. A trace
//! with cuts runs on the lab's virtual LAN (root: network namespaces and nftables), removed
//! again at its end or on SIGINT, SIGTERM or SIGHUP.
//! `--mutation NAME` runs the controllers with `RL_MUTATION=NAME` (a deliberately broken
//! rule, one of `rl_layer::core::mutation::Mutation`), to see which traces catch it; a
//! failure then prints only what departed from the model.
//! The traces real processes cannot take are counted by reason at the end (each reason is
//! argued in docs/conformance.md); `--refusals` only plans, printing each refused trace with
//! its reason and the counts, in a second.
//!
//! A command rather than a test: too long for every test run, and CI runs the ignored tests
//! too. Domain 199, one trace after the other; the `rl` binary with the `fault-injection` and
//! `mutation` features is the one beside this program (`target/release/rl`; build it with
//! `--all-features`), the recordings are kept
//! in `target/tmp/dds-replay-all/NNNN/`. Exit 0: every replayed trace conforms; 1: some did
//! not; 2: the arguments, the trace set, the configuration or the `rl` build could not be had.

use clap::Parser;
use conformance::dds_replay::{self, ReplayError, Setup};
use conformance::trace::{self, Trace};
use std::collections::BTreeMap;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

/// The DDS domain the replays run on.
const DOMAIN: u16 = 199;

/// The DDS-level replay of every trace real processes can take (or of the named ones), each
/// recording validated strictly against its trace.
///
/// Runs on domain 199, one trace after the other, with the `rl` built beside this program
/// (`--all-features`). Exit 0: every replayed trace conforms; 1: some did not; 2: the
/// arguments, the trace set, the configuration or the `rl` build could not be had.
///
/// Example: dds-replay-all --mutation failback 0001-formation-with-3-controllers.jsonl
///
/// Example: dds-replay-all --refusals
#[derive(Parser)]
#[command(name = "dds-replay-all")]
struct Arguments {
    /// Run the controllers with this deliberately broken rule (`RL_MUTATION`):
    /// promote-without-failure, ignore-minority-vote, failback, admit-fourth,
    /// stay-when-unplugged, keep-incarnation-on-resume, no-epoch-ranking.
    #[arg(long, value_name = "NAME")]
    mutation: Option<String>,
    /// Replay nothing: print each trace real processes cannot take with the reason, and the
    /// refusals counted by reason.
    #[arg(long, conflicts_with = "mutation")]
    refusals: bool,
    /// Trace files of traces/ to replay (default: every trace).
    #[arg(value_name = "TRACE.jsonl")]
    files: Vec<String>,
}

fn main() -> ExitCode {
    // Bad arguments exit 2 with clap's message naming them.
    let wanted = Arguments::parse();
    // A trace with cuts builds a virtual LAN: interrupted, it is removed before exiting.
    if let Err(error) = conformance::lab::lan::install_signal_cleanup() {
        eprintln!("dds-replay-all: {error}");
        return ExitCode::from(2);
    }
    let setup = dds_replay::timing().and_then(|timing| {
        // Planning needs no controllers: `--refusals` runs without the rl build.
        let exe = if wanted.refusals {
            None
        } else {
            Some(dds_replay::fault_injection_rl()?)
        };
        let traces = trace::read_dir(&trace::default_dir()).map_err(ReplayError::Unreadable)?;
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
        .files
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
    let mut tally = Tally::default();
    for trace in traces
        .iter()
        .filter(|t| wanted.files.is_empty() || wanted.files.contains(&t.file))
    {
        let plan = match dds_replay::plan(trace, &timing) {
            Ok(plan) => plan,
            Err(why) => {
                if wanted.refusals {
                    println!("{} refused: {why}", trace.file);
                }
                *tally.refused.entry(why.reason()).or_default() += 1;
                continue;
            }
        };
        tally.replayable += 1;
        let Some(exe) = exe.as_deref() else {
            continue;
        };
        let record_dir = record_root.join(trace.file.trim_end_matches(".jsonl"));
        match replay(trace, &plan, exe, &record_dir, wanted.mutation.clone()) {
            Ok(report) => {
                tally.replayed += 1;
                println!("{report}");
            }
            Err(error) => {
                let message = failure_text(&error, wanted.mutation.is_some());
                println!("{} FAILED\n{message}\n", trace.file);
                tally.failures.push(trace.file.clone());
            }
        }
    }
    close(&tally, &wanted, started)
}

/// What a run of the whole set came to.
#[derive(Default)]
struct Tally {
    /// Traces the plan can time on real processes.
    replayable: usize,
    /// Traces replayed and conforming.
    replayed: usize,
    /// Traces that did not conform.
    failures: Vec<String>,
    refused: Refusals,
}

/// The closing lines and the exit status: the counts, the refusals by reason, the failures.
fn close(tally: &Tally, wanted: &Arguments, started: Instant) -> ExitCode {
    let not_replayable: usize = tally.refused.values().sum();
    if wanted.refusals {
        println!(
            "{} traces replayable over DDS, {not_replayable} not replayable on real processes",
            tally.replayable
        );
        print_refusals(&tally.refused);
        return ExitCode::SUCCESS;
    }
    let under = wanted
        .mutation
        .as_ref()
        .map_or(String::new(), |m| format!(" with RL_MUTATION={m}"));
    println!(
        "{} traces replayed over DDS{under}, {} failed, {not_replayable} not \
         replayable on real processes, in {:.0} s",
        tally.replayed,
        tally.failures.len(),
        started.elapsed().as_secs_f64()
    );
    print_refusals(&tally.refused);
    if tally.failures.is_empty() {
        ExitCode::SUCCESS
    } else {
        println!("failed: {}", tally.failures.join(" "));
        ExitCode::from(1)
    }
}

/// The traces real processes cannot take, counted by [`dds_replay::PlanError::reason`].
type Refusals = BTreeMap<String, usize>;

/// The refusals by reason, the most common first.
fn print_refusals(refused: &Refusals) {
    let mut by_count: Vec<(&String, &usize)> = refused.iter().collect();
    by_count.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
    for (reason, count) in by_count {
        println!("  refused, {reason}: {count}");
    }
}

/// Replays one trace on real processes (the recording validated strictly); the line to
/// print, or why it does not conform.
fn replay(
    trace: &Trace,
    plan: &dds_replay::Plan,
    exe: &Path,
    record_dir: &Path,
    mutation: Option<String>,
) -> Result<String, dds_replay::ReplayError> {
    let setup = Setup {
        exe,
        domain: DOMAIN,
        record_dir,
        mutation,
    };
    let done = dds_replay::replay(plan, &setup)?;
    Ok(format!(
        "{} conforms ({}, attempt {}); its recording: {}",
        trace.file, trace.purpose, done.attempts, done.validation
    ))
}

/// Why a replay failed, for the report: only the problem under a mutation (the point is that
/// one is found), everything otherwise.
fn failure_text(error: &dds_replay::ReplayError, brief: bool) -> String {
    match error.problem() {
        Some(problem) if brief => problem.to_string(),
        _ => error.to_string(),
    }
}
