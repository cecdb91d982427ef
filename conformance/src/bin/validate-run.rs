//! `validate-run DIR [--config rl.toml]`: checks a recorded run of `rl` controllers (the JSON
//! event logs `rl demo --record DIR` writes, or any directory of `*.log` / `*.jsonl` files
//! holding `rl controller --json-events` lines) against the model, and says whether the model
//! allows it (docs/conformance.md, "Trace validation").
//!
//! The round length comes from the run's configuration: `--config`, else `DIR/rl.toml`, else
//! `rl`'s defaults. Exit 0: accepted; 1: rejected (the first round no model state explains,
//! with the closest model states); 2: bad arguments or an unreadable recording.

use conformance::record::Recording;
use conformance::validate::{self, describe_lives};
use std::path::PathBuf;
use std::process::ExitCode;

const USAGE: &str = "usage: validate-run DIR [--config PATH]";

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let mut dir: Option<PathBuf> = None;
    let mut config: Option<PathBuf> = None;
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--config" => match args.next() {
                Some(path) => config = Some(PathBuf::from(path)),
                None => return usage("--config needs a path"),
            },
            "-h" | "--help" => {
                println!("{USAGE}");
                return ExitCode::SUCCESS;
            }
            other if other.starts_with('-') => return usage(&format!("unknown option {other}")),
            other if dir.is_none() => dir = Some(PathBuf::from(other)),
            other => return usage(&format!("unexpected argument {other}")),
        }
    }
    let Some(dir) = dir else {
        return usage("no recording directory given");
    };
    let (timing, source) = match validate::run_timing(&dir, config.as_deref()) {
        Ok(found) => found,
        Err(error) => {
            eprintln!("validate-run: configuration: {error}");
            return ExitCode::from(2);
        }
    };
    let recording = match Recording::read_dir(&dir) {
        Ok(recording) => recording,
        Err(error) => {
            eprintln!("validate-run: {error}");
            return ExitCode::from(2);
        }
    };
    println!(
        "{}: heartbeat period {} ms, dead after {} rounds, window {} rounds (from {source})",
        dir.display(),
        timing.period_ms,
        timing.dead_after_rounds,
        timing.window_rounds
    );
    print!("{}", describe_lives(&recording, timing.period_ms));
    let started = std::time::Instant::now();
    match validate::validate(&recording, &timing) {
        Ok(accepted) => {
            println!("{accepted} in {:.2} s", started.elapsed().as_secs_f64());
            ExitCode::SUCCESS
        }
        Err(rejection) => {
            println!("REJECTED\n{rejection}");
            ExitCode::from(1)
        }
    }
}

fn usage(problem: &str) -> ExitCode {
    eprintln!("validate-run: {problem}\n{USAGE}");
    ExitCode::from(2)
}
