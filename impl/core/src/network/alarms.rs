//! Network alarms: what a conclusion implicates, and when an alarm is raised and cleared.
//!
//! An alarm is about a subject, a network or one controller's transceiver on one network, so
//! it keeps its identity while the conclusion about it is refined. A subject is implicated when
//! some minimum explanation holds a fault of it: as concluded when every explanation does, as
//! suspected otherwise (with the alternatives). A controller down is never alarmed here: the
//! controller alarm (RLCHB) covers it, as the paper asks. Nor is a suspicion when one of the
//! alternatives is controllers down and nothing else: a monitor that hears nobody cannot tell
//! both networks dead from both peers dead (as a pair cannot in the paper's table), so it
//! reports the ambiguity in its conclusion and alarms nothing it cannot tell apart.
//!
//! Hysteresis, so a flapping link makes one alarm and not a storm:
//! - raise once the subject has been implicated without a break for `raise_after_ms` (more
//!   than a period: the conclusion settles while the other links' deadlines run out);
//!   a changed cause is republished once it too has held that long;
//! - clear once every link the subject carries (leaving out links of controllers concluded
//!   down, whose silence says nothing of the network) has been Good without a break for
//!   `clear_after_ms`. Unknown links keep the alarm: a stale report is no recovery.

use super::conclude::{findings, Conclusion, Fault, Finding, Verdict};
use super::links::{Link, LinkSet, Network};
use crate::types::ControllerId;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;

/// What a network alarm is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlarmSubject {
    /// A whole network.
    Network(Network),
    /// One controller's transceiver (transmitter, receiver or both) on one network.
    Transceiver {
        /// The controller.
        controller: ControllerId,
        /// The network.
        network: Network,
    },
}

impl AlarmSubject {
    /// The subject a finding is about (two for a double fault, none for a controller down).
    fn of(finding: Finding) -> Vec<AlarmSubject> {
        match finding {
            Finding::NetworkFailure(network) => vec![AlarmSubject::Network(network)],
            Finding::DoubleFault => Network::ALL.map(AlarmSubject::Network).to_vec(),
            Finding::Transceiver {
                controller,
                network,
                ..
            } => vec![AlarmSubject::Transceiver {
                controller,
                network,
            }],
            Finding::ControllerDown(_) => Vec::new(),
        }
    }

    /// The links that show its recovery: every link it carries between members, except the
    /// links of controllers concluded down.
    fn evidence(self, conclusion: &Conclusion) -> LinkSet {
        let carried = match self {
            AlarmSubject::Network(network) => LinkSet::on(network),
            AlarmSubject::Transceiver {
                controller,
                network,
            } => LinkSet::on(network).intersection(LinkSet::touching(controller)),
        };
        let silent = conclusion
            .certainly_down()
            .into_iter()
            .fold(LinkSet::EMPTY, |links, id| {
                links.union(LinkSet::touching(id))
            });
        carried.intersection(conclusion.scope).minus(silent)
    }

    /// Whether every link showing its recovery is Good now (and there is at least one).
    fn recovered(self, conclusion: &Conclusion) -> bool {
        let evidence = self.evidence(conclusion);
        !evidence.is_empty() && evidence.is_subset(conclusion.good)
    }
}

/// Why a network alarm is raised.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlarmCause {
    /// Every minimum explanation holds this finding about the subject.
    Concluded(Finding),
    /// Some minimum explanations hold the subject, others do not: the alternatives (what each
    /// adds to the findings they share).
    Suspected {
        /// The alternatives, as in [`Verdict::Explained`].
        alternatives: Vec<Vec<Finding>>,
    },
    /// Links on the subject's network failed that no small set of faults explains.
    Unexplained {
        /// Those links.
        failed: Vec<Link>,
    },
}

/// When alarms are raised and cleared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AlarmTiming {
    /// A subject implicated without a break this long is alarmed.
    pub raise_after_ms: u64,
    /// A raised subject whose links are all Good this long is cleared.
    pub clear_after_ms: u64,
}

