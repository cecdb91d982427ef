//! The alarm book's hysteresis on literal timelines: which alarm changes come out, and when.
//! Raise after 500 ms (one deadline of the 250 ms period), clear after 1000 ms (4 periods) of
//! good links; the book is evaluated every 10 ms, as the monitor would at its wake-ups.

use super::*;

const TIMING: AlarmTiming = AlarmTiming {
    raise_after_ms: 500,
    clear_after_ms: 1000,
};
const STEP_MS: u64 = 10;
const OBSERVER: ControllerId = 1;

/// Runs the book from 0 to `until_ms` on the matrices `matrix_at` gives; returns its changes
/// with their instants.
fn run(
    until_ms: u64,
    members: Members,
    matrix_at: impl Fn(u64) -> LinkMatrix,
) -> Vec<(u64, AlarmChange)> {
    let mut book = AlarmBook::new();
    let mut changes = Vec::new();
    for now_ms in (0..=until_ms).step_by(STEP_MS as usize) {
        let conclusion = conclude(&matrix_at(now_ms), members, OBSERVER);
        changes.extend(
            book.update(&conclusion, TIMING, now_ms)
                .into_iter()
                .map(|c| (now_ms, c)),
        );
    }
    changes
}

/// The whole matrix with `truth` failed.
fn whole(truth: &[Fault]) -> LinkMatrix {
    seen(truth, Members::ALL, OBSERVER, View::Whole)
}

/// The whole matrix with `fault` failed while `on`.
fn whole_when(on: bool, fault: Fault) -> LinkMatrix {
    let truth = if on { vec![fault] } else { Vec::new() };
    whole(&truth)
}

fn raise(subject: AlarmSubject, cause: AlarmCause) -> AlarmChange {
    AlarmChange::Raise { subject, cause }
}

fn clear(subject: AlarmSubject) -> AlarmChange {
    AlarmChange::Clear { subject }
}

fn network_down(network: Network) -> AlarmCause {
    AlarmCause::Concluded(Finding::NetworkFailure(network))
}

#[test]
fn raised_after_one_deadline_cleared_after_four_good_periods() {
    let changes = run(6000, Members::ALL, |t| {
        whole_when((1000..3000).contains(&t), net(A))
    });
    assert_eq!(
        changes,
        [
            (1500, raise(AlarmSubject::Network(A), network_down(A))),
            (4000, clear(AlarmSubject::Network(A))),
        ]
    );
}

#[test]
fn drops_shorter_than_a_deadline_raise_nothing() {
    // Network B fails for 300 ms out of every 600 ms, for five seconds.
    let changes = run(8000, Members::ALL, |t| {
        let failing = (1000..6000).contains(&t) && (t - 1000) % 600 < 300;
        whole_when(failing, net(B))
    });
    assert_eq!(changes, []);
}

#[test]
fn a_flapping_network_raises_once_and_clears_once() {
    // Network B fails for 700 ms, comes back for 700 ms, ... from 1000 to 8000, then holds:
    // every failure outlasts the raise delay, no recovery lasts the clear delay.
    let changes = run(12_000, Members::ALL, |t| {
        let failing = (1000..8000).contains(&t) && (t - 1000) % 1400 < 700;
        whole_when(failing, net(B))
    });
    // The last failure spans 6600..7300; recovery from 7300 (the last fail is at 7290).
    assert_eq!(
        changes,
        [
            (1500, raise(AlarmSubject::Network(B), network_down(B))),
            (8300, clear(AlarmSubject::Network(B))),
        ]
    );
}

#[test]
fn a_controller_down_is_never_a_network_alarm() {
    let changes = run(6000, Members::ALL, |t| whole_when(t >= 1000, down(3)));
    assert_eq!(changes, []);
}

#[test]
fn a_monitor_hearing_nobody_alarms_nothing_it_cannot_tell_from_its_peers_down() {
    // Both networks dead, seen by a running monitor: its own row all Fail, no report arrives.
    // Both peers down looks the same, so the conclusion names the ambiguity and no alarm goes.
    let isolated = seen(&[net(A), net(B)], Members::ALL, OBSERVER, View::Monitor);
    let changes = run(3000, Members::ALL, |t| {
        if t >= 1000 {
            isolated
        } else {
            whole(&[])
        }
    });
    assert_eq!(changes, []);
    let conclusion = conclude(&isolated, Members::ALL, OBSERVER);
    let Verdict::Explained { alternatives, .. } = &conclusion.verdict else {
        panic!("{:?}", conclusion.verdict);
    };
    assert!(alternatives.contains(&vec![Finding::DoubleFault]));
}

#[test]
fn a_network_and_a_silent_peer_alarm_the_network_only() {
    // Network A dead and controller 3 down: 3's row never arrives, so "3's transmitter on B"
    // explains its silence as well as "3 down"; that part is left to the controller alarm.
    let changes = run(3000, Members::ALL, |t| {
        let truth = if t >= 1000 {
            vec![net(A), down(3)]
        } else {
            vec![]
        };
        seen(&truth, Members::ALL, OBSERVER, View::Monitor)
    });
    assert_eq!(
        changes,
        [(1500, raise(AlarmSubject::Network(A), network_down(A)))]
    );
}

