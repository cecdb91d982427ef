//! Forged heartbeats, votes and commands from a participant that is not the controller it
//! names, and garbage datagrams. The forgeries are functions of their own: `security` runs
//! them against secured controllers too.

use crate::support::Cluster;
use rl::procs::ServoEvent;
use rl_layer::core::{AlarmReason, Heartbeat, Phase, Role, VoteRecord};
use rl_layer::dds::Session;
use rl_layer::event::Event;
use rl_layer::wire::ServoControl;
use std::net::UdpSocket;
use std::time::{Duration, Instant};

const FORMATION: Duration = Duration::from_secs(20);
/// How long a forgery goes on: many peer deadlines.
const ATTACK: Duration = Duration::from_secs(3);

fn formed(tag: &str, domain: u16) -> Cluster {
    let mut cluster = Cluster::new(tag, domain, "");
    for id in 1..=3 {
        cluster.start(id);
    }
    cluster.wait_for("P=1 S=2 T=3", FORMATION, |c| {
        c.steady_with(1, Some(Role::Primary))
            && c.steady_with(2, Some(Role::Secondary))
            && c.steady_with(3, Some(Role::Tertiary))
    });
    cluster
}

/// The forger: a participant of its own on the cluster's domain.
pub fn forger(domain: u16) -> Session {
    let dds = rl_layer::config::Dds {
        domain,
        ..Default::default()
    };
    Session::new(&dds, &rl_layer::config::Timing::default()).expect("the forger joins the domain")
}

/// The latest heartbeat controller `id` reported about itself.
fn report_of(cluster: &Cluster, id: u8) -> Heartbeat {
    cluster.status[&id].report
}

/// Output lines (a role or strength change) since `since`.
pub fn outputs_since(cluster: &Cluster, since: Instant) -> Vec<String> {
    cluster
        .events
        .iter()
        .filter(|(at, e)| *at >= since && matches!(e.event, Event::Output { .. }))
        .map(|(_, e)| e.to_json())
        .collect()
}

/// Who raised (`raised` true) or cleared an impostor alarm about `about` since `since`.
pub fn impostor_alarms(cluster: &Cluster, about: u8, raised: bool, since: Instant) -> Vec<u8> {
    let mut by: Vec<u8> = cluster
        .events
        .iter()
        .filter(|(at, _)| *at >= since)
        .filter(|(_, e)| {
            matches!(e.event, Event::Alarm { about: a, reason: AlarmReason::Impostor, raised: r }
                if a == about && r == raised)
        })
        .map(|(_, e)| e.id)
        .collect();
    by.sort_unstable();
    by.dedup();
    by
}

/// Writes `write` every 100 ms for `ATTACK`, pumping the cluster meanwhile.
pub fn keep_forging(cluster: &mut Cluster, mut write: impl FnMut()) {
    let until = Instant::now() + ATTACK;
    while Instant::now() < until {
        write();
        cluster.pump(Duration::from_millis(100));
    }
}

/// C1's own last heartbeat, same incarnation, now saying FAILED.
pub fn failed_heartbeat_of_c1(cluster: &Cluster) -> Heartbeat {
    Heartbeat {
        phase: Phase::Failed,
        role: None,
        strength: None,
        established_strength: None,
        ..report_of(cluster, 1)
    }
}

#[test]
fn a_forged_failed_heartbeat_for_the_primary_is_refused_and_alarmed() {
    let domain = 160;
    let mut cluster = formed("forged-failed", domain);
    let forger = forger(domain);
    let heartbeats = forger.heartbeat_writer().unwrap();
    let forged = failed_heartbeat_of_c1(&cluster);
    let since = Instant::now();
    keep_forging(&mut cluster, || heartbeats.write(&forged).unwrap());
    assert_eq!(
        outputs_since(&cluster, since),
        Vec::<String>::new(),
        "a role moved"
    );
    assert!(
        cluster.steady_with(1, Some(Role::Primary)),
        "{}",
        cluster.describe()
    );
    assert_eq!(impostor_alarms(&cluster, 1, true, since), vec![2, 3]);
    // The forger stops: the alarm clears within a peer deadline or so.
    cluster.wait_for(
        "impostor alarm about C1 cleared",
        Duration::from_secs(3),
        |c| impostor_alarms(c, 1, false, since) == vec![2, 3],
    );
}

