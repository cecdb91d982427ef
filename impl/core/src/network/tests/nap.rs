//! Whole monitors: three participants exchange heartbeats through a network whose faults the
//! test switches on and off, each stepped only at the instant it asks for
//! ([`Nap::next_deadline`]), so late wake-ups show as late alarms. Delivery is instant; the
//! participants start out of phase (0, 70, 160 ms).

use super::*;

/// One alarm command a participant gave, with when and who.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Logged {
    at_ms: u64,
    by: ControllerId,
    command: NapCommand,
}

/// Steps every timer due at `now_ms` (none due: nothing happens), as the monitor's thread
/// does.
fn tick(nap: &mut Nap, now_ms: u64) -> Vec<NapCommand> {
    let mut commands = Vec::new();
    while let Some(timer) = nap.due_timer(now_ms) {
        commands.extend(nap.step(NapInput::Timer(timer), now_ms));
    }
    commands
}

struct Lab {
    naps: Vec<Nap>,
    wake_ms: Vec<u64>,
    now_ms: u64,
    alarms: Vec<Logged>,
}

impl Lab {
    fn new(members: Members) -> Lab {
        let naps: Vec<Nap> = members
            .iter()
            .map(|id| {
                let config = NapConfig {
                    members,
                    ..NapConfig::new(id)
                };
                Nap::new(config, start_ms(id))
            })
            .collect();
        let wake_ms = members.iter().map(start_ms).collect();
        Lab {
            naps,
            wake_ms,
            now_ms: 0,
            alarms: Vec::new(),
        }
    }

    fn id(&self, at: usize) -> ControllerId {
        self.naps[at].config().id
    }

    /// Runs to `until_ms` with `faults_at` in force (controllers down there are not run).
    fn run(&mut self, until_ms: u64, faults_at: impl Fn(u64) -> Vec<Fault>) {
        while self.now_ms < until_ms {
            let now_ms = self.now_ms;
            let faults = faults_at(now_ms);
            for at in 0..self.naps.len() {
                let id = self.id(at);
                if faults.contains(&down(id)) || now_ms < self.wake_ms[at] {
                    continue;
                }
                let commands = tick(&mut self.naps[at], now_ms);
                self.perform(at, commands, &faults);
            }
            self.now_ms += 1;
        }
    }

    /// Delivers heartbeats along working paths, logs alarm commands, reschedules.
    fn perform(&mut self, at: usize, commands: Vec<NapCommand>, faults: &[Fault]) {
        let (now_ms, by) = (self.now_ms, self.id(at));
        self.wake_ms[at] = self.naps[at].next_deadline().at_ms;
        for command in commands {
            let NapCommand::PublishHeartbeat { network, heartbeat } = command else {
                self.alarms.push(Logged {
                    at_ms: now_ms,
                    by,
                    command,
                });
                continue;
            };
            for to in 0..self.naps.len() {
                let link = Link::new(by, self.id(to), network);
                if to == at || faults.iter().any(|f| f.cuts(link)) {
                    continue;
                }
                let input = NapInput::Heartbeat {
                    received_on: network,
                    heartbeat,
                };
                let replies = self.naps[to].step(input, now_ms);
                self.perform(to, replies, faults);
            }
        }
    }

    /// The alarm commands `id` gave.
    fn alarms_of(&self, id: ControllerId) -> Vec<(u64, NapCommand)> {
        self.alarms
            .iter()
            .filter(|l| l.by == id)
            .map(|l| (l.at_ms, l.command.clone()))
            .collect()
    }
}

fn start_ms(id: ControllerId) -> u64 {
    match id {
        1 => 0,
        2 => 70,
        _ => 160,
    }
}

fn always(faults: Vec<Fault>) -> impl Fn(u64) -> Vec<Fault> {
    move |_| faults.clone()
}

/// `fault` in force during `from_ms..until_ms`.
fn during(fault: Fault, from_ms: u64, until_ms: u64) -> impl Fn(u64) -> Vec<Fault> {
    move |t| {
        if (from_ms..until_ms).contains(&t) {
            vec![fault]
        } else {
            Vec::new()
        }
    }
}

/// Asserts `id` raised `subject` once with `cause` within `raise_window` and cleared it once
/// within `clear_window` (if given), and gave no other alarm command.
#[track_caller]
fn assert_one_alarm(
    lab: &Lab,
    id: ControllerId,
    subject: AlarmSubject,
    cause: AlarmCause,
    raise_window: std::ops::RangeInclusive<u64>,
    clear_window: Option<std::ops::RangeInclusive<u64>>,
) {
    let alarms = lab.alarms_of(id);
    let expected_len = 1 + usize::from(clear_window.is_some());
    assert_eq!(alarms.len(), expected_len, "controller {id}: {alarms:?}");
    let (raised_ms, raised) = &alarms[0];
    assert_eq!(
        raised,
        &NapCommand::RaiseAlarm { subject, cause },
        "controller {id}"
    );
    assert!(
        raise_window.contains(raised_ms),
        "controller {id} raised at {raised_ms}"
    );
    if let Some(window) = clear_window {
        let (cleared_ms, cleared) = &alarms[1];
        assert_eq!(
            cleared,
            &NapCommand::ClearAlarm { subject },
            "controller {id}"
        );
        assert!(
            window.contains(cleared_ms),
            "controller {id} cleared at {cleared_ms}"
        );
    }
}