#[test]
fn an_ambiguous_link_raises_both_suspects_with_the_alternatives() {
    let pair = Members::of(&[1, 2]);
    let changes = run(2000, pair, |t| {
        let truth = if t >= 1000 { vec![tx(2, B)] } else { vec![] };
        seen(&truth, pair, OBSERVER, View::Whole)
    });
    let cause = AlarmCause::Suspected {
        alternatives: vec![
            vec![port(2, B, Part::Transmitter)],
            vec![port(1, B, Part::Receiver)],
        ],
    };
    let suspect = |controller| AlarmSubject::Transceiver {
        controller,
        network: B,
    };
    assert_eq!(
        changes,
        [
            (1500, raise(suspect(1), cause.clone())),
            (1500, raise(suspect(2), cause))
        ]
    );
}

#[test]
fn a_refined_cause_is_republished_once_it_has_held() {
    // 2's transmitter on A fails at 1000, its receiver too at 2000: one alarm, updated.
    let changes = run(4000, Members::ALL, |t| {
        let truth = match t {
            0..=999 => vec![],
            1000..=1999 => vec![tx(2, A)],
            _ => vec![tx(2, A), rx(2, A)],
        };
        whole(&truth)
    });
    let subject = AlarmSubject::Transceiver {
        controller: 2,
        network: A,
    };
    assert_eq!(
        changes,
        [
            (
                1500,
                raise(
                    subject,
                    AlarmCause::Concluded(port(2, A, Part::Transmitter))
                )
            ),
            (
                2500,
                raise(subject, AlarmCause::Concluded(port(2, A, Part::Both)))
            ),
        ]
    );
}

#[test]
fn unknown_links_are_no_recovery() {
    // Network A fails 1000..3000; from 3000 to 5000 the peers' rows are stale (only the
    // monitor's own row is known, and Good); they are known Good again from 5000.
    let changes = run(7000, Members::ALL, |t| {
        if (3000..5000).contains(&t) {
            seen(&[], Members::ALL, OBSERVER, View::Whole).own_row_only(OBSERVER)
        } else {
            whole_when((1000..3000).contains(&t), net(A))
        }
    });
    assert_eq!(
        changes,
        [
            (1500, raise(AlarmSubject::Network(A), network_down(A))),
            (6000, clear(AlarmSubject::Network(A))),
        ]
    );
}

#[test]
fn a_controller_down_does_not_hold_a_network_alarm_up() {
    // Network A fails 1000..3000; controller 3 goes down at 2000 and stays down. Its links
    // never come back, but they say nothing of network A.
    let changes = run(6000, Members::ALL, |t| {
        let mut truth = Vec::new();
        if (1000..3000).contains(&t) {
            truth.push(net(A));
        }
        if t >= 2000 {
            truth.push(down(3));
        }
        whole(&truth)
    });
    assert_eq!(
        changes,
        [
            (1500, raise(AlarmSubject::Network(A), network_down(A))),
            (4000, clear(AlarmSubject::Network(A))),
        ]
    );
}

#[test]
fn the_book_says_when_it_is_next_due() {
    let mut book = AlarmBook::new();
    let failed = conclude(&whole(&[net(A)]), Members::ALL, OBSERVER);
    let healthy = conclude(&whole(&[]), Members::ALL, OBSERVER);
    assert_eq!(book.next_due_ms(TIMING, 0), None);
    assert_eq!(book.update(&failed, TIMING, 100), []);
    assert_eq!(book.next_due_ms(TIMING, 100), Some(600));
    assert_eq!(book.update(&failed, TIMING, 600).len(), 1);
    assert_eq!(book.next_due_ms(TIMING, 600), None);
    assert_eq!(book.update(&healthy, TIMING, 700), []);
    assert_eq!(book.next_due_ms(TIMING, 700), Some(1700));
    assert_eq!(book.raised().count(), 1);
    assert_eq!(book.update(&healthy, TIMING, 1700).len(), 1);
    assert_eq!(book.raised().count(), 0);
    assert_eq!(book.next_due_ms(TIMING, 1700), None);
}

#[test]
fn causes_read_as_alarm_text() {
    let suspected = AlarmCause::Suspected {
        alternatives: vec![vec![Finding::DoubleFault], vec![Finding::ControllerDown(2)]],
    };
    assert_eq!(
        suspected.to_string(),
        "suspected, one of: both networks failed | controller 2 down or cut off on both networks"
    );
    let subject = AlarmSubject::Transceiver {
        controller: 3,
        network: B,
    };
    assert_eq!(subject.to_string(), "controller 3's transceiver on B");
}

impl LinkMatrix {
    /// The same matrix with every row but `receiver`'s Unknown.
    fn own_row_only(mut self, receiver: ControllerId) -> LinkMatrix {
        for link in Link::all().filter(|l| l.to != receiver) {
            self.set(link, LinkState::Unknown);
        }
        self
    }
}
