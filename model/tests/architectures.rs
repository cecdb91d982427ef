//! The paper's two other architectures (`model::architectures`, docs/protocol.md "Other
//! architectures: the spec"): the duplex without preemption and the pair with a bug in one
//! implementation hold; the paper's preempting duplex moves the actuator at every bounce
//! (finding A1); a bug both implementations share reaches the actuator (A2) and one both
//! controllers share leaves it without a writer (A3); broken rules are caught; and the command
//! line checks, refuses and explores them.

use model::architectures::check::{explore, Explored, Outcome, Spec, SpecPath};
use model::architectures::duplex::{DuplexAction, Writing};
use model::architectures::pair::{Answer, Output, PairAction};
use model::architectures::{
    ArchitectureMutation, BugReach, DuplexConfig, DuplexModel, PairConfig, PairModel,
};
use model::Phase;
use stateright::{Checker, HasDiscoveries};
use std::collections::BTreeSet;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const ONE_CHANGE: &str = "one owner change per fault";
const NO_WRONG: &str = "no wrong output reaches the actuator";
const MISMATCH_WRITES_NOTHING: &str = "a self-detected mismatch never reaches the actuator";
const CORRECT_WRITER: &str = "no single failure leaves the actuator without a correct writer";

fn duplex(config: DuplexConfig) -> Explored<DuplexModel> {
    explore(&DuplexModel::new(config))
}

fn pair(config: PairConfig) -> Explored<PairModel> {
    explore(&PairModel::new(config))
}

/// The shortest counterexample to `property`, which must exist.
fn counterexample<M: Spec>(explored: &Explored<M>, property: &str) -> SpecPath<M> {
    explored
        .discovery(property)
        .unwrap_or_else(|| panic!("no counterexample to {property:?}"))
}

/// Every witness is found, but those named in `not_applicable`.
fn assert_witnesses<M: Spec>(explored: &Explored<M>, not_applicable: &[&str]) {
    for verdict in explored.verdicts().iter().filter(|v| !v.always) {
        if not_applicable.contains(&verdict.name) {
            assert!(
                matches!(verdict.outcome, Outcome::NotApplicable(_)),
                "{}: {:?}",
                verdict.name,
                verdict.outcome
            );
        } else {
            assert_eq!(verdict.outcome, Outcome::Witnessed, "{}", verdict.name);
        }
    }
}

/// stateright's count of unique states, to compare with our own search.
fn stateright_count<M: Spec>(model: M) -> usize
where
    M::State: std::hash::Hash + Send + Sync,
{
    model
        .checker()
        .finish_when(HasDiscoveries::AnyOf(BTreeSet::new()))
        .spawn_bfs()
        .join()
        .unique_state_count()
}

// Any change of these numbers is a change of a model's behaviour: review it.
const PINNED_DUPLEX_STATES: usize = 8566;
const PINNED_PAIR_STATES: usize = 8666;

#[test]
fn pinned_state_counts_and_our_search_agrees_with_stateright() {
    let ours = duplex(DuplexConfig::default()).unique_states();
    assert_eq!(
        ours,
        stateright_count(DuplexModel::new(DuplexConfig::default()))
    );
    assert_eq!(ours, PINNED_DUPLEX_STATES);
    let ours = pair(PairConfig::default()).unique_states();
    assert_eq!(
        ours,
        stateright_count(PairModel::new(PairConfig::default()))
    );
    assert_eq!(ours, PINNED_PAIR_STATES);
}

#[test]
fn the_duplex_without_preemption_holds_and_its_witnesses_are_reached() {
    let explored = duplex(DuplexConfig::default());
    assert_eq!(explored.failed(), Vec::<&str>::new());
    assert_eq!(explored.verdicts().len(), 16);
    assert_witnesses(
        &explored,
        &[
            "a returning Primary takes the actuator back",
            "a lapsed Primary takes the actuator back once healthy",
        ],
    );
    // The returned Primary yields at 10 beside the commanding Standby at 20.
    let yielded = counterexample(
        &explored,
        "a returned Primary stays standby while the Standby commands",
    );
    let end = yielded.last();
    assert_eq!(end.controller(1).writing, Writing::Yielded);
    assert_eq!(end.owner, Some(2));
    assert!(end.owner_changes <= end.faults);
}

#[test]
fn the_duplex_holds_for_every_budget_up_to_four() {
    for crashes in 0..=4 {
        for losses in [0, 2, 4] {
            let config = DuplexConfig {
                max_crashes: crashes,
                max_lost_heartbeats: losses,
                ..DuplexConfig::default()
            };
            let explored = duplex(config);
            assert_eq!(explored.failed(), Vec::<&str>::new(), "{config:?}");
        }
    }
}

