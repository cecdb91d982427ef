//! Every fault combination, against a brute force that shares nothing with the search but the
//! `Fault` type.
//!
//! For each configuration (three controllers, or any pair), each monitoring controller, and
//! each set of peers whose rows are unknown to it (their reports stale), ALL 2^16 subsets of
//! the components (all but "the monitor is down": it is running) are taken as the truth. The
//! links they fail, as far as the monitor knows them, are concluded, and:
//! (a) every reported explanation fails exactly the observed links,
//! (b) no smaller set of components does (the brute force's minimum over all subsets),
//! (c) the true set is reported whenever it is of minimum size (and the search's bound allows),
//! and the reported explanations are exactly the brute force's minimum sets.
//! Observations whose minimum exceeds [`MAX_EXPLANATION_FAULTS`] must be Unexplained.

use super::*;
use std::collections::HashMap;

/// Whether `fault` lies on `link`'s path: the fault model restated from first principles.
fn on_path(fault: Fault, link: Link) -> bool {
    let same_network = |network: Network| network == link.network;
    match fault {
        Fault::Network(network) => same_network(network),
        Fault::Transmitter {
            controller,
            network,
        } => same_network(network) && link.from == controller,
        Fault::Receiver {
            controller,
            network,
        } => same_network(network) && link.to == controller,
        Fault::ControllerDown(controller) => controller == link.from || controller == link.to,
    }
}

/// The known links `faults` fail, as a bit mask over `known`'s positions.
fn observed(faults: &[Fault], known: &[Link]) -> u16 {
    known
        .iter()
        .enumerate()
        .filter(|(_, &link)| faults.iter().any(|&f| on_path(f, link)))
        .fold(0, |bits, (at, _)| bits | 1 << at)
}

/// The matrix with `known` links Fail where `bits` says and Good otherwise, the rest Unknown.
fn matrix_of(bits: u16, known: &[Link]) -> LinkMatrix {
    let mut matrix = LinkMatrix::unknown();
    for (at, &link) in known.iter().enumerate() {
        let state = if bits & 1 << at != 0 {
            LinkState::Fail
        } else {
            LinkState::Good
        };
        matrix.set(link, state);
    }
    matrix
}

/// Each true fault set with the observation (bit mask over the known links) it produces.
type Truths = Vec<(Vec<Fault>, u16)>;

/// Per observation: the minimum size of a fault set producing it, and every such set.
type Minimum = HashMap<u16, (usize, Vec<Vec<Fault>>)>;

/// What one case establishes, for the summary assertions.
#[derive(Default)]
struct Tally {
    truths: usize,
    observations: usize,
    largest_minimum: usize,
    unexplained: usize,
}

/// Every subset of `components` with the known links it fails, and for each such observation
/// the smallest subsets producing it (their size and the subsets).
fn brute_force(components: &[Fault], known: &[Link]) -> (Truths, Minimum) {
    let mut truths: Truths = Vec::with_capacity(1 << components.len());
    let mut minimum = Minimum::new();
    for subset in 0u32..1 << components.len() {
        let faults: Vec<Fault> = (0..components.len())
            .filter(|bit| subset & 1 << bit != 0)
            .map(|bit| components[bit])
            .collect();
        let bits = observed(&faults, known);
        let best = minimum.entry(bits).or_insert((usize::MAX, Vec::new()));
        if faults.len() < best.0 {
            *best = (faults.len(), Vec::new());
        }
        if faults.len() == best.0 {
            best.1.push(faults.clone());
        }
        truths.push((faults, bits));
    }
    (truths, minimum)
}

