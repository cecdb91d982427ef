//! The paper's table "Detect Network Failures - Alarm and Clear", row by row, and its
//! generalisation to three controllers.
//!
//! The paper's columns are one like pair's heartbeats per network: "P-N1 Good" = P's RLNHB is
//! received (by S) on N1, i.e. link P->S on A. Here P = 1, S = 2, N1 = A, N2 = B. Each row is
//! checked from both ends of the pair and in both views: the whole matrix (every column of the
//! table filled in) and what a running monitor really knows (peers' rows only while their
//! heartbeats reach it). The two-controller table is run twice: as a duplex configuration
//! (members 1 and 2) and as three controllers with controller 3 down.

use super::*;

const PAIR: [ControllerId; 2] = [1, 2];
const VIEWS: [View; 2] = [View::Whole, View::Monitor];

fn duplex() -> Members {
    Members::of(&PAIR)
}

fn the_other(pair: [ControllerId; 2], id: ControllerId) -> ControllerId {
    if pair[0] == id {
        pair[1]
    } else {
        pair[0]
    }
}

/// The other two of three.
fn others(id: ControllerId) -> [ControllerId; 2] {
    match id {
        1 => [2, 3],
        2 => [1, 3],
        _ => [1, 2],
    }
}

/// Asserts what `observer` concludes in `view` when `truth` failed.
#[track_caller]
fn check(
    row: &str,
    members: Members,
    observer: ControllerId,
    view: View,
    truth: &[Fault],
    expected: &Verdict,
) {
    let matrix = seen(truth, members, observer, view);
    let conclusion = conclude(&matrix, members, observer);
    assert_eq!(
        normalized(conclusion.verdict.clone()),
        normalized(expected.clone()),
        "{row}: observer {observer}, {view:?} view, truth {truth:?}: concluded {}",
        conclusion.verdict
    );
}

#[test]
fn paper_row_1_all_good_is_no_fault() {
    for observer in PAIR {
        for view in VIEWS {
            check("row 1", duplex(), observer, view, &[], &Verdict::None);
        }
    }
}

/// Row 2 and its footnote: a single failed column is the sender's transmitter or the
/// receiver's receiver. Four links times two causes: the eight scenarios the paper leaves out.
#[test]
fn paper_row_2_one_failed_link_is_sender_transmitter_or_receiver_receiver() {
    for link in LinkSet::among(duplex()).iter() {
        let expected = explained(
            &[],
            &[
                &[port(link.from, link.network, Part::Transmitter)],
                &[port(link.to, link.network, Part::Receiver)],
            ],
        );
        for truth in [tx(link.from, link.network), rx(link.to, link.network)] {
            for observer in PAIR {
                for view in VIEWS {
                    check("row 2", duplex(), observer, view, &[truth], &expected);
                }
            }
        }
    }
}

/// Rows 3 and 4 (one pair's four columns failed): "either P or S down" - never the monitor
/// itself, which is running, so it is the other one: a controller alarm, not a network alarm.
#[test]
fn paper_rows_3_and_4_all_of_a_pair_failed_is_the_peer_down() {
    for observer in PAIR {
        let peer = the_other(PAIR, observer);
        let expected = explained(&[Finding::ControllerDown(peer)], &[]);
        for view in VIEWS {
            check("row 3", duplex(), observer, view, &[down(peer)], &expected);
        }
    }
}

#[test]
fn paper_rows_5_and_6_one_network_failed() {
    for network in Network::ALL {
        let expected = explained(&[Finding::NetworkFailure(network)], &[]);
        for observer in PAIR {
            for view in VIEWS {
                check(
                    "rows 5/6",
                    duplex(),
                    observer,
                    view,
                    &[net(network)],
                    &expected,
                );
            }
        }
    }
}

/// Row 7: the paper tells a double fault from row 3 only by the *other* pair's columns
/// failing too. Within one pair every link to the peer is lost either way, so the smallest
/// explanation is the peer down (one fault, not two): no network alarm from a lone pair.
#[test]
fn paper_row_7_double_fault_within_one_pair_looks_like_the_peer_down() {
    for observer in PAIR {
        let peer = the_other(PAIR, observer);
        let expected = explained(&[Finding::ControllerDown(peer)], &[]);
        for view in VIEWS {
            check(
                "row 7",
                duplex(),
                observer,
                view,
                &[net(A), net(B)],
                &expected,
            );
        }
    }
}

