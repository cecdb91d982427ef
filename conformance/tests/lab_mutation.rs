//! The fault lab catches what it exists for: a scenario run against a deliberately broken
//! `rl` (`lab run --mutation NAME`, `conformance/src/lab/mutation.rs`) FAILS, on the judges
//! the broken rule offends, while the same scenario with the same binary and no mutation
//! passes, so the failure is the mutation's and not the binary's or the host's.
//!
//! The first pair is `kill-primary` with `failback`: that mutation ranks controllers by id alone,
//! so the C1 restarted 3 s after its kill takes Primary back from the live C2. The kill then
//! causes two owner changes at the actuators (C1 to C2, C2 to the new C1) where a crash may
//! cause one, and in its first vote the new C1 ranks itself Primary (`P=1#1 S=2 T=3`) where
//! every behaviour of the model keeps the live C2 (`P=2 S=3 T=1#1`), so the model rejects the
//! recording. Both follow from the rule itself on every restart, not from timing, so the
//! failure is certain; the other mutations need a lost heartbeat, a minority vote or a fourth
//! controller at the right moment, which no named scenario guarantees.
//!
//! The second pair is `unplug-primary` with `stay-when-unplugged`: C1 goes on when its links
//! lose their carrier, so its cables out for 0.3 s, longer than either reader's command deadline
//! and shorter than the soonest anyone acts on the silence (a peer is lost after two silent
//! rounds and the new roles hold a round later: at least half a second after the pull), hand
//! the actuator to C2 and, when they are back in, to C1 again, still at 30 (the model's F16
//! reverted). Certain at every round phase, unlike a seed of `flap-primary`, whose outages of
//! 0.5 s and more may outlast the peers' decision.
//!
//! The third is the voting reader's rule: `wrong-primary` with `rl servo --vote` taking a
//! value from one source (`--vote-mutation accept-single-source`). Every answer is taken alone
//! as it arrives, and the wrong Primary answers at least two frames wrongly before its
//! cross-check takes it out, so the voting reader takes wrong commands in every run, which it
//! never does with the rule whole (every run of `wrong-primary` measured 0); nothing else in the run depends on that reader, so every other
//! judge passes and the failure is the mutation's, in one run.
//!
//! The fourth is the lockstep pair's order: `wrong-primary` under the pair with its members
//! writing each output before comparing it (`write-before-compare`, the pair model's
//! mutation). The wrong member still finds the mismatch and leaves, but its first wrong answer
//! has gone out, and it owns the actuator: `rl servo` takes it in every run, where the rule
//! whole lets none through (`lab run wrong-primary --architecture pair` measured 0). The same
//! scenario and build without the mutation passes.
//!
//! The lab runs need root (namespaces, links, nftables) and nft and libfaketime installed, as
//! `lab` itself does: they are ignored by default and CI runs them (as root, the tools
//! installed) with the other ignored tests. Each run takes about 30 s; the `rl` with the
//! `mutation` feature is the workspace build's (`target/release/rl`, `--all-features`).

use conformance::dds_replay::fault_injection_rl;
use conformance::lab::mutation::NAMES;
use rl_layer::core::mutation::Mutation;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Mutex;

/// One lab run at a time: two at once on a small machine would stretch each other's timing.
static ONE_RUN_AT_A_TIME: Mutex<()> = Mutex::new(());

const SCENARIO: &str = "kill-primary";
const MUTATION: &str = "failback";
const UNPLUG_SCENARIO: &str = "unplug-primary";
const UNPLUG_MUTATION: &str = "stay-when-unplugged";
const VOTE_SCENARIO: &str = "wrong-primary";
const VOTE_MUTATION: &str = "accept-single-source";
const PAIR_MUTATION: &str = "write-before-compare";

fn out_dir() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("lab-mutation")
}

/// `lab run kill-primary --rl <mutation build> [--mutation NAME]`; its output and result.json.
fn lab_run(mutation: Option<&str>) -> (Output, Value) {
    lab_run_of(SCENARIO, "1", mutation)
}

/// `lab run SCENARIO --seed SEED --rl <mutation build> [--mutation NAME]`.
fn lab_run_of(scenario: &str, seed: &str, mutation: Option<&str>) -> (Output, Value) {
    let mut result_dir = format!("{scenario}-seed{seed}");
    let mut args = Vec::new();
    if let Some(name) = mutation {
        args.extend(["--mutation", name]);
        result_dir.push_str(&format!("-mutation-{name}"));
    }
    lab_run_with(scenario, seed, &args, &result_dir)
}