/// Checks (a), (b), (c) for one monitor and one set of unknown rows.
fn check_case(members: Members, observer: ControllerId, unknown_rows: &[ControllerId]) -> Tally {
    let components: Vec<Fault> = Fault::all()
        .into_iter()
        .filter(|f| f.controller().is_none_or(|id| members.contains(id)))
        .filter(|&f| f != down(observer))
        .collect();
    let known: Vec<Link> = LinkSet::among(members)
        .iter()
        .filter(|link| !unknown_rows.contains(&link.to))
        .collect();
    let (truths, minimum) = brute_force(&components, &known);
    let mut tally = Tally {
        truths: truths.len(),
        observations: minimum.len(),
        ..Tally::default()
    };
    let mut concluded: HashMap<u16, Conclusion> = HashMap::new();
    for (&bits, (size, smallest)) in &minimum {
        let conclusion = conclude(&matrix_of(bits, &known), members, observer);
        let case = format!("members {members:?}, observer {observer}, unknown rows {unknown_rows:?}, observed {bits:#06x}");
        tally.largest_minimum = tally.largest_minimum.max(*size);
        if *size > MAX_EXPLANATION_FAULTS {
            tally.unexplained += 1;
            assert!(
                conclusion.explanations.is_empty(),
                "{case}: {:?}",
                conclusion.explanations
            );
            assert!(
                matches!(conclusion.verdict, Verdict::Unexplained { .. }),
                "{case}"
            );
        } else {
            for explanation in &conclusion.explanations {
                assert_eq!(
                    observed(explanation, &known),
                    bits,
                    "(a) {case}: {explanation:?}"
                );
                assert_eq!(explanation.len(), *size, "(b) {case}: {explanation:?}");
            }
            let mut expected: Vec<Vec<Fault>> = smallest.clone();
            expected.iter_mut().for_each(|e| e.sort());
            expected.sort();
            assert_eq!(
                conclusion.explanations, expected,
                "{case}: not every minimum set"
            );
            let none_failed = bits == 0;
            assert_eq!(conclusion.verdict == Verdict::None, none_failed, "{case}");
        }
        concluded.insert(bits, conclusion);
    }
    for (truth, bits) in &truths {
        let size = minimum[bits].0;
        if truth.len() == size && size <= MAX_EXPLANATION_FAULTS {
            let mut truth = truth.clone();
            truth.sort();
            assert!(
                concluded[bits].explanations.contains(&truth),
                "(c) observer {observer}, unknown rows {unknown_rows:?}: {truth:?} missing"
            );
        }
    }
    tally
}

/// Every subset of the peers' rows unknown.
fn unknown_row_sets(members: Members, observer: ControllerId) -> Vec<Vec<ControllerId>> {
    let peers: Vec<ControllerId> = members.iter().filter(|&id| id != observer).collect();
    (0u32..1 << peers.len())
        .map(|mask| {
            (0..peers.len())
                .filter(|bit| mask & 1 << bit != 0)
                .map(|bit| peers[bit])
                .collect()
        })
        .collect()
}

#[test]
fn every_fault_combination_of_three_controllers() {
    let mut whole_view = Tally::default();
    for observer in 1..=3 {
        for unknown_rows in unknown_row_sets(Members::ALL, observer) {
            let tally = check_case(Members::ALL, observer, &unknown_rows);
            assert_eq!(tally.truths, 1 << 16);
            if unknown_rows.is_empty() {
                whole_view = tally;
            }
        }
    }
    // With every row known: 841 distinguishable patterns; up to six components are needed to
    // explain one (so the bound of four leaves some Unexplained, as documented).
    assert_eq!(whole_view.observations, 841);
    assert_eq!(whole_view.largest_minimum, 6);
    assert!(whole_view.unexplained > 0);
}

#[test]
fn every_fault_combination_of_each_pair() {
    for pair in [[1, 2], [1, 3], [2, 3]] {
        let members = Members::of(&pair);
        for observer in pair {
            for unknown_rows in unknown_row_sets(members, observer) {
                let tally = check_case(members, observer, &unknown_rows);
                // A pair: two networks, two transceivers each, the peer: 11 components.
                assert_eq!(tally.truths, 1 << 11);
                assert!(tally.largest_minimum <= MAX_EXPLANATION_FAULTS);
                assert_eq!(tally.unexplained, 0);
            }
        }
    }
}
