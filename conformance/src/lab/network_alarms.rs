//! The network alarm judge: what the controllers' network alarm participants (NAPs) reported
//! under a net fault, against what the scenario expects.
//!
//! Each controller prints a `network_alarm` line per alarm change (a whole net, or one
//! controller's transceiver on one net; raised or cleared) and a `network_conclusion` line per
//! change of its conclusion. For the net scenarios (`net-b-down`, `c2-transceiver-a-down`,
//! `c2-both-links-down`, `both-networks-down`) the judge demands, of every controller that ran
//! through the fault: each expected alarm raised within [`RAISE_WITHIN_MS`] of the fault (two
//! network heartbeat deadlines), with the expected certainty, and cleared within
//! [`CLEAR_WITHIN_MS`] of the heal
//! (a period to hear the link again, four of good links) and not before; no other network
//! alarm at all; the conclusion's verdict holding what it must (the double fault a monitor that
//! hears nobody cannot rule out; read typed from the `verdict`, never from the words); the controller alarms (RLCHB's `alarm` events) exactly as
//! expected; and, where voting must be unaffected, no role change and no restart. It measures
//! each raise and clear latency per controller for the outcome and docs/faults.md. The same
//! judge reads each group's lines of `two-groups` (`super::two_groups`): no network alarm, the
//! killed Primary reported down, `lost` about it.
//!
//! An `rl` without network monitoring (no `--network-a` option) prints no network lines: the
//! lab refuses such a run unless `--lenient`, and then the network alarm checks are skipped
//! with a note, the controller alarm and role checks still run. Every check is a pure function of the recorded lines, so the tests
//! (`network_alarms/tests.rs`) feed it literal lines and show that each check can fail.

use super::judge::FaultRecord;
use super::observe::ControllerEvent;
use super::procs::Life;
use rl_layer::core::network::{AlarmCause, AlarmSubject as Subject, Finding, Network, Verdict};
use rl_layer::core::AlarmReason;
use rl_layer::event::{Event, EventLine};
use rl_layer::wire::Certainty;
use serde::Serialize;

/// From a net fault to the alarm, two network heartbeat deadlines: the links' deadline (2
/// periods of 250 ms), then the subject implicated until it is raised (375 ms,
/// `networks.raise_after_ms`) while the last links' deadlines run out.
pub const RAISE_WITHIN_MS: f64 = 1000.0;
/// From the heal to the clear: a period to hear the links again, 4 periods of good links.
pub const CLEAR_WITHIN_MS: f64 = 1500.0;

/// A network line of a controller.
#[derive(Clone, Debug, PartialEq)]
pub enum NapEvent {
    Alarm {
        subject: Subject,
        raised: bool,
        certainty: Option<Certainty>,
        cause: Option<AlarmCause>,
    },
    Conclusion {
        text: String,
        verdict: Verdict,
    },
}

/// A network line on the lab clock.
#[derive(Clone, Debug)]
pub struct NapRecord {
    /// `C1#2`.
    pub life: String,
    pub id: u8,
    pub at_ms: f64,
    pub event: NapEvent,
}

/// A network line (rl's own `EventLine`, so writer and reader cannot drift): its `t_ms`,
/// controller id and event; `None` for any other line.
pub fn parse(text: &str) -> Option<(u64, u8, NapEvent)> {
    let line = EventLine::parse(text)?;
    Some((line.t_ms, line.id, nap_event(&line.event)?))
}

/// The network alarm or conclusion an event is, if it is one.
pub fn nap_event(event: &Event) -> Option<NapEvent> {
    match event {
        Event::NetworkAlarm {
            network,
            controller,
            raised,
            certainty,
            cause,
        } => {
            let network = *network;
            Some(NapEvent::Alarm {
                subject: controller.map_or(Subject::Network(network), |controller| {
                    Subject::Transceiver {
                        controller,
                        network,
                    }
                }),
                raised: *raised,
                certainty: *certainty,
                cause: cause.clone(),
            })
        }
        Event::NetworkConclusion {
            conclusion,
            verdict,
        } => Some(NapEvent::Conclusion {
            text: conclusion.clone(),
            verdict: verdict.clone(),
        }),
        _ => None,
    }
}

