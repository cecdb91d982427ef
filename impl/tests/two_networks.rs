//! Two networks, A and B: which RustDDS participants stay on one of them, and what survives
//! losing one.
//!
//! RL's network alarm participants (one per controller per network) must send their
//! heartbeats over their own network only: a participant for net B whose traffic also leaves
//! on net A would keep hearing its peers after net B dies. RL's own participant uses both
//! networks and should keep working when one dies. These tests build a LAN of network
//! namespaces, each host with one interface into net A (10.201.1.N/24) and one into net B
//! (10.202.1.N/24), run heartbeat probes (`two_networks/probe.rs`), cut a net with nftables on
//! every host and measure what each probe still hears. Findings: docs/protocol.md, "Network monitoring".
//!
//! They need root (namespaces, bridges, nftables), so they are ignored by default:
//! `cargo test --release -p rl --test two_networks -- --include-ignored --nocapture`.

mod two_networks {
    pub mod lan;
    pub mod probe;
}

use std::collections::BTreeMap;
use std::thread;
use std::time::{Duration, Instant};
use two_networks::lan::{MulticastRoute, Net, TwoBridgeLan};
use two_networks::probe::{Probe, ProbeConfig};

const PERIOD: Duration = Duration::from_millis(50);
/// Discovery in the namespaces takes ~0.2 s; allow for a loaded machine.
const DISCOVERY_TIMEOUT: Duration = Duration::from_secs(20);
/// Samples still in flight when a net is cut are not counted.
const SETTLE: Duration = Duration::from_secs(1);
/// How long each phase counts samples (40 beats per sender at 50 ms).
const WINDOW: Duration = Duration::from_secs(2);
/// A silence longer than this after a cut means the cut lost traffic (10 periods).
const NO_LOSS_GAP: Duration = Duration::from_millis(500);

/// How each network alarm participant is built.
#[derive(Clone, Copy, Debug)]
enum Binding {
    /// `DomainParticipant::new`: every interface.
    Default,
    /// `with_only_networks([its address on its net])`.
    OnlyItsNet,
}

/// How the two nets' participants are kept apart above the network.
#[derive(Clone, Copy, Debug)]
enum Separation {
    /// One domain, one topic: the samples say which net they stand for.
    None,
    /// One domain, a topic per net.
    TopicPerNet,
    /// A domain per net (different ports), one topic.
    DomainPerNet,
}

fn nap_config(
    lan: &TwoBridgeLan,
    host: u8,
    net: Net,
    binding: Binding,
    sep: Separation,
) -> ProbeConfig {
    let domain_a = 60;
    let (domain, topic) = match sep {
        Separation::None => (domain_a, "napx_hb".to_string()),
        Separation::TopicPerNet => (domain_a, format!("napx_hb_{}", net.letter())),
        Separation::DomainPerNet => (domain_a + u16::from(net == Net::B), "napx_hb".to_string()),
    };
    ProbeConfig {
        ns: lan.ns(host),
        host,
        net,
        domain,
        topic,
        only_networks: match binding {
            Binding::Default => None,
            Binding::OnlyItsNet => Some(TwoBridgeLan::addr(host, net)),
        },
        every_interface: false,
        period: PERIOD,
        reads: true,
        writes: true,
    }
}

/// Waits until every reading probe hears every other host's writing probe of its net.
fn wait_for_discovery(probes: &[Probe]) {
    let start = Instant::now();
    loop {
        let now = Instant::now();
        let all_heard = probes.iter().filter(|p| p.config.reads).all(|p| {
            let heard = p.heard_between(now - Duration::from_millis(500), now);
            probes
                .iter()
                .filter(|w| w.config.writes && w.config.net == p.config.net)
                .filter(|w| w.config.host != p.config.host)
                .all(|w| heard.contains_key(&(w.config.host, w.config.net)))
        });
        if all_heard {
            println!("  discovery complete after {:?}", start.elapsed());
            return;
        }
        assert!(
            start.elapsed() < DISCOVERY_TIMEOUT,
            "discovery did not complete"
        );
        thread::sleep(Duration::from_millis(100));
    }
}

/// What each probe (host, net) heard from each sender (host, net) in one phase.
type PhaseCounts = BTreeMap<(u8, Net), BTreeMap<(u8, Net), usize>>;

fn count_window(name: &str, probes: &[Probe]) -> PhaseCounts {
    thread::sleep(SETTLE);
    let from = Instant::now();
    thread::sleep(WINDOW);
    let to = Instant::now();
    let counts: PhaseCounts = probes
        .iter()
        .map(|p| ((p.config.host, p.config.net), p.heard_between(from, to)))
        .collect();
    println!("  {name}:");
    for ((host, net), heard) in &counts {
        let list: Vec<String> = heard
            .iter()
            .map(|((h, n), c)| format!("h{h}{}={c}", n.letter()))
            .collect();
        println!("    h{host}{} heard {}", net.letter(), list.join(" "));
    }
    counts
}

