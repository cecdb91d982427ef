//! The judges of a run, from what it observed: owner timelines and owner changes per fault at
//! both actuators, the largest command gap at each, the time two controllers claimed top
//! strength at once, the rounds from the last heal to settled, dead processes and panics.
//! (Trace validation against the model is `super::validation`.) Each judge is a pure function
//! of the observations, so tests drive them with literal timelines.

use super::expect::Expected;
use super::observe::{largest_gap, owner_spans, ActuatorSample, Observations, OwnerSpan};
use super::procs::Life;
use rl::core::{Phase, Status};
use rl::event::Event;
use serde::Serialize;
use std::collections::BTreeMap;

/// The resolution of controller event times (`t_ms` is whole milliseconds).
pub const EVENT_RESOLUTION_MS: f64 = 1.0;

/// A fault as it happened (lab ms).
#[derive(Clone, Debug, Serialize)]
pub struct FaultRecord {
    pub label: String,
    pub applied_ms: f64,
    pub healed_ms: Option<f64>,
}

/// The owner changes a fault caused: those from its application until the next fault's.
#[derive(Clone, Debug, Serialize)]
pub struct FaultChanges {
    pub fault: String,
    pub servo: usize,
    pub connext: Option<usize>,
}

/// Everything the judges measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Metrics {
    pub judged_from_ms: f64,
    pub servo_owners: Vec<OwnerSpan>,
    pub connext_owners: Option<Vec<OwnerSpan>>,
    pub changes_per_fault: Vec<FaultChanges>,
    /// The largest gap between accepted commands, and when it ended (lab ms).
    pub servo_gap: Option<(f64, f64)>,
    pub connext_gap: Option<(f64, f64)>,
    pub two_at_top_ms: f64,
    /// Rounds from the last heal until settled for good; `None`: never settled.
    pub settle_rounds: Option<u64>,
    /// Roles of the live controllers at the end, `C1#2=primary`.
    pub final_roles: Vec<String>,
    pub dead: Vec<String>,
    pub panics: Vec<String>,
}

/// Owner changes per fault: each change counts for the fault whose application or heal came
/// last before it (a heal can move the owner too: a restart, a failback).
pub fn changes_per_fault(
    faults: &[FaultRecord],
    servo: &[OwnerSpan],
    connext: Option<&[OwnerSpan]>,
) -> Vec<FaultChanges> {
    let mut moments: Vec<(f64, usize)> = faults
        .iter()
        .enumerate()
        .flat_map(|(i, f)| [Some((f.applied_ms, i)), f.healed_ms.map(|h| (h, i))])
        .flatten()
        .collect();
    moments.sort_by(|a, b| a.0.total_cmp(&b.0));
    let blame = |spans: &[OwnerSpan]| {
        let mut counts = vec![0; faults.len()];
        for span in spans.iter().skip(1) {
            if let Some((_, i)) = moments.iter().rev().find(|(at, _)| *at <= span.from_ms) {
                counts[*i] += 1;
            }
        }
        counts
    };
    let servo = blame(servo);
    let connext = connext.map(blame);
    faults
        .iter()
        .enumerate()
        .map(|(i, fault)| FaultChanges {
            fault: fault.label.clone(),
            servo: servo[i],
            connext: connext.as_ref().map(|c| c[i]),
        })
        .collect()
}

/// The strength an event says its controller commands with now, if it says: `output` and
/// `status` name it; a controller back from a stall (`resumed`, a new incarnation whose
/// writer is silent until its voting loop has run) or `stopped` commands nothing.
fn claimed_strength(event: &Event) -> Option<Option<u8>> {
    match event {
        Event::Output { strength, .. } => Some(*strength),
        Event::Status { status } => Some(status.report.strength),
        Event::Resumed { .. } | Event::Stopped { .. } => Some(None),
        _ => None,
    }
}

