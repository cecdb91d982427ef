//! The output-voting model (`model::outputs`, docs/protocol.md "Output voting"): its check
//! holds with at most one wrong controller; a broken voting rule and a lagging cross-check are
//! caught with counterexamples, and a cross-check blind to inputs or to raw answers misses a
//! masked wrong input (finding O3) or a masked wrong law (O4); two wrong controllers that
//! disagree make the voting receiver hold; two that agree out-vote the correct one (finding
//! O1); and the consecutive count misses an intermittently wrong Primary (finding O2).

use model::outputs::check::{explore, Explored, Outcome, OutputPath};
use model::outputs::{
    CrossCheck, Fault, OutputAction, OutputConfig, OutputModel, OutputMutation, OutputState,
};
use model::Phase;
use stateright::{Checker, HasDiscoveries, Model};
use std::collections::BTreeSet;
use std::process::Command;

fn explored(config: OutputConfig) -> Explored {
    explore(&OutputModel::new(config))
}

fn mutated(mutation: OutputMutation) -> OutputConfig {
    OutputConfig {
        mutation: Some(mutation),
        ..OutputConfig::default()
    }
}

/// The shortest counterexample to `property`, which must exist.
fn counterexample(explored: &Explored, property: &str) -> OutputPath {
    explored
        .discovery(property)
        .unwrap_or_else(|| panic!("no counterexample to {property:?}"))
}

fn last(path: &OutputPath) -> OutputState {
    path.steps.last().map_or(path.init, |(_, state)| *state)
}

const NEVER_WRONG: &str = "a voting receiver never accepts a wrong command";
const BOUND_K: &str = "an exclusive receiver takes at most K wrong or missing commands";
const WITHIN_N: &str = "a wrong controller leaves within N wrong commands";

#[test]
fn with_one_wrong_controller_every_property_holds_and_every_witness_is_found() {
    let explored = explored(OutputConfig::default());
    assert_eq!(explored.failed(), Vec::<&str>::new());
    for verdict in explored.verdicts().iter().filter(|v| !v.always) {
        let expected = if verdict.name == "a voting receiver holds" {
            // With one wrong controller the two correct ones always agree.
            Outcome::NotApplicable("needs two wrong controllers (--wrong 2)")
        } else {
            Outcome::Witnessed
        };
        assert_eq!(verdict.outcome, expected, "{}", verdict.name);
    }
}

#[test]
fn pinned_state_count_and_our_search_agrees_with_stateright() {
    let model = OutputModel::new(OutputConfig::default());
    let ours = explore(&model).unique_states();
    let checker = model
        .checker()
        .finish_when(HasDiscoveries::AnyOf(BTreeSet::new()))
        .spawn_bfs()
        .join();
    assert_eq!(ours, checker.unique_state_count());
    // Any change of this number is a change of the output model's behaviour: review it.
    assert_eq!(ours, PINNED_DEFAULT_STATES);
}

const PINNED_DEFAULT_STATES: usize = 3268;

#[test]
fn the_bound_is_n_for_every_limit() {
    for odd_limit in 1..=3 {
        let explored = explored(OutputConfig {
            odd_limit,
            ..OutputConfig::default()
        });
        assert_eq!(explored.failed(), Vec::<&str>::new(), "N = {odd_limit}");
    }
}

#[test]
fn accepting_a_single_source_is_caught() {
    let explored = explored(mutated(OutputMutation::AcceptSingleSource));
    let failed = explored.failed();
    assert!(failed.contains(&NEVER_WRONG), "{failed:?}");
    assert!(
        failed.contains(&"a voting receiver accepts only what two sources sent"),
        "{failed:?}"
    );
    // The shortest counterexample: a controller goes wrong and its command arrives first.
    let path = counterexample(&explored, NEVER_WRONG);
    assert_eq!(path.steps.len(), 2, "{}", path.render());
    assert!(matches!(
        path.actions()[..],
        [
            OutputAction::GoWrong { controller: 1, .. },
            OutputAction::Publish { controller: 1, .. }
        ]
    ));
    let end = last(&path);
    assert!(end.voting.accepted.is_some_and(|value| value != end.right));
}

