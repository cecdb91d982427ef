//! The DDS-level replay (docs/conformance.md, "DDS-level replay"): a trace's plan carried out
//! by real `rl controller --json-events` processes talking over DDS on loopback, with the
//! actuator's owner read from a real `rl servo --json` beside them, and the recording then
//! validated strictly against the model.
//!
//! Faults are real: a crash is `kill -9`, a restart or join is a new process, a pause is
//! SIGSTOP and a resume SIGCONT, a cut is nftables and a pulled cable links down on the fault
//! lab's virtual LAN (a trace with either runs there, [`cuts`]), and a lost
//! heartbeat is dropped on arrival by the receiving process (the `fault-injection` build of
//! `rl` reads `drop-heartbeats-from <id>` / `accept-heartbeats-from <id>` on its stdin and
//! logs every drop): a `LoseHeartbeat { from, to }` in round `r` makes `to` drop `from`'s
//! heartbeats for that round, a loss in consecutive rounds keeps dropping. The same build has
//! the `mutation` feature: with `RL_MUTATION` set ([`Setup::mutation`]) the controllers run a
//! deliberately broken rule, and the replay must fail.
//!
//! Timing ([`config`]): every controller process of the trace (the later joins and restarts
//! too) is started before round 0 and held before it votes until all have discovered each
//! other over DDS; the initial ones are let go just after a boundary, which is the trace's
//! boundary 0, and every later one in the round the trace starts it, so it is heard in that
//! round as in the model; a round's faults are applied 20 ms after its boundary; a boundary
//! is observed 230 ms after it: each controller's latest `status` with the later `alarm`s
//! applied, mapped by the abstraction function, and the servo's owner from the commands it
//! accepted since the owner settled. Bounded waits where the plan re-aligns (after a pulled
//! cable is plugged back in) or waits for the settled end, which must then hold for
//! [`HOLD_ROUNDS`] more boundaries.
//!
//! Every observation also checks that no process exited unless the plan killed it, and that
//! the heartbeat drops logged are the injected ones ([`drops`]).
//!
//! If the held processes do not find each other in time, or the harness was too late to
//! apply a fault on time, the attempt is not a replay of the trace: it is repeated with
//! fresh processes, up to [`ATTEMPTS`] times. Any other difference is a failure
//! ([`ReplayError::Diverged`]), reported with the run's context.
//!
//! Modules: [`plan`](mod@plan) (a trace's plan, pure; the trace rebuilt round by round in
//! its `rebuild`), [`refusal`] (why a trace cannot be
//! planned, and the kind of each refusal), [`checks`] (its timing assumptions, checked
//! against the model), [`curated`](mod@curated) (which traces), [`config`] (the `rl.toml` and the
//! timing), [`binary`] (building `rl`), [`processes`] (the children), [`lives`] (a
//! controller process's record and observation), [`servo`] (the actuator's owner),
//! [`drops`] (injected losses against logged drops), [`cuts`] (cuts and pulled cables on the
//! virtual LAN), [`run`] (one attempt's steps),
//! [`transcript`] (output and recording), [`error`].

pub mod binary;
pub mod checks;
pub mod config;
pub mod curated;
pub mod cuts;
pub mod drops;
pub mod error;
pub mod lives;
pub mod plan;
pub mod processes;
pub mod refusal;
pub mod run;
pub mod servo;
pub mod transcript;

pub use binary::fault_injection_rl;
pub use config::{
    run_timing, timing, RunTiming, ATTEMPTS, CONFIG_TOML, HOLD_ROUNDS, OBSERVE_OFFSET_MS,
    START_OFFSET_MS,
};
pub use curated::{curated, select, shows, Curated, Need, Scope, SelectError, Selected, CURATED};
pub use error::{BinaryError, Diverged, Failure, Problem, ReplayError};
pub use plan::{plan, replay_timing, Mode, Plan, PlanError, RoundPlan};

use crate::lab::lan::Lan;
use crate::record::{round_of, Recording};
use crate::validate::{self, Accepted};
use plan::Mode as PlanMode;
use rl::procs::wall_ms;
use run::Run;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Where and how a replay runs.
#[derive(Clone, Debug)]
pub struct Setup<'a> {
    /// `rl` built with the `fault-injection` and `mutation` features ([`fault_injection_rl`]).
    pub exe: &'a Path,
    /// The DDS domain (each concurrently running replay its own).
    pub domain: u16,
    /// Where the events are recorded (emptied first).
    pub record_dir: &'a Path,
    /// The broken rule the controllers run with (`RL_MUTATION`, e.g. `failback`), if any.
    pub mutation: Option<String>,
}

/// A replay that matched the model, and its recording that trace validation accepted.
#[derive(Clone, Debug)]
pub struct Replayed {
    pub file: String,
    pub attempts: usize,
    /// Boundaries compared in lockstep (each on its own real round).
    pub lockstep_boundaries: usize,
    /// Real rounds from boundary 1 to the end of the hold.
    pub rounds: u64,
    pub elapsed: Duration,
    /// The recorded events (one log per process) and the run's `rl.toml`.
    pub record_dir: PathBuf,
    /// Strict trace validation of the recording (no lag tolerance).
    pub validation: Accepted,
}