/// The other hosts' probes of `from_net` that probe (host, net) heard.
fn peers_heard(counts: &PhaseCounts, host: u8, net: Net, from_net: Net) -> usize {
    counts[&(host, net)]
        .keys()
        .filter(|(h, n)| *n == from_net && *h != host)
        .count()
}

/// What the probes heard with both nets up, net B cut, and net A cut.
struct Phases {
    up: PhaseCounts,
    b_cut: PhaseCounts,
    a_cut: PhaseCounts,
}

/// Runs one network alarm participant per host per net on three hosts, cuts B, then A.
fn nap_pairs(binding: Binding, sep: Separation) -> Phases {
    println!("binding {binding:?}, separation {sep:?}");
    let lan = TwoBridgeLan::build(3, MulticastRoute::AOnly);
    let mut probes = Vec::new();
    for host in lan.hosts().to_vec() {
        for net in [Net::A, Net::B] {
            probes.push(Probe::start(nap_config(&lan, host, net, binding, sep)));
        }
    }
    wait_for_discovery(&probes);
    let up = count_window("both nets up", &probes);
    lan.cut(Net::B);
    let b_cut = count_window("net B cut", &probes);
    lan.heal(Net::B);
    lan.cut(Net::A);
    let a_cut = count_window("net A cut", &probes);
    Phases { up, b_cut, a_cut }
}

#[test]
#[ignore = "needs root and network namespaces"]
fn default_participants_leak_a_dead_net_b_over_net_a() {
    let phases = nap_pairs(Binding::Default, Separation::TopicPerNet);
    for host in [1, 2, 3] {
        assert_eq!(peers_heard(&phases.up, host, Net::B, Net::B), 2);
        // The leak: net B is dead, yet the B participants still hear each other.
        assert_eq!(
            peers_heard(&phases.b_cut, host, Net::B, Net::B),
            2,
            "h{host}b"
        );
    }
}

fn assert_each_net_alone(phases: &Phases) {
    for host in [1, 2, 3] {
        for net in [Net::A, Net::B] {
            assert_eq!(
                peers_heard(&phases.up, host, net, net),
                2,
                "h{host}{net:?} up"
            );
        }
        assert_eq!(
            peers_heard(&phases.b_cut, host, Net::B, Net::B),
            0,
            "h{host}b, B cut"
        );
        assert_eq!(
            peers_heard(&phases.b_cut, host, Net::A, Net::A),
            2,
            "h{host}a, B cut"
        );
        assert_eq!(
            peers_heard(&phases.a_cut, host, Net::A, Net::A),
            0,
            "h{host}a, A cut"
        );
        assert_eq!(
            peers_heard(&phases.a_cut, host, Net::B, Net::B),
            2,
            "h{host}b, A cut"
        );
    }
}

#[test]
#[ignore = "needs root and network namespaces"]
fn only_networks_with_a_topic_per_net_keeps_each_net_alone() {
    assert_each_net_alone(&nap_pairs(Binding::OnlyItsNet, Separation::TopicPerNet));
}

#[test]
#[ignore = "needs root and network namespaces"]
fn only_networks_with_a_domain_per_net_keeps_each_net_alone() {
    assert_each_net_alone(&nap_pairs(Binding::OnlyItsNet, Separation::DomainPerNet));
}

#[test]
#[ignore = "needs root and network namespaces"]
fn only_networks_with_one_topic_hears_the_other_net_s_participants() {
    let phases = nap_pairs(Binding::OnlyItsNet, Separation::None);
    for host in [1, 2, 3] {
        // Its own net is silent, but the A participants of the other hosts reach the B
        // participant over net A: its sockets listen on every interface.
        assert_eq!(
            peers_heard(&phases.b_cut, host, Net::B, Net::B),
            0,
            "h{host}b"
        );
        assert_eq!(
            peers_heard(&phases.b_cut, host, Net::B, Net::A),
            2,
            "h{host}b"
        );
    }
}

/// Packets sent on `net`'s interface by all hosts together while `during` runs.
fn packets_sent_on(lan: &TwoBridgeLan, net: Net, during: impl FnOnce()) -> u64 {
    let sent =
        |lan: &TwoBridgeLan| -> u64 { lan.hosts().iter().map(|h| lan.packets(*h, net).0).sum() };
    let before = sent(lan);
    during();
    sent(lan) - before
}

/// Packets on net A in 3 s while only B participants run (three hosts).
fn packets_on_a_from_b_participants(binding: Binding) -> u64 {
    let lan = TwoBridgeLan::build(3, MulticastRoute::AOnly);
    let probes: Vec<Probe> = lan
        .hosts()
        .iter()
        .map(|h| Probe::start(nap_config(&lan, *h, Net::B, binding, Separation::None)))
        .collect();
    wait_for_discovery(&probes);
    thread::sleep(SETTLE);
    let on_a = packets_sent_on(&lan, Net::A, || thread::sleep(Duration::from_secs(3)));
    println!("  {binding:?}: {on_a} packets on net A in 3 s");
    on_a
}

