//! Tests of the network monitor: the paper's table and its generalisation row by row
//! (`table`), every fault combination against a brute force (`exhaustive`), the alarms'
//! hysteresis (`alarms`), and whole monitors exchanging heartbeats over faulty networks
//! (`nap`). Shared here: fault shorthands and the two ways a monitor can see a fault set.

use super::*;
use crate::types::ControllerId;

mod alarms;
mod exhaustive;
mod nap;
mod table;

const A: Network = Network::A;
const B: Network = Network::B;

fn net(network: Network) -> Fault {
    Fault::Network(network)
}

fn tx(controller: ControllerId, network: Network) -> Fault {
    Fault::Transmitter {
        controller,
        network,
    }
}

fn rx(controller: ControllerId, network: Network) -> Fault {
    Fault::Receiver {
        controller,
        network,
    }
}

fn down(controller: ControllerId) -> Fault {
    Fault::ControllerDown(controller)
}

fn port(controller: ControllerId, network: Network, part: Part) -> Finding {
    Finding::Transceiver {
        controller,
        network,
        part,
    }
}

/// How much of the matrix the monitor knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum View {
    /// Every link's true state (the paper's table: every column filled in).
    Whole,
    /// What a running monitor really knows: its own row, and the row of each peer that is up
    /// and whose heartbeat reaches it on at least one network; the rest Unknown.
    Monitor,
}

/// The matrix `observer` sees when `truth` has failed, among `members`.
fn seen(truth: &[Fault], members: Members, observer: ControllerId, view: View) -> LinkMatrix {
    let failed = links_failed_by(truth);
    let reaches_observer = |receiver: ControllerId| {
        receiver == observer
            || Network::ALL
                .iter()
                .any(|&n| !failed.contains(Link::new(receiver, observer, n)))
    };
    let mut matrix = LinkMatrix::unknown();
    for link in LinkSet::among(members).iter() {
        if view == View::Whole || reaches_observer(link.to) {
            matrix.set(link, LinkState::known(failed.contains(link)));
        }
    }
    matrix
}

/// A verdict with its alternatives in a fixed order, to compare regardless of search order.
fn normalized(verdict: Verdict) -> Verdict {
    match verdict {
        Verdict::Explained {
            mut certain,
            mut alternatives,
        } => {
            certain.sort();
            alternatives.iter_mut().for_each(|a| a.sort());
            alternatives.sort();
            Verdict::Explained {
                certain,
                alternatives,
            }
        }
        other => other,
    }
}

/// `Explained` from literal findings.
fn explained(certain: &[Finding], alternatives: &[&[Finding]]) -> Verdict {
    normalized(Verdict::Explained {
        certain: certain.to_vec(),
        alternatives: alternatives.iter().map(|a| a.to_vec()).collect(),
    })
}