/// Every network alarm raise and clear of a run, `C1: net B raised (concluded) at 3.250 s`:
/// recorded for every scenario, judged only for the net scenarios.
pub fn changes(network: &[NapRecord]) -> Vec<String> {
    network
        .iter()
        .filter_map(|r| match &r.event {
            NapEvent::Alarm {
                subject,
                raised,
                certainty,
                ..
            } => Some(format!(
                "{}: {subject} {} at {:.3} s",
                r.life,
                match (raised, certainty) {
                    (true, Some(c)) => format!("raised ({})", c.name()),
                    (true, None) => "raised".into(),
                    (false, _) => "cleared".into(),
                },
                r.at_ms / 1000.0
            )),
            NapEvent::Conclusion { .. } => None,
        })
        .collect()
}

/// What a net scenario expects.
#[derive(Clone, Debug, PartialEq)]
pub struct NapExpected {
    /// Alarms every controller that ran through the fault raises and clears, with the
    /// certainty it must end the fault on (`None`: any); any other raise fails.
    pub alarms: Vec<(Subject, Option<Certainty>)>,
    /// A finding every such controller's conclusion must hold during the fault, as certain or
    /// among its alternatives.
    pub conclusion_allows: Option<Finding>,
    /// Controller alarms `(observer, about)` raised as `lost`; any other raise fails.
    pub controller_alarms: Vec<(u8, u8)>,
    /// Voting unaffected: no role change and no restart from judging on.
    pub roles_unchanged: bool,
}

/// What a net scenario expects of two monitors (the duplex's or the pair's), from what it
/// expects of three: a controller's transceiver on one net is a net's failure to them. Its
/// two links on that net are then all the links there are on it, so a net down and the
/// transceiver fail the same ones (the paper's table, rows 5 and 6, for one pair; the core's
/// `network::tests::table`): they alarm the net, concluded, as the paper's duplex does.
///
/// Both nets down are, to two monitors, the partner down (row 7 for one pair: every link to
/// the partner lost either way, and one fault explains it where the nets take two): the
/// double fault is not among their conclusions, and no net is alarmed.
pub fn for_two_members(expected: &mut NapExpected) {
    for (subject, _) in &mut expected.alarms {
        if let Subject::Transceiver { network, .. } = *subject {
            *subject = Subject::Network(network);
        }
    }
    if expected.conclusion_allows == Some(Finding::DoubleFault) {
        expected.conclusion_allows = None;
    }
}

/// What net scenario `name` expects (`None`: not a net scenario).
pub fn for_scenario(name: &str) -> Option<NapExpected> {
    let nothing = NapExpected {
        alarms: Vec::new(),
        conclusion_allows: None,
        controller_alarms: Vec::new(),
        roles_unchanged: true,
    };
    let everyone_loses = |ids: &[u8]| -> Vec<(u8, u8)> {
        ids.iter()
            .flat_map(|a| ids.iter().filter(move |b| *b != a).map(move |b| (*a, *b)))
            .collect()
    };
    match name {
        "net-b-down" => Some(NapExpected {
            alarms: vec![(Subject::Network(Network::B), Some(Certainty::Concluded))],
            ..nothing
        }),
        "c2-transceiver-a-down" => Some(NapExpected {
            alarms: vec![(
                Subject::Transceiver {
                    controller: 2,
                    network: Network::A,
                },
                Some(Certainty::Concluded),
            )],
            ..nothing
        }),
        // A controller down is the controller alarm's (RLCHB), not a network alarm; C2, which
        // hears nobody, cannot tell both its links from both peers and alarms nothing.
        "c2-both-links-down" => Some(NapExpected {
            controller_alarms: vec![(1, 2), (3, 2), (2, 1), (2, 3)],
            roles_unchanged: false,
            ..nothing
        }),
        // Nobody hears anybody: both nets dead or both peers dead look alike to each monitor
        // (the paper's double-fault row needs a second pair), so no network alarm, the double
        // fault named as a possibility.
        "both-networks-down" => Some(NapExpected {
            conclusion_allows: Some(Finding::DoubleFault),
            controller_alarms: everyone_loses(&[1, 2, 3]),
            roles_unchanged: false,
            ..nothing
        }),
        // Each group's own monitor when both groups' Primaries are killed (`two-groups`,
        // `super::two_groups`): a dead controller is the controller alarm's and never a network
        // alarm; its peers' monitors report it down, and its peers raise `lost` about it.
        "two-groups" => Some(NapExpected {
            conclusion_allows: Some(Finding::ControllerDown(1)),
            controller_alarms: vec![(2, 1), (3, 1)],
            roles_unchanged: false,
            ..nothing
        }),
        _ => None,
    }
}

