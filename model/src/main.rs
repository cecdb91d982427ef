//! `model`: check, explore, export and walk RL's voting protocol specification.

use clap::parser::ValueSource;
use clap::{ArgMatches, Args, CommandFactory, FromArgMatches, Parser, Subcommand, ValueEnum};
use model::architectures::{ArchitectureArgs, ArchitectureConfig, ArchitectureConfigError};
use model::config::ConfigError;
use model::explore::{ExploreError, Front};
use model::outputs::check::OutputReport;

use model::outputs::{self, OutputConfigError, OutputModel};
use model::properties::{catalogue, PropertyInfo};
use model::traces::TraceFileError;
use model::{search, simulate, traces, Config, RlModel};
use stateright::{Checker, Expectation, HasDiscoveries, Model};
use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

mod cli {
    pub mod scope;
}
use cli::scope::{OutputScope, Scope};

/// Why a command could not run (exit code 2); each names the bad argument or file.
#[derive(Debug, thiserror::Error)]
enum CliError {
    /// The scope's flags describe a configuration outside the model's bounds.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// `--threads 0`.
    #[error("threads: must be at least 1")]
    ZeroThreads,
    /// The trace directory could not be read or written.
    #[error(transparent)]
    Traces(#[from] TraceFileError),
    /// The explorer's address cannot be listened on, or the explorer did not start.
    #[error(transparent)]
    Explore(#[from] ExploreError),
    /// The output model's flags describe a configuration outside its bounds.
    #[error(transparent)]
    Outputs(#[from] OutputConfigError),
    /// `--depth` or `--order dfs` with `--outputs`, whose check is always exhaustive BFS.
    #[error("{0}: the output model's check is an exhaustive breadth-first search")]
    OutputsSearch(&'static str),
    /// The duplex's or the pair's flags describe a configuration outside their bounds, or
    /// the role or output model's flags were given with them.
    #[error(transparent)]
    Architecture(#[from] ArchitectureConfigError),
}

/// RL's voting protocol, as a checkable specification.
///
/// Time is counted in rounds of one heartbeat period; see docs/model.md. `--architecture
/// duplex|pair` checks the paper's two other architectures instead. Exit codes: 0 all
/// properties hold, 1 a property failed or a trace differs, 2 bad arguments.
#[derive(Parser)]
#[command(name = "model", version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Exhaustively check every property over the configuration.
    ///
    /// Prints a progress line while running, then each property with its result, the unique
    /// and total state counts, states/s and wall time. A violated `always` property (or a
    /// `sometimes` property never witnessed) prints the shortest path as numbered steps and
    /// exits 1.
    ///
    /// With `--outputs`, the output-voting model instead (docs/protocol.md, "Output voting").
    /// With `--architecture duplex` or `pair`, the paper's simple duplex or a lockstep pair in
    /// software, with the flags marked "Duplex:" and "Pair:" (docs/protocol.md, "Other
    /// architectures: the spec"; findings A1-A3 of docs/findings.md exit 1).
    Check(CheckArgs),
    /// Serve stateright's explorer UI: walk the protocol step by step in a browser.
    ///
    /// The initial states are named by which controllers start and which may join later
    /// (stateright itself says "Init 0", "Init 1", ...). `--outputs` and `--architecture
    /// duplex|pair` explore those models, with the same flags as `check`.
    Explore {
        #[command(flatten)]
        scope: Scope,
        #[command(flatten)]
        outputs: OutputScope,
        #[command(flatten)]
        architecture: ArchitectureArgs,
        /// Address to listen on.
        #[arg(long, default_value = "127.0.0.1:3000")]
        addr: String,
    },
    /// Write (or verify) the trace set the conformance suite replays.
    Traces {
        #[command(flatten)]
        scope: Scope,
        /// Directory of the trace set.
        #[arg(long, default_value = "traces")]
        out: PathBuf,
        /// Compare the committed traces with what the model generates now; exit 1 on a
        /// difference instead of writing.
        #[arg(long)]
        check: bool,
    },
    /// A reproducible random walk: the same seed gives the same walk.
    Simulate {
        #[command(flatten)]
        scope: Scope,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(long, default_value_t = 40)]
        steps: usize,
    },
}

#[derive(Args)]
struct CheckArgs {
    #[command(flatten)]
    scope: Scope,
    #[command(flatten)]
    outputs: OutputScope,
    #[command(flatten)]
    architecture: ArchitectureArgs,
    /// Search order.
    #[arg(long, value_enum, default_value_t = Order::Bfs)]
    order: Order,
    /// Checker threads.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Stop at this depth (number of actions); unbounded by default.
    #[arg(long)]
    depth: Option<usize>,
}

#[derive(Clone, Copy, ValueEnum)]
enum Order {
    Bfs,
    Dfs,
}

fn main() -> ExitCode {
    let matches = Cli::command().get_matches();
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|error| error.exit());
    let given = command_line_flags(&matches);
    let result = match cli.command {
        Command::Check(args) => check(args, &given),
        Command::Explore {
            scope,
            outputs,
            architecture,
            addr,
        } => explore(&scope, &outputs, &architecture, &addr, &given),
        Command::Traces { scope, out, check } => write_traces(&scope, &out, check),
        Command::Simulate { scope, seed, steps } => walk(&scope, seed, steps),
    };
    match result {
        Ok(code) => code,
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::from(2)
        }
    }
}

/// The ids of the flags given on the command line to the subcommand (not by default).
fn command_line_flags(matches: &ArgMatches) -> Vec<String> {
    let Some((name, given)) = matches.subcommand() else {
        return Vec::new();
    };
    let Some(command) = Cli::command().find_subcommand(name).cloned() else {
        return Vec::new();
    };
    command
        .get_arguments()
        .map(|arg| arg.get_id().as_str().to_string())
        .filter(|id| given.value_source(id) == Some(ValueSource::CommandLine))
        .collect()
}

type DynChecker = Box<dyn Checker<RlModel> + Send + Sync>;

fn check(args: CheckArgs, given: &[String]) -> Result<ExitCode, CliError> {
    if args.threads == 0 {
        return Err(CliError::ZeroThreads);
    }
    if let Some(config) = args.architecture.config()? {
        config.refuse_foreign_flags(given)?;
        return check_architecture(&config, args.threads);
    }
    if args.outputs.outputs {
        return check_outputs(&args);
    }
    let config = args.scope.config()?;
    println!("checking: {}", config.summary());
    let model = RlModel::new(config.clone());
    let start = Instant::now();
    let checker = run_checker(&model, &args, start);
    let secs = start.elapsed().as_secs_f64();
    println!();
    let failures = print_verdicts(&config, &checker);
    println!();
    println!(
        "{} unique states, {} total, max depth {}, {:.0} states/s, {:.2} s wall ({} threads, {})",
        checker.unique_state_count(),
        checker.state_count(),
        checker.max_depth(),
        checker.state_count() as f64 / secs,
        secs,
        args.threads,
        match args.order {
            Order::Bfs => "BFS",
            Order::Dfs => "DFS",
        }
    );
    if failures.is_empty() {
        println!("result: all {} properties as expected", catalogue().len());
        return Ok(ExitCode::SUCCESS);
    }
    print_shortest_paths(&model, &failures);
    println!("result: {} properties failed", failures.len());
    Ok(ExitCode::from(1))
}

/// Runs stateright's checker to completion, printing a progress line every 2 s.
fn run_checker(model: &RlModel, args: &CheckArgs, start: Instant) -> DynChecker {
    let mut builder = model
        .clone()
        .checker()
        .threads(args.threads)
        // Run exhaustively: stateright stops early once every property has a discovery.
        .finish_when(HasDiscoveries::AnyOf(BTreeSet::new()));
    if let Some(depth) = args.depth {
        // stateright checks states within depth - 2 actions (docs/model.md); compensate.
        builder = builder.target_max_depth(depth + 2);
    }
    let checker: DynChecker = match args.order {
        Order::Bfs => Box::new(builder.spawn_bfs()),
        Order::Dfs => Box::new(builder.spawn_dfs()),
    };
    let mut last = Instant::now();
    while !checker.is_done() {
        std::thread::sleep(Duration::from_millis(100));
        if checker.is_done() {
            break;
        }
        if last.elapsed() >= Duration::from_secs(2) {
            last = Instant::now();
            let secs = start.elapsed().as_secs_f64();
            eprintln!(
                "  ... {} unique states, {} total, depth {}, {:.0} states/s, {:.1} s",
                checker.unique_state_count(),
                checker.state_count(),
                checker.max_depth(),
                checker.state_count() as f64 / secs,
                secs
            );
        }
    }
    join(checker)
}

/// One line per property with its verdict; returns the properties that failed.
fn print_verdicts(config: &Config, checker: &DynChecker) -> Vec<PropertyInfo> {
    let discoveries = checker.discoveries();
    let mut failures = Vec::new();
    for info in catalogue() {
        let found = discoveries.contains_key(info.name);
        let (verdict, ok) = match (&info.expectation, found) {
            (Expectation::Sometimes, false) if !info.applies(config) => ("not applicable", true),
            (Expectation::Always, false) => ("holds", true),
            (Expectation::Always, true) => ("VIOLATED", false),
            (Expectation::Sometimes, true) => ("witnessed", true),
            (Expectation::Sometimes, false) => ("NEVER WITNESSED", false),
            (Expectation::Eventually, _) => ("not checked", true),
        };
        let kind = match &info.expectation {
            Expectation::Always => "always",
            Expectation::Sometimes => "sometimes",
            Expectation::Eventually => "eventually",
        };
        print!("  {verdict:>15}  {kind:<9} {}", info.name);
        if verdict == "not applicable" {
            print!(" ({})", info.needs(config));
            if info.losses_needed(config) > config.max_lost_heartbeats {
                print!(
                    " - see check --controllers 3 --late-joiners 0 --crashes 0 --restarts 0 \
                     --lost-heartbeats {}",
                    Config::link_failure().max_lost_heartbeats
                );
            }
        }
        println!();
        if !ok {
            failures.push(info);
        }
    }
    failures
}

/// stateright's discovery paths are not the shortest; search again and print the shortest.
fn print_shortest_paths(model: &RlModel, failures: &[PropertyInfo]) {
    let explored = search::explore(model, usize::MAX, |_, _| {});
    for info in failures {
        println!();
        match explored.discovery(info.name) {
            Some(path) if info.expectation == Expectation::Always => {
                println!(
                    "counterexample to \"{}\" ({} steps): {}",
                    info.name,
                    path.steps.len(),
                    info.meaning
                );
                print!("{}", path.render());
                let addr = "127.0.0.1:3000";
                println!(
                    "  explore it: cargo run --release -p model -- explore {} --addr {addr}\n  \
                     then open http://{addr}/{}",
                    model.config.flags(),
                    path.explorer_fragment(model)
                );
            }
            _ => println!(
                "\"{}\" was never witnessed: {} (a rule is unreachable or vacuous)",
                info.name, info.meaning
            ),
        }
    }
}

fn join(mut checker: DynChecker) -> DynChecker {
    for handle in checker.handles() {
        let _ = handle.join();
    }
    checker
}

/// `check --outputs`: the output-voting model, exhaustively; the shortest counterexample of
/// every failure.
fn check_outputs(args: &CheckArgs) -> Result<ExitCode, CliError> {
    let config = args.outputs.config()?;
    if args.depth.is_some() {
        return Err(CliError::OutputsSearch("--depth"));
    }
    if let Order::Dfs = args.order {
        return Err(CliError::OutputsSearch("--order dfs"));
    }
    println!("checking: {}", config.summary());
    let report: OutputReport = outputs::check::check(&config, args.threads);
    println!();
    print!("{}", report.render());
    let failed = report.failures().len();
    Ok(result(report.verdicts.len(), failed, || {
        outputs::check::render_failures(&report)
    }))
}

/// The result line of a check of `total` properties of which `failed` failed (after
/// `failures`, their counterexamples) and the exit status: 0, or 1 if any failed.
fn result(total: usize, failed: usize, failures: impl FnOnce() -> String) -> ExitCode {
    if failed == 0 {
        println!("result: all {total} properties as expected");
        return ExitCode::SUCCESS;
    }
    print!("{}", failures());
    println!("result: {failed} properties failed");
    ExitCode::from(1)
}

/// `check --architecture duplex|pair`: the model exhaustively; the shortest counterexample
/// of every failure.
fn check_architecture(config: &ArchitectureConfig, threads: usize) -> Result<ExitCode, CliError> {
    println!("checking: {}", config.summary());
    let report = config.check(threads);
    println!();
    print!("{}", report.render());
    let failed = report.failures().len();
    Ok(result(report.verdicts.len(), failed, || {
        config.render_failures(&report)
    }))
}

/// stateright's explorer behind a front that names the initial states (model::explore).
fn explore(
    scope: &Scope,
    outputs: &OutputScope,
    architecture: &ArchitectureArgs,
    addr: &str,
    given: &[String],
) -> Result<ExitCode, CliError> {
    if let Some(config) = architecture.config()? {
        config.refuse_foreign_flags(given)?;
        return Ok(serve(config.explorer(addr)?, &config.summary(), addr));
    }
    if outputs.outputs {
        let config = outputs.config()?;
        let model = OutputModel::new(config.clone());
        let front = Front::start_named(&model, model.initial_state_names(), addr)?;
        return Ok(serve(front, &config.summary(), addr));
    }
    let config = scope.config()?;
    let front = Front::start(&RlModel::new(config.clone()), addr)?;
    Ok(serve(front, &config.summary(), addr))
}

/// Serves the explorer until the process ends.
fn serve(front: Front, summary: &str, addr: &str) -> ExitCode {
    println!("explorer for {summary} at http://{addr}/");
    println!("initial states: {}", front.names().join(" | "));
    front.run();
    ExitCode::SUCCESS
}

fn write_traces(scope: &Scope, out: &std::path::Path, check: bool) -> Result<ExitCode, CliError> {
    // The configured scope, a persistent link failure for the minority voter's path, and
    // the paper variant's counterexamples.
    let scopes = traces::standard(scope.config()?);
    for scope in &scopes {
        eprintln!("exploring {} ...", scope.model.config.summary());
    }
    let set = traces::generate(&scopes, |states, edges| {
        eprintln!("  ... {states} states, {edges} edges");
    });
    println!("{}", set.coverage_report());
    if !check {
        traces::write(&set, out)?;
        println!("wrote {} files to {}", set.files.len(), out.display());
        return Ok(ExitCode::SUCCESS);
    }
    let differences = traces::compare(&set, out)?;
    if differences.is_empty() {
        println!(
            "traces in {} match the model ({} files)",
            out.display(),
            set.files.len()
        );
        return Ok(ExitCode::SUCCESS);
    }
    for difference in &differences {
        println!("differs: {difference}");
    }
    println!(
        "{} trace files differ: run `cargo run -p model -- traces --out {}` and review",
        differences.len(),
        out.display()
    );
    Ok(ExitCode::from(1))
}

fn walk(scope: &Scope, seed: u64, steps: usize) -> Result<ExitCode, CliError> {
    let config = scope.config()?;
    let model = RlModel::new(config);
    let path = simulate::walk(&model, seed, steps);
    println!(
        "seed {seed}, {} steps, {}",
        path.steps.len(),
        model.config.summary()
    );
    print!("{}", path.render());
    let violated: Vec<&str> = catalogue()
        .iter()
        .filter(|info| info.expectation == Expectation::Always)
        .filter(|info| {
            std::iter::once(&path.init)
                .chain(path.steps.iter().map(|(_, s)| s))
                .any(|state| !(info.condition)(&model, state))
        })
        .map(|info| info.name)
        .collect();
    if violated.is_empty() {
        println!("every `always` property held along the walk");
        Ok(ExitCode::SUCCESS)
    } else {
        println!("violated along the walk: {}", violated.join(", "));
        Ok(ExitCode::from(1))
    }
}
