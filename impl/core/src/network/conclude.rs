//! The conclusion: which faults explain the links a monitor sees failed (the paper's table
//! "Detect Network Failures - Alarm and Clear", generalised to three controllers).
//!
//! The fault components, each failing exactly the links whose path crosses it:
//!
//! | component | fails |
//! |---|---|
//! | network N | every link on N |
//! | X's transmitter on N | X's links to its peers on N |
//! | X's receiver on N | its peers' links to X on N |
//! | controller X down | every link from or to X, on both networks |
//!
//! A pulled cable or a dead port is X's transmitter and receiver on N (two components). The
//! conclusion is every minimum-size set of components that fails exactly the links observed
//! Fail and none observed Good (Unknown links are ignored): the most specific explanation.
//! Several at that size are an ambiguity, reported as such (with two controllers, one failed
//! link is the sender's transmitter or the receiver's receiver: the paper's "eight scenarios").
//! The monitoring controller is running, so "it is down" is never an explanation.
//!
//! The search stops at [`MAX_EXPLANATION_FAULTS`] components; a pattern that needs more, or that
//! no set of components produces (one link lost one way while its ends talk to everybody
//! else), is [`Verdict::Unexplained`] and its failed links are reported as they are.

use super::links::{Link, LinkMatrix, LinkSet, LinkState, Members, Network, NAP_CONTROLLERS};
use crate::types::ControllerId;
use serde::{Deserialize, Serialize};
use std::fmt;

/// The largest explanation searched for. Four covers two pulled cables at once, or a pulled
/// cable plus a dead network and a controller down, and every row of the paper's table; the
/// ambiguity never grows past four alternatives up to here. Patterns whose smallest
/// explanation is larger (up to six components explain every producible pattern) are more
/// likely per-link losses outside the component model than five simultaneous component faults,
/// so they are reported as Unexplained. The search costs at most 2,517 subsets per evaluation.
pub const MAX_EXPLANATION_FAULTS: usize = 4;

/// One failed component.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Fault {
    /// A whole network.
    Network(Network),
    /// A controller's transmitter on one network.
    Transmitter {
        /// The controller.
        controller: ControllerId,
        /// The network.
        network: Network,
    },
    /// A controller's receiver on one network.
    Receiver {
        /// The controller.
        controller: ControllerId,
        /// The network.
        network: Network,
    },
    /// A controller down (or cut off on both networks: from outside the two look alike).
    ControllerDown(ControllerId),
}

impl Fault {
    /// Every component of three controllers on two networks (17).
    pub fn all() -> Vec<Fault> {
        let ids = 1..=NAP_CONTROLLERS as ControllerId;
        let mut faults: Vec<Fault> = Network::ALL.into_iter().map(Fault::Network).collect();
        for controller in ids.clone() {
            for network in Network::ALL {
                faults.push(Fault::Transmitter {
                    controller,
                    network,
                });
                faults.push(Fault::Receiver {
                    controller,
                    network,
                });
            }
        }
        faults.extend(ids.map(Fault::ControllerDown));
        faults
    }

    /// The controller it belongs to (`None` for a network).
    pub fn controller(self) -> Option<ControllerId> {
        match self {
            Fault::Network(_) => None,
            Fault::Transmitter { controller, .. }
            | Fault::Receiver { controller, .. }
            | Fault::ControllerDown(controller) => Some(controller),
        }
    }

    /// The links it fails.
    pub fn fails(self) -> LinkSet {
        LinkSet::filter(|link| self.cuts(link))
    }

    /// Whether it lies on `link`'s path.
    pub fn cuts(self, link: Link) -> bool {
        match self {
            Fault::Network(network) => link.network == network,
            Fault::Transmitter {
                controller,
                network,
            } => link.from == controller && link.network == network,
            Fault::Receiver {
                controller,
                network,
            } => link.to == controller && link.network == network,
            Fault::ControllerDown(controller) => link.from == controller || link.to == controller,
        }
    }
}

/// The links a set of faults fails together.
pub fn links_failed_by(faults: &[Fault]) -> LinkSet {
    faults
        .iter()
        .fold(LinkSet::EMPTY, |failed, fault| failed.union(fault.fails()))
}

/// Which part of a transceiver failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Part {
    /// Its transmitter: what it sends on the network is lost.
    Transmitter,
    /// Its receiver: it hears nobody on the network.
    Receiver,
    /// Both (a pulled cable, a dead port).
    Both,
}

