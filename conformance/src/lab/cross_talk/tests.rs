//! The cross-talk judges fed literal lines: two groups that kept to themselves pass, and each
//! judge fails when a group heard the other (a reader's sample from the other group's writer
//! or an unknown one, a vote naming the other group's incarnation, a heartbeat of its own id
//! from another process, an impostor alarm), failed over wrongly (no change, two, one to the
//! wrong controller or before the kill), or its monitor followed another C1.

use super::*;
use crate::lab::observe::ControllerEvent;
use rl_layer::core::network::{Finding, Verdict};
use rl_layer::core::Status;
use rl_layer::event::EventLine;

const KILL_MS: f64 = 3_000.0;
const RESTART_MS: f64 = 6_000.0;

fn life(id: u8, number: u32, started_ms: f64, ended_ms: Option<f64>) -> Life {
    Life {
        id,
        number,
        pid: 0,
        clock_offset_s: 0.0,
        clock_rate: 1.0,
        started_ms,
        started_wall_ms: 0.0,
        ended_ms,
        paused: Vec::new(),
        exit: None,
    }
}

/// C1 killed and restarted, C2 and C3 through.
fn lives() -> Vec<Life> {
    vec![
        life(1, 1, 0.0, Some(KILL_MS)),
        life(2, 1, 0.0, None),
        life(3, 1, 0.0, None),
        life(1, 2, RESTART_MS, None),
    ]
}

fn kill() -> FaultRecord {
    FaultRecord {
        label: "kill -9 C1, restart".into(),
        applied_ms: KILL_MS,
        healed_ms: Some(RESTART_MS),
        target: None,
        alarm_within_ms: None,
    }
}

fn failover(kill: &FaultRecord) -> Failover<'_> {
    Failover {
        kill,
        killed: 1,
        successor: "C2",
    }
}

/// An event of life `life` (id from its label's digit), of incarnation `incarnation`.
fn event(life: &str, incarnation: Incarnation, at_ms: f64, event: Event) -> ControllerEvent {
    let id = life[1..2].parse().unwrap_or(0);
    ControllerEvent {
        life: life.into(),
        at_ms,
        line: EventLine {
            t_ms: at_ms as u64,
            id,
            incarnation,
            event,
        },
    }
}

/// A status of `life` voting P, S, T = `holders`.
fn status(life: &str, incarnation: Incarnation, holders: &[(u8, Incarnation)]) -> Event {
    let id = life[1..2].parse().unwrap_or(0);
    let mut status = Status::initial(id, incarnation);
    let holders = holders.iter().map(|(id, incarnation)| Holder {
        id: *id,
        incarnation: *incarnation,
    });
    status.report.vote = Some(Assignment::from_ranked(holders));
    Event::Status {
        status: Box::new(status),
    }
}

/// A group whose C1, C2, C3 are incarnations `base + 1..3`, each with a status voting for
/// the three, and whose servo identified participants `pN` (`N` = `base + id`) from each.
fn group(base: u64) -> Observations {
    let mut observed = Observations::default();
    let holders: Vec<(u8, Incarnation)> = (1..=3).map(|id| (id, base + u64::from(id))).collect();
    for (id, incarnation) in &holders {
        let label = format!("C{id}");
        let vote = status(&label, *incarnation, &holders);
        observed
            .controller
            .push(event(&label, *incarnation, 1_000.0, vote));
        observed
            .participant_ids
            .insert(format!("p{}", base + u64::from(*id)), *id);
    }
    observed
}

fn sample(at_ms: f64, participant: &str) -> ActuatorSample {
    ActuatorSample {
        at_ms,
        participant: participant.into(),
        writer_entity: String::new(),
        own_ms: at_ms,
        pan_tilt: None,
    }
}

fn lines<'a>(name: &'a str, observed: &'a Observations, lives: &'a [Life]) -> GroupLines<'a> {
    GroupLines {
        name,
        observed,
        lives,
    }
}

#[test]
fn readers_that_heard_only_their_own_group_pass() {
    let (mut nav, act, lives) = (group(10), group(20), lives());
    nav.servo_commands = vec![sample(1.0, "p11"), sample(2.0, "p12")];
    nav.connext = vec![sample(1.0, "p11")];
    let (counts, failed) =
        readers_hear_own(&lines("nav", &nav, &lives), &lines("act", &act, &lives));
    assert!(failed.is_empty(), "{failed:?}");
    assert_eq!(
        counts[0],
        ReaderCount {
            reader: "rl servo",
            samples: 2,
            own: 2
        }
    );
    assert_eq!(
        counts[1],
        ReaderCount {
            reader: "Connext",
            samples: 1,
            own: 1
        }
    );
}