/// Intervals (lab ms) in which a life claimed strength 30: from its `output` events, ended by
/// its death or `end_ms`, without the times it was paused (a stopped process writes nothing).
pub fn top_strength_intervals(
    observed: &Observations,
    life: &Life,
    end_ms: f64,
) -> Vec<(f64, f64)> {
    let label = life.label();
    let life_end = life.ended_ms.unwrap_or(end_ms);
    let mut intervals = Vec::new();
    let mut since: Option<f64> = None;
    for event in observed.controller.iter().filter(|e| e.life == label) {
        let Some(strength) = claimed_strength(&event.line.event) else {
            continue;
        };
        match (since, strength == Some(30)) {
            (None, true) => since = Some(event.at_ms),
            (Some(from), false) => {
                intervals.push((from, event.at_ms));
                since = None;
            }
            _ => {}
        }
    }
    if let Some(from) = since {
        intervals.push((from, life_end));
    }
    let mut running = Vec::new();
    for (from, to) in intervals {
        let mut pieces = vec![(from, to.min(life_end))];
        for (stop, cont) in &life.paused {
            // The writer stays silent from SIGCONT until the stall is noticed (`resumed`).
            let cont = cont.map_or(end_ms, |cont| resumed_after(observed, &label, cont));
            pieces = pieces
                .into_iter()
                .flat_map(|(a, b)| [(a, b.min(*stop)), (a.max(cont), b)])
                .filter(|(a, b)| b > a)
                .collect();
        }
        running.extend(pieces);
    }
    running
}

/// When life `label` said `resumed` after being continued at `cont_ms` (within a second;
/// `cont_ms` itself when it did not).
fn resumed_after(observed: &Observations, label: &str, cont_ms: f64) -> f64 {
    observed
        .controller
        .iter()
        .filter(|e| e.life == label && matches!(e.line.event, Event::Resumed { .. }))
        .map(|e| e.at_ms)
        .find(|at| *at >= cont_ms && *at <= cont_ms + 1000.0)
        .unwrap_or(cont_ms)
}

/// Milliseconds from `from_ms` on in which two or more of `intervals` overlap.
pub fn overlap_ms(intervals: &[Vec<(f64, f64)>], from_ms: f64) -> f64 {
    let mut edges: Vec<(f64, i32)> = intervals
        .iter()
        .flatten()
        .filter(|(_, b)| *b > from_ms)
        .flat_map(|(a, b)| [(a.max(from_ms), 1), (*b, -1)])
        .collect();
    edges.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let (mut count, mut last, mut total) = (0, 0.0, 0.0);
    for (at, delta) in edges {
        if count >= 2 {
            total += at - last;
        }
        count += delta;
        last = at;
    }
    total
}

/// Whether the live lives' statuses are settled: every one steady with a role at its
/// strength, all agreeing on one result that names exactly them.
fn settled(statuses: &BTreeMap<String, Status>, live: &[&Life]) -> bool {
    let reports: Vec<&Status> = live
        .iter()
        .filter_map(|l| statuses.get(&l.label()))
        .collect();
    if reports.len() != live.len() || reports.is_empty() {
        return false;
    }
    let agreed = reports[0].report.agreed;
    reports.iter().all(|s| {
        let r = &s.report;
        r.phase == Phase::Steady
            && r.agreed == agreed
            && r.role
                .is_some_and(|role| Some(role.strength()) == r.strength)
            && agreed
                .as_ref()
                .is_some_and(|a| a.role_of(r.id) == r.role && a.len() == live.len())
    })
}