#[test]
fn healthy_networks_raise_nothing_and_conclude_none() {
    let mut lab = Lab::new(Members::ALL);
    lab.run(5000, always(Vec::new()));
    assert_eq!(lab.alarms, []);
    for nap in &lab.naps {
        assert_eq!(nap.conclusion().verdict, Verdict::None);
        let known = nap.matrix(lab.now_ms).links_in(LinkState::Good);
        assert_eq!(known, LinkSet::among(Members::ALL), "every link Good");
    }
}

/// Network A fails at 5000 and returns at 10000. Every link on A misses its deadline within
/// (5250, 5500], the reports say so at once, then the conclusion holds 375 ms: raised within
/// (5625, 5875], inside two deadlines. Back: links and reports are Good within two periods, then four
/// good periods: cleared between 11000 and 11500. Nothing else, by anybody.
#[test]
fn a_network_failure_is_raised_and_cleared_once_by_every_monitor() {
    let mut lab = Lab::new(Members::ALL);
    lab.run(14_000, during(net(A), 5000, 10_000));
    for id in 1..=3 {
        assert_one_alarm(
            &lab,
            id,
            AlarmSubject::Network(A),
            AlarmCause::Concluded(Finding::NetworkFailure(A)),
            5625..=5875,
            Some(11_000..=11_500),
        );
    }
}

#[test]
fn a_dead_transmitter_is_named_by_every_monitor_including_its_own() {
    let mut lab = Lab::new(Members::ALL);
    lab.run(9000, during(tx(2, B), 3000, 6000));
    let subject = AlarmSubject::Transceiver {
        controller: 2,
        network: B,
    };
    let cause = AlarmCause::Concluded(port(2, B, Part::Transmitter));
    for id in 1..=3 {
        assert_one_alarm(
            &lab,
            id,
            subject,
            cause.clone(),
            3625..=3875,
            Some(7000..=7500),
        );
    }
}

#[test]
fn a_controller_down_is_concluded_but_not_alarmed() {
    let mut lab = Lab::new(Members::ALL);
    lab.run(6000, |t| if t >= 2000 { vec![down(3)] } else { Vec::new() });
    assert_eq!(lab.alarms, []);
    for at in 0..2 {
        let verdict = &lab.naps[at].conclusion().verdict;
        assert_eq!(verdict, &explained(&[Finding::ControllerDown(3)], &[]));
    }
}

#[test]
fn a_double_fault_is_concluded_as_an_ambiguity_and_not_alarmed() {
    let mut lab = Lab::new(Members::ALL);
    lab.run(6000, |t| {
        if t >= 2000 {
            vec![net(A), net(B)]
        } else {
            Vec::new()
        }
    });
    assert_eq!(lab.alarms, []);
    for nap in &lab.naps {
        let Verdict::Explained { alternatives, .. } = &nap.conclusion().verdict else {
            panic!("{:?}", nap.conclusion().verdict);
        };
        assert!(alternatives.contains(&vec![Finding::DoubleFault]));
        assert_eq!(alternatives.len(), 5, "{alternatives:?}");
    }
}

#[test]
fn a_network_failure_with_a_controller_down_alarms_the_network() {
    let mut lab = Lab::new(Members::ALL);
    lab.run(6000, |t| match t {
        0..=1999 => Vec::new(),
        2000..=2999 => vec![down(3)],
        _ => vec![down(3), net(A)],
    });
    let cause = AlarmCause::Concluded(Finding::NetworkFailure(A));
    for id in 1..=2 {
        assert_one_alarm(
            &lab,
            id,
            AlarmSubject::Network(A),
            cause.clone(),
            3625..=3875,
            None,
        );
    }
    assert_eq!(lab.alarms_of(3), []);
}

#[test]
fn a_flapping_network_makes_no_storm() {
    // Short drops (300 ms of every 600 ms): the deadline absorbs most, none lasts to a raise.
    let mut lab = Lab::new(Members::ALL);
    lab.run(12_000, |t| {
        let dropping = (2000..8000).contains(&t) && (t - 2000) % 600 < 300;
        if dropping {
            vec![net(B)]
        } else {
            Vec::new()
        }
    });
    assert_eq!(lab.alarms, []);
    // Long drops (1500 ms down, 500 ms up): raised once, held through the flapping, cleared
    // once after the network holds.
    let mut lab = Lab::new(Members::ALL);
    lab.run(16_000, |t| {
        let dropping = (2000..10_000).contains(&t) && (t - 2000) % 2000 < 1500;
        if dropping {
            vec![net(B)]
        } else {
            Vec::new()
        }
    });
    let cause = AlarmCause::Concluded(Finding::NetworkFailure(B));
    for id in 1..=3 {
        // The last drop ends at 9500.
        let window = Some(10_500..=11_000);
        assert_one_alarm(
            &lab,
            id,
            AlarmSubject::Network(B),
            cause.clone(),
            2625..=2875,
            window,
        );
    }
}

