//! The `rl` command: controllers, simulators, status, demo and benchmarks.
//!
//! Exit codes: 0 success, 1 runtime failure, 2 bad arguments or configuration (the message
//! names the field), 75 a controller that voted itself FAILED and left to be restarted
//! (`timing.failed_exit_delay_ms`; the systemd unit restarts on it).

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

/// RL, a model-checked Redundancy Layer for three-way voting controllers over DDS.
///
/// Three `rl controller`s (ids 1, 2, 3) heartbeat each other at 4 Hz, vote roles
/// Primary/Secondary/Tertiary (lowest id first) and command the actuator
/// (`pixy/servo_control`) with DDS exclusive ownership at strength 30/20/10 by role. When the
/// Primary dies the actuator follows the Secondary within the command deadline (100 ms), and
/// the survivors re-vote.
///
/// Try it on one machine:  rl demo
#[derive(Parser)]
#[command(name = "rl", propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run one voting controller with the tracker application.
    ///
    /// Example: rl controller --id 1 --config /etc/rl/rl.toml
    Controller(rl::controller::ControllerArgs),
    /// Camera simulator: publishes a YELLOW circle moving on a path, plus other colours.
    Shapes(rl::sim::shapes::ShapesArgs),
    /// Actuator simulator: an exclusive-ownership reader of the command topic.
    ///
    /// With --json it prints one JSON object per line (a stable interface, see
    /// docs/architecture.md): {"event":"command",...} per accepted command and
    /// {"event":"owner_changed",...} per ownership change.
    Servo(rl::sim::servo::ServoArgs),
    /// Live tables of the controllers (phase, role, strength) and alarms of every redundancy
    /// group on the domain, read from DDS.
    ///
    /// `rl status --json --once` prints one JSON object per group and exits.
    Status(rl::status::StatusArgs),
    /// Three controllers, camera and servo on this machine; kills and restarts the Primary
    /// every few seconds so you can watch switchover, promotion and rejoin (`--chain`: the
    /// paper's navigation and actuator groups, each of three).
    Demo(rl::demo::DemoArgs),
    /// The paper's chain of two redundant groups: navigation (camera ball to aim) and
    /// actuator (aim to servo commands) controllers; `rl demo --chain` runs it.
    Chain(rl::chain::ChainArgs),
    /// Failover, promotion, formation and resource benchmarks (docs/performance.md).
    Bench(rl::bench::BenchArgs),
    /// DDS Security keystores: a CA, then one per controller or application (docs/security.md).
    Keys(rl::keys::KeysArgs),
    /// Check a configuration file and print the effective configuration.
    CheckConfig {
        /// The TOML file to check.
        path: std::path::PathBuf,
    },
}

/// `rl --version`: the version, then the optional features this binary was built with, so a
/// test build (`fault-injection`, `mutation`) is told from a shipped one at a glance, and the
/// conformance suite checks the binary it runs can do what it asks of it.
fn version_text() -> String {
    let features: Vec<&str> = [
        ("fault-injection", cfg!(feature = "fault-injection")),
        ("mutation", cfg!(feature = "mutation")),
        ("security", cfg!(feature = "security")),
    ]
    .into_iter()
    .filter_map(|(name, on)| on.then_some(name))
    .collect();
    let features = if features.is_empty() {
        "none".to_string()
    } else {
        features.join(", ")
    };
    format!("{} (features: {features})", env!("CARGO_PKG_VERSION"))
}

fn parse() -> Result<Cli, clap::Error> {
    // Once per process: clap takes the version as a 'static string.
    let version: &'static str = Box::leak(version_text().into_boxed_str());
    let matches = Cli::command().version(version).try_get_matches()?;
    Cli::from_arg_matches(&matches)
}

fn main() -> ExitCode {
    let one_arena = rl_layer::malloc::limit_arenas();
    let cli = match parse() {
        Ok(cli) => cli,
        Err(error) => {
            // clap prints help/version to stdout with success, misuse to stderr with code 2.
            let _ = error.print();
            return match error.kind() {
                clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion => {
                    ExitCode::SUCCESS
                }
                _ => ExitCode::from(2),
            };
        }
    };
    rl_layer::logging::init();
    if !one_arena {
        tracing::warn!("glibc refused mallopt(M_ARENA_MAX, 1): memory use may be higher");
    }
    let result = match cli.command {
        Command::Controller(args) => rl::controller::run(args),
        Command::Shapes(args) => rl::sim::shapes::run(args),
        Command::Servo(args) => rl::sim::servo::run(args),
        Command::Status(args) => rl::status::run(args),
        Command::Demo(args) => rl::demo::run(args),
        Command::Chain(args) => rl::chain::run(args),
        Command::Bench(args) => rl::bench::run(args),
        Command::Keys(args) => rl::keys::run(args),
        Command::CheckConfig { path } => rl_layer::config::Config::load(&path)
            .map(|config| print!("{}", toml::to_string(&config).unwrap_or_default()))
            .map_err(rl::Error::from),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("rl: {error}");
            ExitCode::from(error.exit_code())
        }
    }
}
