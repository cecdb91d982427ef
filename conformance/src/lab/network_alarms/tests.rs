//! The network alarm judge fed literal lines: what the contract promises passes, and each
//! check fails when its promise is broken (a missing, extra, early or late alarm, a wrong
//! certainty, a clear that is early, late, missing or undone, a controller alarm, a role
//! change, a conclusion without the double fault).

use super::*;
use rl_layer::event::EventLine;

const FAULT_MS: f64 = 10_000.0;
const HEAL_MS: f64 = 18_000.0;

fn life(id: u8) -> Life {
    Life {
        id,
        number: 1,
        pid: 0,
        clock_offset_s: 0.0,
        clock_rate: 1.0,
        started_ms: 0.0,
        started_wall_ms: 0.0,
        ended_ms: None,
        paused: Vec::new(),
        exit: None,
    }
}

fn lives() -> Vec<Life> {
    vec![life(1), life(2), life(3)]
}

fn faults() -> Vec<FaultRecord> {
    vec![FaultRecord {
        label: "net B down".into(),
        applied_ms: FAULT_MS,
        healed_ms: Some(HEAL_MS),
        target: None,
        alarm_within_ms: None,
    }]
}

/// A network line of controller `id` at lab ms `at_ms`, from its JSON text.
fn nap(id: u8, at_ms: f64, json: &str) -> NapRecord {
    let text = format!(
        r#"{{"t_ms":{},"id":{id},"incarnation":7,{json}}}"#,
        at_ms as u64
    );
    let (t_ms, id, event) = parse(&text).expect("a network line");
    NapRecord {
        life: format!("C{id}"),
        id,
        at_ms: t_ms as f64,
        event,
    }
}

fn raise(id: u8, at_ms: f64, network: &str, controller: &str, certainty: &str) -> NapRecord {
    nap(
        id,
        at_ms,
        &format!(
            r#""event":"network_alarm","network":"{network}","controller":{controller},"raised":true,"certainty":"{certainty}","cause":{{"concluded":{{"network_failure":"{network}"}}}}"#
        ),
    )
}

fn clear(id: u8, at_ms: f64, network: &str, controller: &str) -> NapRecord {
    nap(
        id,
        at_ms,
        &format!(
            r#""event":"network_alarm","network":"{network}","controller":{controller},"raised":false,"certainty":null,"cause":null"#
        ),
    )
}

/// A controller alarm `observer` raises about `about` at `at_ms`.
fn lost(observer: u8, about: u8, at_ms: f64) -> ControllerEvent {
    let text = format!(
        r#"{{"t_ms":{},"id":{observer},"incarnation":7,"event":"alarm","about":{about},"reason":"lost","raised":true}}"#,
        at_ms as u64
    );
    ControllerEvent {
        life: format!("C{observer}"),
        at_ms,
        line: EventLine::parse(&text).expect("an alarm line"),
    }
}

/// A net-B alarm raised 600 ms after the fault and cleared 1200 ms after the heal at each
/// of the three controllers: what the contract promises.
fn net_b_alarms() -> Vec<NapRecord> {
    (1..=3)
        .flat_map(|id| {
            [
                raise(id, FAULT_MS + 600.0, "B", "null", "concluded"),
                clear(id, HEAL_MS + 1200.0, "B", "null"),
            ]
        })
        .collect()
}

fn judged(scenario: &str, network: &[NapRecord], controller: &[ControllerEvent]) -> NapReport {
    let (lives, faults) = (lives(), faults());
    let recorded = Recorded {
        network,
        controller,
        lives: &lives,
        faults: &faults,
        judged_from_ms: 5_000.0,
    };
    let expected = for_scenario(scenario).expect("a net scenario");
    judge(&recorded, &expected, true)
}

fn assert_fails_with(report: &NapReport, words: &str) {
    assert!(
        report.failures.iter().any(|f| f.contains(words)),
        "no failure with {words:?} in {:?}",
        report.failures
    );
}