/// One expected alarm at one controller, as measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AlarmTiming {
    /// The controller life (`C1`).
    pub observer: String,
    pub subject: String,
    /// From the fault to the first raise (ms).
    pub raised_after_ms: Option<f64>,
    /// The certainty of the last raise before the heal.
    pub certainty: Option<Certainty>,
    /// From the heal to the clear (ms); negative: cleared while the fault lasted.
    pub cleared_after_ms: Option<f64>,
    /// From the heal to a raise after that clear (ms), if it was raised again.
    pub raised_again_ms: Option<f64>,
}

/// What the network alarm judge measured and decided.
#[derive(Clone, Debug, Default, Serialize)]
pub struct NapReport {
    /// Whether network alarms were judged (`false`: the `rl` has no network monitoring).
    pub network_judged: bool,
    /// From the first fault's application to the last's (ms): faults meant to start together
    /// (both links of a controller, both nets) are applied one after the other, and on a
    /// loaded machine the first may hold alone long enough to be alarmed on its own.
    pub applied_over_ms: f64,
    pub timings: Vec<AlarmTiming>,
    /// Every network alarm raise outside the expected ones, described.
    pub other_alarms: Vec<String>,
    /// Each controller's conclusions during the fault, `C1: text`.
    pub conclusions: Vec<String>,
    /// Controller alarm raises from judging on, `C1 about C2 (lost) at 3.25 s`.
    pub controller_alarms: Vec<String>,
    /// Role changes and restarts from judging on.
    pub role_changes: Vec<String>,
    pub failures: Vec<String>,
}

/// What the judge reads: every line of the run and when it was judged.
pub struct Recorded<'a> {
    pub network: &'a [NapRecord],
    pub controller: &'a [ControllerEvent],
    pub lives: &'a [Life],
    pub faults: &'a [FaultRecord],
    pub judged_from_ms: f64,
}

/// Judges a net scenario; `network_judged` false skips the network alarm checks.
pub fn judge(recorded: &Recorded, expected: &NapExpected, network_judged: bool) -> NapReport {
    let mut report = NapReport {
        network_judged,
        ..NapReport::default()
    };
    let applied_ms = recorded
        .faults
        .iter()
        .map(|f| f.applied_ms)
        .fold(f64::INFINITY, f64::min);
    let healed_ms = recorded
        .faults
        .iter()
        .filter_map(|f| f.healed_ms)
        .fold(applied_ms, f64::max);
    report.applied_over_ms = recorded
        .faults
        .iter()
        .map(|f| f.applied_ms - applied_ms)
        .fold(0.0, f64::max);
    if !applied_ms.is_finite() {
        report.failures.push("no fault was applied".into());
        return report;
    }
    let observers: Vec<&Life> = recorded
        .lives
        .iter()
        .filter(|l| l.started_ms <= applied_ms && l.ended_ms.is_none_or(|end| end >= healed_ms))
        .collect();
    if network_judged {
        for life in &observers {
            for (subject, certainty) in &expected.alarms {
                let timing = alarm_timing(recorded.network, life, *subject, applied_ms, healed_ms);
                report.failures.extend(timing_failures(&timing, *certainty));
                report.timings.push(timing);
            }
        }
        other_alarms(recorded, expected, &mut report);
        conclusions(
            recorded,
            expected,
            &observers,
            applied_ms,
            healed_ms,
            &mut report,
        );
    }
    controller_alarms(recorded, expected, &mut report);
    if expected.roles_unchanged {
        role_changes(recorded, &mut report);
    }
    report
}