/// Replays one plan on real processes, then validates the recording strictly.
pub fn replay(plan: &Plan, setup: &Setup) -> Result<Replayed, ReplayError> {
    let timing = run_timing()?;
    let started = Instant::now();
    // One LAN for every attempt; dropped (namespaces, links and all) when the replay ends.
    let lan = if plan.needs_lan() {
        let built = Lan::build(&Lan::fresh_prefix()).map_err(|e| ReplayError::Lan {
            file: plan.file.clone(),
            error: e.to_string(),
        })?;
        Some(built)
    } else {
        None
    };
    let mut earlier = Vec::new();
    let mut attempt = 0;
    loop {
        attempt += 1;
        let config = prepare_dir(setup.record_dir)?;
        let mut run = Run::new(plan, setup, timing, &config, lan.as_ref());
        let outcome = carry_out(&mut run);
        run.stop();
        run.output().write_record(setup.record_dir)?;
        match outcome {
            Ok((lockstep_boundaries, rounds)) => {
                let validation = validate_strictly(plan, setup.record_dir, &timing)?;
                return Ok(Replayed {
                    file: plan.file.clone(),
                    attempts: attempt,
                    lockstep_boundaries,
                    rounds,
                    elapsed: started.elapsed(),
                    record_dir: setup.record_dir.to_path_buf(),
                    validation,
                });
            }
            Err(failure) if failure.retry && attempt < ATTEMPTS => {
                println!(
                    "{}: attempt {attempt} did not line up with the trace, retrying: {}",
                    plan.file, failure.problem
                );
                earlier.push(failure.problem.to_string());
                std::thread::sleep(Duration::from_millis(300));
            }
            Err(failure) => {
                return Err(ReplayError::Diverged(Box::new(Diverged {
                    file: plan.file.clone(),
                    purpose: plan.purpose.clone(),
                    mutation: setup.mutation.clone(),
                    attempt,
                    failure,
                    earlier,
                    record_dir: setup.record_dir.to_path_buf(),
                })))
            }
        }
    }
}

/// The driver: the plan's boundaries one after the other, each reached as its mode says;
/// returns the boundaries compared in lockstep and the real rounds run.
fn carry_out(run: &mut Run) -> Result<(usize, u64), Failure> {
    let plan = run.plan;
    let period_ms = run.period_ms();
    // Every process held until all have found each other; then round 0: the initial
    // controllers let go and round 0's faults, right after a boundary.
    run.start_held()?;
    let start_round = round_of(wall_ms(), period_ms) + 1;
    run.sleep_until(start_round * period_ms + START_OFFSET_MS);
    run.start(start_round)?;
    let first = start_round + 1;
    let mut base = (1usize, first);
    let mut lockstep = 0;
    let mut last_real = first;
    for (k, mode) in plan.modes().into_iter().enumerate().skip(1) {
        let real = base.1 + (k - base.0) as u64;
        match mode {
            PlanMode::Start => {}
            PlanMode::Lockstep => {
                if let Some(round) = plan.rounds.get(k) {
                    run.apply_on_time(k, round, real)?;
                }
                if let Some(next) = plan.rounds.get(k + 1) {
                    run.starve_ahead(next, real)?;
                }
                run.sleep_until(real * period_ms + OBSERVE_OFFSET_MS);
                let expected = run.expected_in_lockstep(k);
                run.compare(&expected, real, "lockstep")?;
                lockstep += 1;
                last_real = real;
            }
            PlanMode::Realign => {
                let matched = run.await_state(&run.expected_at_rest(k), 2)?;
                base = (k, matched + 1);
                run.apply_on_time(k, &plan.rounds[k], matched + 1)?;
                last_real = matched + 1;
            }
            PlanMode::Free => {
                // The losses of the round that started a process end with it.
                if run.dropping() {
                    run.apply_on_time(k, &RoundPlan::default(), real)?;
                }
                if k == plan.last() {
                    last_real = run.await_state(&run.expected_at_rest(k), 1)?;
                }
            }
        }
    }
    for real in last_real + 1..=last_real + HOLD_ROUNDS {
        run.sleep_until(real * period_ms + OBSERVE_OFFSET_MS);
        run.compare(
            &run.expected_at_rest(plan.last()),
            real,
            "settled end, held",
        )?;
    }
    Ok((lockstep, last_real + HOLD_ROUNDS + 1 - first))
}

/// Empties the recording directory and writes the run's `rl.toml` there; returns its path.
fn prepare_dir(dir: &Path) -> Result<PathBuf, ReplayError> {
    let error = |what, path: &Path| {
        let path = path.to_path_buf();
        move |source| ReplayError::RecordDir { what, path, source }
    };
    if dir.exists() {
        std::fs::remove_dir_all(dir).map_err(error("emptying", dir))?;
    }
    std::fs::create_dir_all(dir).map_err(error("creating", dir))?;
    let config = dir.join("rl.toml");
    std::fs::write(&config, CONFIG_TOML).map_err(error("writing", &config))?;
    Ok(config)
}

/// Trace validation of the recording, without the lag tolerance and with a boundary's
/// reports its decisions ([`config::DECIDED_BY_MS`]): the replay observes each boundary after
/// its reports, so a report late by a round is a defect here.
fn validate_strictly(
    plan: &Plan,
    record_dir: &Path,
    timing: &RunTiming,
) -> Result<Accepted, ReplayError> {
    let recording = Recording::read_dir(record_dir)?;
    validate::validate_replayed(&recording, &timing.rounds, config::DECIDED_BY_MS).map_err(
        |rejection| ReplayError::Rejected {
            file: plan.file.clone(),
            record_dir: record_dir.to_path_buf(),
            rejection,
        },
    )
}