#[test]
#[ignore = "needs root and network namespaces"]
fn alone_an_only_networks_participant_sends_nothing_on_the_other_net() {
    // Three participants at 20 Hz: hundreds of packets when they use net A; what remains
    // with only_networks is the kernel's own (IPv6 neighbour discovery, IGMP).
    assert!(packets_on_a_from_b_participants(Binding::Default) > 150);
    assert!(packets_on_a_from_b_participants(Binding::OnlyItsNet) < 30);
}

/// RL's own participant: one per host, on both nets.
#[derive(Clone, Copy, Debug)]
struct Ordinary {
    hosts: u8,
    /// Every participant writes and reads the topic (RL's heartbeats and votes), or host 1
    /// only writes and the others only read (RL's commands: the actuator reads them).
    everyone_reads: bool,
    every_interface: bool,
    multicast_route: MulticastRoute,
}

/// Which net to cut in [`ordinary_traffic_loses`].
#[derive(Clone, Copy, Debug)]
enum Victim {
    Net(Net),
    /// The net that carried more packets with both up.
    TheBusierNet,
}

fn ordinary_probes(lan: &TwoBridgeLan, setup: Ordinary) -> Vec<Probe> {
    lan.hosts()
        .iter()
        .map(|host| {
            let mut config = nap_config(lan, *host, Net::A, Binding::Default, Separation::None);
            config.topic = "napx_rl".into();
            config.every_interface = setup.every_interface;
            config.writes = setup.everyone_reads || *host == 1;
            config.reads = setup.everyone_reads || *host != 1;
            config
        })
        .map(Probe::start)
        .collect()
}

/// Cuts a net under RL-like traffic; returns the longest silence any reader had from any
/// writer between one second before the cut and `observe` after it.
fn ordinary_traffic_loses(setup: Ordinary, victim: Victim, observe: Duration) -> Duration {
    println!("{setup:?}, cut {victim:?}");
    let lan = TwoBridgeLan::build(setup.hosts, setup.multicast_route);
    let probes = ordinary_probes(&lan, setup);
    wait_for_discovery(&probes);
    thread::sleep(SETTLE);
    let mut sent = BTreeMap::new();
    for net in [Net::A, Net::B] {
        sent.insert(net, packets_sent_on(&lan, net, || thread::sleep(WINDOW)));
    }
    println!(
        "  both up, 2 s: {} packets on A, {} on B",
        sent[&Net::A],
        sent[&Net::B]
    );
    let dead = match victim {
        Victim::Net(net) => net,
        Victim::TheBusierNet if sent[&Net::A] >= sent[&Net::B] => Net::A,
        Victim::TheBusierNet => Net::B,
    };
    lan.cut(dead);
    let cut_at = Instant::now();
    thread::sleep(observe);
    let writers: Vec<u8> = probes
        .iter()
        .filter(|p| p.config.writes)
        .map(|p| p.config.host)
        .collect();
    let mut longest = Duration::ZERO;
    for p in probes.iter().filter(|p| p.config.reads) {
        for writer in writers.iter().filter(|h| **h != p.config.host) {
            let gap = p.longest_gap_from(*writer, cut_at - SETTLE, cut_at + observe);
            println!(
                "  {dead:?} cut: h{} heard nothing from h{writer} for {gap:?}",
                p.config.host
            );
            longest = longest.max(gap);
        }
    }
    longest
}

#[test]
#[ignore = "needs root and network namespaces"]
fn a_participant_that_reads_its_own_topic_survives_either_net_dying() {
    let setup = Ordinary {
        hosts: 3,
        everyone_reads: true,
        every_interface: false,
        multicast_route: MulticastRoute::AOnly,
    };
    for net in [Net::A, Net::B] {
        let gap = ordinary_traffic_loses(setup, Victim::Net(net), Duration::from_secs(10));
        assert!(gap < NO_LOSS_GAP, "{gap:?}");
    }
}

#[test]
#[ignore = "needs root and network namespaces"]
fn a_writer_to_a_remote_reader_goes_unheard_for_30_s_when_its_net_dies() {
    let setup = Ordinary {
        hosts: 2,
        everyone_reads: false,
        every_interface: false,
        // A multicast route on each net does not help: RustDDS picks the interface itself.
        multicast_route: MulticastRoute::Both,
    };
    let gap = ordinary_traffic_loses(setup, Victim::TheBusierNet, Duration::from_secs(45));
    // RustDDS narrows the route to one net and keeps it until it was silent for 30 s.
    assert!(gap > Duration::from_secs(25), "{gap:?}");
    assert!(gap < Duration::from_secs(44), "never resumed: {gap:?}");
}

#[test]
#[ignore = "needs root and network namespaces"]
fn send_on_every_interface_keeps_a_writer_heard_when_either_net_dies() {
    let setup = Ordinary {
        hosts: 2,
        everyone_reads: false,
        every_interface: true,
        multicast_route: MulticastRoute::AOnly,
    };
    for net in [Net::A, Net::B] {
        let gap = ordinary_traffic_loses(setup, Victim::Net(net), Duration::from_secs(10));
        assert!(gap < NO_LOSS_GAP, "{gap:?}");
    }
}
