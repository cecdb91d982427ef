//! The DDS-level replay (docs/conformance.md, "DDS-level replay"): a curated subset of the
//! model's traces, every fault kind at least once, replayed against real
//! `rl controller --json-events` processes over DDS on loopback, with real faults (`kill -9`,
//! new processes, heartbeats dropped by the fault-injection control, SIGSTOP and SIGCONT;
//! a trace with cuts runs on the lab's virtual LAN, a network namespace per process, its cuts
//! nftables rules and its pulled cables links down) and the actuator's owner
//! read from a real `rl servo --json`. Each run's recording is then validated strictly.
//!
//! The subset is `conformance::dds_replay::CURATED`, resolved by purpose from
//! `traces/index.json`; each test has its own DDS domain (186, 187, 190-197, 218, 220 and 225,
//! in that table; 199 the broken replay; 188, 189, 219, 221-224 and 226 the mutation checks) and the tests take turns (they are timed on
//! the wall clock, and this machine has 2 cores). The `rl` binary with the `fault-injection`
//! and `mutation` features is the workspace build's (`target/release/rl`, `--all-features`);
//! the recordings are
//! kept in `target/tmp/dds-replay/`.
//!
//! The mutation checks: a suite that cannot fail proves nothing. Each curated family that one
//! of the core's deliberately broken rules can change is replayed with the controllers
//! running that rule (`RL_MUTATION`), and must fail at a boundary with a diff row that shows
//! the broken rule. The families no mutation can change are listed in docs/conformance.md
//! with the reason.
//!
//! Every replayable trace, not only this subset, is a command, not a test (about 30 minutes):
//! `cargo run --release -p conformance --bin dds-replay-all`.

use conformance::dds_replay::{self, Need, Problem, ReplayError, Selected, Setup, CURATED};
use conformance::diff::{NAME_WIDTH, VALUE_WIDTH};
use conformance::trace;
use rl_layer::core::mutation::Mutation;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

/// One replay at a time.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

fn selected(name: &str) -> Selected {
    let curated = dds_replay::curated(name).unwrap_or_else(|| panic!("no curated entry {name:?}"));
    let timing = dds_replay::timing().unwrap_or_else(|e| panic!("{e}"));
    dds_replay::select(&trace::default_dir(), curated, &timing).unwrap_or_else(|e| panic!("{e}"))
}

fn record_dir(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join("dds-replay")
        .join(name)
}

/// Replays `selected` on `domain` with `mutation` (if any); the recording goes to
/// `target/tmp/dds-replay/<record>`.
fn replay(
    selected: &Selected,
    domain: u16,
    mutation: Option<Mutation>,
    record: &str,
) -> Result<dds_replay::Replayed, ReplayError> {
    let exe = dds_replay::fault_injection_rl().unwrap_or_else(|e| panic!("{e}"));
    let record_dir = record_dir(record);
    let setup = Setup {
        exe: &exe,
        domain,
        record_dir: &record_dir,
        mutation: mutation.map(|m| m.name().to_string()),
    };
    dds_replay::replay(&selected.plan, &setup)
}

fn replay_curated(name: &str) {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let selected = selected(name);
    let started = Instant::now();
    let stem = selected.plan.file.trim_end_matches(".jsonl").to_string();
    let domain = selected.curated.domain;
    let replayed = replay(&selected, domain, None, &stem).unwrap_or_else(|e| panic!("{e}"));
    println!(
        "{name}: traces/{} ({}) conforms over DDS on domain {domain}: lockstep boundaries {}, \
         real rounds {}, attempt {}, {:.1} s\n  its recording ({}), validated strictly: {}",
        replayed.file,
        selected.plan.purpose,
        replayed.lockstep_boundaries,
        replayed.rounds,
        replayed.attempts,
        started.elapsed().as_secs_f64(),
        replayed.record_dir.display(),
        replayed.validation
    );
}