#[test]
fn a_preempting_primary_moves_the_actuator_at_every_bounce() {
    let explored = duplex(DuplexConfig::paper());
    assert_eq!(explored.failed(), [ONE_CHANGE]);
    assert_witnesses(
        &explored,
        &[
            "a returned Primary stays standby while the Standby commands",
            "a yielded Primary takes the actuator when the Standby fails",
            "lost heartbeats hand the actuator to a yielded Primary",
            "a lapsed Primary takes the actuator back once healthy",
        ],
    );
    // C1 crashes (to C2), C2's deadline passes (alarm), C1 restarts at 30 (back to C1).
    let bounce = counterexample(&explored, ONE_CHANGE);
    assert_eq!(
        bounce.actions(),
        [
            DuplexAction::Crash { controller: 1 },
            DuplexAction::Tick,
            DuplexAction::Tick,
            DuplexAction::Restart { controller: 1 },
        ],
        "{}",
        bounce.render()
    );
    assert_eq!((bounce.last().faults, bounce.last().owner_changes), (1, 2));
    // Every bounce costs two changes: three crashes of the Primary, no other fault, six.
    assert!(explored
        .states()
        .iter()
        .any(|state| state.crashes == 3 && state.lost_heartbeats == 0 && state.owner_changes == 6));
}

#[test]
fn an_actuator_that_ignores_strength_is_caught() {
    let explored = duplex(DuplexConfig {
        mutation: Some(ArchitectureMutation::OwnerByLowestId),
        ..DuplexConfig::default()
    });
    let failed = explored.failed();
    assert!(
        failed.contains(&"the actuator follows the strongest live writer"),
        "{failed:?}"
    );
    assert!(failed.contains(&ONE_CHANGE), "{failed:?}");
    // The returning Primary yields at 10, and the actuator takes it anyway.
    let path = counterexample(&explored, ONE_CHANGE);
    assert_eq!(path.steps.len(), 4, "{}", path.render());
    assert_eq!(path.last().owner, Some(1));
    assert_eq!(path.last().controller(1).writing, Writing::Yielded);
}

#[test]
fn a_silent_standby_leaves_the_actuator_without_a_writer() {
    let explored = duplex(DuplexConfig {
        mutation: Some(ArchitectureMutation::SilentStandby),
        ..DuplexConfig::default()
    });
    let failed = explored.failed();
    let property = "the actuator has a writer unless both are down";
    assert!(failed.contains(&property), "{failed:?}");
    let end = *counterexample(&explored, property).last();
    assert_eq!(end.owner, None);
    assert!(end.controllers.iter().any(|c| c.is_up()));
}

#[test]
fn a_bounce_faster_than_the_deadline_ties_two_yielded_writers() {
    let explored = duplex(DuplexConfig {
        mutation: Some(ArchitectureMutation::QuickRestart),
        ..DuplexConfig::default()
    });
    let tie = "no two writers at one strength";
    let mut failed = explored.failed();
    failed.sort();
    assert_eq!(failed, [tie, ONE_CHANGE]);
    // C1 bounces before C2 noticed and yields at 10; C2 bounces likewise: both at 10.
    let path = counterexample(&explored, tie);
    assert_eq!(path.steps.len(), 4, "{}", path.render());
    let end = path.last();
    assert!(end
        .controllers
        .iter()
        .all(|c| c.writing == Writing::Yielded));
}

#[test]
fn the_pair_holds_and_its_witnesses_are_reached() {
    let explored = pair(PairConfig::default());
    assert_eq!(explored.failed(), Vec::<&str>::new());
    assert_eq!(explored.verdicts().len(), 11);
    assert_witnesses(&explored, &[]);
    for bugs in 0..=3 {
        for crashes in 0..=3 {
            let config = PairConfig {
                max_crashes: crashes,
                max_bugs: bugs,
                ..PairConfig::default()
            };
            assert_eq!(pair(config).failed(), Vec::<&str>::new(), "{config:?}");
        }
    }
}

#[test]
fn writing_before_comparing_lets_a_wrong_output_through() {
    let explored = pair(PairConfig {
        mutation: Some(ArchitectureMutation::WriteBeforeCompare),
        ..PairConfig::default()
    });
    let mut failed = explored.failed();
    failed.sort();
    assert_eq!(failed, [MISMATCH_WRITES_NOTHING, NO_WRONG]);
    // A bug appears in one implementation at an input that triggers it; the write goes out.
    let path = counterexample(&explored, NO_WRONG);
    assert_eq!(path.steps.len(), 2, "{}", path.render());
    assert!(matches!(
        path.actions()[..],
        [PairAction::BugAppears { .. }, PairAction::Answer { .. }]
    ));
    let end = path.last();
    assert!(end.samples.contains(&Some(Output::Wrong)));
    assert!(end.controllers.iter().any(|c| c.answer == Answer::Left));
}