/// Heartbeats in the names of C1 and C2, live incumbents of a newer epoch, agreeing on C3
/// as Primary: two of three would be a majority.
pub fn incumbent_claims(cluster: &Cluster) -> Vec<Heartbeat> {
    let c3 = report_of(cluster, 3);
    let agreed =
        rl_layer::core::Assignment::from_ranked([3, 1, 2].map(|id| rl_layer::core::Holder {
            id,
            incarnation: report_of(cluster, id).incarnation,
        }));
    [1u8, 2]
        .iter()
        .map(|&id| Heartbeat {
            agreed: Some(agreed),
            vote: Some(agreed),
            epoch: c3.epoch + 5,
            ..report_of(cluster, id)
        })
        .collect()
}

#[test]
fn two_forged_incumbents_cannot_outvote_the_three() {
    let domain = 161;
    let mut cluster = formed("forged-incumbents", domain);
    // Two participants, each claiming a live controller's id, agreeing on C3 as Primary.
    let forgers = [forger(domain), forger(domain)];
    let writers: Vec<_> = forgers
        .iter()
        .map(|f| f.heartbeat_writer().unwrap())
        .collect();
    let claims = incumbent_claims(&cluster);
    let since = Instant::now();
    keep_forging(&mut cluster, || {
        for (writer, claim) in writers.iter().zip(&claims) {
            writer.write(claim).unwrap();
        }
    });
    assert_eq!(
        outputs_since(&cluster, since),
        Vec::<String>::new(),
        "a role moved"
    );
    assert_eq!(impostor_alarms(&cluster, 1, true, since), vec![2, 3]);
    assert_eq!(impostor_alarms(&cluster, 2, true, since), vec![1, 3]);
}

/// A vote in C2's name, its incarnation, for the reverse order (C3, C2, C1).
pub fn reversed_vote_of_c2(cluster: &Cluster) -> VoteRecord {
    let reversed =
        rl_layer::core::Assignment::from_ranked([3, 2, 1].map(|id| rl_layer::core::Holder {
            id,
            incarnation: report_of(cluster, id).incarnation,
        }));
    VoteRecord {
        from: 2,
        incarnation: report_of(cluster, 2).incarnation,
        vote: Some(reversed),
    }
}

#[test]
fn a_forged_vote_is_refused_and_alarmed() {
    let domain = 162;
    let mut cluster = formed("forged-vote", domain);
    let forger = forger(domain);
    let votes = forger.vote_writer().unwrap();
    let record = reversed_vote_of_c2(&cluster);
    let since = Instant::now();
    keep_forging(&mut cluster, || votes.write(&record).unwrap());
    assert_eq!(
        outputs_since(&cluster, since),
        Vec::<String>::new(),
        "a role moved"
    );
    assert_eq!(impostor_alarms(&cluster, 2, true, since), vec![1, 3]);
}

/// Commands at strength 100 from the forger's participant, for `ATTACK`; what the servo
/// accepted from it.
fn strength_100_attack(any_writer: bool, domain: u16) -> (Cluster, usize) {
    let mut cluster = formed("forged-command", domain);
    if any_writer {
        cluster
            .fleet
            .start_other("servo", &["servo", "--json", "--any-writer"])
            .expect("start rl servo");
    } else {
        cluster.start_servo();
    }
    cluster.wait_for("the servo follows C1", Duration::from_secs(10), |c| {
        c.servo_commander() == Some(1)
    });
    let forger = forger(domain);
    let mut writer = forger
        .command_writer(Some(rl_layer::core::Strength(100)))
        .unwrap();
    let forged = ServoControl {
        pan: 999,
        tilt: 1,
        frequency: 60,
    };
    let since = Instant::now();
    keep_forging(&mut cluster, || {
        writer.write(forged).unwrap();
    });
    let taken = cluster
        .servo
        .iter()
        .filter(|(at, e)| *at >= since && matches!(e, ServoEvent::Command { pan: 999, .. }))
        .count();
    (cluster, taken)
}

