use super::*;
use std::process::Command;
use std::time::{Duration, Instant};

fn link(interface: &str, address: Option<[u8; 4]>, running: bool) -> Link {
    Link {
        interface: interface.into(),
        addresses: address.map(Ipv4Addr::from).into_iter().collect(),
        loopback: interface == "lo",
        running,
    }
}

fn names(list: &[&str]) -> BTreeSet<String> {
    list.iter().map(|s| s.to_string()).collect()
}

#[test]
fn networks_name_their_interfaces_by_address_or_name() {
    let host = [
        link("lo", Some([127, 0, 0, 1]), true),
        link("eth0", Some([10, 202, 1, 2]), true),
        link("eth1", None, true),
        link("wlan0", Some([192, 168, 1, 5]), true),
    ];
    let by_address = Watched::Networks(vec![
        NetworkName::Address(Ipv4Addr::new(10, 202, 1, 2)),
        NetworkName::Interface("eth1".into()),
    ]);
    assert_eq!(by_address.interfaces(&host), names(&["eth0", "eth1"]));
    assert_eq!(
        Watched::AllButLoopback.interfaces(&host),
        names(&["eth0", "wlan0"]),
        "loopback and interfaces without an IPv4 address are not RL's links"
    );
}

#[test]
fn detached_only_when_every_known_link_has_lost_its_carrier() {
    let known = names(&["a0", "b0"]);
    let both_up = [link("a0", None, true), link("b0", None, true)];
    let one_down = [link("a0", None, false), link("b0", None, true)];
    let both_down = [link("a0", None, false), link("b0", None, false)];
    let one_gone = [link("a0", None, false)];
    assert_eq!(detached(&known, &both_up), Links::Attached);
    assert_eq!(
        detached(&known, &one_down),
        Links::Attached,
        "one net carries RL"
    );
    assert_eq!(detached(&known, &both_down), Links::Detached);
    assert_eq!(
        detached(&known, &one_gone),
        Links::Detached,
        "a vanished link is down"
    );
    assert_eq!(
        detached(&BTreeSet::new(), &both_down),
        Links::Attached,
        "no known link (loopback only, or not up yet): nothing to be cut off from"
    );
}

#[test]
fn the_configured_networks_are_watched_or_else_every_link() {
    let mut networks = Networks::default();
    assert_eq!(Watched::from_config(&networks), Watched::AllButLoopback);
    networks.a = "10.202.1.2".into();
    networks.b = "eth1".into();
    assert_eq!(
        Watched::from_config(&networks),
        Watched::Networks(vec![
            NetworkName::Address(Ipv4Addr::new(10, 202, 1, 2)),
            NetworkName::Interface("eth1".into()),
        ])
    );
}

fn ip(args: &[&str]) {
    let status = Command::new("ip").args(args).status();
    assert!(
        status.as_ref().is_ok_and(|s| s.success()),
        "ip {args:?}: {status:?}"
    );
}

/// Waits up to 3 s for `watch` to report a change; also shows the socket woke for it.
fn next_change(watch: &mut LinkWatch) -> Option<Links> {
    let fd = watch.fd().expect("a netlink socket");
    let until = Instant::now() + Duration::from_secs(3);
    while Instant::now() < until {
        let mut poll = [libc::pollfd {
            fd,
            events: libc::POLLIN,
            revents: 0,
        }];
        // SAFETY: one pollfd, the length given.
        let ready = unsafe { libc::poll(poll.as_mut_ptr(), 1, 100) };
        if ready > 0 {
            if let Some(change) = watch.changed(true) {
                return Some(change);
            }
        }
    }
    None
}

/// A veth pair in a network namespace of the test's own: taking the far end down takes the
/// near end's carrier, as a pulled cable does, and the socket says so at once.
#[test]
fn a_lost_carrier_wakes_the_watch_and_detaches() {
    let outcome = std::thread::spawn(|| {
        // The namespace is this thread's only; `ip` inherits it.
        nix::sched::unshare(nix::sched::CloneFlags::CLONE_NEWNET)
            .expect("a network namespace (the tests run as root)");
        ip(&["link", "add", "near", "type", "veth", "peer", "name", "far"]);
        ip(&["addr", "add", "10.77.0.1/24", "dev", "near"]);
        ip(&["link", "set", "near", "up"]);
        ip(&["link", "set", "far", "up"]);
        let until = Instant::now() + Duration::from_secs(3);
        while !links()
            .unwrap()
            .iter()
            .any(|l| l.interface == "near" && l.running)
        {
            assert!(Instant::now() < until, "the veth never came up");
            std::thread::sleep(Duration::from_millis(10));
        }
        let mut watch = LinkWatch::new(Watched::Networks(vec![NetworkName::Address(
            Ipv4Addr::new(10, 77, 0, 1),
        )]));
        assert_eq!(watch.last, Links::Attached);
        assert_eq!(watch.changed(false), None, "nothing said anything changed");
        ip(&["link", "set", "far", "down"]);
        assert_eq!(next_change(&mut watch), Some(Links::Detached));
        ip(&["link", "set", "far", "up"]);
        assert_eq!(next_change(&mut watch), Some(Links::Attached));
        // Without networks configured, the same link is found as the host's only one.
        let mut every = LinkWatch::new(Watched::AllButLoopback);
        ip(&["link", "set", "far", "down"]);
        assert_eq!(next_change(&mut every), Some(Links::Detached));
    })
    .join();
    if let Err(panic) = outcome {
        std::panic::resume_unwind(panic);
    }
}

