//! `rl bench`: the failover, promotion, formation and resource benchmarks, measured on real
//! processes over DDS on this machine (docs/performance.md has the figures and the command).
//!
//! - failover ([`failover`]): `kill -9` of the Primary at a seeded random phase of the
//!   heartbeat round; the command gap at `rl servo`, the promotion of the Secondary (its output
//!   at 30 and its status steady as Primary) and the owner changes at `rl servo` per kill;
//! - formation ([`formation`]): the third controller joins two others;
//! - resources ([`resources`]): RSS and CPU of one controller under load;
//! - groups ([`groups`], `--groups 1,2,4,8` alone): N groups of three on one domain, their
//!   formation, RSS and CPU, and one kill of every group's Primary at once;
//! - architectures ([`architectures`], `--architectures voting,duplex,pair` alone): the
//!   paper's three architectures side by side, their RSS and CPU, and kills of the servo's
//!   owner with its restart (docs/architectures.md).
//!
//! A kill or a formation that fails is counted and reported, and makes `rl bench` exit
//! non-zero after printing every figure. `--json` prints one JSON document with every figure,
//! every sample and the seed (docs/performance.json is one).

pub mod architectures;
pub mod failover;
pub mod formation;
pub mod groups;
mod report;
pub mod resources;
pub mod security;
pub mod stats;
mod watch;