/// A fault as reported: components grouped as a person names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Finding {
    /// One network failed.
    NetworkFailure(Network),
    /// Both networks failed.
    DoubleFault,
    /// One controller's transceiver on one network.
    Transceiver {
        /// The controller.
        controller: ControllerId,
        /// The network.
        network: Network,
        /// Which part.
        part: Part,
    },
    /// A controller is down or cut off on both networks: the controller alarm (RLCHB) covers
    /// it, so the network monitor reports it and never alarms it.
    ControllerDown(ControllerId),
}

/// Groups a set of faults into findings: both networks into a double fault, a transmitter and
/// receiver of one port into `Both`. The result is sorted.
pub fn findings(faults: &[Fault]) -> Vec<Finding> {
    let has = |fault: Fault| faults.contains(&fault);
    let mut out = Vec::new();
    if Network::ALL.iter().all(|&n| has(Fault::Network(n))) {
        out.push(Finding::DoubleFault);
    } else {
        out.extend(
            Network::ALL
                .into_iter()
                .filter(|&n| has(Fault::Network(n)))
                .map(Finding::NetworkFailure),
        );
    }
    for controller in 1..=NAP_CONTROLLERS as ControllerId {
        for network in Network::ALL {
            let tx = has(Fault::Transmitter {
                controller,
                network,
            });
            let rx = has(Fault::Receiver {
                controller,
                network,
            });
            let part = match (tx, rx) {
                (true, true) => Part::Both,
                (true, false) => Part::Transmitter,
                (false, true) => Part::Receiver,
                (false, false) => continue,
            };
            out.push(Finding::Transceiver {
                controller,
                network,
                part,
            });
        }
        if has(Fault::ControllerDown(controller)) {
            out.push(Finding::ControllerDown(controller));
        }
    }
    out.sort();
    out
}

/// The conclusion in the paper's terms.
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// No link is observed failed.
    None,
    /// The failed links are explained. `certain` holds in every minimum explanation; when
    /// there are several, `alternatives` lists what each adds to `certain` (otherwise empty).
    Explained {
        /// Findings every minimum explanation shares.
        certain: Vec<Finding>,
        /// The rest of each minimum explanation, when there are several.
        alternatives: Vec<Vec<Finding>>,
    },
    /// No set of at most [`MAX_EXPLANATION_FAULTS`] components fails exactly these links.
    Unexplained {
        /// The links observed failed.
        failed: Vec<Link>,
    },
}

/// What one evaluation concluded, with what it was concluded from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Conclusion {
    /// The links between members (the others do not exist in this configuration).
    pub scope: LinkSet,
    /// Links observed Good.
    pub good: LinkSet,
    /// Links observed Fail.
    pub failed: LinkSet,
    /// Every minimum explanation, each sorted; empty when unexplained, one empty set when
    /// nothing failed.
    pub explanations: Vec<Vec<Fault>>,
    /// The same in the paper's terms.
    pub verdict: Verdict,
}

impl Conclusion {
    /// The faults in every minimum explanation (none when unexplained).
    pub fn certain_faults(&self) -> Vec<Fault> {
        shared(&self.explanations)
    }

    /// Controllers down in every minimum explanation: their links say nothing of the networks.
    pub fn certainly_down(&self) -> Vec<ControllerId> {
        self.certain_faults()
            .into_iter()
            .filter_map(|fault| match fault {
                Fault::ControllerDown(id) => Some(id),
                _ => None,
            })
            .collect()
    }
}

/// Concludes from `matrix` as seen by `observer` (a running member) in a configuration of
/// `members`: the minimum sets of components that fail exactly the links observed Fail.
pub fn conclude(matrix: &LinkMatrix, members: Members, observer: ControllerId) -> Conclusion {
    let scope = LinkSet::among(members);
    let good = matrix.links_in(LinkState::Good).intersection(scope);
    let failed = matrix.links_in(LinkState::Fail).intersection(scope);
    // A component that fails a link seen Good is in no consistent explanation; one that fails
    // no known link is in no minimum one. The rest fail only links seen Fail, so a set of them
    // is consistent exactly when together they fail all of those.
    let known = good.union(failed);
    let candidates: Vec<(Fault, LinkSet)> = Fault::all()
        .into_iter()
        .filter(|fault| fault.controller().is_none_or(|id| members.contains(id)))
        .filter(|&fault| fault != Fault::ControllerDown(observer))
        .map(|fault| (fault, fault.fails().intersection(known)))
        .filter(|&(_, fails)| !fails.is_empty() && fails.is_subset(failed))
        .collect();
    let mut explanations = (0..=MAX_EXPLANATION_FAULTS)
        .map(|size| covers_of_size(&candidates, failed, size))
        .find(|found| !found.is_empty())
        .unwrap_or_default();
    // Canonical order, so an unchanged conclusion compares equal (alarm causes rely on it).
    for explanation in &mut explanations {
        explanation.sort();
    }
    explanations.sort();
    let verdict = verdict_of(failed, &explanations);
    Conclusion {
        scope,
        good,
        failed,
        explanations,
        verdict,
    }
}