/// The same table with three controllers configured and controller 3 down: every row keeps
/// its finding and adds "3 down", except where 3's silence leaves a real ambiguity (its row is
/// unknown to a running monitor, so "3's transmitter on B" explains its silence as well as
/// "3 down" once A is dead).
#[test]
fn paper_table_with_controller_3_down() {
    let all = Members::ALL;
    let down3 = Finding::ControllerDown(3);
    for observer in PAIR {
        let peer = the_other(PAIR, observer);
        for view in VIEWS {
            check(
                "row 1 + 3 down",
                all,
                observer,
                view,
                &[down(3)],
                &explained(&[down3], &[]),
            );
            for link in LinkSet::among(duplex()).iter() {
                let expected = explained(
                    &[down3],
                    &[
                        &[port(link.from, link.network, Part::Transmitter)],
                        &[port(link.to, link.network, Part::Receiver)],
                    ],
                );
                let truth = [down(3), tx(link.from, link.network)];
                check("row 2 + 3 down", all, observer, view, &truth, &expected);
            }
            for network in Network::ALL {
                let failure = Finding::NetworkFailure(network);
                let expected = match view {
                    View::Whole => explained(&[failure, down3], &[]),
                    View::Monitor => explained(
                        &[failure],
                        &[&[down3], &[port(3, network.other(), Part::Transmitter)]],
                    ),
                };
                check(
                    "rows 5/6 + 3 down",
                    all,
                    observer,
                    view,
                    &[down(3), net(network)],
                    &expected,
                );
            }
            // Rows 3 and 7 with 3 down: the monitor hears nobody at all.
            let isolated = match view {
                View::Whole => explained(
                    &[],
                    &[
                        &[Finding::DoubleFault],
                        &[Finding::ControllerDown(peer), down3],
                    ],
                ),
                View::Monitor => isolated_monitor(observer),
            };
            check(
                "row 3 + 3 down",
                all,
                observer,
                view,
                &[down(3), down(peer)],
                &isolated,
            );
            check(
                "row 7 + 3 down",
                all,
                observer,
                view,
                &[down(3), net(A), net(B)],
                &isolated,
            );
        }
    }
}

/// What a monitor that hears nobody on either network concludes: both networks, its own two
/// receivers, one network and the other receiver, or both peers down.
fn isolated_monitor(observer: ControllerId) -> Verdict {
    let [p, q] = others(observer);
    let deaf_a = port(observer, A, Part::Receiver);
    let deaf_b = port(observer, B, Part::Receiver);
    explained(
        &[],
        &[
            &[Finding::DoubleFault],
            &[deaf_a, deaf_b],
            &[Finding::NetworkFailure(A), deaf_b],
            &[Finding::NetworkFailure(B), deaf_a],
            &[Finding::ControllerDown(p), Finding::ControllerDown(q)],
        ],
    )
}

/// With three controllers a single transceiver fault is unambiguous: a transmitter fails both
/// of its outgoing links, a receiver both incoming ones.
#[test]
fn three_controllers_every_single_transceiver_fault() {
    for observer in 1..=3 {
        for controller in 1..=3 {
            for network in Network::ALL {
                let parts = [
                    (Part::Transmitter, vec![tx(controller, network)]),
                    (Part::Receiver, vec![rx(controller, network)]),
                    (
                        Part::Both,
                        vec![tx(controller, network), rx(controller, network)],
                    ),
                ];
                for (part, truth) in parts {
                    let expected = explained(&[port(controller, network, part)], &[]);
                    for view in VIEWS {
                        check(
                            "transceiver",
                            Members::ALL,
                            observer,
                            view,
                            &truth,
                            &expected,
                        );
                    }
                }
            }
        }
    }
}

#[test]
fn three_controllers_networks_and_controllers_down() {
    for observer in 1..=3 {
        let [p, q] = others(observer);
        for view in VIEWS {
            for network in Network::ALL {
                let expected = explained(&[Finding::NetworkFailure(network)], &[]);
                check(
                    "network",
                    Members::ALL,
                    observer,
                    view,
                    &[net(network)],
                    &expected,
                );
            }
            for peer in [p, q] {
                let expected = explained(&[Finding::ControllerDown(peer)], &[]);
                check(
                    "down",
                    Members::ALL,
                    observer,
                    view,
                    &[down(peer)],
                    &expected,
                );
            }
            let double = match view {
                View::Whole => explained(
                    &[],
                    &[
                        &[Finding::DoubleFault],
                        &[Finding::ControllerDown(p), Finding::ControllerDown(q)],
                    ],
                ),
                View::Monitor => isolated_monitor(observer),
            };
            check(
                "double fault",
                Members::ALL,
                observer,
                view,
                &[net(A), net(B)],
                &double,
            );
        }
    }
}