/// Sends a datagram of `round` from `socket` to `to` every 10 ms for `for_ms`: the round and
/// the time it was sent.
fn send_for(socket: &std::net::UdpSocket, to: &str, round: u8, for_ms: u64) {
    let until = Instant::now() + Duration::from_millis(for_ms);
    while Instant::now() < until {
        let mut datagram = vec![round];
        datagram.extend(micros_now().to_be_bytes());
        let _ = socket.send_to(&datagram, to);
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn micros_now() -> u64 {
    let since_epoch = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap();
    u64::try_from(since_epoch.as_micros()).unwrap()
}

/// The first byte of the datagram that ends a run.
const END_OF_RUN: u8 = u8::MAX;

/// The largest age (ms) of each round's datagrams received at `socket`, until the sender's
/// end-of-run datagram (or 20 s without a datagram).
fn oldest_arrival_ms(socket: &std::net::UdpSocket) -> [u64; 2] {
    socket
        .set_read_timeout(Some(Duration::from_secs(20)))
        .unwrap();
    let mut oldest = [0; 2];
    let mut buffer = [0u8; 16];
    while let Ok(9) = socket.recv(&mut buffer) {
        if buffer[0] == END_OF_RUN {
            break;
        }
        let sent_at = u64::from_be_bytes(buffer[1..9].try_into().unwrap());
        let age_ms = micros_now().saturating_sub(sent_at) / 1000;
        let round = usize::from(buffer[0].min(1));
        oldest[round] = oldest[round].max(age_ms);
    }
    oldest
}

/// Waits (at most 5 s) until the kernel reports `interface` in namespace `ns` up or not: the
/// operational state follows the carrier only once the kernel's link-event batch has run, and
/// that batch is also where it flushes the neighbours of a link that lost its carrier.
fn wait_for_operstate(ns: &str, interface: &str, up: bool) {
    let until = Instant::now() + Duration::from_secs(5);
    loop {
        let shown = Command::new("ip")
            .args(["-n", ns, "-o", "link", "show", interface])
            .output()
            .expect("ip link show");
        let is_up = String::from_utf8_lossy(&shown.stdout).contains(" state UP ");
        if is_up == up {
            return;
        }
        assert!(
            Instant::now() < until,
            "{interface} in {ns} did not go {}",
            if up { "up" } else { "down" }
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Waits (at most 5 s) until namespace `ns` knows the link-layer address of `address`.
fn wait_for_neighbour(ns: &str, address: &str) {
    let until = Instant::now() + Duration::from_secs(5);
    loop {
        let shown = Command::new("ip")
            .args(["-n", ns, "neigh", "show", address])
            .output()
            .expect("ip neigh show");
        if String::from_utf8_lossy(&shown.stdout).contains("lladdr") {
            return;
        }
        assert!(
            Instant::now() < until,
            "{address} was not resolved again in {ns}"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Runs `body` in a thread inside the named network namespace `ns`.
fn in_namespace<T: Send + 'static>(
    ns: &str,
    body: impl FnOnce() -> T + Send + 'static,
) -> std::thread::JoinHandle<T> {
    let path = format!("/run/netns/{ns}");
    std::thread::spawn(move || {
        let file = std::fs::File::open(&path).expect("the namespace");
        nix::sched::setns(file, nix::sched::CloneFlags::CLONE_NEWNET).expect("setns");
        body()
    })
}

/// Puts a switch (a bridge) in the calling thread's own new network namespace, and plugs
/// into it each host `(namespace, switch port, address)`: its `eth0` on that port.
fn plug_into_a_switch(hosts: &[(&str, &str, &str)]) {
    nix::sched::unshare(nix::sched::CloneFlags::CLONE_NEWNET)
        .expect("a network namespace (the tests run as root)");
    ip(&["link", "add", "switch", "type", "bridge"]);
    ip(&["link", "set", "switch", "up"]);
    for (ns, port, address) in hosts {
        ip(&["netns", "add", ns]);
        ip(&[
            "link", "add", port, "type", "veth", "peer", "name", "eth0", "netns", ns,
        ]);
        ip(&["link", "set", port, "master", "switch", "up"]);
        ip(&["-n", ns, "link", "set", "eth0", "up"]);
        ip(&["-n", ns, "addr", "add", address, "dev", "eth0"]);
    }
    std::thread::sleep(Duration::from_millis(300));
}

/// Why RL's hosts turn the kernel's queue for unresolved neighbours off: with it, datagrams
/// sent while the carrier was down arrive when it is back, a second old; without it, only the
/// newest, a moment old (Linux holds the one datagram sent last, and the sender keeps sending).
/// A sender and a receiver host on a switch (a bridge); the sender's switch port goes down
/// for a second and up, as a pulled and re-plugged cable, in each of two rounds.
#[test]
fn datagrams_sent_while_the_cable_was_out_arrive_late_unless_the_queue_is_off() {
    let pid = std::process::id();
    let (sender_ns, receiver_ns) = (format!("rl-lw-s{pid}"), format!("rl-lw-r{pid}"));
    let names = (sender_ns.clone(), receiver_ns.clone());
    let outcome = std::thread::spawn(move || {
        let (sender_ns, receiver_ns) = names;
        plug_into_a_switch(&[
            (&sender_ns, "port-s", "10.78.0.1/24"),
            (&receiver_ns, "port-r", "10.78.0.2/24"),
        ]);
        let (bound, is_bound) = std::sync::mpsc::channel();
        let receiver = in_namespace(&receiver_ns, move || {
            let socket = std::net::UdpSocket::bind("10.78.0.2:7401").expect("bind");
            let _ = bound.send(());
            oldest_arrival_ms(&socket)
        });
        is_bound.recv().unwrap();
        // The sender sends every 10 ms from start to end, as a controller does: with the
        // queue off the kernel still holds the one newest datagram for an unresolved
        // neighbour, which is then a moment old. The test's thread tells it each new round.
        let (new_round, next_round) = std::sync::mpsc::channel::<u8>();
        let sender = in_namespace(&sender_ns, move || {
            let socket = std::net::UdpSocket::bind("10.78.0.1:0").unwrap();
            let mut round = 0;
            loop {
                match next_round.try_recv() {
                    Ok(next) => {
                        round = next;
                        if round == 1 {
                            std::fs::write(unresolved_queue_setting("eth0"), "0").unwrap();
                        }
                    }
                    Err(std::sync::mpsc::TryRecvError::Empty) => {}
                    Err(std::sync::mpsc::TryRecvError::Disconnected) => break,
                }
                send_for(&socket, "10.78.0.2:7401", round, 10);
            }
            send_for(&socket, "10.78.0.2:7401", END_OF_RUN, 50);
        });
        for round in [0, 1] {
            // Up, down for a second, up again. The outage's second starts once the kernel
            // has acted on the lost carrier (it may batch link events), as it has on a real
            // host long before a controller's deadlines matter.
            new_round.send(round).unwrap();
            std::thread::sleep(Duration::from_millis(300));
            ip(&["link", "set", "port-s", "down"]);
            wait_for_operstate(&sender_ns, "eth0", false);
            std::thread::sleep(Duration::from_millis(1000));
            ip(&["link", "set", "port-s", "up"]);
            wait_for_operstate(&sender_ns, "eth0", true);
            // The kernel asks for the receiver's address once a second; the question asked
            // as the cable returns may be lost, the next one is answered. The round ends
            // when it has been, and the queue with it (the next round's outage would drop it).
            wait_for_neighbour(&sender_ns, "10.78.0.2");
            std::thread::sleep(Duration::from_millis(300));
        }
        drop(new_round);
        sender.join().unwrap();
        receiver.join().unwrap()
    })
    .join();
    for ns in [&sender_ns, &receiver_ns] {
        let _ = Command::new("ip").args(["netns", "del", ns]).status();
    }
    match outcome {
        Ok([default_queue, queue_off]) => {
            assert!(
                default_queue >= 500,
                "the default queue delivers the outage's datagrams late: {default_queue} ms (queue off: {queue_off} ms)"
            );
            assert!(
                queue_off < 100,
                "with the queue off nothing arrives late: {queue_off} ms (default queue: {default_queue} ms)"
            );
        }
        Err(panic) => std::panic::resume_unwind(panic),
    }
}