use crate::procs::Fleet;
use rl_layer::config::{ArchitectureName, ControlLaw};
use rl_layer::core::ControllerId;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Arguments of `rl bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Kills of the Primary per command deadline.
    #[arg(long, default_value_t = 20, value_name = "N")]
    pub kills: u32,
    /// Command deadlines to measure failover at (ms, comma-separated).
    #[arg(
        long,
        default_value = "100,20",
        value_delimiter = ',',
        value_name = "MS",
        value_parser = clap::value_parser!(u64).range(1..)
    )]
    pub deadlines_ms: Vec<u64>,
    /// Fresh formations to time.
    #[arg(long, default_value_t = 10, value_name = "N")]
    pub formations: u32,
    /// Seconds of steady running to sample RSS and CPU over.
    #[arg(long, default_value_t = 10, value_name = "S")]
    pub resources_s: u64,
    /// DDS domain id (keep it away from running systems).
    #[arg(long, default_value_t = 220, value_name = "D")]
    pub domain: u16,
    /// Seed of the kill phases (default: from the clock); printed, and in the JSON, so a run's
    /// phases can be repeated.
    #[arg(long, value_name = "N")]
    pub seed: Option<u64>,
    /// Print one JSON document with every figure on stdout (the report goes to stderr).
    #[arg(long)]
    pub json: bool,
    /// Also run the first deadline's failover and the resource run with DDS Security
    /// (keystores made in the bench's temporary directory) and report each figure secured
    /// over unsecured (docs/performance.md, "DDS Security").
    #[arg(long)]
    pub security: bool,
    /// Instead of the other runs: N redundancy groups of three controllers on one domain, for
    /// each N given (comma-separated, e.g. 1,2,4,8): the time to form, every controller's RSS
    /// and CPU over --resources-s seconds, and one kill of every group's Primary at once
    /// (docs/performance.md, "Groups").
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "N",
        value_parser = clap::value_parser!(u32).range(1..=16)
    )]
    pub groups: Vec<u32>,
    /// The control law of C1, C2 and C3 (`tracker.law`, comma-separated, C1 first): `integer`
    /// (the original's arithmetic, the default) or `float` (the second implementation);
    /// `integer,float,integer` runs diverse implementations (docs/performance.md, "Diverse
    /// control laws").
    #[arg(long, value_delimiter = ',', value_name = "LAW", value_parser = parse_law)]
    pub laws: Vec<ControlLaw>,
    /// Instead of the other runs: each redundancy architecture given (comma-separated:
    /// `voting`, `duplex`, `pair`) with its controllers, the camera and the servo: every
    /// controller's RSS and CPU over --resources-s seconds, then --kills kills of the
    /// controller the servo follows, each restarted once alarmed; the gap, the owner changes
    /// per fault and the time to the alarm (docs/architectures.md).
    #[arg(long, value_delimiter = ',', value_name = "NAME", value_parser = parse_architecture)]
    pub architectures: Vec<ArchitectureName>,
}

/// An `--architectures` entry that names no architecture.
#[derive(Debug, thiserror::Error)]
#[error("{0:?} is not an architecture: voting, duplex or pair")]
pub struct UnknownArchitecture(String);

fn parse_architecture(text: &str) -> Result<ArchitectureName, UnknownArchitecture> {
    match text {
        "voting" => Ok(ArchitectureName::Voting),
        "duplex" => Ok(ArchitectureName::Duplex),
        "pair" => Ok(ArchitectureName::Pair),
        _ => Err(UnknownArchitecture(text.to_string())),
    }
}

/// A `--laws` entry that names no control law.
#[derive(Debug, thiserror::Error)]
#[error("{0:?} is not a control law: integer or float")]
pub struct UnknownLaw(String);

fn parse_law(text: &str) -> Result<ControlLaw, UnknownLaw> {
    match text {
        "integer" => Ok(ControlLaw::Integer),
        "float" => Ok(ControlLaw::Float),
        _ => Err(UnknownLaw(text.to_string())),
    }
}

/// `tracker.law`'s name of `law`.
fn law_name(law: ControlLaw) -> &'static str {
    match law {
        ControlLaw::Integer => "integer",
        ControlLaw::Float => "float",
    }
}

/// What a run of one kind measured: the JSON document of `--groups ... --json` and of
/// `--architectures ... --json`.
#[derive(Clone, Debug, Serialize)]
pub struct RunReport<T> {
    pub rl_version: &'static str,
    /// The command that repeats this run.
    pub command: String,
    /// CPUs available to the run (the machine may be shared).
    pub cores: usize,
    pub results: Vec<T>,
}

impl<T> RunReport<T> {
    /// The report of `command`'s `results`, on this machine.
    fn new(command: String, results: Vec<T>) -> RunReport<T> {
        RunReport {
            rl_version: env!("CARGO_PKG_VERSION"),
            command,
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            results,
        }
    }
}

/// What `rl bench --groups` measured.
pub type GroupsReport = RunReport<groups::GroupsResult>;

/// What `rl bench --architectures` measured.
pub type ArchitecturesReport = RunReport<architectures::ArchitectureResult>;

pub use crate::error::BenchError;

/// Everything one run measured: the JSON document of `--json`.
#[derive(Clone, Debug, Serialize)]
pub struct BenchResult {
    pub rl_version: &'static str,
    /// The command that repeats this run (with its seed).
    pub command: String,
    pub seed: u64,
    /// CPUs available to the run (the machine may be shared).
    pub cores: usize,
    pub heartbeat_period_ms: u64,
    pub failover: Vec<failover::FailoverResult>,
    pub formation: formation::FormationResult,
    pub resources: resources::ResourceResult,
    pub failed_kills: u32,
    pub failed_formations: u32,
    /// The secured runs and their ratios to the unsecured ones (`--security`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub security: Option<security::SecurityComparison>,
}

/// Where the runs happen: the `rl` executable, a directory for configurations, the domain.
pub struct Setup {
    exe: PathBuf,
    dir: PathBuf,
    domain: u16,
    heartbeat_period_ms: u64,
    /// With DDS Security: the directory of `rl keys` (`c<id>`, `servo`, `camera`).
    keystores: Option<PathBuf>,
    /// `--laws`: each controller's control law, C1 first (empty: the default for all).
    laws: Vec<ControlLaw>,
}

impl Setup {
    fn write_config(&self, name: &str, text: &str) -> Result<PathBuf, BenchError> {
        let path = self.dir.join(name);
        std::fs::write(&path, text)
            .map_err(|e| BenchError::io(format!("writing {}", path.display()), e))?;
        Ok(path)
    }

    /// A fleet with `config` and the watch over its output.
    fn fleet(&self, config: &Path) -> (Fleet, watch::Watch) {
        let (fleet, lines) = Fleet::new(&self.exe, Some(config), self.domain);
        (fleet, watch::Watch::new(lines))
    }

    /// The fleet's configuration, or a copy with what is `who`'s own: its keystore (with
    /// DDS Security) and its control law (with `--laws`).
    fn configured(&self, fleet: &Fleet, who: &str) -> Result<Option<PathBuf>, BenchError> {
        let Some(base) = fleet.config() else {
            return Ok(None);
        };
        let mut own = String::new();
        if let Some(keys) = &self.keystores {
            let keystore = keys.join(who).display().to_string();
            own.push_str(&format!("\n[security]\nkeystore = {keystore:?}\n"));
        }
        let law = who
            .strip_prefix('c')
            .and_then(|id| id.parse::<usize>().ok())
            .and_then(|id| self.laws.get(id.wrapping_sub(1)));
        if let Some(law) = law {
            own.push_str(&format!("\n[tracker]\nlaw = {:?}\n", law_name(*law)));
        }
        if own.is_empty() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(base)
            .map_err(|e| BenchError::io(format!("reading {}", base.display()), e))?;
        let name = format!(
            "{}-{who}.toml",
            base.file_stem().unwrap_or_default().to_string_lossy()
        );
        self.write_config(&name, &format!("{text}{own}")).map(Some)
    }

    fn start_controller(&self, fleet: &mut Fleet, id: ControllerId) -> Result<(), BenchError> {
        self.start_controller_with(fleet, id, &[])
    }

    /// Starts controller `id` with `extra` arguments after `--json-events`.
    fn start_controller_with(
        &self,
        fleet: &mut Fleet,
        id: ControllerId,
        extra: &[&str],
    ) -> Result<(), BenchError> {
        let mut args = vec!["--json-events"];
        args.extend_from_slice(extra);
        match self.configured(fleet, &format!("c{id}"))? {
            Some(config) => fleet.start_controller_configured(id, &config, &args),
            None => fleet.start_controller_with(id, &args),
        }
        .map(|_| ())
        .map_err(BenchError::spawn)
    }

    /// Starts `rl <args>` (the servo, the camera) as application `who`.
    fn start_app(&self, fleet: &mut Fleet, who: &str, args: &[&str]) -> Result<(), BenchError> {
        match self.configured(fleet, who)? {
            Some(config) => fleet.start_other_configured(who, &config, args),
            None => fleet.start_other(who, args),
        }
        .map(|_| ())
        .map_err(BenchError::spawn)
    }
}

/// A seed from the clock, for runs without `--seed`.
fn clock_seed() -> u64 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    nanos ^ u64::from(std::process::id()).rotate_left(32)
}

/// The command line that repeats a run.
fn command_line(args: &BenchArgs, seed: u64) -> String {
    let deadlines: Vec<String> = args.deadlines_ms.iter().map(u64::to_string).collect();
    format!(
        "rl bench --kills {} --deadlines-ms {} --formations {} --resources-s {} --domain {} --seed {seed}{}",
        args.kills,
        deadlines.join(","),
        args.formations,
        args.resources_s,
        args.domain,
        if args.json { " --json" } else { "" },
    ) + if args.security { " --security" } else { "" }
        + &if args.laws.is_empty() {
            String::new()
        } else {
            let laws: Vec<&str> = args.laws.iter().map(|law| law_name(*law)).collect();
            format!(" --laws {}", laws.join(","))
        }
}

/// Runs the benchmarks, prints the report (and the JSON document), and fails when a kill or
/// a formation failed.
pub fn run(args: BenchArgs) -> Result<(), crate::Error> {
    crate::cli::check_domain_with_networks(args.domain)?;
    if !(args.laws.is_empty() || args.laws.len() == 3) {
        return Err(crate::Error::Usage(format!(
            "--laws: one control law per controller, C1 first: three, not {}",
            args.laws.len()
        )));
    }
    Ok(run_bench(args)?)
}

fn run_bench(args: BenchArgs) -> Result<(), BenchError> {
    let seed = args.seed.unwrap_or_else(clock_seed);
    eprintln!("rl bench: seed {seed} (repeat the kill phases with --seed {seed})");
    let exe = std::env::current_exe().map_err(|e| BenchError::io("locating rl", e))?;
    let dir = std::env::temp_dir().join(format!("rl-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)
        .map_err(|e| BenchError::io("creating a temporary directory", e))?;
    let setup = Setup {
        exe,
        dir,
        domain: args.domain,
        heartbeat_period_ms: rl_layer::config::Timing::default().heartbeat_period_ms,
        keystores: None,
        laws: args.laws.clone(),
    };
    if !args.architectures.is_empty() {
        let measured =
            architectures::architectures(&setup, &args.architectures, args.kills, args.resources_s);
        let _ = std::fs::remove_dir_all(&setup.dir);
        return report_architectures(&args, measured?);
    }
    if !args.groups.is_empty() {
        let measured = groups::groups(&setup, &args.groups, args.resources_s);
        let _ = std::fs::remove_dir_all(&setup.dir);
        return report_groups(&args, measured?);
    }
    let measured = measure(&setup, &args, seed);
    let _ = std::fs::remove_dir_all(&setup.dir);
    let result = measured?;
    if args.json {
        let _ = report::write_report(&mut std::io::stderr(), &result);
        println!("{}", serde_json::to_string_pretty(&result)?);
    } else {
        let _ = report::write_report(&mut std::io::stdout(), &result);
    }
    if result.failed_kills > 0 || result.failed_formations > 0 {
        return Err(BenchError::Failed {
            failed_kills: result.failed_kills,
            kills: result.failover.iter().map(|f| f.kills).sum(),
            failed_formations: result.failed_formations,
            formations: result.formation.runs,
            seed,
        });
    }
    Ok(())
}

/// Prints what `--architectures` measured (a table; with `--json` the document too).
fn report_architectures(
    args: &BenchArgs,
    results: Vec<architectures::ArchitectureResult>,
) -> Result<(), BenchError> {
    let names: Vec<String> = results
        .iter()
        .map(|r| format!("{:?}", r.architecture).to_lowercase())
        .collect();
    let report = ArchitecturesReport::new(
        format!(
            "rl bench --architectures {} --kills {} --resources-s {} --domain {}{}",
            names.join(","),
            args.kills,
            args.resources_s,
            args.domain,
            if args.json { " --json" } else { "" }
        ),
        results,
    );
    emit(args.json, &report, report::write_architectures)
}

/// Prints `report` as text (on stderr with `--json`, whose document goes to stdout).
fn emit<R: Serialize>(
    json: bool,
    report: &R,
    write: fn(&mut Box<dyn std::io::Write>, &R) -> std::io::Result<()>,
) -> Result<(), BenchError> {
    let mut out: Box<dyn std::io::Write> = if json {
        Box::new(std::io::stderr())
    } else {
        Box::new(std::io::stdout())
    };
    // A closed output is not an error worth more than the figures.
    let _ = write(&mut out, report);
    if json {
        println!("{}", serde_json::to_string_pretty(report)?);
    }
    Ok(())
}

/// Prints what `--groups` measured, and fails when a group did not form or a kill failed.
fn report_groups(args: &BenchArgs, results: Vec<groups::GroupsResult>) -> Result<(), BenchError> {
    let counts: Vec<String> = args.groups.iter().map(u32::to_string).collect();
    let report = GroupsReport::new(
        format!(
            "rl bench --groups {} --resources-s {} --domain {}{}",
            counts.join(","),
            args.resources_s,
            args.domain,
            if args.json { " --json" } else { "" }
        ),
        results,
    );
    emit(args.json, &report, report::write_groups)?;
    let failed_kills: u32 = report.results.iter().map(|r| r.failed_kills).sum();
    let failed_formations: u32 = report.results.iter().map(|r| r.failed_formations).sum();
    if failed_kills > 0 || failed_formations > 0 {
        return Err(BenchError::GroupsFailed {
            failed_kills,
            kills: report.results.iter().map(|r| r.kills.len() as u32).sum(),
            failed_formations,
            groups: report.results.iter().map(|r| r.groups).sum(),
        });
    }
    Ok(())
}

fn measure(setup: &Setup, args: &BenchArgs, seed: u64) -> Result<BenchResult, BenchError> {
    let mut phases = stats::SplitMix64::new(seed);
    let mut failovers = Vec::new();
    for &deadline_ms in &args.deadlines_ms {
        failovers.push(failover::failover(
            setup,
            deadline_ms,
            args.kills,
            &mut phases,
        )?);
    }
    let formation = formation::formation(setup, args.formations)?;
    let resources = resources::resources(setup, args.resources_s)?;
    let security = match (args.security, failovers.first()) {
        (true, Some(unsecured)) => Some(security::compare(
            setup,
            unsecured,
            &resources,
            args,
            &mut phases,
        )?),
        _ => None,
    };
    Ok(BenchResult {
        rl_version: env!("CARGO_PKG_VERSION"),
        command: command_line(args, seed),
        seed,
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        heartbeat_period_ms: setup.heartbeat_period_ms,
        failed_kills: failovers.iter().map(|f| f.failed_kills).sum::<u32>()
            + security.as_ref().map_or(0, |s| s.failover.failed_kills),
        failed_formations: formation.failed_formations,
        failover: failovers,
        formation,
        resources,
        security,
    })
}
