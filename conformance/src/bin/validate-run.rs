//! `validate-run DIR [--config rl.toml]`: checks a recorded run of `rl` controllers (the JSON
//! event logs `rl demo --record DIR` writes, or any directory of `*.log` / `*.jsonl` files
//! holding `rl controller --json-events` lines) against the model, and says whether the model
//! allows it (docs/conformance.md, "Trace validation").
//!
//! The round length comes from the run's configuration: `--config`, else `DIR/rl.toml`, else
//! `rl`'s defaults. Exit 0: accepted; 1: rejected (the first round no model state explains,
//! with the closest model states); 2: bad arguments or an unreadable recording.

use clap::Parser;
use conformance::record::Recording;
use conformance::validate::{self, describe_lives};
use std::path::PathBuf;
use std::process::ExitCode;

/// Checks a recorded run of `rl` controllers against the model: whether the model allows it.
///
/// DIR holds the JSON event logs `rl demo --record DIR` writes (or any `*.log` / `*.jsonl`
/// files of `rl controller --json-events` lines). Exit 0: accepted; 1: rejected (the first
/// round no model state explains, with the closest model states); 2: bad arguments or an
/// unreadable recording.
///
/// Example: validate-run /tmp/demo-run --config rl.toml
#[derive(Parser)]
#[command(name = "validate-run")]
struct Arguments {
    /// The recording directory.
    #[arg(value_name = "DIR")]
    dir: PathBuf,
    /// The run's configuration, for its round length (default: DIR/rl.toml, else rl's
    /// defaults).
    #[arg(long, value_name = "PATH")]
    config: Option<PathBuf>,
}

fn main() -> ExitCode {
    // Bad arguments exit 2 with clap's message naming them.
    let Arguments { dir, config } = Arguments::parse();
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