/// A change to publish on the network alarm topic.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AlarmChange {
    /// Raise the alarm (or republish it with a new cause).
    Raise {
        /// What it is about.
        subject: AlarmSubject,
        /// Why.
        cause: AlarmCause,
    },
    /// Clear it.
    Clear {
        /// What it was about.
        subject: AlarmSubject,
    },
}

/// Every subject a conclusion implicates, with its cause.
pub fn implicated(conclusion: &Conclusion) -> BTreeMap<AlarmSubject, AlarmCause> {
    let mut out = BTreeMap::new();
    match &conclusion.verdict {
        Verdict::None => {}
        Verdict::Unexplained { failed } => {
            for network in Network::ALL {
                let on: Vec<Link> = failed
                    .iter()
                    .copied()
                    .filter(|l| l.network == network)
                    .collect();
                if !on.is_empty() {
                    out.insert(
                        AlarmSubject::Network(network),
                        AlarmCause::Unexplained { failed: on },
                    );
                }
            }
        }
        Verdict::Explained { alternatives, .. } => {
            let certain = conclusion.certain_faults();
            for finding in findings(&certain) {
                for subject in AlarmSubject::of(finding) {
                    out.insert(subject, AlarmCause::Concluded(finding));
                }
            }
            let rest = |e: &'_ Vec<Fault>| -> Vec<Fault> {
                e.iter().copied().filter(|f| !certain.contains(f)).collect()
            };
            // When some alternative is controllers down and nothing else, the failure may be
            // no network's at all: the controller alarm covers that case, as in the paper's
            // row "either P or S down".
            let controllers_alone = conclusion.explanations.iter().any(|e| {
                rest(e)
                    .iter()
                    .all(|f| matches!(f, Fault::ControllerDown(_)))
            });
            if controllers_alone {
                return out;
            }
            for fault in conclusion.explanations.iter().flat_map(rest) {
                for subject in findings(&[fault]).into_iter().flat_map(AlarmSubject::of) {
                    out.entry(subject).or_insert_with(|| AlarmCause::Suspected {
                        alternatives: alternatives.clone(),
                    });
                }
            }
        }
    }
    out
}

/// One subject's hysteresis state.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct Entry {
    /// Implicated without a break since then (`None`: not implicated now).
    implicated_since_ms: Option<u64>,
    /// The cause it is implicated with now, and since when it has not changed.
    cause: Option<(AlarmCause, u64)>,
    /// The cause published, while the alarm is raised.
    raised: Option<AlarmCause>,
    /// Its links all Good without a break since then (only while raised, not implicated).
    recovered_since_ms: Option<u64>,
}

/// The alarms of one monitor: those raised and those on their way up or down.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct AlarmBook {
    entries: BTreeMap<AlarmSubject, Entry>,
}

impl AlarmBook {
    /// No alarm.
    pub fn new() -> AlarmBook {
        AlarmBook::default()
    }

    /// The alarms raised, with the cause last published.
    pub fn raised(&self) -> impl Iterator<Item = (AlarmSubject, &AlarmCause)> {
        self.entries
            .iter()
            .filter_map(|(&subject, entry)| entry.raised.as_ref().map(|cause| (subject, cause)))
    }

    /// Takes in the conclusion of `now_ms`; returns the alarms to raise, republish or clear.
    pub fn update(
        &mut self,
        conclusion: &Conclusion,
        timing: AlarmTiming,
        now_ms: u64,
    ) -> Vec<AlarmChange> {
        let implicated = implicated(conclusion);
        let mut changes = Vec::new();
        for (&subject, cause) in &implicated {
            let entry = self.entries.entry(subject).or_default();
            if let Some(cause) = entry.implicated(cause, timing, now_ms) {
                changes.push(AlarmChange::Raise { subject, cause });
            }
        }
        self.entries.retain(|&subject, entry| {
            if implicated.contains_key(&subject) {
                return true;
            }
            let cleared = entry.not_implicated(subject.recovered(conclusion), timing, now_ms);
            if cleared {
                changes.push(AlarmChange::Clear { subject });
            }
            entry.raised.is_some()
        });
        changes
    }

