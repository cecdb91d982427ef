//! The judges two redundancy groups on one LAN need beyond what each group is judged on alone
//! (`super::two_groups`; each group also gets `super::judge` and `super::network_alarms`):
//! that neither group heard the other, and that each failed over on its own.
//!
//! - readers: every sample at a group's `rl servo` and Connext reader came from a participant
//!   that group's servo identified as one of its controllers (the servo learns a writer's
//!   controller from its group's heartbeats), and from none the other group's servo identified;
//! - holders: every controller incarnation a group's controllers named (agreed result, vote,
//!   F17's `took_over_from`, vote records) is one of that group's own lives, never the other
//!   group's: ids 1-3 exist in both groups, incarnations are per process;
//! - ids: no controller counted a heartbeat of its id from another process
//!   (`duplicate_id_heartbeats`) and none raised an impostor alarm, over the whole run;
//! - owner: exactly one owner change at each of the group's readers from judging on, after the
//!   kill, to the group's own C2;
//! - monitor: each of the group's surviving network monitors, once it reports its group's C1
//!   down (`ControllerDown`, the fault table's dead controller), keeps reporting it until that
//!   group's C1 is restarted, and no longer at the end. The two groups' C1s come back at
//!   different times, so a monitor that heard the other group's network heartbeats would drop
//!   its C1 early, or keep it.
//!
//! Each judge is a pure function of the recorded lines; the tests (`cross_talk/tests.rs`) feed
//! them literal lines and show each one failing.

use super::judge::{FaultRecord, Metrics};
use super::network_alarms::{self, NapEvent, NapRecord};
use super::observe::{ActuatorSample, Observations, OwnerSpan};
use super::procs::Life;
use rl_layer::core::network::Finding;
use rl_layer::core::{AlarmReason, Assignment, Holder, Incarnation};
use rl_layer::event::Event;
use serde::Serialize;
use std::collections::BTreeMap;

/// What one group's run recorded, as the judges read it.
pub struct GroupLines<'a> {
    /// The group's name (`nav`).
    pub name: &'a str,
    pub observed: &'a Observations,
    pub lives: &'a [Life],
}

/// The controller each group loses, and the owner its readers must move to.
#[derive(Clone, Copy, Debug)]
pub struct Failover<'a> {
    /// The kill of the group's `killed` controller, healed by its restart.
    pub kill: &'a FaultRecord,
    pub killed: u8,
    /// The life the readers must end up on (`C2`).
    pub successor: &'a str,
}

/// One reader's samples: how many, and how many came from the group's own controllers.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReaderCount {
    pub reader: &'static str,
    pub samples: usize,
    pub own: usize,
}

/// How long one surviving monitor reported its group's killed controller down (lab ms).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MonitorSpan {
    /// The monitor's controller life (`C2`).
    pub observer: String,
    /// The first conclusion after the kill that names it down.
    pub down_from_ms: Option<f64>,
    /// The first conclusion after that which no longer does.
    pub down_until_ms: Option<f64>,
}

/// What the cross-talk judges measured and decided for one group.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CrossTalkReport {
    pub group: String,
    /// The participants the group's servo identified, `C2 0110f3...` (24 hex digits).
    pub participants: Vec<String>,
    pub readers: Vec<ReaderCount>,
    /// Controller incarnations named in statuses and vote records, all checked.
    pub holders_named: usize,
    /// Each surviving monitor's report of the killed controller (network monitoring only).
    pub monitor: Vec<MonitorSpan>,
    pub failures: Vec<String>,
}

/// Judges group `own` against `other`; `monitored`: the controllers ran network monitors.
pub fn judge(
    own: &GroupLines,
    other: &GroupLines,
    failover: &Failover,
    metrics: &Metrics,
    monitored: bool,
) -> CrossTalkReport {
    let (readers, mut failures) = readers_hear_own(own, other);
    let (holders_named, holder_failures) = holders_are_own(own, other);
    failures.extend(holder_failures);
    failures.extend(no_other_with_its_id(own));
    failures.extend(one_change_to(metrics, failover));
    let monitor = if monitored {
        let (spans, monitor_failures) =
            monitor_follows_own(&own.observed.network, own.lives, failover);
        failures.extend(monitor_failures);
        spans
    } else {
        Vec::new()
    };
    CrossTalkReport {
        group: own.name.to_string(),
        participants: identified(own),
        readers,
        holders_named,
        monitor,
        failures: failures
            .into_iter()
            .map(|f| format!("{}: {f}", own.name))
            .collect(),
    }
}