#[test]
fn the_curated_subset_shows_every_fault_kind() {
    println!("{:<24} {:<12} {:<6} why", "fault", "trace", "domain");
    for curated in CURATED {
        let selected = selected(curated.name);
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

/// The rows of a failure's diff marked as different: (field, model value, processes' value).
fn differing_rows(message: &str) -> Vec<(String, String, String)> {
    message
        .lines()
        .filter_map(|line| line.strip_prefix("  >> "))
        .filter_map(|rest| {
            let observed_column = NAME_WIDTH + VALUE_WIDTH;
            let name = rest.get(..NAME_WIDTH)?.trim().to_string();
            let model_value = rest.get(NAME_WIDTH..observed_column)?.trim().to_string();
            let observed_value = rest.get(observed_column..)?.trim().to_string();
            Some((name, model_value, observed_value))
        })
        .collect()
}

/// A suite that cannot fail proves nothing: the Primary-crash replay with the `kill -9` left
/// out must fail at the first boundary where the model has the Primary down, with a diff.
/// Domain 199.
#[test]
fn a_replay_that_departs_from_the_trace_fails_with_a_diff() {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let curated = CURATED
        .iter()
        .find(|c| c.need == Need::CrashOf(model::Role::Primary))
        .expect("the subset has a crash of the Primary");
    let mut selected = selected(curated.name);
    let crash_round = selected
        .plan
        .rounds
        .iter()
        .position(|r| !r.lifecycle.is_empty())
        .expect("the trace crashes a controller");
    selected.plan.rounds[crash_round].lifecycle.clear();
    let error = replay(&selected, 199, None, "departing")
        .expect_err("the processes keep the Primary alive; the model has it killed");
    let message = error.to_string();
    println!("{message}");
    let Some(Problem::StateDiffers { boundary, .. }) = error.problem() else {
        panic!("a state difference, not: {message}");
    };
    // The model has the Primary's commands stop in the crash round (the actuator goes to the
    // Secondary, or to nobody while the standbys' writers wait for the Primary's, F13); the
    // servo still takes the Primary's commands.
    assert_eq!(
        *boundary, crash_round,
        "fails in the round of the missing crash: {message}"
    );
    assert!(
        message.contains(">> actuator owner: model C2, processes C1")
            || message.contains(">> actuator owner: model none, processes C1"),
        "the diff shows the Primary still owning the actuator: {message}"
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
fn restart_of_a_low_id() {
    replay_curated("restart of a low id");
}

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

// Domain 220.
#[test]
fn lone_lost_heartbeat() {
    replay_curated("lone lost heartbeat");
}

// Domain 186: SIGSTOP for two rounds, SIGCONT, a new incarnation (F12).
#[test]
fn pause_and_resume() {
    replay_curated("pause and resume");
}

// Domain 218: SIGSTOP of the Primary, SIGCONT within the round, a new incarnation (F12).
#[test]
fn short_pause_of_the_primary() {
    replay_curated("short pause of the Primary");
}

// Domain 187: a cut by nftables on the virtual LAN, healed two rounds later (F11).
#[test]
fn cut_healed() {
    replay_curated("cut healed");
}

// Domain 185: the Primary's commands late, its Secondary takes over (F17).
#[test]
fn starved_primary_taken_over() {
    replay_curated("starved Primary taken over");
}

/// Replays a curated family with the controllers running `mutation` on `domain`; the replay
/// must fail, and some row of its diff must show `field` differing as `shows` accepts (model
/// value, processes' value).
fn assert_caught(
    family: &str,
    mutation: Mutation,
    domain: u16,
    field: &str,
    shows: impl Fn(&str, &str) -> bool,
) {
    let expected = format!("a diff row showing the expected {field} difference");
    assert_caught_where(family, mutation, domain, &expected, |problem| {
        differing_rows(problem)
            .iter()
            .any(|(name, model_value, observed)| name == field && shows(model_value, observed))
    });
}

/// Replays a curated family with the controllers running `mutation` on `domain`; the replay
/// must fail with a problem that `shows` accepts (`expected` says what it looks for).
fn assert_caught_where(
    family: &str,
    mutation: Mutation,
    domain: u16,
    expected: &str,
    shows: impl Fn(&str) -> bool,
) {
    let _turn = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let selected = selected(family);
    let started = Instant::now();
    let record = format!(
        "{}-{}",
        selected.plan.file.trim_end_matches(".jsonl"),
        mutation.name()
    );
    let error = match replay(&selected, domain, Some(mutation), &record) {
        Ok(replayed) => panic!(
            "{family} (traces/{}) conforms with RL_MUTATION={}: the replay cannot see this \
             rule broken; its recording: {}",
            replayed.file,
            mutation.name(),
            replayed.validation
        ),
        Err(error) => error,
    };
    let problem = error
        .problem()
        .unwrap_or_else(|| panic!("a departure from the model, not: {error}"))
        .to_string();
    println!(
        "{family} with RL_MUTATION={} fails in {:.1} s:\n{problem}",
        mutation.name(),
        started.elapsed().as_secs_f64()
    );
    assert!(
        shows(&problem),
        "{family} with RL_MUTATION={}: not {expected}:\n{error}",
        mutation.name()
    );
}

/// The Secondary takes Primary when the crashed Primary misses its first heartbeat, a round
/// before the dead-man deadline lets the model promote it. Domain 221.
#[test]
fn promote_without_failure_breaks_the_crash_of_the_primary() {
    assert_caught(
        "crash of the Primary",
        Mutation::PromoteWithoutFailure,
        221,
        "role",
        |model, processes| model == "secondary" && processes == "primary",
    );
}

/// The same broken rule turns one lost heartbeat into a takeover. Domain 222.
#[test]
fn promote_without_failure_breaks_the_lone_lost_heartbeat() {
    assert_caught(
        "lone lost heartbeat",
        Mutation::PromoteWithoutFailure,
        222,
        "role",
        |model, processes| model == "secondary" && processes == "primary",
    );
}

/// The restarted C1 is ranked by its id: every vote puts it back as Primary over the live C2
/// (heard in the round it restarts, it is voted for at the next boundary). Domain 226.
#[test]
fn failback_breaks_the_restart_of_a_low_id() {
    assert_caught(
        "restart of a low id",
        Mutation::Failback,
        226,
        "vote",
        |model, processes| processes.starts_with("P=1") && !model.starts_with("P=1"),
    );
}

/// The fourth controller votes itself in as Tertiary. Domain 223.
#[test]
fn admit_fourth_breaks_the_fourth_controller() {
    assert_caught(
        "fourth controller",
        Mutation::AdmitFourth,
        223,
        "vote",
        |model, processes| processes.contains("T=4") && !model.contains("T=4"),
    );
}

/// The minority voter is never marked FAILED. Domain 224.
#[test]
fn ignore_minority_vote_breaks_the_minority_vote() {
    assert_caught(
        "minority vote",
        Mutation::IgnoreMinorityVote,
        224,
        "failed",
        |model, processes| model != "{}" && processes == "{}",
    );
}

/// The resumed controller goes on as the incarnation it was (F12 reverted): where the model
/// has a new incarnation, silent until it has heard a round, it still holds its place, and
/// speaks at once with what it knew before the stall. Which shows first depends on how soon
/// after the SIGCONT its old writer reaches the servo: its stale commands take the actuator
/// from the Primary in the resume round, or the next boundary shows its old incarnation.
/// Domain 188.
#[test]
fn keep_incarnation_on_resume_breaks_the_pause_and_resume() {
    assert_caught_where(
        "pause and resume",
        Mutation::KeepIncarnationOnResume,
        188,
        "C2's old incarnation (a diff row incarnation 1 against 0), or its stale commands \
         owning the actuator",
        |problem| {
            let old_incarnation = differing_rows(problem)
                .iter()
                .any(|(name, model, processes)| {
                    name == "incarnation" && model == "1" && processes == "0"
                });
            old_incarnation || problem.contains(">> actuator owner: model C1, processes C2")
        },
    );
}

/// The same broken rule after a stop shorter than the peer deadline: the continued Primary
/// goes on as it was, its commands take the actuator back from the Secondary and the next
/// boundary shows its old incarnation where the model has a new, silent one. Domain 219.
#[test]
fn keep_incarnation_on_resume_breaks_the_short_pause_of_the_primary() {
    assert_caught_where(
        "short pause of the Primary",
        Mutation::KeepIncarnationOnResume,
        219,
        "C1's old incarnation (a diff row incarnation 1 against 0), or its commands owning \
         the actuator (alone, or beside C2's where the model allows only C2: its old writer \
         stops after the pause's gap, RustDDS fix 20, and the kept life writes on from a new one)",
        |problem| {
            let old_incarnation = differing_rows(problem)
                .iter()
                .any(|(name, model, processes)| {
                    name == "incarnation" && model == "1" && processes == "0"
                });
            old_incarnation
                || problem.contains(">> actuator owner: model C2, processes C1")
                || problem.contains("where the model allows C2: it accepted commands from C1 x")
        },
    );
}

/// Results are ranked without their epochs (F11 reverted): at the heal the result the cut-off
/// controller agreed alone ranks with the majority's, and the votes differ. Domain 189.
#[test]
fn no_epoch_ranking_breaks_the_cut_healed() {
    assert_caught(
        "cut healed",
        Mutation::NoEpochRanking,
        189,
        "vote",
        |model, processes| model != processes,
    );
}
