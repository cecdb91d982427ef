//! The controllers' cross-check over real DDS (`fault-injection` build, domain 155): three
//! `rl controller`s, the exclusive `rl servo`, `rl servo --vote` (alarming at a controller's
//! second dissent, as the controllers leave at their second odd input) and the camera on the
//! vote. The Primary's commands are made wrong by 300 on pan while it keeps heartbeating: it
//! finds itself the odd one out of three at `tracker.odd_limit` = 2 frames, reports it, stops
//! commanding and exits 75; the exclusive servo takes at most those 2 wrong commands (one more
//! for each answer C1 says went out before it could be judged: the timing assumption broken
//! on a loaded host) and moves to C2, once; the voting servo takes none and names C1. Restarted (as its service manager
//! would), C1 comes back as Tertiary, correct, the servo stays with C2, and the dissent alarm
//! clears (docs/protocol.md, "Output voting").

#![cfg(feature = "fault-injection")]

mod support;

use rl::procs::{ServoEvent, VotedServoEvent};
use rl_layer::core::Role;
use rl_layer::event::Event;
use std::collections::BTreeSet;
use std::io::Write;
use std::time::{Duration, Instant};
use support::Cluster;

const FORM: Duration = Duration::from_secs(30);
const SKEW: u16 = 300;

fn formed(cluster: &Cluster) -> bool {
    cluster.steady_with(1, Some(Role::Primary))
        && cluster.steady_with(2, Some(Role::Secondary))
        && cluster.steady_with(3, Some(Role::Tertiary))
}

/// Pans the exclusive servo took, with when it read them.
type Pans = Vec<(Instant, u16)>;

/// The exclusive servo's commands from C1 since `from`, and the commands of C2 and C3.
fn commands_since(cluster: &Cluster, from: Instant) -> (Pans, Pans) {
    let (mut c1, mut others) = (Vec::new(), Vec::new());
    for (at, event) in cluster.servo.iter().filter(|(at, _)| *at >= from) {
        if let ServoEvent::Command {
            controller_id: Some(id),
            pan,
            ..
        } = event
        {
            if *id == 1 {
                c1.push((*at, *pan));
            } else {
                others.push((*at, *pan));
            }
        }
    }
    (c1, others)
}

/// The exclusive servo's owner changes from one controller to another since `from`: (from,
/// to). A controller's own writer re-created at its new role's strength is no owner change.
fn owner_changes_since(cluster: &Cluster, from: Instant) -> Vec<(Option<u8>, Option<u8>)> {
    let changes = cluster.servo.iter().filter(|(at, _)| *at >= from);
    let changes = changes.filter_map(|(_, event)| match event {
        ServoEvent::OwnerChanged {
            from_controller_id,
            to_controller_id,
            ..
        } if from_controller_id != to_controller_id => {
            Some((*from_controller_id, *to_controller_id))
        }
        _ => None,
    });
    changes.collect()
}

fn dissent_about_c1(cluster: &Cluster, raised: bool) -> bool {
    cluster.voted.iter().any(|(_, event)| {
        matches!(event, VotedServoEvent::Dissent { controller_id: 1, raised: r, .. } if *r == raised)
    })
}

/// C1's `odd_one_out` event, if it reported one: the inputs, the agreeing peers, and how
/// many of its answers went out before they could be judged at their next input.
fn odd_one_out(cluster: &Cluster) -> Option<(Vec<u64>, Vec<u8>, u32)> {
    cluster
        .events
        .iter()
        .find_map(|(_, line)| match &line.event {
            Event::OddOneOut {
                inputs,
                peers,
                late,
                ..
            } if line.id == 1 => Some((inputs.clone(), peers.clone(), *late)),
            _ => None,
        })
}

/// The three controllers (C1's stdin piped, for the fault), both servos and the camera on the
/// vote, formed with the exclusive servo following C1; C1's stdin.
fn start(cluster: &mut Cluster) -> std::process::ChildStdin {
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
    cluster.start_voting_servo(&["--dissent-after", "2"]);
    cluster.wait_for("C1, C2, C3 formed", FORM, formed);
    cluster.wait_for("the servo follows C1", FORM, |c| c.servo_owner() == Some(1));
    c1
}