/// Rounds from `healed_ms` until the live lives settled for good (`None`: not by the end).
pub fn settle_rounds(
    observed: &Observations,
    lives: &[Life],
    healed_ms: f64,
    period_ms: f64,
) -> Option<u64> {
    let live: Vec<&Life> = lives.iter().filter(|l| l.ended_ms.is_none()).collect();
    let mut statuses: BTreeMap<String, Status> = BTreeMap::new();
    let mut events: Vec<_> = observed.controller.iter().collect();
    events.sort_by(|a, b| a.at_ms.total_cmp(&b.at_ms));
    let mut settled_since: Option<f64> = None;
    let mut was_settled = false;
    for event in events {
        if let Some(status) = event.line.status() {
            statuses.insert(event.life.clone(), status.clone());
        }
        let now = settled(&statuses, &live);
        if now && !was_settled {
            settled_since = Some(event.at_ms.max(healed_ms));
        }
        was_settled = now;
    }
    let since = settled_since.filter(|_| was_settled)?;
    Some(((since - healed_ms) / period_ms).ceil().max(0.0) as u64)
}

/// Panics in stderr, `C2#2: thread 'main' panicked at ...`.
pub fn panics(observed: &Observations) -> Vec<String> {
    observed
        .stderr
        .iter()
        .filter(|(_, text)| text.contains("panicked"))
        .map(|(source, text)| format!("{source}: {text}"))
        .collect()
}

/// The judges' measurements of a run; `connext_judged`: the Connext reader ran (`--lenient`
/// lets a run go without it), so its silence is a gap like the servo's.
pub fn measure(
    observed: &Observations,
    lives: &[Life],
    faults: &[FaultRecord],
    judged_from_ms: f64,
    end_ms: f64,
    period_ms: f64,
    connext_judged: bool,
) -> Metrics {
    let name = |p: &str, at: f64| observed.owner_name(p, at, lives);
    // What the actuators saw while the processes were being stopped is not judged.
    let until_end = |samples: &[ActuatorSample]| -> Vec<ActuatorSample> {
        samples
            .iter()
            .filter(|s| s.at_ms <= end_ms)
            .cloned()
            .collect()
    };
    let (servo, connext) = (
        until_end(&observed.servo_commands),
        until_end(&observed.connext),
    );
    let servo_owners = owner_spans(&servo, name);
    let connext_owners = connext_judged.then(|| owner_spans(&connext, name));
    let intervals: Vec<Vec<(f64, f64)>> = lives
        .iter()
        .map(|l| top_strength_intervals(observed, l, end_ms))
        .collect();
    let healed_ms = faults
        .iter()
        .filter_map(|f| f.healed_ms)
        .fold(judged_from_ms, f64::max);
    let final_roles = lives
        .iter()
        .filter(|l| l.ended_ms.is_none())
        .map(|l| {
            let role = observed
                .controller
                .iter()
                .rev()
                .filter(|e| e.life == l.label())
                .find_map(|e| e.line.status())
                .and_then(|s| s.report.role)
                .map_or("-", |r| r.name());
            format!("{}={role}", l.label())
        })
        .collect();
    Metrics {
        judged_from_ms,
        changes_per_fault: changes_per_fault(faults, &servo_owners, connext_owners.as_deref()),
        servo_gap: Some(largest_gap(&servo, judged_from_ms, end_ms)),
        connext_gap: connext_judged.then(|| largest_gap(&connext, judged_from_ms, end_ms)),
        two_at_top_ms: overlap_ms(&intervals, judged_from_ms),
        settle_rounds: settle_rounds(observed, lives, healed_ms, period_ms),
        final_roles,
        servo_owners,
        connext_owners,
        dead: Vec::new(),
        panics: panics(observed),
    }
}