    /// The next instant after `now_ms` at which an alarm is due to be raised, republished or
    /// cleared if nothing changes meanwhile.
    pub fn next_due_ms(&self, timing: AlarmTiming, now_ms: u64) -> Option<u64> {
        self.entries
            .values()
            .flat_map(|entry| {
                let raise = entry.implicated_since_ms.filter(|_| entry.raised.is_none());
                let republish = entry
                    .cause
                    .as_ref()
                    .filter(|(cause, _)| entry.raised.as_ref().is_some_and(|r| r != cause))
                    .map(|&(_, since_ms)| since_ms);
                let clear = entry
                    .recovered_since_ms
                    .map(|since_ms| since_ms.saturating_add(timing.clear_after_ms));
                [raise, republish]
                    .into_iter()
                    .flatten()
                    .map(|since_ms| since_ms.saturating_add(timing.raise_after_ms))
                    .chain(clear)
            })
            .filter(|&due_ms| due_ms > now_ms)
            .min()
    }
}

impl Entry {
    /// The subject is implicated with `cause` at `now_ms`: returns the cause to publish, if
    /// the alarm is due to be raised or republished.
    fn implicated(
        &mut self,
        cause: &AlarmCause,
        timing: AlarmTiming,
        now_ms: u64,
    ) -> Option<AlarmCause> {
        self.recovered_since_ms = None;
        let since_ms = *self.implicated_since_ms.get_or_insert(now_ms);
        if self
            .cause
            .as_ref()
            .is_none_or(|(current, _)| current != cause)
        {
            self.cause = Some((cause.clone(), now_ms));
        }
        let cause_since_ms = self.cause.as_ref().map_or(now_ms, |&(_, at_ms)| at_ms);
        let held = |from_ms: u64| now_ms.saturating_sub(from_ms) >= timing.raise_after_ms;
        let due = match &self.raised {
            None => held(since_ms),
            Some(published) => published != cause && held(cause_since_ms),
        };
        if due {
            self.raised = Some(cause.clone());
            return Some(cause.clone());
        }
        None
    }

    /// The subject is not implicated at `now_ms` (`recovered`: its links are all Good):
    /// returns whether its alarm clears now.
    fn not_implicated(&mut self, recovered: bool, timing: AlarmTiming, now_ms: u64) -> bool {
        self.implicated_since_ms = None;
        self.cause = None;
        if self.raised.is_none() || !recovered {
            self.recovered_since_ms = None;
            return false;
        }
        let since_ms = *self.recovered_since_ms.get_or_insert(now_ms);
        if now_ms.saturating_sub(since_ms) >= timing.clear_after_ms {
            self.raised = None;
            return true;
        }
        false
    }
}

impl fmt::Display for AlarmSubject {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AlarmSubject::Network(network) => write!(f, "network {network}"),
            AlarmSubject::Transceiver {
                controller,
                network,
            } => write!(f, "controller {controller}'s transceiver on {network}"),
        }
    }
}

impl fmt::Display for AlarmCause {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AlarmCause::Concluded(finding) => write!(f, "{finding}"),
            AlarmCause::Suspected { alternatives } => {
                let verdict = Verdict::Explained {
                    certain: Vec::new(),
                    alternatives: alternatives.clone(),
                };
                write!(f, "suspected, {verdict}")
            }
            AlarmCause::Unexplained { failed } => {
                let verdict = Verdict::Unexplained {
                    failed: failed.clone(),
                };
                write!(f, "{verdict}")
            }
        }
    }
}