#[test]
fn a_strength_100_writer_does_not_take_the_servo() {
    let (cluster, taken) = strength_100_attack(false, 163);
    assert_eq!(taken, 0, "the servo obeyed the forged writer");
    assert_eq!(
        cluster.servo_commander(),
        Some(1),
        "the Primary still commands"
    );
}

#[test]
fn with_plain_dds_ownership_a_strength_100_writer_takes_the_servo() {
    // What the check above guards against: `--any-writer` is plain exclusive ownership, and
    // the strongest writer wins whoever it is. Only DDS Security keeps it off the LAN.
    let (_cluster, taken) = strength_100_attack(true, 164);
    assert!(
        taken > 10,
        "the forged writer got only {taken} commands through"
    );
}

/// Random datagrams, half of them with an RTPS header, at every DDS port of `domain` for
/// `ATTACK`, then a second's quiet; how many were sent.
pub fn flood_with_garbage(cluster: &mut Cluster, domain: u16) -> u32 {
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    let base = 7400 + 250 * domain;
    // Discovery and user ports of participants 0-9, multicast and unicast (RTPS 9.6.1.1).
    let ports: Vec<u16> = [0u16, 1]
        .into_iter()
        .chain((0..10).flat_map(|p| [10 + 2 * p, 11 + 2 * p]))
        .map(|offset| base + offset)
        .collect();
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let mut sent = 0u32;
    let until = Instant::now() + ATTACK;
    while Instant::now() < until {
        for &port in &ports {
            let len = (next() % 600) as usize + 1;
            let mut datagram: Vec<u8> = (0..len).map(|_| next() as u8).collect();
            // Half of them look like RTPS: the magic and a version, then garbage.
            if next() % 2 == 0 && len >= 8 {
                datagram[..6].copy_from_slice(b"RTPS\x02\x04");
            }
            for target in ["127.0.0.1", "239.255.0.1"] {
                if socket.send_to(&datagram, (target, port)).is_ok() {
                    sent += 1;
                }
            }
        }
        cluster.pump(Duration::from_millis(1));
    }
    cluster.pump(Duration::from_secs(1));
    sent
}

/// What RustDDS prints about a datagram it ignores: its count (fix 19), and the per-datagram
/// lines it printed before.
const MALFORMED_LINES: [&str; 4] = [
    "malformed datagram",
    "unknown start of header",
    "RTPS deserialize error",
    "shorter than RTPS header",
];
/// A controller's participants (RL's and its ROS 2 node's), each reporting the first
/// malformed datagram of a period, within the attack's 3 s: a margin over 2.
const MALFORMED_LINES_PER_CONTROLLER: usize = 4;

#[test]
fn garbage_datagrams_on_the_dds_ports_change_nothing() {
    let domain = 165;
    let mut cluster = formed("garbage", domain);
    let since = Instant::now();
    let sent = flood_with_garbage(&mut cluster, domain);
    println!("sent {sent} garbage datagrams in {ATTACK:?}");
    assert!(sent > 10_000, "only {sent} sent");
    // The flood reaches the operator's console as one line per participant and report period
    // (RustDDS fix 19), not a line or two per datagram written from the DDS event loop.
    for id in 1..=3u8 {
        let lines = cluster
            .lines_from(&format!("C{id}!"))
            .filter(|line| MALFORMED_LINES.iter().any(|m| line.contains(m)))
            .count();
        assert!(
            lines <= MALFORMED_LINES_PER_CONTROLLER,
            "C{id} printed {lines} lines about malformed datagrams"
        );
    }
    assert_eq!(
        outputs_since(&cluster, since),
        Vec::<String>::new(),
        "a role moved"
    );
    for (id, role) in [
        (1, Role::Primary),
        (2, Role::Secondary),
        (3, Role::Tertiary),
    ] {
        assert!(
            cluster.steady_with(id, Some(role)),
            "{}",
            cluster.describe()
        );
    }
}
