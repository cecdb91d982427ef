//! A LAN of network namespaces joined by two Linux bridges, net A and net B, each host with one
//! veth into each (`a0`: 10.201.1.N/24, `b0`: 10.202.1.N/24, `lo` up), and nftables rules that
//! cut a net off at every host. Names start with `napx` and four hex digits, so parallel runs
//! never collide and never touch anything else on the machine; everything is removed on drop.

use std::net::Ipv4Addr;
use std::process::Command;

/// One of the two networks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Net {
    A,
    B,
}

impl Net {
    pub fn letter(self) -> char {
        match self {
            Net::A => 'a',
            Net::B => 'b',
        }
    }

    /// The third byte-pair of the net's prefix: A is 10.201.1.0/24, B is 10.202.1.0/24.
    fn second_byte(self) -> u8 {
        match self {
            Net::A => 201,
            Net::B => 202,
        }
    }

    /// The interface inside every namespace that leads to this net.
    pub fn device(self) -> String {
        format!("{}0", self.letter())
    }
}

/// Where the multicast route (224.0.0.0/4) of each host points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MulticastRoute {
    /// `dev a0` only, as the fault lab does.
    AOnly,
    /// `dev a0` and `dev b0` (two routes, metrics 1 and 2).
    Both,
}

/// The LAN; removed when dropped (also while a failed test unwinds).
pub struct TwoBridgeLan {
    tag: String,
    hosts: Vec<u8>,
}

/// Runs a command, panicking with its stderr when it fails (setup must not half-work).
fn run(program: &str, args: &[&str]) {
    let output = Command::new(program)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {program}: {e}"));
    assert!(
        output.status.success(),
        "{program} {} failed: {}",
        args.join(" "),
        String::from_utf8_lossy(&output.stderr)
    );
}

/// Runs a command and ignores the outcome (cleanup on the way out).
fn run_quietly(program: &str, args: &[&str]) {
    let _ = Command::new(program).args(args).output();
}

impl TwoBridgeLan {
    /// Builds hosts `1..=hosts` with the given multicast route.
    pub fn build(hosts: u8, multicast: MulticastRoute) -> TwoBridgeLan {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let mixed = (std::process::id() ^ nanos.rotate_left(11)) & 0xffff;
        let lan = TwoBridgeLan {
            tag: format!("napx{mixed:04x}"),
            hosts: (1..=hosts).collect(),
        };
        for net in [Net::A, Net::B] {
            run("ip", &["link", "add", &lan.bridge(net), "type", "bridge"]);
            run("ip", &["link", "set", &lan.bridge(net), "up"]);
        }
        for host in lan.hosts.clone() {
            lan.wire(host, multicast);
        }
        lan
    }

    fn wire(&self, host: u8, multicast: MulticastRoute) {
        let ns = self.ns(host);
        run("ip", &["netns", "add", &ns]);
        run("ip", &["-n", &ns, "link", "set", "lo", "up"]);
        for net in [Net::A, Net::B] {
            let outside = format!("{}{host}{}", self.tag, net.letter());
            let inside = net.device();
            run(
                "ip",
                &[
                    "link", "add", &outside, "type", "veth", "peer", "name", &inside, "netns", &ns,
                ],
            );
            run(
                "ip",
                &["link", "set", &outside, "master", &self.bridge(net), "up"],
            );
            run("ip", &["-n", &ns, "link", "set", &inside, "up"]);
            let addr = format!("{}/24", Self::addr(host, net));
            run("ip", &["-n", &ns, "addr", "add", &addr, "dev", &inside]);
        }
        let routes: &[(&str, &str)] = match multicast {
            MulticastRoute::AOnly => &[("a0", "1")],
            MulticastRoute::Both => &[("a0", "1"), ("b0", "2")],
        };
        for (dev, metric) in routes {
            run(
                "ip",
                &[
                    "-n",
                    &ns,
                    "route",
                    "add",
                    "224.0.0.0/4",
                    "dev",
                    dev,
                    "metric",
                    metric,
                ],
            );
        }
    }

    /// A host's address on a net.
    pub fn addr(host: u8, net: Net) -> Ipv4Addr {
        Ipv4Addr::new(10, net.second_byte(), 1, host)
    }

    pub fn ns(&self, host: u8) -> String {
        format!("{}h{host}", self.tag)
    }

    fn bridge(&self, net: Net) -> String {
        format!("{}br{}", self.tag, net.letter())
    }

    pub fn hosts(&self) -> &[u8] {
        &self.hosts
    }

    fn cut_table(net: Net) -> String {
        format!("napxcut{}", net.letter())
    }

    /// Drops every packet in or out of `net`'s interface on every host (the net is dead;
    /// the interfaces stay up with their addresses and routes).
    pub fn cut(&self, net: Net) {
        self.cut_at(net, &self.hosts.clone());
    }

    /// The same at `hosts` only: their links into `net` are dead.
    pub fn cut_at(&self, net: Net, hosts: &[u8]) {
        let table = Self::cut_table(net);
        let dev = net.device();
        for host in hosts {
            let ns = self.ns(*host);
            let nft = |args: &[&str]| {
                let mut full = vec!["netns", "exec", ns.as_str(), "nft"];
                full.extend_from_slice(args);
                run("ip", &full);
            };
            nft(&["add", "table", "inet", &table]);
            nft(&[
                "add",
                "chain",
                "inet",
                &table,
                "in",
                "{ type filter hook input priority 0 ; }",
            ]);
            nft(&[
                "add",
                "chain",
                "inet",
                &table,
                "out",
                "{ type filter hook output priority 0 ; }",
            ]);
            nft(&["add", "rule", "inet", &table, "in", "iifname", &dev, "drop"]);
            nft(&[
                "add", "rule", "inet", &table, "out", "oifname", &dev, "drop",
            ]);
        }
    }

    /// Undoes [`Self::cut`].
    pub fn heal(&self, net: Net) {
        self.heal_at(net, &self.hosts.clone());
    }

    /// Undoes [`Self::cut_at`].
    pub fn heal_at(&self, net: Net, hosts: &[u8]) {
        let table = Self::cut_table(net);
        for host in hosts {
            let ns = self.ns(*host);
            run(
                "ip",
                &[
                    "netns", "exec", &ns, "nft", "delete", "table", "inet", &table,
                ],
            );
        }
    }

    /// Packets sent and received on `net`'s interface of `host` so far.
    pub fn packets(&self, host: u8, net: Net) -> (u64, u64) {
        let ns = self.ns(host);
        let read = |counter: &str| -> u64 {
            let path = format!("/sys/class/net/{}/statistics/{counter}", net.device());
            let output = Command::new("ip")
                .args(["netns", "exec", &ns, "cat", &path])
                .output()
                .unwrap();
            String::from_utf8_lossy(&output.stdout)
                .trim()
                .parse()
                .unwrap()
        };
        (read("tx_packets"), read("rx_packets"))
    }
}

impl Drop for TwoBridgeLan {
    fn drop(&mut self) {
        for host in &self.hosts {
            run_quietly("ip", &["netns", "del", &self.ns(*host)]);
            for net in [Net::A, Net::B] {
                run_quietly(
                    "ip",
                    &[
                        "link",
                        "del",
                        &format!("{}{host}{}", self.tag, net.letter()),
                    ],
                );
            }
        }
        for net in [Net::A, Net::B] {
            run_quietly("ip", &["link", "del", &self.bridge(net)]);
        }
    }
}