/// The distinct pans from C1 the exclusive servo took since `from` that are wrong: off the
/// nearest (in time) command of C2 or C3 by more than half the skew.
fn wrong_pans_of_c1(cluster: &Cluster, from: Instant) -> BTreeSet<u16> {
    let (c1_commands, others) = commands_since(cluster, from);
    let reference = others.first().map(|(_, pan)| *pan);
    let wrong = c1_commands.iter().filter(|(at, pan)| {
        let nearest = others
            .iter()
            .min_by_key(|(when, _)| when.max(at).duration_since(*when.min(at)))
            .map(|(_, pan)| *pan)
            .or(reference);
        nearest.is_some_and(|right| right.abs_diff(*pan) > SKEW / 2)
    });
    wrong.map(|(_, pan)| *pan).collect()
}

fn exited_75(cluster: &Cluster) -> bool {
    cluster.events.iter().any(|(_, line)| {
        line.id == 1
            && matches!(
                line.event,
                Event::Stopped {
                    exit_status: Some(75),
                    ..
                }
            )
    })
}

#[test]
fn a_wrong_primary_leaves_after_two_odd_frames_and_the_servo_moves_once() {
    let mut cluster = Cluster::new("cross-check", 155, "");
    let mut c1 = start(&mut cluster);
    cluster.pump(Duration::from_secs(2));
    assert_eq!(odd_one_out(&cluster), None, "no correct controller is odd");

    writeln!(c1, "wrong-commands offset {SKEW}").expect("inject");
    c1.flush().expect("inject");
    let injected = Instant::now();
    cluster.wait_for("C1 finds itself the odd one out", FORM, |c| {
        odd_one_out(c).is_some()
    });
    let (inputs, peers, late) = odd_one_out(&cluster).unwrap_or_default();
    assert_eq!((inputs.len(), peers), (2, vec![2, 3]));
    cluster.wait_for("C1 exits 75", FORM, exited_75);
    cluster.wait_for("C2 Primary", FORM, |c| {
        c.steady_with(2, Some(Role::Primary))
    });
    cluster.pump(Duration::from_secs(1));

    // The exclusive servo: C1's wrong commands, at most N = 2 distinct ones (K = N; one more
    // for each answer that went out before it could be judged, which C1 counts), then C2, in
    // one owner change.
    let wrong = wrong_pans_of_c1(&cluster, injected);
    assert!(
        !wrong.is_empty() && wrong.len() <= 2 + late as usize,
        "wrong commands at the exclusive servo: {wrong:?} ({late} of C1's answers late)"
    );
    assert_eq!(
        owner_changes_since(&cluster, injected),
        [(Some(1), Some(2))]
    );
    // The voting servo: none of C1's wrong values, and C1 named.
    let voted = cluster.voted.iter().filter(|(at, _)| *at >= injected);
    for (_, event) in voted {
        if let VotedServoEvent::VotedCommand { agreeing, pan, .. } = event {
            assert!(
                !agreeing.contains(&1) || !wrong.contains(pan),
                "voted {event:?}"
            );
        }
    }
    assert!(dissent_about_c1(&cluster, true), "dissent about C1 raised");
    comes_back_as_tertiary(&mut cluster);
}

/// Restarted, C1 is correct and comes back below the two that stayed; the dissent alarm
/// clears, the servo stays with C2, and nobody else ever left.
fn comes_back_as_tertiary(cluster: &mut Cluster) {
    let restarted = Instant::now();
    cluster.start(1);
    cluster.wait_for("C1 back as Tertiary", FORM, |c| {
        c.steady_with(1, Some(Role::Tertiary)) && c.steady_with(3, Some(Role::Secondary))
    });
    cluster.wait_for("dissent about C1 cleared", FORM, |c| {
        dissent_about_c1(c, false)
    });
    cluster.pump(Duration::from_secs(1));
    assert_eq!(owner_changes_since(cluster, restarted), []);
    let odd_reports = cluster
        .events
        .iter()
        .filter(|(_, line)| matches!(line.event, Event::OddOneOut { .. }));
    assert_eq!(odd_reports.count(), 1, "only the wrong C1 ever left");
}