#[test]
fn closing_the_comparison_after_the_next_command_breaks_k() {
    let explored = explored(mutated(OutputMutation::CompareAfterNextCommand));
    let failed = explored.failed();
    assert!(failed.contains(&BOUND_K), "{failed:?}");
    assert!(failed.contains(&WITHIN_N), "{failed:?}");
    let end = last(&counterexample(&explored, BOUND_K));
    let bound = OutputConfig::default().exclusive_bound();
    assert!(end
        .controllers
        .iter()
        .any(|c| c.exclusive_wrong + c.exclusive_missed == bound + 1));
}

const INPUT_WITHIN_N: &str = "a masked wrong input is found within N inputs";

#[test]
fn comparing_outputs_only_never_finds_a_masked_wrong_input() {
    let explored = explored(mutated(OutputMutation::NoInputCongruence));
    let mut failed = explored.failed();
    failed.sort();
    assert_eq!(
        failed,
        vec!["a controller with a wrong input leaves", INPUT_WITHIN_N],
        "only the input bound breaks, and its witness is never reached"
    );
    let path = counterexample(&explored, INPUT_WITHIN_N);
    let end = last(&path);
    let wrong = end
        .controllers
        .iter()
        .find(|c| c.fault == Some(Fault::WrongInput))
        .expect("a controller reading a wrong input");
    assert!(
        wrong.role.is_some(),
        "it is still in its role: {}",
        path.render()
    );
    assert!(!wrong.ever_sent_wrong, "its output was right throughout");
    assert!(
        end.voting.dissent.iter().all(|alarm| !alarm),
        "and no receiver can name it"
    );
}

const LAW_WITHIN_N: &str = "a masked wrong law is found within N inputs";
const LAW_ALARMED: &str = "a controller that leaves for its law is alarmed by name";
const LAW_LEAVES: &str = "a controller with a wrong law leaves";

#[test]
fn comparing_raw_answers_finds_a_masked_wrong_law_and_names_it() {
    let explored = explored(OutputConfig::default());
    let outcome = |name: &str| {
        explored
            .verdicts()
            .into_iter()
            .find(|v| v.name == name)
            .unwrap_or_else(|| panic!("no property {name:?}"))
            .outcome
    };
    assert_eq!(outcome(LAW_WITHIN_N), Outcome::Holds);
    assert_eq!(outcome(LAW_ALARMED), Outcome::Holds);
    assert_eq!(outcome(LAW_LEAVES), Outcome::Witnessed);
    let path = explored
        .discovery(LAW_LEAVES)
        .expect("the witness is reached");
    let end = last(&path);
    let leaver = end
        .controllers
        .iter()
        .find(|c| c.phase == Phase::Failed)
        .expect("a controller that left");
    assert_eq!(leaver.fault, Some(Fault::WrongLaw), "{}", path.render());
    // Named for its law, not its input, and never for its output.
    assert!(leaver.law_alarm && !leaver.input_alarm);
    assert!(!leaver.ever_sent_wrong);
    assert!(end.voting.dissent.iter().all(|alarm| !alarm));
}

#[test]
fn comparing_aligned_outputs_only_never_finds_a_masked_wrong_law() {
    let explored = explored(mutated(OutputMutation::NoRawCompare));
    let mut failed = explored.failed();
    failed.sort();
    assert_eq!(
        failed,
        vec![LAW_LEAVES, LAW_WITHIN_N],
        "only the law bound breaks, and its witness is never reached"
    );
    let path = counterexample(&explored, LAW_WITHIN_N);
    assert_eq!(path.steps.len(), 9, "{}", path.render());
    let end = last(&path);
    let wrong = end
        .controllers
        .iter()
        .find(|c| c.fault == Some(Fault::WrongLaw))
        .expect("a controller computing with a wrong law");
    assert!(
        wrong.role.is_some(),
        "it is still in its role: {}",
        path.render()
    );
    assert!(!wrong.ever_sent_wrong, "its output was right throughout");
    assert!(
        end.voting.dissent.iter().all(|alarm| !alarm),
        "and no receiver can name it"
    );
}

#[test]
fn two_wrong_controllers_that_disagree_make_the_voting_receiver_hold() {
    let explored = explored(OutputConfig::two_wrong_disagreeing());
    assert_eq!(explored.failed(), Vec::<&str>::new());
    let hold = explored
        .discovery("a voting receiver holds")
        .expect("the hold is reached");
    let end = last(&hold);
    assert!(end.voting.hold_alarm);
    assert_eq!(end.wrong_now(), 2);
    assert!(end.two_wrong_at_once);
}