#[test]
fn a_sample_from_the_other_groups_writer_or_an_unknown_one_fails() {
    let (mut nav, act, lives) = (group(10), group(20), lives());
    nav.servo_commands = vec![sample(1.0, "p11")];
    nav.connext = vec![sample(1.0, "p21"), sample(2.0, "p21"), sample(3.0, "p99")];
    let (counts, failed) =
        readers_hear_own(&lines("nav", &nav, &lives), &lines("act", &act, &lives));
    assert_eq!(counts[1].own, 0);
    assert_eq!(failed.len(), 2, "{failed:?}");
    assert!(failed[0].contains("2 samples at its Connext from participant p21, which act's servo identifies as act's C1"), "{failed:?}");
    assert!(
        failed[1].contains("p99, which nav's servo never identified"),
        "{failed:?}"
    );
    // The same participant identified by both groups' servos is the other group's too.
    let mut shared = group(20);
    shared.participant_ids.insert("p11".into(), 1);
    let (_, failed) = readers_hear_own(&lines("nav", &nav, &lives), &lines("act", &shared, &lives));
    assert!(
        failed
            .iter()
            .any(|f| f.contains("rl servo from participant p11")),
        "{failed:?}"
    );
}

#[test]
fn votes_naming_only_the_groups_own_incarnations_pass() {
    let (nav, act, lives) = (group(10), group(20), lives());
    let (named, failed) = holders_are_own(&lines("nav", &nav, &lives), &lines("act", &act, &lives));
    assert_eq!(named, 9);
    assert!(failed.is_empty(), "{failed:?}");
}

#[test]
fn a_vote_naming_the_other_groups_incarnation_fails() {
    let (mut nav, act, lives) = (group(10), group(20), lives());
    // nav's C2 votes for act's C1 (incarnation 21) as Primary, twice.
    for at_ms in [2_000.0, 2_250.0] {
        let vote = status("C2", 12, &[(1, 21), (2, 12), (3, 13)]);
        nav.controller.push(event("C2", 12, at_ms, vote));
    }
    let record = Event::Vote {
        vote: Some(Assignment::from_ranked([Holder {
            id: 3,
            incarnation: 77,
        }])),
    };
    nav.controller.push(event("C3", 13, 2_500.0, record));
    let (_, failed) = holders_are_own(&lines("nav", &nav, &lives), &lines("act", &act, &lives));
    assert_eq!(failed.len(), 2, "{failed:?}");
    assert!(
        failed[0].contains(
            "C2 named C1 of incarnation 21, which is act's C1, at 2.000 s (2 times in all)"
        ),
        "{failed:?}"
    );
    assert!(
        failed[1].contains("C3 named C3 of incarnation 77, which is no life of either group"),
        "{failed:?}"
    );
}

#[test]
fn another_process_with_its_id_or_an_impostor_alarm_fails_and_a_lost_alarm_does_not() {
    let mut nav = group(10);
    let lost = Event::Alarm {
        about: 1,
        reason: AlarmReason::Lost,
        raised: true,
    };
    nav.controller.push(event("C2", 12, KILL_MS + 600.0, lost));
    let lives = lives();
    assert!(no_other_with_its_id(&lines("nav", &nav, &lives)).is_empty());
    let mut heard = Status::initial(2, 12);
    heard.duplicate_id_heartbeats = 4;
    let heard = Event::Status {
        status: Box::new(heard),
    };
    nav.controller.push(event("C2", 12, 1_500.0, heard));
    let impostor = Event::Alarm {
        about: 3,
        reason: AlarmReason::Impostor,
        raised: true,
    };
    nav.controller.push(event("C1", 11, 1_200.0, impostor));
    let failed = no_other_with_its_id(&lines("nav", &nav, &lives));
    assert_eq!(
        failed,
        [
            "C1 raised an impostor alarm about C3 at 1.200 s",
            "C2 heard 4 heartbeats of its id from another process"
        ]
    );
}

fn span(from_ms: f64, owner: &str) -> OwnerSpan {
    OwnerSpan {
        from_ms,
        to_ms: from_ms + 100.0,
        owner: owner.into(),
    }
}

fn owners(changes: &[(f64, &str)]) -> Metrics {
    let mut spans = vec![span(500.0, "C1")];
    spans.extend(changes.iter().map(|(at, owner)| span(*at, owner)));
    Metrics {
        judged_from_ms: 1_000.0,
        servo_owners: spans.clone(),
        connext_owners: Some(spans),
        ..Metrics::default()
    }
}

#[test]
fn exactly_one_change_after_the_kill_to_the_groups_c2_passes() {
    let kill = kill();
    assert!(one_change_to(&owners(&[(KILL_MS + 100.0, "C2")]), &failover(&kill)).is_empty());
}