/// Every `size`-subset of `candidates` whose union is exactly `target`, in candidate order.
fn covers_of_size(
    candidates: &[(Fault, LinkSet)],
    target: LinkSet,
    size: usize,
) -> Vec<Vec<Fault>> {
    let mut found = Vec::new();
    let mut chosen = Vec::with_capacity(size);
    extend_cover(
        candidates,
        target,
        size,
        LinkSet::EMPTY,
        &mut chosen,
        &mut found,
    );
    found
}

/// Depth-first choice of the remaining components from `candidates` (in order, so every
/// subset is visited once).
fn extend_cover(
    candidates: &[(Fault, LinkSet)],
    target: LinkSet,
    size: usize,
    covered: LinkSet,
    chosen: &mut Vec<Fault>,
    found: &mut Vec<Vec<Fault>>,
) {
    if chosen.len() == size {
        if covered == target {
            found.push(chosen.clone());
        }
        return;
    }
    let still_needed = size - chosen.len();
    for (at, &(fault, fails)) in candidates.iter().enumerate() {
        if candidates.len() - at < still_needed {
            break;
        }
        chosen.push(fault);
        extend_cover(
            &candidates[at + 1..],
            target,
            size,
            covered.union(fails),
            chosen,
            found,
        );
        chosen.pop();
    }
}

/// The faults every explanation holds (none when there is none).
fn shared(explanations: &[Vec<Fault>]) -> Vec<Fault> {
    let Some((first, rest)) = explanations.split_first() else {
        return Vec::new();
    };
    first
        .iter()
        .copied()
        .filter(|fault| rest.iter().all(|e| e.contains(fault)))
        .collect()
}

/// The verdict of a set of minimum explanations.
fn verdict_of(failed: LinkSet, explanations: &[Vec<Fault>]) -> Verdict {
    if failed.is_empty() {
        return Verdict::None;
    }
    if explanations.is_empty() {
        return Verdict::Unexplained {
            failed: failed.iter().collect(),
        };
    }
    let certain = shared(explanations);
    let alternatives = if explanations.len() > 1 {
        explanations
            .iter()
            .map(|e| {
                let rest: Vec<Fault> = e.iter().copied().filter(|f| !certain.contains(f)).collect();
                findings(&rest)
            })
            .collect()
    } else {
        Vec::new()
    };
    Verdict::Explained {
        certain: findings(&certain),
        alternatives,
    }
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Finding::NetworkFailure(network) => write!(f, "network {network} failed"),
            Finding::DoubleFault => f.write_str("both networks failed"),
            Finding::Transceiver {
                controller,
                network,
                part,
            } => {
                let part = match part {
                    Part::Transmitter => "transmitter",
                    Part::Receiver => "receiver",
                    Part::Both => "transmitter and receiver",
                };
                write!(f, "controller {controller}'s {part} on {network}")
            }
            Finding::ControllerDown(id) => {
                write!(f, "controller {id} down or cut off on both networks")
            }
        }
    }
}

/// `a, b` (or `-` for none).
fn write_list<T: fmt::Display>(f: &mut fmt::Formatter<'_>, items: &[T]) -> fmt::Result {
    if items.is_empty() {
        return f.write_str("-");
    }
    for (at, item) in items.iter().enumerate() {
        if at > 0 {
            f.write_str(", ")?;
        }
        write!(f, "{item}")?;
    }
    Ok(())
}

impl fmt::Display for Verdict {
    /// `none`, `network A failed`, `controller 1 down ...; one of: a | b`, `unexplained: ...`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Verdict::None => f.write_str("none"),
            Verdict::Explained {
                certain,
                alternatives,
            } => {
                if !certain.is_empty() || alternatives.is_empty() {
                    write_list(f, certain)?;
                }
                if !alternatives.is_empty() {
                    if !certain.is_empty() {
                        f.write_str("; and ")?;
                    }
                    f.write_str("one of: ")?;
                    for (at, alternative) in alternatives.iter().enumerate() {
                        if at > 0 {
                            f.write_str(" | ")?;
                        }
                        write_list(f, alternative)?;
                    }
                }
                Ok(())
            }
            Verdict::Unexplained { failed } => {
                f.write_str("unexplained failed links: ")?;
                write_list(f, failed)
            }
        }
    }
}
