//! Output voting at the receiver over real DDS: three `rl controller`s publish every command on
//! the voted command topic too, `rl servo --vote --json` votes on them, `rl shapes --vote`
//! moves the gimbal by the vote, and a plain `rl servo --json` reads the exclusive topic beside
//! them (docs/protocol.md, "Output voting at the receiver").
//!
//! Domain 156: every controller agrees, the voted commands are the commanding controller's, no
//! dissent; the Primary killed, the two left keep the vote going. Domain 158 (`fault-injection`
//! build): the Primary's commands made wrong by 300 on pan, with the controllers' cross-check
//! only counting (`tracker.odd_limit = 0`: it keeps heartbeating and keeps its role): the
//! voting servo names it, never takes its value, and clears the alarm when its commands are
//! right again. Domain 159 (`mutation` build too): the same with the voting servo's rule broken
//! (`RL_VOTE_MUTATION=accept-single-source`), and the judge of the test before sees C1's wrong
//! values taken. The cross-check itself, leaving, is `cross_check.rs`.

mod support;

use rl::procs::ServoEvent;
use rl::procs::VotedServoEvent;
use rl_layer::core::Role;
use std::collections::{BTreeMap, BTreeSet};
use std::time::{Duration, Instant};
use support::Cluster;

const FORM: Duration = Duration::from_secs(30);
/// The voting servo's tolerance per axis (its default).
const TOLERANCE: u16 = rl_layer::vote_reader::SERVO_TOLERANCE_DEFAULT;

/// Three controllers, the exclusive servo, the voting servo and the camera on the vote.
fn start(cluster: &mut Cluster) {
    cluster.start_servo();
    cluster.start_voting_servo(&[]);
    cluster
        .fleet
        .start_other("camera", &["shapes", "--vote"])
        .expect("start rl shapes --vote");
}

fn formed(cluster: &Cluster) -> bool {
    cluster.steady_with(1, Some(Role::Primary))
        && cluster.steady_with(2, Some(Role::Secondary))
        && cluster.steady_with(3, Some(Role::Tertiary))
}

/// The voted commands read at or after `from`: when, agreeing ids, pan, tilt.
fn voted_since(cluster: &Cluster, from: Instant) -> Vec<(Instant, Vec<u8>, u16, u16)> {
    let voted = cluster.voted.iter().filter(|(at, _)| *at >= from);
    let voted = voted.filter_map(|(at, event)| match event {
        VotedServoEvent::VotedCommand {
            agreeing,
            pan,
            tilt,
            ..
        } => Some((*at, agreeing.clone(), *pan, *tilt)),
        _ => None,
    });
    voted.collect()
}

/// The exclusive servo's commands from controller `id` read at or after `from`.
fn commands_of(cluster: &Cluster, id: u8, from: Instant) -> Vec<(Instant, u16, u16)> {
    let commands = cluster.servo.iter().filter(|(at, _)| *at >= from);
    let commands = commands.filter_map(|(at, event)| match event {
        ServoEvent::Command {
            controller_id: Some(from),
            pan,
            tilt,
            ..
        } if *from == id => Some((*at, *pan, *tilt)),
        _ => None,
    });
    commands.collect()
}

/// The command of `commands` read nearest to `at`.
fn nearest(commands: &[(Instant, u16, u16)], at: Instant) -> (Instant, u16, u16) {
    let distance = |(when, _, _): &&(Instant, u16, u16)| {
        if *when > at {
            when.duration_since(at)
        } else {
            at.duration_since(*when)
        }
    };
    *commands
        .iter()
        .min_by_key(distance)
        .expect("commands to compare with")
}

fn dissents(cluster: &Cluster) -> Vec<&VotedServoEvent> {
    let events = cluster.voted.iter().map(|(_, event)| event);
    events
        .filter(|event| matches!(event, VotedServoEvent::Dissent { .. }))
        .collect()
}

fn no_majorities_since(cluster: &Cluster, from: Instant) -> Vec<&VotedServoEvent> {
    let events = cluster.voted.iter().filter(|(at, _)| *at >= from);
    let events = events.map(|(_, event)| event);
    events
        .filter(|event| matches!(event, VotedServoEvent::NoMajority { .. }))
        .collect()
}

/// Formation, then the vote of all three on the camera's frames.
fn voting_with_all_three(cluster: &mut Cluster) -> Instant {
    cluster.wait_for("C1, C2, C3 formed", FORM, formed);
    cluster.wait_for("a command all three agree on", FORM, |c| {
        voted_since(c, c.started)
            .iter()
            .any(|(_, agreeing, _, _)| agreeing == &[1, 2, 3])
    });
    Instant::now()
}