/// The participants `own`'s servo identified, each named by the life it is (`C1#2 0112...`:
/// the life of its id that ran when the servo first heard it).
fn identified(own: &GroupLines) -> Vec<String> {
    let observed = own.observed;
    observed
        .participant_ids
        .keys()
        .map(|participant| {
            let first_heard_ms = observed
                .servo_commands
                .iter()
                .find(|s| s.participant == *participant)
                .map_or(0.0, |s| s.at_ms);
            let life = observed.owner_name(participant, first_heard_ms, own.lives);
            format!("{life} {participant}")
        })
        .collect()
}

/// Every sample at `own`'s readers from a participant `own`'s servo identified and `other`'s
/// did not.
pub fn readers_hear_own(own: &GroupLines, other: &GroupLines) -> (Vec<ReaderCount>, Vec<String>) {
    let mut counts = Vec::new();
    let mut failed = Vec::new();
    let readers: [(&'static str, &[ActuatorSample]); 2] = [
        ("rl servo", &own.observed.servo_commands),
        ("Connext", &own.observed.connext),
    ];
    for (reader, samples) in readers {
        let mut strangers: BTreeMap<&str, usize> = BTreeMap::new();
        for sample in samples {
            let participant = sample.participant.as_str();
            let theirs = other.observed.participant_ids.contains_key(participant);
            if theirs || !own.observed.participant_ids.contains_key(participant) {
                *strangers.entry(participant).or_default() += 1;
            }
        }
        let foreign: usize = strangers.values().sum();
        counts.push(ReaderCount {
            reader,
            samples: samples.len(),
            own: samples.len() - foreign,
        });
        for (participant, count) in strangers {
            let whose = match other.observed.participant_ids.get(participant) {
                Some(id) => format!(
                    "{}'s servo identifies as {}'s C{id}",
                    other.name, other.name
                ),
                None => format!(
                    "{}'s servo never identified as one of {}'s controllers",
                    own.name, own.name
                ),
            };
            failed.push(format!(
                "{count} samples at its {reader} from participant {participant}, which {whose}"
            ));
        }
    }
    (counts, failed)
}

/// The holders an event names: a status's agreed result, vote and F17 predecessor, or a
/// vote record's assignment.
fn named_holders(event: &Event) -> Vec<Holder> {
    let of = |assignment: &Option<Assignment>| -> Vec<Holder> {
        assignment
            .iter()
            .flat_map(|a| a.0.iter().flatten().copied())
            .collect()
    };
    match event {
        Event::Status { status } => {
            let report = &status.report;
            let mut holders = of(&report.agreed);
            holders.extend(of(&report.vote));
            holders.extend(report.took_over_from);
            holders
        }
        Event::Vote { vote } => of(vote),
        _ => Vec::new(),
    }
}

/// Every holder `own`'s controllers named is an incarnation one of `own`'s lives reported as
/// its own; returns how many were named, and the failures.
pub fn holders_are_own(own: &GroupLines, other: &GroupLines) -> (usize, Vec<String>) {
    let incarnations = |group: &GroupLines| -> BTreeMap<Incarnation, String> {
        group
            .observed
            .controller
            .iter()
            .map(|e| (e.line.incarnation, e.life.clone()))
            .collect()
    };
    let (mine, theirs) = (incarnations(own), incarnations(other));
    let mut named = 0;
    // Per stranger: (its id, who named it first and when, how often).
    let mut strangers: BTreeMap<Incarnation, (u8, String, f64, usize)> = BTreeMap::new();
    for event in &own.observed.controller {
        for holder in named_holders(&event.line.event) {
            named += 1;
            if !mine.contains_key(&holder.incarnation) {
                strangers
                    .entry(holder.incarnation)
                    .or_insert((holder.id, event.life.clone(), event.at_ms, 0))
                    .3 += 1;
            }
        }
    }
    let failed = strangers
        .into_iter()
        .map(|(incarnation, (id, first, at_ms, count))| {
            let whose = theirs.get(&incarnation).map_or_else(
                || "no life of either group".to_string(),
                |life| format!("{}'s {life}", other.name),
            );
            format!(
                "{first} named C{id} of incarnation {incarnation}, which is {whose}, at {:.3} s \
                 ({count} times in all)",
                at_ms / 1000.0
            )
        })
        .collect();
    (named, failed)
}

/// No controller heard another process with its id, nor raised an impostor alarm.
pub fn no_other_with_its_id(own: &GroupLines) -> Vec<String> {
    let mut duplicates: BTreeMap<&str, u64> = BTreeMap::new();
    let mut failed = Vec::new();
    for event in &own.observed.controller {
        match &event.line.event {
            Event::Status { status } if status.duplicate_id_heartbeats > 0 => {
                let most = duplicates.entry(event.life.as_str()).or_default();
                *most = (*most).max(status.duplicate_id_heartbeats);
            }
            Event::Alarm {
                about,
                reason: AlarmReason::Impostor,
                raised: true,
            } => failed.push(format!(
                "{} raised an impostor alarm about C{about} at {:.3} s",
                event.life,
                event.at_ms / 1000.0
            )),
            _ => {}
        }
    }
    failed.extend(duplicates.into_iter().map(|(life, count)| {
        format!("{life} heard {count} heartbeats of its id from another process")
    }));
    failed
}

/// How many owner changes a failure lists (a reader that hears two groups changes hundreds
/// of times).
const LISTED_CHANGES: usize = 4;

/// Exactly one owner change at each reader from judging on: after the kill, to the successor.
pub fn one_change_to(metrics: &Metrics, failover: &Failover) -> Vec<String> {
    let readers = [
        ("rl servo", Some(&metrics.servo_owners)),
        ("Connext", metrics.connext_owners.as_ref()),
    ];
    let mut failed = Vec::new();
    for (reader, spans) in readers {
        let Some(spans) = spans else {
            continue;
        };
        let changes: Vec<&OwnerSpan> = spans
            .iter()
            .skip(1)
            .filter(|s| s.from_ms >= metrics.judged_from_ms)
            .collect();
        let to_successor = |span: &OwnerSpan| {
            span.from_ms >= failover.kill.applied_ms && span.owner == failover.successor
        };
        if changes.len() != 1 || !changes.iter().all(|s| to_successor(s)) {
            let mut listed: Vec<String> = changes
                .iter()
                .take(LISTED_CHANGES)
                .map(|s| format!("to {} at {:.3} s", s.owner, s.from_ms / 1000.0))
                .collect();
            if changes.len() > LISTED_CHANGES {
                listed.push(format!("{} more", changes.len() - LISTED_CHANGES));
            }
            failed.push(format!(
                "{} owner changes at its {reader} from judging on ({}), where the kill at {:.3} s \
                 must cause exactly one, to its {}",
                changes.len(),
                listed.join(", "),
                failover.kill.applied_ms / 1000.0,
                failover.successor
            ));
        }
    }
    failed
}

/// Each surviving monitor reports the killed controller down from the kill until the group's
/// own restart of it, and not at the end.
pub fn monitor_follows_own(
    network: &[NapRecord],
    lives: &[Life],
    failover: &Failover,
) -> (Vec<MonitorSpan>, Vec<String>) {
    let applied_ms = failover.kill.applied_ms;
    let restarted_ms = failover.kill.healed_ms.unwrap_or(f64::INFINITY);
    let killed = failover.killed;
    let mut spans = Vec::new();
    let mut failed = Vec::new();
    let survivors = lives.iter().filter(|l| {
        l.id != killed
            && l.started_ms <= applied_ms
            && l.ended_ms.is_none_or(|end| end >= restarted_ms)
    });
    for life in survivors {
        let label = life.label();
        let reports_down: Vec<(f64, bool)> = network
            .iter()
            .filter(|r| r.life == label && r.at_ms >= applied_ms)
            .filter_map(|r| match &r.event {
                NapEvent::Conclusion { verdict, .. } => Some((
                    r.at_ms,
                    network_alarms::allows(verdict, Finding::ControllerDown(killed)),
                )),
                NapEvent::Alarm { .. } => None,
            })
            .collect();
        let from = reports_down
            .iter()
            .find(|(_, down)| *down)
            .map(|(at, _)| *at);
        let until = from.and_then(|from| {
            reports_down
                .iter()
                .find(|(at, down)| *at > from && !down)
                .map(|(at, _)| *at)
        });
        match (from, until) {
            // Never reported: the network alarm judge's conclusion check says so.
            (None, _) => {}
            (Some(_), Some(until)) if until < restarted_ms => failed.push(format!(
                "{label}'s monitor stopped reporting C{killed} down at {:.3} s, before its own \
                 C{killed} was restarted at {:.3} s",
                until / 1000.0,
                restarted_ms / 1000.0
            )),
            (Some(_), None) if failover.kill.healed_ms.is_some() => failed.push(format!(
                "{label}'s monitor still reported C{killed} down at the end, though its own \
                 C{killed} was restarted at {:.3} s",
                restarted_ms / 1000.0
            )),
            (Some(_), _) => {}
        }
        spans.push(MonitorSpan {
            observer: label,
            down_from_ms: from,
            down_until_ms: until,
        });
    }
    (spans, failed)
}

#[cfg(test)]
mod tests;