/// The judges' verdict: every expectation `metrics` misses, in words (empty: pass).
pub fn failures(metrics: &Metrics, expected: &Expected, accepted: Result<(), &str>) -> Vec<String> {
    let mut failed = Vec::new();
    for change in &metrics.changes_per_fault {
        let most = change.servo.max(change.connext.unwrap_or(0));
        if let Some(limit) = expected
            .owner_changes_per_fault
            .filter(|limit| most > *limit)
        {
            failed.push(format!(
                "{}: {} owner changes at rl servo, {} at Connext (expected at most {limit})",
                change.fault,
                change.servo,
                change.connext.map_or("-".into(), |c| c.to_string()),
            ));
        }
    }
    for (judge, gap) in [
        ("rl servo", metrics.servo_gap),
        ("Connext", metrics.connext_gap),
    ] {
        if let Some((gap_ms, at_ms)) = gap.filter(|(g, _)| *g > expected.largest_gap_ms) {
            failed.push(format!(
                "a command gap of {gap_ms:.0} ms at {judge}, ending at {:.1} s (expected at most {:.0} ms)",
                at_ms / 1000.0,
                expected.largest_gap_ms
            ));
        }
    }
    // Controller events carry whole milliseconds: an overlap below one is their resolution.
    if metrics.two_at_top_ms > expected.two_at_top_ms + EVENT_RESOLUTION_MS {
        failed.push(format!(
            "two controllers at top strength for {:.0} ms (expected at most {:.0} ms)",
            metrics.two_at_top_ms, expected.two_at_top_ms
        ));
    }
    match metrics.settle_rounds {
        Some(rounds) if rounds <= expected.settle_rounds => {}
        Some(rounds) => failed.push(format!(
            "settled {rounds} rounds after the last heal (expected at most {})",
            expected.settle_rounds
        )),
        None => failed.push("never settled after the last heal".into()),
    }
    if let (Err(why), true) = (accepted, expected.model_accepts) {
        failed.push(format!("the model rejects the recorded events: {why}"));
    }
    failed.extend(
        metrics
            .dead
            .iter()
            .map(|d| format!("not running at the end: {d}")),
    );
    failed.extend(metrics.panics.iter().map(|p| format!("panic: {p}")));
    failed
}

#[cfg(test)]
mod tests {
    use super::*;

    fn span(from_ms: f64, owner: &str) -> OwnerSpan {
        OwnerSpan {
            from_ms,
            to_ms: from_ms + 50.0,
            owner: owner.into(),
        }
    }

    #[test]
    fn each_owner_change_counts_for_the_latest_fault() {
        let spans = [
            span(0.0, "C1"),
            span(1100.0, "C2"),
            span(5200.0, "C1"),
            span(9000.0, "C3"),
        ];
        let faults = [
            FaultRecord {
                label: "cut".into(),
                applied_ms: 1000.0,
                healed_ms: Some(4000.0),
            },
            FaultRecord {
                label: "kill".into(),
                applied_ms: 8000.0,
                healed_ms: Some(9500.0),
            },
        ];
        let counted = changes_per_fault(&faults, &spans, None);
        assert_eq!((counted[0].servo, counted[1].servo), (2, 1));
    }

    #[test]
    fn a_change_after_a_heal_counts_for_the_healed_fault() {
        let spans = [span(0.0, "C1"), span(4000.0, "C2"), span(10100.0, "C3")];
        let faults = [
            FaultRecord {
                label: "clock".into(),
                applied_ms: 1000.0,
                healed_ms: Some(10000.0),
            },
            FaultRecord {
                label: "kill".into(),
                applied_ms: 3000.0,
                healed_ms: Some(5000.0),
            },
        ];
        let counted = changes_per_fault(&faults, &spans, Some(&spans));
        assert_eq!((counted[0].servo, counted[1].servo), (1, 1));
        assert_eq!(counted[0].connext, Some(1));
    }

    #[test]
    fn overlap_counts_only_two_or_more_at_once() {
        let intervals = vec![
            vec![(0.0, 100.0)],
            vec![(50.0, 300.0)],
            vec![(250.0, 400.0)],
        ];
        assert_eq!(overlap_ms(&intervals, 0.0), 100.0);
        assert_eq!(overlap_ms(&intervals, 280.0), 20.0);
        assert_eq!(overlap_ms(&[vec![(0.0, 100.0)]], 0.0), 0.0);
    }
}