#[test]
fn no_change_two_changes_or_one_to_another_controller_fail() {
    let kill = kill();
    let failed = |changes: &[(f64, &str)]| one_change_to(&owners(changes), &failover(&kill));
    let none = failed(&[]);
    assert_eq!(none.len(), 2, "{none:?}");
    assert!(
        none[0].starts_with("0 owner changes at its rl servo from judging on ()"),
        "{none:?}"
    );
    let two = failed(&[(KILL_MS + 100.0, "C2"), (KILL_MS + 9_000.0, "C3")]);
    assert!(
        two[1].contains(
            "2 owner changes at its Connext from judging on (to C2 at 3.100 s, to C3 at 12.000 s)"
        ),
        "{two:?}"
    );
    assert_eq!(failed(&[(KILL_MS + 100.0, "C3")]).len(), 2);
    // The other group's C2 is not a life of this group's: its participant is named `?...`.
    assert_eq!(failed(&[(KILL_MS + 100.0, "?0112ab")]).len(), 2);
    // Before the kill, even to C2.
    assert_eq!(failed(&[(KILL_MS - 500.0, "C2")]).len(), 2);
    // A reader that hears both groups changes owner all the time: the first few are listed.
    let flapping: Vec<(f64, &str)> = (0..7)
        .map(|i| {
            (
                KILL_MS + 100.0 * f64::from(i),
                ["C2", "?0112ab"][i as usize % 2],
            )
        })
        .collect();
    let listed = failed(&flapping);
    assert!(listed[0].contains("(to C2 at 3.000 s, to ?0112ab at 3.100 s, to C2 at 3.200 s, to ?0112ab at 3.300 s, 3 more)"), "{listed:?}");
}

/// A conclusion of `life` at `at_ms`: `down` names C1 down, otherwise every link good.
fn conclusion(life: &str, at_ms: f64, down: bool) -> NapRecord {
    let verdict = if down {
        Verdict::Explained {
            certain: vec![Finding::ControllerDown(1)],
            alternatives: Vec::new(),
        }
    } else {
        Verdict::None
    };
    NapRecord {
        life: life.into(),
        id: life[1..2].parse().unwrap_or(0),
        at_ms,
        event: NapEvent::Conclusion {
            text: "as the verdict says".into(),
            verdict,
        },
    }
}

#[test]
fn a_monitor_reporting_its_c1_down_until_its_own_restart_passes() {
    let network = [
        conclusion("C2", KILL_MS + 300.0, true),
        conclusion("C3", KILL_MS + 300.0, true),
        conclusion("C2", RESTART_MS + 250.0, false),
        conclusion("C3", RESTART_MS + 260.0, false),
    ];
    let kill = kill();
    let (spans, failed) = monitor_follows_own(&network, &lives(), &failover(&kill));
    assert!(failed.is_empty(), "{failed:?}");
    assert_eq!(spans.len(), 2);
    assert_eq!(spans[0].down_from_ms, Some(KILL_MS + 300.0));
    assert_eq!(spans[1].down_until_ms, Some(RESTART_MS + 260.0));
}

#[test]
fn a_monitor_dropping_c1_before_its_own_restart_or_never_fails() {
    // C2's monitor hears a C1 back 2 s before its group's: the other group's restarted C1.
    let network = [
        conclusion("C2", KILL_MS + 300.0, true),
        conclusion("C3", KILL_MS + 300.0, true),
        conclusion("C2", RESTART_MS - 2_000.0, false),
    ];
    let kill = kill();
    let (_, failed) = monitor_follows_own(&network, &lives(), &failover(&kill));
    assert_eq!(
        failed,
        [
            "C2's monitor stopped reporting C1 down at 4.000 s, before its own C1 was restarted at 6.000 s",
            "C3's monitor still reported C1 down at the end, though its own C1 was restarted at 6.000 s"
        ]
    );
    // A monitor that never reported it is the network alarm judge's conclusion check's.
    let (spans, failed) = monitor_follows_own(&[], &lives(), &failover(&kill));
    assert!(failed.is_empty());
    assert_eq!(spans[0].down_from_ms, None);
}

#[test]
fn the_report_prefixes_each_failure_with_its_group() {
    let (nav, act, lives) = (group(10), group(20), lives());
    let kill = kill();
    let report = judge(
        &lines("nav", &nav, &lives),
        &lines("act", &act, &lives),
        &failover(&kill),
        &owners(&[]),
        false,
    );
    assert_eq!(report.group, "nav");
    assert!(report.monitor.is_empty());
    assert!(
        report.failures.iter().all(|f| f.starts_with("nav: ")),
        "{:?}",
        report.failures
    );
    assert_eq!(report.failures.len(), 2);
    assert_eq!(report.participants, ["C1 p11", "C2 p12", "C3 p13"]);
}
