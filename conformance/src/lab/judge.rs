//! The judges of a run, from what it observed: owner timelines and owner changes per fault at
//! both actuators, the largest command gap at each, the time two controllers claimed top
//! strength at once, the rounds from the last heal to settled, dead processes and panics.
//! (Trace validation against the model is `super::validation`.) Each judge is a pure function
//! of the observations, so tests drive them with literal timelines.

use super::architecture::{self, Architecture};
use super::expect::{Expected, OwnerChanges, SETTLE_ROUNDS};
use super::observe::{largest_gap, owner_spans, ActuatorSample, Observations, OwnerSpan};
use super::procs::Life;
use rl_layer::core::{Status, Strength};
use rl_layer::event::Event;
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
    /// The controller it was applied to (`None`: a fault of a net, or of every controller).
    pub target: Option<u8>,
    /// Within this long of its application an alarm must name `target`
    /// ([`super::expect::alarm_within_ms`]; `None`: not judged).
    pub alarm_within_ms: Option<f64>,
}

/// When an alarm first named a fault's controller, against the fault's bound.
#[derive(Clone, Debug, Serialize)]
pub struct FaultNamed {
    pub fault: String,
    pub about: u8,
    pub within_ms: f64,
    /// The first raised alarm about `about` at or after the fault, ms after it (`None`: none).
    pub named_after_ms: Option<f64>,
    /// Who raised it, and why (`C1#1 stalled`).
    pub by: Option<String>,
}

/// Each judged fault's first alarm naming its controller: raised by any life (its peers'
/// `lost` or `failed`, its own new life's `stalled`) at or after the fault's application.
pub fn alarms_naming(faults: &[FaultRecord], observed: &Observations) -> Vec<FaultNamed> {
    faults
        .iter()
        .filter_map(|fault| {
            let (about, within_ms) = (fault.target?, fault.alarm_within_ms?);
            let first = observed.controller.iter().find(|e| {
                e.at_ms >= fault.applied_ms
                    && matches!(e.line.event, Event::Alarm { about: a, raised: true, .. } if a == about)
            });
            Some(FaultNamed {
                fault: fault.label.clone(),
                about,
                within_ms,
                named_after_ms: first.map(|e| e.at_ms - fault.applied_ms),
                by: first.map(|e| match &e.line.event {
                    Event::Alarm { reason, .. } => format!("{} {reason:?}", e.life),
                    _ => e.life.clone(),
                }),
            })
        })
        .collect()
}

/// The owner changes a fault caused (see [`changes_per_fault`]), with when each happened.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FaultChanges {
    pub fault: String,
    pub healed_ms: Option<f64>,
    /// How many at each reader (`None`: the Connext reader did not run).
    pub servo: usize,
    pub connext: Option<usize>,
    /// When each happened (lab ms).
    pub servo_at_ms: Vec<f64>,
    pub connext_at_ms: Option<Vec<f64>>,
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
    /// Rounds from the last heal or later process start ([`quiet_from_ms`]) until settled for
    /// good; `None`: never settled.
    pub settle_rounds: Option<u64>,
    /// When the controllers settled for good (lab ms).
    pub settled_ms: Option<f64>,
    /// How long every fault held at once (from the last application to the first heal).
    pub all_faults_held_ms: f64,
    /// Roles of the live controllers at the end, `C1#2=primary`.
    pub final_roles: Vec<String>,
    pub dead: Vec<String>,
    pub panics: Vec<String>,
    /// The faults whose controller an alarm must name, and when one did.
    pub named: Vec<FaultNamed>,
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
        let mut times: Vec<Vec<f64>> = vec![Vec::new(); faults.len()];
        for span in spans.iter().skip(1) {
            if let Some((_, i)) = moments.iter().rev().find(|(at, _)| *at <= span.from_ms) {
                times[*i].push(span.from_ms);
            }
        }
        times
    };
    let servo = blame(servo);
    let connext = connext.map(blame);
    faults
        .iter()
        .enumerate()
        .map(|(i, fault)| FaultChanges {
            fault: fault.label.clone(),
            healed_ms: fault.healed_ms,
            servo: servo[i].len(),
            connext: connext.as_ref().map(|c| c[i].len()),
            servo_at_ms: servo[i].clone(),
            connext_at_ms: connext.as_ref().map(|c| c[i].clone()),
        })
        .collect()
}