/// Of the frames the vote accepted since `from`, those whose acceptances all carry one value
/// (the controllers answered them alike), and all of them.
fn frames_answered_alike(cluster: &Cluster, from: Instant) -> (usize, usize) {
    let mut values: BTreeMap<u64, BTreeSet<(u16, u16)>> = BTreeMap::new();
    for (at, event) in &cluster.voted {
        if let VotedServoEvent::VotedCommand {
            input, pan, tilt, ..
        } = event
        {
            if *at >= from {
                values.entry(*input).or_default().insert((*pan, *tilt));
            }
        }
    }
    let alike = values.values().filter(|v| v.len() == 1).count();
    (alike, values.len())
}

#[test]
fn the_vote_takes_the_controllers_commands_and_goes_on_with_two() {
    let mut cluster = Cluster::new("vote", 156, "");
    for id in 1..=3 {
        cluster.start(id);
    }
    start(&mut cluster);
    let settled = voting_with_all_three(&mut cluster);
    cluster.pump(Duration::from_secs(3));
    let voted = voted_since(&cluster, settled);
    let positions: BTreeSet<(u16, u16)> = voted.iter().map(|(_, _, p, t)| (*p, *t)).collect();
    assert!(
        positions.len() >= 10,
        "the gimbal tracks: {} voted positions in 3 s",
        positions.len()
    );
    // The voted commands are the commanding controller's (C1's on the exclusive topic), each
    // within the tolerance of C1's command of that moment.
    let commanded = commands_of(&cluster, 1, settled);
    for (at, _, pan, tilt) in &voted {
        let (_, c1_pan, c1_tilt) = nearest(&commanded, *at);
        assert!(
            c1_pan.abs_diff(*pan) <= TOLERANCE && c1_tilt.abs_diff(*tilt) <= TOLERANCE,
            "voted {pan},{tilt} against C1's {c1_pan},{c1_tilt}"
        );
    }
    // Every controller computes the same command from the same frame once all are aligned to
    // the vote (a second after the first frame all three agreed on: formation's first frames
    // are answered from each controller's own start): a frame's acceptances (two agreeing,
    // then the third joining) carry one value on nearly every frame.
    let (alike, frames) = frames_answered_alike(&cluster, settled + Duration::from_secs(1));
    assert!(
        alike * 10 >= frames * 9,
        "{alike} of {frames} frames answered alike by the controllers"
    );
    // Each frame is accepted when two agree and again when the third joins them.
    let all_three = voted.iter().filter(|(_, a, _, _)| a == &[1, 2, 3]).count();
    assert!(
        all_three * 5 >= voted.len() * 2,
        "the third joins on nearly every frame: {all_three} of {} acceptances",
        voted.len()
    );
    assert_eq!(dissents(&cluster), Vec::<&VotedServoEvent>::new());

    let killed = Instant::now();
    cluster.fleet.kill(1).expect("kill C1");
    cluster.pump(Duration::from_secs(3));
    let after: Vec<_> = voted_since(&cluster, killed + Duration::from_millis(500));
    assert!(
        after.len() >= 30,
        "the vote goes on with two: {} voted commands",
        after.len()
    );
    assert!(
        after.iter().all(|(_, agreeing, _, _)| agreeing == &[2, 3]),
        "C2 and C3 agree: {:?}",
        after.iter().map(|(_, a, _, _)| a).collect::<BTreeSet<_>>()
    );
    let gaps = after.windows(2).map(|w| w[1].0.duration_since(w[0].0));
    let longest = gaps.max().unwrap_or_default();
    assert!(
        longest < Duration::from_millis(400),
        "a voted command at least every few camera frames: {longest:?}"
    );
    assert_eq!(
        no_majorities_since(&cluster, killed),
        Vec::<&VotedServoEvent>::new()
    );
    assert_eq!(dissents(&cluster), Vec::<&VotedServoEvent>::new());
}

/// The controllers' cross-check only counts: the receiver alone stands between a wrong
/// Primary and a voting actuator.
#[cfg(feature = "fault-injection")]
const RECEIVER_ALONE: &str = "[tracker]\nodd_limit = 0";

/// How wrong C1's commands are made on pan.
#[cfg(feature = "fault-injection")]
const SKEW: u16 = 300;

/// C1 with its fault-injection control piped, C2 and C3, the servos and the camera; the voting
/// servo with `RL_VOTE_MUTATION` set to `vote_mutation`, if any.
#[cfg(feature = "fault-injection")]
fn start_with_c1_piped(
    cluster: &mut Cluster,
    vote_mutation: Option<&str>,
) -> std::process::ChildStdin {
    let (_, c1) = cluster
        .fleet
        .start_controller_piped(1, "C1", &["--json-events"])
        .expect("start C1");
    for id in 2..=3 {
        cluster.start(id);
    }
    cluster.start_servo();
    cluster
        .fleet
        .start_other("camera", &["shapes", "--vote"])
        .expect("start rl shapes --vote");
    if let Some(mutation) = vote_mutation {
        cluster.fleet.env("RL_VOTE_MUTATION", mutation);
    }
    cluster.start_voting_servo(&[]);
    c1
}

