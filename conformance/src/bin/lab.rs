//! `lab`: the fault lab. Real `rl` processes on a virtual LAN of network namespaces, under
//! real faults, judged at two actuators and against the model (docs/faults.md).

use clap::builder::PossibleValuesParser;
use clap::{Parser, Subcommand};
use conformance::lab::wrong_output::tracking;
use conformance::lab::{self, host, matrix, run, scenario, session::Setup, soak, LabError};
use std::path::PathBuf;
use std::process::ExitCode;

/// RL's fault lab: three `rl controller`s, `rl servo --json`, a Connext reader and `rl shapes`,
/// each in its own network namespace on a virtual LAN of two nets (A 10.201.1.0/24, B
/// 10.202.1.0/24), under kills, pauses, partitions, cuts, one-way and random loss, multicast
/// drop, flapping links, clock offsets and rate limits (each on both nets), and a net or one
/// controller's link into a net going down, and controllers whose commands go wrong while
/// their heartbeats stay right.
///
/// Every run forms P/S/T, applies its faults, heals them, and must settle within the model's
/// bound (10 rounds). It is judged on the owner changes each fault caused at both actuators,
/// the largest command gap, the time two controllers claimed top strength, the controllers'
/// recorded events against the model, and every process alive without a panic. The net
/// scenarios (net-b-down, c2-transceiver-a-down, c2-both-links-down, both-networks-down; not
/// in matrix --ci) are also judged on the controllers' network alarms: raised within 1000 ms
/// of the fault, cleared within 1500 ms of the heal, no other. two-groups (in neither matrix)
/// runs two redundancy groups (nav, act) on one LAN, kills both Primaries at once and judges
/// each group as kill-primary is judged, and for cross-talk between the groups. The
/// wrong-output scenarios (wrong-primary, wrong-primary-vote-camera, wrong-secondary,
/// frozen-primary, drift-primary, wrong-input-primary, random-primary, two-wrong; not in
/// matrix --ci) need an rl built with the fault-injection feature; they add a voting reader
/// (rl servo --vote --json) beside the two exclusive ones and are judged on the wrong commands
/// each reader took, the wrong controller's odd-one-out decision (on input for
/// wrong-input-primary, with its input_disagrees alarm), exit and return, and the voting
/// reader's dissent and hold; the camera's tracking error is drawn to
/// OUT/NAME-seedN-tracking.svg. The gray process faults (freeze-primary, stutter-primary,
/// starve-primary, starve-primary-long) freeze or starve the Primary in a cgroup (v1 freezer,
/// cpu quota).
/// Controllers get --network-a and --network-b (their addresses on A and B) when the rl takes them; a judge that cannot
/// run (an rl without them, no Connext connector) is an error unless --lenient skips it. A run leaves its recording, result.json and
/// timeline in OUT/NAME-seedN/ and its picture in
/// OUT/NAME-seedN.svg; a failing run prints the command that replays it.
///
/// Needs root, iproute2 (ip, tc), nftables and faketime (apt-get install nftables faketime);
/// the Connext judge needs `pip install rticonnextdds-connector==1.2.4` (without it: exit 2,
/// or skipped with a warning under --lenient). Build rl first: cargo build --release -p rl.
///
/// Examples:
///   lab list
///   lab run cut-primary
///   lab run net-b-down
///   lab run random --seed 17
///   lab run two-groups
///   lab run kill-primary --mutation failback   (rl built with --features mutation)
///   lab run wrong-primary --vote-mutation accept-single-source
///   lab matrix --ci
///   lab run kill-primary --architecture duplex
///   lab matrix --architecture pair
///   lab run wrong-primary --architecture pair --mutation write-before-compare
///   lab traffic --architecture duplex --seconds 10
///   lab soak --minutes 30
///   lab figure --to tracking.svg OUT/wrong-primary-seed1 OUT/wrong-primary-vote-camera-seed1
#[derive(Parser)]
#[command(name = "lab", verbatim_doc_comment)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// The rl binary the processes run (default: rl beside this program, target/release/rl).
    #[arg(long, global = true, value_name = "PATH")]
    rl: Option<PathBuf>,
    /// Where runs leave their output.
    #[arg(long, global = true, value_name = "DIR", default_value = "target/lab")]
    out: PathBuf,
    /// DDS domain inside the namespaces (each run's namespaces isolate it from everything
    /// else, so any domain will do).
    #[arg(long, global = true, value_name = "D", default_value_t = 53)]
    domain: u16,
    /// Go on when a judge cannot run (no Connext connector, an rl without network alarm
    /// participants): that judge is skipped with a warning. Without it such a run is an
    /// error (exit 2), so a missing judge never passes for a judge that said yes.
    #[arg(long, global = true)]
    lenient: bool,
}