/// How long every one of `faults` held at once: from the last application to the first heal
/// (0 when they never all held together).
pub fn all_held_ms(faults: &[FaultRecord], end_ms: f64) -> f64 {
    if faults.is_empty() {
        return 0.0;
    }
    let last_applied = faults.iter().map(|f| f.applied_ms).fold(f64::MIN, f64::max);
    let first_healed = faults
        .iter()
        .map(|f| f.healed_ms.unwrap_or(end_ms))
        .fold(f64::MAX, f64::min);
    (first_healed - last_applied).max(0.0)
}

/// The strength an event says its controller commands with now, if it says: `output` and
/// `status` name it; a controller back from a stall (`resumed`, a new incarnation whose
/// writer is silent until its voting loop has run), cut off at its links (`detached`, the
/// same), deposed by a takeover (`deposed`, the same) or `stopped` commands nothing.
fn claimed_strength(event: &Event) -> Option<Option<Strength>> {
    match event {
        Event::Output { strength, .. } => Some(*strength),
        Event::Status { status } => Some(status.report.strength),
        Event::Resumed { .. } | Event::Detached | Event::Deposed | Event::Stopped { .. } => {
            Some(None)
        }
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
        match (
            since,
            strength == Some(rl_layer::core::Role::Primary.strength()),
        ) {
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

/// Whether the controllers of `live` have all reported and settled as `architecture` settles
/// ([`architecture::settled`]).
fn settled(
    architecture: Architecture,
    statuses: &BTreeMap<String, Status>,
    live: &[&Life],
) -> bool {
    let reports: Vec<&Status> = live
        .iter()
        .filter_map(|l| statuses.get(&l.label()))
        .collect();
    reports.len() == live.len() && architecture::settled(architecture, &reports)
}

/// Where the fault-free rounds the settle bound counts begin: the last heal, or a controller
/// process started after it (a restart after voting itself FAILED, as systemd does), whichever
/// came last. The model counts them so: its `Restart` and `Join` reset the fault-free rounds
/// as its faults do (`model::protocol`, `history.quiet_rounds`).
pub fn quiet_from_ms(faults: &[FaultRecord], lives: &[Life], judged_from_ms: f64) -> f64 {
    let last_heal = faults
        .iter()
        .filter_map(|f| f.healed_ms)
        .fold(judged_from_ms, f64::max);
    lives.iter().map(|l| l.started_ms).fold(last_heal, f64::max)
}

/// Rounds from `healed_ms` until `settled_ms`, begun rounds counted whole.
pub fn rounds_between(healed_ms: f64, settled_ms: f64, period_ms: f64) -> u64 {
    ((settled_ms - healed_ms) / period_ms).ceil().max(0.0) as u64
}

/// When, from `healed_ms` on, the live lives settled for good (`None`: not by the end).
pub fn settled_since(
    architecture: Architecture,
    observed: &Observations,
    lives: &[Life],
    healed_ms: f64,
) -> Option<f64> {
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
        let now = settled(architecture, &statuses, &live);
        if now && !was_settled {
            settled_since = Some(event.at_ms.max(healed_ms));
        }
        was_settled = now;
    }
    settled_since.filter(|_| was_settled)
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
    architecture: Architecture,
    connext_judged: bool,
) -> Metrics {
    let period_ms = rl_layer::config::Config::default()
        .timing
        .heartbeat_period_ms as f64;
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
    let healed_ms = quiet_from_ms(faults, lives, judged_from_ms);
    let settled_ms = settled_since(architecture, observed, lives, healed_ms);
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
        settle_rounds: settled_ms.map(|at| rounds_between(healed_ms, at, period_ms)),
        settled_ms,
        all_faults_held_ms: all_held_ms(faults, end_ms),
        final_roles,
        servo_owners,
        connext_owners,
        dead: Vec::new(),
        panics: panics(observed),
        named: alarms_naming(faults, observed),
    }
}

/// The judges' verdict: every expectation `metrics` misses, in words (empty: pass).
pub fn failures(
    metrics: &Metrics,
    expected: &Expected,
    accepted: Result<(), &super::validation::NotAccepted>,
) -> Vec<String> {
    let mut failed = owner_change_failures(metrics, expected);
    failed.extend(gap_failures(metrics, expected));
    // Controller events carry whole milliseconds: an overlap below one is their resolution.
    if metrics.two_at_top_ms > expected.two_at_top_ms + EVENT_RESOLUTION_MS {
        failed.push(format!(
            "two controllers at top strength for {:.0} ms (expected at most {:.0} ms)",
            metrics.two_at_top_ms, expected.two_at_top_ms
        ));
    }
    match metrics.settle_rounds {
        Some(rounds) if rounds <= SETTLE_ROUNDS => {}
        Some(rounds) => failed.push(format!(
            "settled {rounds} rounds after the last heal or restart (expected at most {SETTLE_ROUNDS})"
        )),
        None => failed.push("never settled after the last heal or restart".into()),
    }
    if let Err(why) = accepted {
        failed.push(format!("the model rejects the recorded events: {why}"));
    }
    failed.extend(
        metrics
            .dead
            .iter()
            .map(|d| format!("not running at the end: {d}")),
    );
    failed.extend(metrics.panics.iter().map(|p| format!("panic: {p}")));
    // A gray fault no reader saw (a starvation the controller absorbed: every command on time)
    // left nothing to name; one that moved an owner must be named (expect::alarm_within_ms).
    let moved_an_owner = |fault: &str| {
        metrics
            .changes_per_fault
            .iter()
            .find(|changes| changes.fault == fault)
            .is_none_or(|changes| changes.servo > 0 || changes.connext.is_some_and(|n| n > 0))
    };
    for named in &metrics.named {
        match named.named_after_ms {
            Some(after) if after <= named.within_ms => {}
            None if !moved_an_owner(&named.fault) => {}
            Some(after) => failed.push(format!(
                "{}: the first alarm naming C{} came {after:.0} ms after it (expected within {:.0} ms)",
                named.fault, named.about, named.within_ms
            )),
            None => failed.push(format!(
                "{}: no alarm named C{} (expected within {:.0} ms)",
                named.fault, named.about, named.within_ms
            )),
        }
    }
    failed
}

/// Each fault's owner changes at each reader against that fault's own bound.
fn owner_change_failures(metrics: &Metrics, expected: &Expected) -> Vec<String> {
    let recorded = &metrics.changes_per_fault;
    if recorded.len() != expected.faults.len() {
        // Changes that cannot be paired with their fault's bound are not judged by another's.
        return vec![format!(
            "{} faults recorded where the schedule has {}: their owner changes cannot be judged",
            recorded.len(),
            expected.faults.len()
        )];
    }
    let mut failed = Vec::new();
    for (change, bound) in recorded.iter().zip(&expected.faults) {
        let connext = change.connext.map_or("-".into(), |c| c.to_string());
        match bound.owner_changes {
            OwnerChanges::AtMost(limit) => {
                if change.servo.max(change.connext.unwrap_or(0)) > limit {
                    failed.push(format!(
                        "{}: {} owner changes at rl servo, {connext} at Connext (expected at most {limit})",
                        change.fault, change.servo,
                    ));
                }
            }
            OwnerChanges::OnlyWhileMerging => {
                let outside = |times: &[f64]| {
                    times
                        .iter()
                        .filter(|at| {
                            change.healed_ms.is_none_or(|healed| **at < healed)
                                || metrics.settled_ms.is_some_and(|settled| **at > settled)
                        })
                        .count()
                };
                let servo = outside(&change.servo_at_ms);
                let connext = change.connext_at_ms.as_deref().map_or(0, outside);
                if servo + connext > 0 {
                    failed.push(format!(
                        "{}: {servo} owner changes at rl servo, {connext} at Connext while it held or after the controllers settled (expected none outside the merge after its heal)",
                        change.fault,
                    ));
                }
            }
            // Measured (the table and the summary show it), not judged.
            OwnerChanges::Unbounded(_) => {}
        }
    }
    failed
}

/// The largest gap at each reader against that reader's bound; both grow by the time every
/// fault held at once where the schedule silences the actuator so.
fn gap_failures(metrics: &Metrics, expected: &Expected) -> Vec<String> {
    let silent_ms = if expected.silent_while_all_hold {
        metrics.all_faults_held_ms
    } else {
        0.0
    };
    let mut failed = Vec::new();
    for (judge, gap, bound) in [
        ("rl servo", metrics.servo_gap, expected.servo_gap_ms),
        ("Connext", metrics.connext_gap, expected.connext_gap_ms),
    ] {
        let bound = bound + silent_ms;
        if let Some((gap_ms, at_ms)) = gap.filter(|(g, _)| *g > bound) {
            failed.push(format!(
                "a command gap of {gap_ms:.0} ms at {judge}, ending at {:.1} s (expected at most {bound:.0} ms)",
                at_ms / 1000.0,
            ));
        }
    }
    failed
}

#[cfg(test)]
mod tests;