/// The lines about `subject` at `life`, in time order.
fn alarm_lines<'a>(
    network: &'a [NapRecord],
    life: &'a Life,
    subject: Subject,
) -> impl Iterator<Item = (f64, bool, Option<Certainty>)> + 'a {
    let label = life.label();
    network
        .iter()
        .filter(move |r| r.life == label)
        .filter_map(move |r| match &r.event {
            NapEvent::Alarm {
                subject: s,
                raised,
                certainty,
                ..
            } if *s == subject => Some((r.at_ms, *raised, *certainty)),
            _ => None,
        })
}

fn alarm_timing(
    network: &[NapRecord],
    life: &Life,
    subject: Subject,
    applied_ms: f64,
    healed_ms: f64,
) -> AlarmTiming {
    let lines: Vec<_> = alarm_lines(network, life, subject).collect();
    let first_raise = lines
        .iter()
        .find(|(at, raised, _)| *raised && *at >= applied_ms)
        .map(|(at, _, _)| *at);
    let certainty = lines
        .iter()
        .rfind(|(at, raised, _)| *raised && *at >= applied_ms && *at <= healed_ms)
        .and_then(|(_, _, c)| *c);
    let clear_at = first_raise.and_then(|raised_at| {
        lines
            .iter()
            .find(|(at, raised, _)| !*raised && *at >= raised_at)
            .map(|(at, _, _)| *at)
    });
    let raised_again = clear_at.and_then(|cleared| {
        lines
            .iter()
            .find(|(at, raised, _)| *raised && *at > cleared)
            .map(|(at, _, _)| at - healed_ms)
    });
    AlarmTiming {
        observer: life.label(),
        subject: subject.to_string(),
        raised_after_ms: first_raise.map(|at| at - applied_ms),
        certainty,
        cleared_after_ms: clear_at.map(|at| at - healed_ms),
        raised_again_ms: raised_again,
    }
}

fn timing_failures(timing: &AlarmTiming, certainty: Option<Certainty>) -> Vec<String> {
    let who = format!("{}: {}", timing.observer, timing.subject);
    let mut failed = Vec::new();
    match timing.raised_after_ms {
        None => failed.push(format!("{who}: alarm never raised")),
        Some(ms) if ms > RAISE_WITHIN_MS => failed.push(format!(
            "{who}: alarm raised {ms:.0} ms after the fault (expected within {RAISE_WITHIN_MS:.0} ms)"
        )),
        Some(_) => {}
    }
    if let Some(want) = certainty.filter(|want| timing.certainty != Some(*want)) {
        failed.push(format!(
            "{who}: certainty {} at the heal (expected {})",
            timing.certainty.map_or("-", Certainty::name),
            want.name()
        ));
    }
    match (timing.raised_after_ms, timing.cleared_after_ms) {
        (Some(_), None) => failed.push(format!("{who}: alarm never cleared")),
        (_, Some(ms)) if ms < 0.0 => failed.push(format!(
            "{who}: alarm cleared {:.0} ms before the heal",
            -ms
        )),
        (_, Some(ms)) if ms > CLEAR_WITHIN_MS => failed.push(format!(
            "{who}: alarm cleared {ms:.0} ms after the heal (expected within {CLEAR_WITHIN_MS:.0} ms)"
        )),
        _ => {}
    }
    if let Some(ms) = timing.raised_again_ms {
        failed.push(format!(
            "{who}: alarm raised again {ms:.0} ms after the heal, after its clear"
        ));
    }
    failed
}

/// Raises of subjects the scenario does not expect, and of expected ones before the fault.
fn other_alarms(recorded: &Recorded, expected: &NapExpected, report: &mut NapReport) {
    let applied_ms = recorded
        .faults
        .iter()
        .map(|f| f.applied_ms)
        .fold(f64::INFINITY, f64::min);
    for record in recorded.network {
        let NapEvent::Alarm {
            subject,
            raised: true,
            cause,
            ..
        } = &record.event
        else {
            continue;
        };
        let expected_subject = expected.alarms.iter().any(|(s, _)| s == subject);
        let judged = record.at_ms >= recorded.judged_from_ms;
        let early = expected_subject && record.at_ms < applied_ms;
        if judged && (!expected_subject || early) {
            let text = format!(
                "{}: {subject} raised at {:.3} s ({})",
                record.life,
                record.at_ms / 1000.0,
                cause
                    .as_ref()
                    .map_or_else(|| "no cause".to_string(), ToString::to_string)
            );
            report
                .failures
                .push(format!("unexpected network alarm: {text}"));
            report.other_alarms.push(text);
        }
    }
}