/// `lab run SCENARIO --seed SEED --rl <mutation build> ARGS`, whose output is `result_dir`.
fn lab_run_with(scenario: &str, seed: &str, args: &[&str], result_dir: &str) -> (Output, Value) {
    let _one = ONE_RUN_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let rl = fault_injection_rl().unwrap_or_else(|e| panic!("{e}"));
    let mut command = Command::new(env!("CARGO_BIN_EXE_lab"));
    command
        .args(["run", scenario, "--seed", seed, "--rl"])
        .arg(&rl)
        .arg("--out")
        .arg(out_dir())
        .args(args);
    let output = command.output().expect("lab starts");
    println!(
        "lab run {scenario} --seed {seed} {args:?}: {}\n{}{}",
        output.status,
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    let result_path = out_dir().join(result_dir).join("result.json");
    let text = std::fs::read_to_string(&result_path)
        .unwrap_or_else(|e| panic!("{}: {e} (the run did not finish)", result_path.display()));
    (
        output,
        serde_json::from_str(&text).expect("result.json is JSON"),
    )
}

fn failures(result: &Value) -> Vec<String> {
    result["failures"]
        .as_array()
        .expect("result.json lists its failures")
        .iter()
        .map(|f| f.as_str().unwrap_or_default().to_string())
        .collect()
}

/// Each failure's first line (the model judge's goes on with the whole rejection).
fn first_lines(failures: &[String]) -> Vec<&str> {
    failures
        .iter()
        .map(|f| f.lines().next().unwrap_or_default())
        .collect()
}

/// The servo's owner changes for each fault, from result.json.
fn servo_changes(result: &Value) -> Vec<u64> {
    result["metrics"]["changes_per_fault"]
        .as_array()
        .expect("result.json has the owner changes per fault")
        .iter()
        .map(|c| c["servo"].as_u64().unwrap_or_default())
        .collect()
}

#[test]
#[ignore = "needs root, nft and faketime (the fault lab's namespaces and firewall rules); CI runs it"]
fn a_failback_build_fails_kill_primary_on_owner_changes_and_the_model() {
    let (output, result) = lab_run(Some(MUTATION));
    // 1 is a verdict (FAIL); 2 a run that could not be carried out (not root, a tool missing).
    assert_eq!(output.status.code(), Some(1), "lab's exit status");
    assert_eq!(result["mutation"], MUTATION, "result.json marks the run");
    let failures = failures(&result);
    let changes = servo_changes(&result);
    assert!(
        changes.first().is_some_and(|n| *n >= 2),
        "the restarted C1 takes Primary back: two owner changes for the kill, measured {changes:?}"
    );
    assert!(
        failures.iter().any(|f| f.starts_with("kill")
            && f.contains("owner changes at rl servo")
            && f.ends_with("(expected at most 1)")),
        "the owner-change judge names the kill: {:#?}",
        first_lines(&failures)
    );
    assert!(
        failures
            .iter()
            .any(|f| f.starts_with("the model rejects the recorded events")
                && !f.contains("did not finish")),
        "the model judge rejects the recording (not merely runs out of time): {:#?}",
        first_lines(&failures)
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        stdout.contains("FAIL") && stdout.contains(&format!("--mutation {MUTATION}")),
        "the summary says FAIL and how to replay the mutation run:\n{stdout}"
    );
}

#[test]
#[ignore = "needs root, nft and faketime (the fault lab's namespaces and firewall rules); CI runs it"]
fn the_same_build_without_a_mutation_passes_kill_primary() {
    let (output, result) = lab_run(None);
    assert_eq!(
        failures(&result),
        Vec::<String>::new(),
        "the mutation build with no mutation runs RL's rules"
    );
    assert_eq!(output.status.code(), Some(0));
    assert_eq!(result["mutation"], Value::Null);
    assert_eq!(
        servo_changes(&result),
        vec![1],
        "one owner change for one kill"
    );
}

#[test]
#[ignore = "needs root, nft and faketime (the fault lab's namespaces and firewall rules); CI runs it"]
fn a_build_that_stays_when_unplugged_fails_unplug_primary_on_owner_changes() {
    let (output, result) = lab_run_of(UNPLUG_SCENARIO, "1", Some(UNPLUG_MUTATION));
    assert_eq!(output.status.code(), Some(1), "lab's exit status");
    let failures = failures(&result);
    let changes = servo_changes(&result);
    assert!(
        changes.first().is_some_and(|n| *n >= 2),
        "C1 takes the actuator back when its links are up again, measured {changes:?}"
    );
    assert!(
        failures.iter().any(|f| f.contains("cables pulled")
            && f.contains("owner changes at rl servo")
            && f.ends_with("(expected at most 1)")),
        "the owner-change judge names the pulled cables: {:#?}",
        first_lines(&failures)
    );
}

#[test]
#[ignore = "needs root, nft and faketime (the fault lab's namespaces and firewall rules); CI runs it"]
fn the_same_build_without_a_mutation_passes_unplug_primary() {
    let (output, result) = lab_run_of(UNPLUG_SCENARIO, "1", None);
    assert_eq!(
        first_lines(&failures(&result)),
        Vec::<&str>::new(),
        "C1 starts again when its links go, so the actuator switches once"
    );
    assert_eq!(output.status.code(), Some(0));
    assert_eq!(
        servo_changes(&result),
        vec![1],
        "one owner change for the pulled cables"
    );
}

#[test]
#[ignore = "needs root, nft and faketime (the fault lab's namespaces and firewall rules); CI runs it"]
fn a_voting_reader_that_takes_one_source_fails_wrong_primary_on_wrong_commands_accepted() {
    let (output, result) = lab_run_with(
        VOTE_SCENARIO,
        "1",
        &["--vote-mutation", VOTE_MUTATION],
        &format!("{VOTE_SCENARIO}-seed1-mutation-vote-{VOTE_MUTATION}"),
    );
    assert_eq!(output.status.code(), Some(1), "lab's exit status");
    assert_eq!(result["mutation"], format!("vote-{VOTE_MUTATION}"));
    let failures = failures(&result);
    let lines = first_lines(&failures);
    assert!(
        lines
            .iter()
            .any(|f| f.starts_with("the voting reader accepted") && f.contains("wrong commands")),
        "the voting reader is caught taking the wrong Primary's commands: {lines:#?}"
    );
    // Everything else held: the controllers, the exclusive readers and the model are
    // untouched by the voting reader's rule, so the failure is the mutation's.
    assert!(
        lines.iter().all(|f| f.starts_with("the voting reader")),
        "only the voting reader fails: {lines:#?}"
    );
}

/// `lab run wrong-primary --architecture pair [--mutation write-before-compare]`.
fn pair_run(mutation: Option<&str>) -> (Output, Value) {
    let mut args = vec!["--architecture", "pair"];
    let mut result_dir = format!("{VOTE_SCENARIO}-seed1");
    if let Some(name) = mutation {
        args.extend(["--mutation", name]);
        result_dir.push_str(&format!("-mutation-{name}"));
    }
    lab_run_with(VOTE_SCENARIO, "1", &args, &format!("{result_dir}-pair"))
}

#[test]
#[ignore = "needs root, nft and faketime (the fault lab's namespaces and firewall rules); CI runs it"]
fn a_pair_that_writes_before_it_compares_fails_wrong_primary_on_wrong_commands_delivered() {
    let (output, result) = pair_run(Some(PAIR_MUTATION));
    assert_eq!(output.status.code(), Some(1), "lab's exit status");
    assert_eq!(
        result["mutation"], PAIR_MUTATION,
        "result.json marks the run"
    );
    let failures = failures(&result);
    let lines = first_lines(&failures);
    assert!(
        lines
            .iter()
            .any(|f| f.starts_with("rl servo took") && f.contains("wrong samples")),
        "the exclusive servo is caught taking the wrong member's command: {lines:#?}"
    );
    // The compare itself still works, after the write: the member leaves as it should.
    assert!(
        !lines.iter().any(|f| f.contains("lockstep mismatch")),
        "the wrong member still finds its mismatch in time: {lines:#?}"
    );
}

#[test]
#[ignore = "needs root, nft and faketime (the fault lab's namespaces and firewall rules); CI runs it"]
fn the_same_build_without_a_mutation_passes_wrong_primary_under_the_pair() {
    let (output, result) = pair_run(None);
    assert_eq!(
        first_lines(&failures(&result)),
        Vec::<&str>::new(),
        "the pair compares before it writes: nothing wrong reaches a reader"
    );
    assert_eq!(output.status.code(), Some(0));
    assert_eq!(
        servo_changes(&result),
        vec![1],
        "one owner change: from the wrong member to its partner"
    );
}

#[test]
fn the_lab_knows_the_mutations_rl_knows() {
    let rl_names: Vec<&str> = Mutation::ALL.iter().map(|m| m.name()).collect();
    assert_eq!(NAMES.to_vec(), rl_names);
}

#[test]
fn an_unknown_mutation_is_refused_with_exit_2_and_the_known_names() {
    // Checked by the command line, before anything needs root.
    let output = Command::new(env!("CARGO_BIN_EXE_lab"))
        .args(["run", SCENARIO, "--mutation", "no-such-rule"])
        .output()
        .expect("lab starts");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("no-such-rule"), "{stderr}");
    assert!(NAMES.iter().all(|name| stderr.contains(name)), "{stderr}");
}