#[test]
fn two_wrong_controllers_that_agree_outvote_the_correct_one() {
    let explored = explored(OutputConfig::two_wrong());
    let mut failed = explored.failed();
    failed.sort();
    assert_eq!(
        failed,
        [
            "a correct controller never leaves",
            "a dissent alarm names only a wrong controller",
            NEVER_WRONG,
        ]
    );
    // Both go wrong, and their two commands agree on a wrong value before the correct one's.
    let accepted = counterexample(&explored, NEVER_WRONG);
    assert_eq!(accepted.steps.len(), 4, "{}", accepted.render());
    let end = last(&accepted);
    assert_eq!(end.wrong_now(), 2);
    assert!(end.voting.accepted.is_some_and(|value| value != end.right));
    // The correct controller is the odd one out and leaves.
    let expelled = last(&counterexample(
        &explored,
        "a correct controller never leaves",
    ));
    assert!(expelled
        .controllers
        .iter()
        .any(|c| c.phase == Phase::Failed && c.fault.is_none()));
}

#[test]
fn counting_consecutive_inputs_misses_an_intermittently_wrong_primary() {
    let explored = explored(OutputConfig {
        cross_check: CrossCheck::Consecutive,
        ..OutputConfig::default()
    });
    let failed = explored.failed();
    assert!(failed.contains(&BOUND_K), "{failed:?}");
    assert!(failed.contains(&WITHIN_N), "{failed:?}");
    let end = last(&counterexample(&explored, BOUND_K));
    let bound = OutputConfig::default().exclusive_bound();
    let owner = end
        .controllers
        .iter()
        .find(|c| c.exclusive_wrong + c.exclusive_missed > bound)
        .expect("a controller past the bound");
    // Wrong at every other input: never the odd one out twice in a row, never gone.
    assert!(
        matches!(owner.fault, Some(Fault::Erratic | Fault::Frozen(_))),
        "{owner:?}"
    );
    assert!(owner.role.is_some(), "it is still in its role");
    // A frozen Primary does the same while the plant's right command keeps crossing its value.
    assert!(explored
        .states()
        .iter()
        .any(|state| state
            .controllers
            .iter()
            .any(|c| matches!(c.fault, Some(Fault::Frozen(_)))
                && c.role.is_some()
                && c.exclusive_wrong > bound)));
}

/// `model check --outputs ...`: its exit code and standard output.
fn run_check(args: &[&str]) -> (Option<i32>, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_model"))
        .args(["check", "--outputs"])
        .args(args)
        .output()
        .expect("the model binary runs");
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
    )
}

#[test]
fn the_command_line_checks_and_prints_the_finding() {
    let (code, out) = run_check(&[]);
    assert_eq!(code, Some(0), "{out}");
    assert!(
        out.contains("result: all 26 properties as expected"),
        "{out}"
    );
    let (code, out) = run_check(&["--wrong", "2"]);
    assert_eq!(code, Some(1), "{out}");
    assert!(
        out.contains(&format!("counterexample to \"{NEVER_WRONG}\" (4 steps)")),
        "{out}"
    );
    assert!(out.contains("explore --outputs --wrong 2"), "{out}");
    let (code, out) = run_check(&["--wrong", "2", "--disagreeing"]);
    assert_eq!(code, Some(0), "{out}");
}

#[test]
fn the_command_line_refuses_mixed_and_bad_flags() {
    let (code, _) = run_check(&["--crashes", "1"]);
    assert_eq!(code, Some(2), "a role-model flag with --outputs");
    let (code, _) = run_check(&["--wrong", "3"]);
    assert_eq!(code, Some(2), "three wrong controllers");
    let (code, _) = run_check(&["--depth", "4"]);
    assert_eq!(code, Some(2), "a depth bound");
    let status = Command::new(env!("CARGO_BIN_EXE_model"))
        .args(["check", "--wrong", "2"])
        .output()
        .expect("the model binary runs")
        .status;
    assert_eq!(status.code(), Some(2), "--wrong without --outputs");
}