/// Each observer's conclusions during the fault; the required mention checked.
fn conclusions(
    recorded: &Recorded,
    expected: &NapExpected,
    observers: &[&Life],
    applied_ms: f64,
    healed_ms: f64,
    report: &mut NapReport,
) {
    for life in observers {
        let label = life.label();
        let conclusions: Vec<(&String, &Verdict)> = recorded
            .network
            .iter()
            .filter(|r| r.life == label && r.at_ms >= applied_ms && r.at_ms <= healed_ms)
            .filter_map(|r| match &r.event {
                NapEvent::Conclusion { text, verdict } => Some((text, verdict)),
                _ => None,
            })
            .collect();
        report
            .conclusions
            .extend(conclusions.iter().map(|(t, _)| format!("{label}: {t}")));
        if let Some(finding) = expected.conclusion_allows {
            if !conclusions.iter().any(|(_, v)| allows(v, finding)) {
                report.failures.push(format!(
                    "{label}: no conclusion during the fault holds \"{finding}\", as certain or \
                     as an alternative"
                ));
            }
        }
    }
}

/// Whether `verdict` holds `finding`, in every smallest explanation or in one of them.
pub fn allows(verdict: &Verdict, finding: Finding) -> bool {
    match verdict {
        Verdict::Explained {
            certain,
            alternatives,
        } => certain.contains(&finding) || alternatives.iter().any(|a| a.contains(&finding)),
        Verdict::None | Verdict::Unexplained { .. } => false,
    }
}

/// Controller alarms from judging on against the expected `(observer, about)` pairs.
fn controller_alarms(recorded: &Recorded, expected: &NapExpected, report: &mut NapReport) {
    let mut seen_lost: Vec<(u8, u8)> = Vec::new();
    for event in recorded
        .controller
        .iter()
        .filter(|e| e.at_ms >= recorded.judged_from_ms)
    {
        let Event::Alarm {
            about,
            reason,
            raised: true,
        } = &event.line.event
        else {
            continue;
        };
        let pair = (event.line.id, *about);
        let text = format!(
            "{} about C{about} ({reason:?}) at {:.3} s",
            event.life,
            event.at_ms / 1000.0
        );
        if *reason == AlarmReason::Lost {
            seen_lost.push(pair);
        }
        if !expected.controller_alarms.contains(&pair) {
            report
                .failures
                .push(format!("unexpected controller alarm: {text}"));
        }
        report.controller_alarms.push(text);
    }
    for (observer, about) in &expected.controller_alarms {
        if !seen_lost.contains(&(*observer, *about)) {
            report.failures.push(format!(
                "C{observer} raised no controller alarm about C{about} (lost)"
            ));
        }
    }
}

/// Role changes and restarts from judging on.
fn role_changes(recorded: &Recorded, report: &mut NapReport) {
    for life in recorded.lives {
        let label = life.label();
        if life.started_ms > recorded.judged_from_ms {
            let text = format!("{label} started at {:.3} s", life.started_ms / 1000.0);
            report.failures.push(format!("a restart: {text}"));
            report.role_changes.push(text);
        }
        let mut role = None;
        for event in recorded.controller.iter().filter(|e| e.life == label) {
            let Some(status) = event.line.status() else {
                continue;
            };
            let now = status.report.role;
            if event.at_ms > recorded.judged_from_ms && now != role {
                let name = |r: Option<rl_layer::core::Role>| r.map_or("none", |r| r.name());
                let text = format!(
                    "{label}: {} to {} at {:.3} s",
                    name(role),
                    name(now),
                    event.at_ms / 1000.0
                );
                report.failures.push(format!("a role change: {text}"));
                report.role_changes.push(text);
            }
            role = now;
        }
    }
}

#[cfg(test)]
mod tests;