#[test]
fn a_duplex_pair_alarms_a_network_and_reports_its_peer_down() {
    let pair = Members::of(&[1, 2]);
    let mut lab = Lab::new(pair);
    lab.run(8000, during(net(B), 2000, 5000));
    let cause = AlarmCause::Concluded(Finding::NetworkFailure(B));
    for id in 1..=2 {
        assert_one_alarm(
            &lab,
            id,
            AlarmSubject::Network(B),
            cause.clone(),
            2625..=2875,
            Some(6000..=6500),
        );
    }
    let mut lab = Lab::new(pair);
    lab.run(5000, |t| if t >= 2000 { vec![down(2)] } else { Vec::new() });
    assert_eq!(lab.alarms, []);
    assert_eq!(
        lab.naps[0].conclusion().verdict,
        explained(&[Finding::ControllerDown(2)], &[])
    );
}

#[test]
fn heartbeats_from_itself_or_strangers_are_dropped_and_counted() {
    let mut nap = Nap::new(NapConfig::new(1), 0);
    // Its first heartbeat, due at once; ignored heartbeats change nothing, so none follows.
    assert_eq!(tick(&mut nap, 0).len(), 2);
    let mut hearing = Hearing::default();
    hearing.set(1, A, LinkState::Fail);
    for from in [1, 4, 0] {
        let heartbeat = NetworkHeartbeat { from, hearing };
        let input = NapInput::Heartbeat {
            received_on: A,
            heartbeat,
        };
        assert_eq!(nap.step(input, 10), []);
    }
    assert_eq!(nap.ignored_heartbeats(), 3);
    assert_eq!(nap.matrix(10), LinkMatrix::unknown(), "nothing heard yet");
}

#[test]
fn links_are_unknown_in_the_start_up_grace_then_fail_at_the_deadline() {
    let mut observer = Observer::new(1, Members::ALL, 500, 1000);
    let from_2 = Link::new(2, 1, A);
    assert_eq!(observer.matrix(1499).get(from_2), LinkState::Unknown);
    assert_eq!(observer.matrix(1500).get(from_2), LinkState::Fail);
    let mut hearing = Hearing::default();
    hearing.set(3, B, LinkState::Fail);
    let heartbeat = NetworkHeartbeat { from: 2, hearing };
    assert!(observer.hear(A, &heartbeat, 1600));
    let matrix = observer.matrix(2099);
    assert_eq!(matrix.get(from_2), LinkState::Good);
    assert_eq!(matrix.get(Link::new(2, 1, B)), LinkState::Fail);
    assert_eq!(
        matrix.get(Link::new(3, 2, B)),
        LinkState::Fail,
        "2's report"
    );
    assert_eq!(observer.next_change_ms(2099), Some(2100));
    // A deadline on: the link has failed and 2's report is stale, so its row is Unknown.
    let matrix = observer.matrix(2100);
    assert_eq!(matrix.get(from_2), LinkState::Fail);
    assert_eq!(matrix.get(Link::new(3, 2, B)), LinkState::Unknown);
    assert_eq!(observer.next_change_ms(2100), None);
}

#[test]
fn heartbeats_go_out_on_both_networks_every_period_carrying_the_row() {
    let mut nap = Nap::new(NapConfig::new(2), 100);
    let published = tick(&mut nap, 100);
    let heartbeat = NetworkHeartbeat {
        from: 2,
        hearing: Hearing::default(),
    };
    assert_eq!(
        published,
        [
            NapCommand::PublishHeartbeat {
                network: A,
                heartbeat
            },
            NapCommand::PublishHeartbeat {
                network: B,
                heartbeat
            },
        ]
    );
    assert_eq!(nap.next_deadline().at_ms, 350);
    assert_eq!(tick(&mut nap, 349), []);
    let later = tick(&mut nap, 1000);
    assert_eq!(later.len(), 2, "a late tick publishes once");
    let NapCommand::PublishHeartbeat { heartbeat, .. } = later[0] else {
        panic!("not a heartbeat: {later:?}");
    };
    assert_eq!(heartbeat.hearing.of(1, A), LinkState::Fail);
    assert_eq!(heartbeat.hearing.of(3, B), LinkState::Fail);
    assert_eq!(
        heartbeat.hearing.of(2, B),
        LinkState::Unknown,
        "its own slot"
    );
    assert_eq!(nap.next_deadline().at_ms, 1250);
}