#[test]
fn a_bug_both_implementations_share_reaches_the_actuator() {
    let explored = pair(PairConfig::common_bug());
    assert_eq!(explored.failed(), [NO_WRONG]);
    assert_witnesses(
        &explored,
        &[
            "a mismatch removes a controller",
            "the survivor alarms a removed partner",
        ],
    );
    let path = counterexample(&explored, NO_WRONG);
    assert_eq!(path.steps.len(), 2, "{}", path.render());
    let end = path.last();
    assert!(end.samples.contains(&Some(Output::Wrong)));
    // Nobody found anything: the wrong controller is still in service.
    assert!(end.controllers.iter().all(|c| c.phase == Phase::Steady));
    // The partner's right sample comes next: two samples that differ, no way to tell which.
    assert!(explored
        .states()
        .iter()
        .any(|s| s.samples.contains(&Some(Output::Wrong))
            && s.samples.contains(&Some(Output::Right))
            && !s.double_failure));
}

#[test]
fn a_bug_both_controllers_share_removes_both() {
    let explored = pair(PairConfig::shared_implementation());
    assert_eq!(explored.failed(), [CORRECT_WRITER]);
    let path = counterexample(&explored, CORRECT_WRITER);
    assert_eq!(path.steps.len(), 4, "{}", path.render());
    let end = path.last();
    assert!(end.controllers.iter().all(|c| c.phase == Phase::Failed));
    assert_eq!(end.bugs, 1);
    assert!(!end.double_failure);
    // Fail-silent, not fail-wrong: nothing wrong ever reached the actuator.
    assert!(!explored.failed().contains(&NO_WRONG));
    assert_eq!(
        PairConfig::shared_implementation().bug_reach,
        BugReach::BothControllers
    );
}

/// `model check ...`: its exit code and standard output.
fn run_check(args: &[&str]) -> (Option<i32>, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_model"))
        .arg("check")
        .args(args)
        .output()
        .expect("the model binary runs");
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
    )
}