#[derive(Subcommand)]
enum Command {
    /// The scenarios, with their faults.
    List {
        /// Also the schedules random seeds 1..=N draw.
        #[arg(long, value_name = "N")]
        random: Option<u64>,
    },
    /// One scenario; `random` draws its faults and times from the seed.
    Run {
        /// A name from `lab list`, or `random`.
        scenario: String,
        /// The seed: picks a random schedule's faults and times, a flapping link's intervals.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Run the controllers with a deliberately broken rule (RL_MUTATION=NAME, set for the
        /// controllers only: a voting rule, or write-before-compare, the lockstep pair's order
        /// broken), to see the lab catch it: the run must FAIL. Needs an rl
        /// built with the `mutation` feature (the workspace's test build, --all-features, or
        /// cargo build --release -p rl --features mutation); with any other rl the run stops
        /// with an error.
        #[arg(long, value_name = "NAME", value_parser = PossibleValuesParser::new(lab::mutation::NAMES))]
        mutation: Option<String>,
        /// Run the voting reader of a wrong-output scenario with a deliberately broken voting
        /// rule (RL_VOTE_MUTATION=NAME, set for `rl servo --vote` only), to see the lab catch
        /// it: the run must FAIL. Needs an rl built with the `mutation` feature.
        #[arg(long, value_name = "NAME", value_parser = PossibleValuesParser::new(lab::mutation::VOTE_NAMES), conflicts_with = "mutation")]
        vote_mutation: Option<String>,
        /// The redundancy architecture the controllers run: voting (three controllers), duplex
        /// (C1 Primary, C2 Standby, the paper's preemption) or pair (the lockstep pair, C1 and
        /// C2), each judged on what its own rules let a fault cause (docs/architectures.md).
        /// two-groups runs under voting only, two-wrong not under the pair (both members
        /// leave: two failures); under the other two a wrong-output scenario's voting reader
        /// is only the reference for the right commands.
        #[arg(long, value_name = "A", default_value = "voting", value_parser = lab::architecture::parse)]
        architecture: lab::architecture::Architecture,
    },
    /// Every scenario and random seeds 1, 2, 3, 7, 8, as a table (--ci: the short subset CI runs).
    Matrix {
        #[arg(long)]
        ci: bool,
        /// The architecture every run's controllers run (as for `run`).
        #[arg(long, value_name = "A", default_value = "voting", value_parser = lab::architecture::parse)]
        architecture: lab::architecture::Architecture,
    },
    /// One system under random faults for M minutes, memory and descriptors sampled.
    Soak {
        #[arg(long, value_name = "M")]
        minutes: u64,
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Draws the camera's tracking error of wrong-output runs (their OUT/NAME-seedN
    /// directories) on one figure, against the time since each run's wrong commands began.
    Figure {
        /// The SVG to write.
        #[arg(long, value_name = "FILE")]
        to: PathBuf,
        /// Seconds shown after the fault began.
        #[arg(long, value_name = "S", default_value_t = 4.0)]
        seconds: f64,
        #[arg(required = true, value_name = "RUN_DIR")]
        runs: Vec<PathBuf>,
    },
    /// Forms a system and measures each controller's traffic (both nets, from its links'
    /// kernel counters) over a fault-free window, as a Markdown table (--json: JSON).
    Traffic {
        /// The window's length.
        #[arg(long, value_name = "S", default_value_t = 10)]
        seconds: u64,
        /// The architecture the controllers run (as for `run`).
        #[arg(long, value_name = "A", default_value = "voting", value_parser = lab::architecture::parse)]
        architecture: lab::architecture::Architecture,
        #[arg(long)]
        json: bool,
    },
    /// Removes every lab LAN left on this host (after a run killed with SIGKILL), other
    /// runs' included.
    Clean,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match execute(&cli) {
        Ok(code) => code,
        Err(error) => {
            eprintln!("lab: {error}");
            ExitCode::from(2)
        }
    }
}

fn execute(cli: &Cli) -> Result<ExitCode, LabError> {
    if let Command::List { random } = cli.command {
        list(random);
        return Ok(ExitCode::SUCCESS);
    }
    if let Command::Figure { to, seconds, runs } = &cli.command {
        figure(to, *seconds, runs)?;
        return Ok(ExitCode::SUCCESS);
    }
    host::require_root()?;
    host::require_tools()?;
    lab::lan::install_signal_cleanup()?;
    if let Command::Clean = cli.command {
        for prefix in lab::lan::remove_all_leftovers() {
            println!("removed {prefix}");
        }
        return Ok(ExitCode::SUCCESS);
    }
    let setup = setup(cli)?;
    std::fs::create_dir_all(&cli.out).map_err(|e| LabError::output(&cli.out, e))?;
    let passed = match &cli.command {
        Command::Run {
            scenario,
            architecture,
            ..
        } if scenario == lab::two_groups::NAME
            && *architecture != lab::architecture::Architecture::Voting =>
        {
            return Err(LabError::NotUnderArchitecture {
                scenario: scenario.clone(),
                architecture: lab::architecture::name(*architecture),
                reason: lab::two_groups::ONLY_VOTING,
            });
        }
        Command::Run { scenario, seed, .. } if scenario == lab::two_groups::NAME => {
            let outcome = lab::two_groups::run(*seed, &setup, &cli.out)?;
            print!("{}", lab::two_groups::summary(&outcome));
            outcome.passed()
        }
        Command::Run { scenario, seed, .. } => {
            let found =
                scenario::find(scenario, *seed).ok_or_else(|| LabError::UnknownScenario {
                    name: scenario.clone(),
                })?;
            let outcome = run::run(&found, *seed, &setup, &cli.out)?;
            print!("{}", run::summary(&outcome));
            outcome.passed()
        }
        Command::Matrix { ci, .. } => {
            let outcomes = matrix::run_matrix(*ci, &setup, &cli.out)?;
            let failed: Vec<&run::Outcome> = outcomes.iter().filter(|o| !o.passed()).collect();
            for o in &failed {
                eprintln!(
                    "lab: FAILED {} (seed {}): {}\n  replay: {}",
                    o.scenario,
                    o.seed,
                    o.failures.join("; "),
                    o.replay
                );
            }
            failed.is_empty()
        }
        Command::Soak { minutes, seed } => {
            let failures = soak::soak(*minutes, *seed, &setup, &cli.out)?;
            for failure in &failures {
                eprintln!("lab soak: FAILED {failure}");
            }
            // The verdict last, so a long run's end says it without reading back.
            if failures.is_empty() {
                eprintln!("lab soak (seed {seed}, {minutes} min): PASS");
            } else {
                eprintln!(
                    "lab soak (seed {seed}, {minutes} min): FAIL, {} failure(s) above",
                    failures.len()
                );
            }
            failures.is_empty()
        }
        Command::Traffic { seconds, json, .. } => {
            let traffic = lab::traffic::measure(&setup, std::time::Duration::from_secs(*seconds))?;
            if *json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&traffic).unwrap_or_default()
                );
            } else {
                print!("{}", lab::traffic::table(&traffic));
            }
            true
        }
        Command::List { .. } | Command::Clean | Command::Figure { .. } => true,
    };
    Ok(if passed {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// `lab figure`: the tracking error of the wrong-output runs in `runs` on one figure at `to`.
fn figure(to: &std::path::Path, seconds: f64, runs: &[PathBuf]) -> Result<(), LabError> {
    let series = runs
        .iter()
        .map(|dir| tracking::read_series(dir))
        .collect::<Result<Vec<_>, _>>()?;
    let title = "the ball off centre at the camera, a wrong Primary at 0 s";
    tracking::draw(to, title, &series, -1.0, seconds)
}

/// `lab list`: every named scenario with its schedule, `two-groups`, and what random seeds
/// 1..=`random` draw.
fn list(random: Option<u64>) {
    for s in scenario::named() {
        let ci = if s.in_ci { " [ci]" } else { "" };
        println!(
            "{:<34}{}{ci}\n{:<34}{}",
            s.name,
            s.about,
            "",
            scenario::describe(&s.steps)
        );
    }
    let two_groups = lab::two_groups::NAME;
    println!(
        "{two_groups:<34}{}\n{:<34}{}",
        lab::two_groups::about(),
        "",
        lab::two_groups::describe()
    );
    println!("{:<34}a seeded random schedule (--seed N)", "random");
    for seed in 1..=random.unwrap_or(0) {
        println!(
            "  --seed {seed}: {}",
            scenario::describe(&scenario::random(seed).steps)
        );
    }
}

fn setup(cli: &Cli) -> Result<Setup, LabError> {
    let rl = match &cli.rl {
        Some(path) => path.clone(),
        None => std::env::current_exe()
            .ok()
            .and_then(|exe| exe.parent().map(|dir| dir.join("rl")))
            .unwrap_or_else(|| PathBuf::from("target/release/rl")),
    };
    if !rl.is_file() {
        return Err(LabError::NoRlBinary { path: rl });
    }
    let connext = host::connext_available();
    if !connext {
        let fix = format!(
            "python3 cannot import rticonnextdds_connector (pip install {})",
            host::CONNEXT_PACKAGE
        );
        if !cli.lenient {
            return Err(LabError::MissingJudge {
                judge: "the Connext judge".into(),
                fix,
            });
        }
        eprintln!("lab: {fix}: the Connext judge is skipped (--lenient)");
    }
    let (mutation, vote_mutation, architecture) = match &cli.command {
        Command::Run {
            mutation,
            vote_mutation,
            architecture,
            ..
        } => (mutation.clone(), vote_mutation.clone(), *architecture),
        Command::Matrix { architecture, .. } | Command::Traffic { architecture, .. } => {
            (None, None, *architecture)
        }
        _ => (None, None, Default::default()),
    };
    Ok(Setup {
        rl,
        domain: cli.domain,
        connext,
        lenient: cli.lenient,
        mutation,
        vote_mutation,
        output_readers: false,
        camera: Default::default(),
        architecture,
    })
}