/// The voted commands since `from` whose pan is C1's wrong pan (within half the skew of C1's
/// command nearest in time at the exclusive servo), as (pan, tilt, C1's pan).
#[cfg(feature = "fault-injection")]
fn wrong_values_voted(cluster: &Cluster, from: Instant) -> Vec<(u16, u16, u16)> {
    let wrong = commands_of(cluster, 1, from);
    assert!(!wrong.is_empty(), "the exclusive servo follows C1");
    let voted = voted_since(cluster, from).into_iter();
    let taken = voted.filter_map(|(at, _, pan, tilt)| {
        let (_, c1_pan, _) = nearest(&wrong, at);
        (c1_pan.abs_diff(pan) <= SKEW / 2).then_some((pan, tilt, c1_pan))
    });
    taken.collect()
}

/// Writes one fault-injection line to controller 1.
#[cfg(feature = "fault-injection")]
fn inject(stdin: &mut std::process::ChildStdin, line: &str) {
    use std::io::Write;
    writeln!(stdin, "{line}").expect("write to C1's fault-injection control");
    stdin.flush().expect("flush C1's fault-injection control");
}

#[cfg(feature = "fault-injection")]
#[test]
fn a_primary_with_wrong_commands_is_named_and_never_followed_by_the_vote() {
    let mut cluster = Cluster::new("vote-dissent", 158, RECEIVER_ALONE);
    let mut c1 = start_with_c1_piped(&mut cluster, None);
    voting_with_all_three(&mut cluster);
    inject(&mut c1, &format!("skew-commands {SKEW}"));
    let skewed = Instant::now();
    cluster.wait_for("dissent raised about C1", Duration::from_secs(10), |c| {
        dissents(c).iter().any(|e| {
            matches!(
                e,
                VotedServoEvent::Dissent {
                    controller_id: 1,
                    raised: true,
                    ..
                }
            )
        })
    });
    let raised = Instant::now();
    cluster.pump(Duration::from_secs(3));
    // C1 keeps its role: the role vote alone never compares commands.
    assert!(
        cluster.steady_with(1, Some(Role::Primary)),
        "{}",
        cluster.describe()
    );
    let voted = voted_since(&cluster, raised);
    assert!(voted.len() >= 30, "voted commands go on: {}", voted.len());
    assert!(
        voted.iter().all(|(_, agreeing, _, _)| agreeing == &[2, 3]),
        "C1 is never among the agreeing, and C2 and C3 always are: {:?}",
        voted.iter().map(|(_, a, _, _)| a).collect::<BTreeSet<_>>()
    );
    // C1's wrong commands, as the exclusive servo follows them: the vote never took one.
    assert_eq!(wrong_values_voted(&cluster, raised), Vec::new());
    assert_eq!(
        no_majorities_since(&cluster, skewed),
        Vec::<&VotedServoEvent>::new()
    );
    inject(&mut c1, "skew-commands 0");
    cluster.wait_for("dissent about C1 cleared", Duration::from_secs(10), |c| {
        dissents(c).iter().any(|e| {
            matches!(
                e,
                VotedServoEvent::Dissent {
                    controller_id: 1,
                    raised: false,
                    ..
                }
            )
        })
    });
    cluster.wait_for("C1 agrees again", Duration::from_secs(5), |c| {
        voted_since(c, c.started)
            .last()
            .is_some_and(|(_, agreeing, _, _)| agreeing == &[1, 2, 3])
    });
}

/// The judge above can fail: with the voting servo's rule broken (one source suffices), C1's
/// wrong values are taken as they arrive.
#[cfg(all(feature = "fault-injection", feature = "mutation"))]
#[test]
fn a_vote_that_accepts_one_source_takes_the_wrong_primarys_values() {
    let mut cluster = Cluster::new("vote-mutated", 159, RECEIVER_ALONE);
    let mut c1 = start_with_c1_piped(&mut cluster, Some("accept-single-source"));
    // The broken vote takes each answer alone: it never reports three agreeing.
    cluster.wait_for("C1, C2, C3 formed", FORM, formed);
    cluster.wait_for("each controller's commands taken", FORM, |c| {
        let taken: BTreeSet<Vec<u8>> = voted_since(c, c.started)
            .into_iter()
            .map(|(_, agreeing, _, _)| agreeing)
            .collect();
        (1..=3).all(|id| taken.contains(&vec![id]))
    });
    assert!(
        cluster
            .lines_from("vote!")
            .any(|line| line.contains("RL_VOTE_MUTATION")),
        "the voting servo announces its broken rule"
    );
    inject(&mut c1, &format!("skew-commands {SKEW}"));
    let skewed = Instant::now();
    cluster.pump(Duration::from_secs(4));
    let taken = wrong_values_voted(&cluster, skewed + Duration::from_millis(500));
    assert!(
        taken.len() >= 3,
        "C1's wrong values taken by the broken vote: {taken:?}"
    );
}