#[test]
fn three_controllers_combinations() {
    for observer in 1..=3 {
        for peer in others(observer) {
            for network in Network::ALL {
                let failure = Finding::NetworkFailure(network);
                let silent_tx = port(peer, network.other(), Part::Transmitter);
                // A network and a controller down: a running monitor cannot tell "down" from
                // "its transmitter on the other network", since the peer's row never arrives.
                let truths = [
                    vec![net(network), down(peer)],
                    vec![net(network), tx(peer, network.other())],
                ];
                for truth in truths {
                    let monitor = explained(
                        &[failure],
                        &[&[Finding::ControllerDown(peer)], &[silent_tx]],
                    );
                    check(
                        "net + silent peer",
                        Members::ALL,
                        observer,
                        View::Monitor,
                        &truth,
                        &monitor,
                    );
                }
                let whole = explained(&[failure, Finding::ControllerDown(peer)], &[]);
                let truth = [net(network), down(peer)];
                check(
                    "net + down",
                    Members::ALL,
                    observer,
                    View::Whole,
                    &truth,
                    &whole,
                );
                // A network and a receiver on the other: the peer still talks, so it is known.
                let deaf = port(peer, network.other(), Part::Receiver);
                let truth = [net(network), rx(peer, network.other())];
                for view in VIEWS {
                    check(
                        "net + rx",
                        Members::ALL,
                        observer,
                        view,
                        &truth,
                        &explained(&[failure, deaf], &[]),
                    );
                }
            }
            // Deaf on both networks: its reports still arrive and say so.
            let truth = [rx(peer, A), rx(peer, B)];
            let expected = explained(
                &[port(peer, A, Part::Receiver), port(peer, B, Part::Receiver)],
                &[],
            );
            for view in VIEWS {
                check("deaf", Members::ALL, observer, view, &truth, &expected);
            }
        }
    }
}

/// One link lost one way while both ends hear and reach everybody else: no component lies on
/// that path alone, so it is reported as it is.
#[test]
fn a_single_one_way_loss_among_three_is_unexplained() {
    for link in Link::all() {
        let matrix = LinkMatrix::with_failed(LinkSet::EMPTY.with(link));
        for observer in 1..=3 {
            let conclusion = conclude(&matrix, Members::ALL, observer);
            assert_eq!(
                conclusion.verdict,
                Verdict::Unexplained { failed: vec![link] },
                "{link} seen by {observer}"
            );
            assert!(conclusion.explanations.is_empty());
        }
    }
}

/// Links and components of a controller outside the configuration play no part.
#[test]
fn a_non_member_is_outside_the_conclusion() {
    let mut matrix = LinkMatrix::with_failed(LinkSet::touching(3));
    let conclusion = conclude(&matrix, duplex(), 1);
    assert_eq!(conclusion.verdict, Verdict::None);
    matrix.set(Link::new(2, 1, A), LinkState::Fail);
    matrix.set(Link::new(1, 2, A), LinkState::Fail);
    let conclusion = conclude(&matrix, duplex(), 1);
    assert_eq!(
        conclusion.verdict,
        explained(&[Finding::NetworkFailure(A)], &[])
    );
}

#[test]
fn verdicts_read_as_the_table_does() {
    let ambiguous = explained(
        &[Finding::ControllerDown(3)],
        &[
            &[port(1, B, Part::Transmitter)],
            &[port(2, B, Part::Receiver)],
        ],
    );
    assert_eq!(
        ambiguous.to_string(),
        "controller 3 down or cut off on both networks; and one of: \
         controller 1's transmitter on B | controller 2's receiver on B"
    );
    assert_eq!(
        explained(&[Finding::DoubleFault, port(2, A, Part::Both)], &[]).to_string(),
        "both networks failed, controller 2's transmitter and receiver on A"
    );
    assert_eq!(Verdict::None.to_string(), "none");
    let lost = Verdict::Unexplained {
        failed: vec![Link::new(1, 2, A)],
    };
    assert_eq!(lost.to_string(), "unexplained failed links: 1->2 on A");
}