#[test]
fn the_lines_of_the_contract_parse() {
    let (t_ms, id, event) = parse(
        r#"{"t_ms":5,"id":2,"incarnation":1,"event":"network_alarm","network":"B","controller":null,"raised":true,"certainty":"concluded","cause":{"concluded":{"network_failure":"B"}}}"#,
    )
    .expect("an alarm");
    assert_eq!((t_ms, id), (5, 2));
    assert_eq!(
        event,
        NapEvent::Alarm {
            subject: Subject::Network(Network::B),
            raised: true,
            certainty: Some(Certainty::Concluded),
            cause: Some(AlarmCause::Concluded(Finding::NetworkFailure(Network::B))),
        }
    );
    let cleared = parse(
        r#"{"t_ms":5,"id":2,"incarnation":1,"event":"network_alarm","network":"A","controller":2,"raised":false}"#,
    );
    assert!(matches!(
        cleared,
        Some((
            _,
            _,
            NapEvent::Alarm {
                subject: Subject::Transceiver {
                    controller: 2,
                    network: Network::A
                },
                raised: false,
                certainty: None,
                ..
            }
        ))
    ));
    let conclusion = parse(
        r#"{"t_ms":5,"id":1,"incarnation":1,"event":"network_conclusion","conclusion":"none","verdict":"none"}"#,
    );
    assert!(matches!(
        conclusion,
        Some((
            _,
            1,
            NapEvent::Conclusion {
                verdict: Verdict::None,
                ..
            }
        ))
    ));
    assert!(parse(r#"{"t_ms":5,"id":1,"incarnation":1,"event":"started"}"#).is_none());
    assert!(parse("not json").is_none());
}

#[test]
fn alarms_as_promised_pass_and_are_measured() {
    let report = judged("net-b-down", &net_b_alarms(), &[]);
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    assert_eq!(report.timings.len(), 3);
    for timing in &report.timings {
        assert_eq!(timing.raised_after_ms, Some(600.0));
        assert_eq!(timing.cleared_after_ms, Some(1200.0));
        assert_eq!(timing.certainty, Some(Certainty::Concluded));
    }
}

#[test]
fn a_missing_raise_fails() {
    let mut lines = net_b_alarms();
    lines.retain(|r| r.id != 3);
    assert_fails_with(
        &judged("net-b-down", &lines, &[]),
        "C3: network B: alarm never raised",
    );
}

#[test]
fn an_extra_alarm_fails() {
    let mut lines = net_b_alarms();
    lines.push(raise(1, FAULT_MS + 700.0, "A", "3", "suspected"));
    let report = judged("net-b-down", &lines, &[]);
    assert_fails_with(
        &report,
        "unexpected network alarm: C1: controller 3's transceiver on A",
    );
    assert_eq!(report.other_alarms.len(), 1);
    // An alarm where none is expected at all: both links of C2 down.
    let report = judged("c2-both-links-down", &net_b_alarms(), &[]);
    assert_fails_with(&report, "unexpected network alarm: C2: network B");
}

#[test]
fn a_late_raise_fails() {
    let mut lines = net_b_alarms();
    lines[0] = raise(1, FAULT_MS + 1100.0, "B", "null", "concluded");
    assert_fails_with(
        &judged("net-b-down", &lines, &[]),
        "C1: network B: alarm raised 1100 ms after the fault",
    );
}

#[test]
fn a_raise_before_the_fault_fails() {
    let mut lines = net_b_alarms();
    lines.insert(0, raise(2, FAULT_MS - 2000.0, "B", "null", "concluded"));
    lines.insert(1, clear(2, FAULT_MS - 1000.0, "B", "null"));
    assert_fails_with(
        &judged("net-b-down", &lines, &[]),
        "unexpected network alarm: C2: network B",
    );
}

#[test]
fn a_wrong_certainty_fails() {
    let mut lines = net_b_alarms();
    lines[2] = raise(2, FAULT_MS + 600.0, "B", "null", "suspected");
    assert_fails_with(
        &judged("net-b-down", &lines, &[]),
        "C2: network B: certainty suspected at the heal (expected concluded)",
    );
}

#[test]
fn clears_early_late_missing_or_undone_fail() {
    let early = {
        let mut lines = net_b_alarms();
        lines[1] = clear(1, HEAL_MS - 500.0, "B", "null");
        judged("net-b-down", &lines, &[])
    };
    assert_fails_with(
        &early,
        "C1: network B: alarm cleared 500 ms before the heal",
    );
    let late = {
        let mut lines = net_b_alarms();
        lines[1] = clear(1, HEAL_MS + 2000.0, "B", "null");
        judged("net-b-down", &lines, &[])
    };
    assert_fails_with(&late, "C1: network B: alarm cleared 2000 ms after the heal");
    let missing = {
        let mut lines = net_b_alarms();
        lines.remove(1);
        judged("net-b-down", &lines, &[])
    };
    assert_fails_with(&missing, "C1: network B: alarm never cleared");
    let undone = {
        let mut lines = net_b_alarms();
        lines.push(raise(1, HEAL_MS + 3000.0, "B", "null", "concluded"));
        judged("net-b-down", &lines, &[])
    };
    assert_fails_with(
        &undone,
        "C1: network B: alarm raised again 3000 ms after the heal",
    );
}

#[test]
fn a_controller_alarm_or_role_change_under_a_net_fault_fails() {
    let report = judged(
        "net-b-down",
        &net_b_alarms(),
        &[lost(1, 2, FAULT_MS + 500.0)],
    );
    assert_fails_with(&report, "unexpected controller alarm: C1 about C2");
    let status = |role: rl_layer::core::Role, at_ms: f64| {
        let mut status = rl_layer::core::Status::initial(3, 7);
        status.report.role = Some(role);
        ControllerEvent {
            life: "C3".into(),
            at_ms,
            line: EventLine {
                t_ms: at_ms as u64,
                id: 3,
                incarnation: 7,
                event: Event::Status {
                    status: Box::new(status),
                },
            },
        }
    };
    let report = judged(
        "net-b-down",
        &net_b_alarms(),
        &[
            status(rl_layer::core::Role::Tertiary, 1000.0),
            status(rl_layer::core::Role::Secondary, FAULT_MS + 300.0),
        ],
    );
    assert_fails_with(&report, "a role change: C3: tertiary to secondary");
}

#[test]
fn both_nets_down_needs_the_double_fault_and_every_controller_alarm() {
    let conclusion = |id: u8, verdict: &str| {
        nap(
            id,
            FAULT_MS + 900.0,
            &format!(
                r#""event":"network_conclusion","conclusion":"as the verdict says","verdict":{verdict}"#
            ),
        )
    };
    let every_lost: Vec<ControllerEvent> = [(1, 2), (1, 3), (2, 1), (2, 3), (3, 1), (3, 2)]
        .into_iter()
        .map(|(a, b)| lost(a, b, FAULT_MS + 500.0))
        .collect();
    // One of: both networks failed | controllers 2 and 3 down or cut off on both networks.
    let ambiguous = r#"{"explained":{"certain":[],"alternatives":[["double_fault"],[{"controller_down":2},{"controller_down":3}]]}}"#;
    let good: Vec<NapRecord> = (1..=3).map(|id| conclusion(id, ambiguous)).collect();
    let report = judged("both-networks-down", &good, &every_lost);
    assert!(report.failures.is_empty(), "{:?}", report.failures);
    let mut vague = good.clone();
    // The same words, but a verdict without the double fault: the judge reads the verdict.
    vague[1] = conclusion(
        2,
        r#"{"explained":{"certain":[{"network_failure":"B"}],"alternatives":[]}}"#,
    );
    assert_fails_with(
        &judged("both-networks-down", &vague, &every_lost),
        "C2: no conclusion during the fault holds \"both networks failed\"",
    );
    assert_fails_with(
        &judged("both-networks-down", &good, &every_lost[1..]),
        "C1 raised no controller alarm about C2 (lost)",
    );
}

#[test]
fn without_network_monitoring_only_controller_alarms_and_roles_are_judged() {
    let (lives, faults) = (lives(), faults());
    let recorded = Recorded {
        network: &[],
        controller: &[],
        lives: &lives,
        faults: &faults,
        judged_from_ms: 5_000.0,
    };
    let net_b = for_scenario("net-b-down").expect("a net scenario");
    assert!(judge(&recorded, &net_b, false).failures.is_empty());
    let both = for_scenario("c2-both-links-down").expect("a net scenario");
    assert_fails_with(
        &judge(&recorded, &both, false),
        "C1 raised no controller alarm about C2",
    );
}