#[test]
fn the_command_line_checks_and_prints_the_findings() {
    let (code, out) = run_check(&["--architecture", "duplex"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(
        out.contains("result: all 16 properties as expected"),
        "{out}"
    );
    let (code, out) = run_check(&["--architecture", "duplex", "--preempt", "true"]);
    assert_eq!(code, Some(1), "{out}");
    assert!(
        out.contains(&format!("counterexample to \"{ONE_CHANGE}\" (4 steps)")),
        "{out}"
    );
    assert!(
        out.contains("explore --architecture duplex --preempt true"),
        "{out}"
    );
    assert!(out.contains("#/steps/0/0/1/1/0"), "{out}");
    let (code, out) = run_check(&["--architecture", "pair"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(
        out.contains("result: all 11 properties as expected"),
        "{out}"
    );
    for (reach, property) in [
        ("both-implementations", NO_WRONG),
        ("both-controllers", CORRECT_WRITER),
    ] {
        let (code, out) = run_check(&["--architecture", "pair", "--bug-in", reach]);
        assert_eq!(code, Some(1), "{out}");
        assert!(
            out.contains(&format!("counterexample to \"{property}\"")),
            "{out}"
        );
    }
    // The voting architecture is the role and output models, with their own flags.
    let (code, out) = run_check(&["--architecture", "voting", "--outputs"]);
    assert_eq!(code, Some(0), "{out}");
    assert!(out.contains("output voting"), "{out}");
}

#[test]
fn the_command_line_refuses_flags_of_another_model() {
    for args in [
        &["--architecture", "duplex", "--crashes", "1"][..],
        &["--architecture", "duplex", "--outputs"],
        &["--architecture", "duplex", "--depth", "4"],
        &["--architecture", "duplex", "--bugs", "1"],
        &["--architecture", "duplex", "--bounces", "9"],
        &["--architecture", "pair", "--preempt", "true"],
        &["--architecture", "pair", "--heartbeat-losses", "1"],
        &["--architecture", "voting", "--bounces", "1"],
        &[
            "--architecture",
            "duplex",
            "--architecture-mutation",
            "write-before-compare",
        ],
        &["--preempt", "true"],
        &["--architecture", "triplex"],
    ] {
        let (code, out) = run_check(args);
        assert_eq!(code, Some(2), "{args:?}: {out}");
    }
}

/// The explorer process, killed when the test ends.
struct Explorer(Child);

impl Drop for Explorer {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `GET path` from the explorer on `port`, the body of its answer.
fn get(port: u16, path: &str) -> std::io::Result<String> {
    let mut stream = TcpStream::connect(("127.0.0.1", port))?;
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    write!(stream, "GET {path} HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")?;
    let mut answer = String::new();
    stream.read_to_string(&mut answer)?;
    Ok(answer
        .split_once("\r\n\r\n")
        .map_or(String::new(), |(_, body)| body.to_string()))
}

/// Starts `explore` with `args` on a free port (three attempts: the port may be taken between
/// our pick and the explorer's bind) and waits until it answers.
fn start_explorer(args: &[&str]) -> (Explorer, u16) {
    for _ in 0..3 {
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|listener| listener.local_addr())
            .map(|addr| addr.port())
            .expect("a free loopback port");
        let child = Command::new(env!("CARGO_BIN_EXE_model"))
            .arg("explore")
            .args(args)
            .args(["--addr", &format!("127.0.0.1:{port}")])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("the model binary starts");
        let mut explorer = Explorer(child);
        let deadline = Instant::now() + Duration::from_secs(20);
        while Instant::now() < deadline {
            if explorer.0.try_wait().expect("its status").is_some() {
                break;
            }
            if get(port, "/.status").is_ok_and(|body| !body.is_empty()) {
                return (explorer, port);
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
    panic!("the explorer did not start");
}

#[test]
fn the_explorer_walks_the_duplex_bounce() {
    let (_explorer, port) = start_explorer(&["--architecture", "duplex", "--preempt", "true"]);
    let initial = get(port, "/.states").expect("the initial states");
    assert!(
        initial.contains("C1 Primary commands at 30, C2 Standby writes at 20"),
        "{initial}"
    );
    // The counterexample's fragment, #/steps/0/0/1/1/0: the last step from its prefix.
    let steps = get(port, "/.states/0/0/1/1").expect("the steps after three actions");
    let steps: serde_json::Value = serde_json::from_str(&steps).expect("JSON");
    let restart = steps
        .as_array()
        .and_then(|steps| steps.iter().find(|step| step["actionIndex"] == 0))
        .expect("the step of index 0");
    assert_eq!(restart["action"], "C1 restarts");
    let state = restart["state"].as_str().unwrap_or_default();
    assert!(state.contains("owner changes 2"), "{state}");
    assert!(state.contains("faults 1"), "{state}");
}

const ONE_BOUNCE: &str = "one bounce per fault";

#[test]
fn a_sick_preempting_primary_bounces_the_actuator_once_per_episode_with_its_dwell() {
    // A4: the paper's preemption with a dwell after a lapse. Only A1's property fails (a
    // crash or an episode still costs two changes), and never more than two per fault.
    let explored = duplex(DuplexConfig::sick_primary());
    assert_eq!(explored.failed(), [ONE_CHANGE]);
    assert_witnesses(
        &explored,
        &[
            "lost heartbeats hand the actuator to a yielded Primary",
            "both down: the actuator has no writer",
        ],
    );
    // The dwelling Primary is a yielded one: it stays below the commanding Standby, and takes
    // the actuator at once when the Standby fails.
    // The episode with every lapse the budget holds, then the dwell: two changes in all.
    let back = counterexample(
        &explored,
        "a lapsed Primary takes the actuator back once healthy",
    );
    assert!(back.last().lapses >= 1);
    assert!(back.last().owner_changes <= 2 * back.last().faults);
    assert!(explored.states().iter().any(|state| state.lapses == 3
        && state.crashes == 0
        && state.lost_heartbeats == 0
        && state.owner_changes == 2
        && state.owner == Some(1)));
}

#[test]
fn a_preempting_primary_without_the_dwell_bounces_at_every_lapse() {
    let explored = duplex(DuplexConfig {
        mutation: Some(ArchitectureMutation::NoDwell),
        ..DuplexConfig::sick_primary()
    });
    assert!(
        explored.failed().contains(&ONE_BOUNCE),
        "{:?}",
        explored.failed()
    );
    // Starved, lapsing, back at 30 at the next round end, lapsing again: four changes for
    // one episode.
    let bounces = counterexample(&explored, ONE_BOUNCE);
    assert_eq!(
        bounces.actions(),
        [
            DuplexAction::Sicken { controller: 1 },
            DuplexAction::Lapse { controller: 1 },
            DuplexAction::Tick,
            DuplexAction::Lapse { controller: 1 },
        ],
        "{}",
        bounces.render()
    );
}
