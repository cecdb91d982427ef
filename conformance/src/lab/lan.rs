//! The virtual LAN of one run: a network namespace per node (three controllers, the actuator
//! side, the camera), each joined by a veth pair (`a0`, `b0` inside) to two Linux bridges,
//! net A and net B.
//!
//! Controllers' namespaces are set as RL's package sets a controller's host
//! (`unres_qlen_bytes = 0`, `retrans_time_ms = 50`, impl/debian/60-rl.conf).
//!
//! Every node has an address on both nets with the same host byte (net A 10.201.1.N/24 on
//! `a0`, net B 10.202.1.N/24 on `b0`; controllers 1-3, actuator 10, camera 20), and multicast
//! is routed to `a0` (RustDDS picks its multicast interfaces itself and sends on both; the
//! route is for peers that follow the routing table). There is no route and no forwarding
//! between the nets. RL's own participant uses both nets, the controllers' network alarm
//! participants one each (DDS domains `domain+1` on A, `domain+2` on B), so a controller-level
//! fault (a partition, a cut, loss) must hit both nets, and a fault of one net or one link
//! (`super::faults`: `LinkDown`, `NetworkDown`) leaves the other carrying RL's traffic.
//! Names start with the run's prefix (`lab` and four hex digits), so interface names stay
//! within Linux's 15 characters and runs never collide.
//!
//! Everything is removed when the [`Lan`] is dropped (also while a panic unwinds) and, on
//! SIGINT, SIGTERM or SIGHUP, by the handler [`install_signal_cleanup`] starts: it removes
//! every LAN still registered, killing the processes inside, and exits 130.

use super::error::LabError;
use super::host;
use std::sync::Mutex;

/// One machine of the LAN.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Node {
    /// Controller 1, 2 or 3.
    Controller(u8),
    /// The actuator side: `rl servo --json` and the Connext reader.
    Actuator,
    /// The camera: `rl shapes`.
    Camera,
}

/// The controller ids of a formation.
pub const CONTROLLER_IDS: [u8; 3] = [1, 2, 3];

impl Node {
    /// Every node, controllers first.
    pub fn all() -> [Node; 5] {
        [
            Node::Controller(1),
            Node::Controller(2),
            Node::Controller(3),
            Node::Actuator,
            Node::Camera,
        ]
    }

    /// A short name, part of namespace and link names.
    pub fn short(self) -> String {
        match self {
            Node::Controller(id) => format!("c{id}"),
            Node::Actuator => "act".into(),
            Node::Camera => "cam".into(),
        }
    }

    /// The last byte of its addresses, the same on both nets.
    fn host_byte(self) -> u8 {
        match self {
            Node::Controller(id) => id,
            Node::Actuator => 10,
            Node::Camera => 20,
        }
    }

    /// Its address on `net`.
    pub fn addr(self, net: Net) -> String {
        format!("{}.{}", net.subnet(), self.host_byte())
    }

    /// Its addresses on both nets, A first.
    pub fn addrs(self) -> [String; 2] {
        Net::BOTH.map(|net| self.addr(net))
    }
}

/// The multicast range, routed to net A.
pub const MULTICAST: &str = "224.0.0.0/4";

/// The run prefixes whose LANs exist now, for the signal handler.
static LIVE_PREFIXES: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// The two nets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub enum Net {
    A,
    B,
}

impl Net {
    /// Both nets, A first.
    pub const BOTH: [Net; 2] = [Net::A, Net::B];

    fn letter(self) -> char {
        match self {
            Net::A => 'a',
            Net::B => 'b',
        }
    }

    /// The first three bytes of its /24.
    fn subnet(self) -> &'static str {
        match self {
            Net::A => "10.201.1",
            Net::B => "10.202.1",
        }
    }

    /// The interface inside each namespace that joins this net.
    pub fn inside(self) -> String {
        format!("{}0", self.letter())
    }

    /// `A` or `B`, as RL's network alarms name it.
    pub fn name(self) -> &'static str {
        match self {
            Net::A => "A",
            Net::B => "B",
        }
    }
}

impl std::fmt::Display for Net {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "net {}", self.name())
    }
}

/// A LAN that exists until dropped.
pub struct Lan {
    pub prefix: String,
}

impl Lan {
    /// A fresh prefix: `lab` and four hex digits from the pid and the clock.
    pub fn fresh_prefix() -> String {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let mixed = (std::process::id() ^ nanos.rotate_left(7)) & 0xffff;
        format!("lab{mixed:04x}")
    }

    /// Builds the LAN; on an error, whatever was built is removed again.
    pub fn build(prefix: &str) -> Result<Lan, LabError> {
        if let Ok(mut live) = LIVE_PREFIXES.lock() {
            live.push(prefix.to_string());
        }
        let lan = Lan {
            prefix: prefix.to_string(),
        };
        for net in Net::BOTH {
            let bridge = lan.bridge(net);
            host::run("ip", &["link", "add", &bridge, "type", "bridge"])?;
            host::run("ip", &["link", "set", &bridge, "up"])?;
        }
        for node in Node::all() {
            lan.wire(node)?;
        }
        Ok(lan)
    }

    /// A node's namespace, its links to both bridges, its addresses and multicast route.
    fn wire(&self, node: Node) -> Result<(), LabError> {
        let ns = self.ns(node);
        host::run("ip", &["netns", "add", &ns])?;
        host::run("ip", &["-n", &ns, "link", "set", "lo", "up"])?;
        for net in Net::BOTH {
            let outside = self.link(node, net);
            let inside = net.inside();
            host::run(
                "ip",
                &[
                    "link", "add", &outside, "type", "veth", "peer", "name", &inside, "netns", &ns,
                ],
            )?;
            host::run(
                "ip",
                &["link", "set", &outside, "master", &self.bridge(net), "up"],
            )?;
            host::run("ip", &["-n", &ns, "link", "set", &inside, "up"])?;
            let addr = format!("{}/24", node.addr(net));
            host::run("ip", &["-n", &ns, "addr", "add", &addr, "dev", &inside])?;
        }
        if let Node::Controller(_) = node {
            // As a controller's host is deployed (impl/debian/60-rl.conf): a datagram for an
            // unresolved neighbour is dropped, not sent seconds late when the link is back,
            // and an unresolved neighbour is probed every 50 ms, not every second.
            for net in Net::BOTH {
                let queue = rl_layer::link_watch::unresolved_queue_setting(&net.inside());
                let probe = rl_layer::link_watch::neighbour_probe_setting(&net.inside());
                let probe_ms = rl_layer::link_watch::NEIGHBOUR_PROBE_MS;
                host::run(
                    "ip",
                    &[
                        "netns",
                        "exec",
                        &ns,
                        "sh",
                        "-c",
                        &format!("echo 0 > {queue} && echo {probe_ms} > {probe}"),
                    ],
                )?;
            }
        }
        let multicast_dev = Net::A.inside();
        host::run(
            "ip",
            &["-n", &ns, "route", "add", MULTICAST, "dev", &multicast_dev],
        )
    }

    pub fn ns(&self, node: Node) -> String {
        format!("{}{}", self.prefix, node.short())
    }

    pub fn bridge(&self, net: Net) -> String {
        format!("{}br{}", self.prefix, net.letter())
    }

    /// The host-side end of a node's veth pair into `net`.
    pub fn link(&self, node: Node, net: Net) -> String {
        format!("{}{}{}", self.prefix, node.short(), net.letter())
    }
}

impl Drop for Lan {
    fn drop(&mut self) {
        remove(&self.prefix);
        if let Ok(mut live) = LIVE_PREFIXES.lock() {
            live.retain(|p| *p != self.prefix);
        }
    }
}

/// Removes everything named with `prefix`: the processes in its namespaces (SIGKILL), the
/// namespaces, the links and bridges. Errors are ignored: this runs on the way out.
pub fn remove(prefix: &str) {
    let namespaces: Vec<String> = host::stdout_of("ip", &["netns", "list"])
        .lines()
        .filter_map(|line| line.split_whitespace().next())
        .filter(|name| name.starts_with(prefix))
        .map(str::to_string)
        .collect();
    for ns in &namespaces {
        for pid in host::stdout_of("ip", &["netns", "pids", ns]).split_whitespace() {
            if let Ok(pid) = pid.parse::<i32>() {
                // SAFETY: kill(2) has no memory effects.
                unsafe { libc::kill(pid, libc::SIGKILL) };
            }
        }
        let _ = host::run("ip", &["netns", "del", ns]);
    }
    for link in links_named(prefix) {
        let _ = host::run("ip", &["link", "del", &link]);
    }
}

/// Host links whose names start with `prefix`.
fn links_named(prefix: &str) -> Vec<String> {
    host::stdout_of("ip", &["-o", "link", "show"])
        .lines()
        .filter_map(|line| line.split(':').nth(1))
        .map(|name| name.trim().split('@').next().unwrap_or("").to_string())
        .filter(|name| name.starts_with(prefix))
        .collect()
}

/// Removes every lab LAN on this host (`lab` + four hex digits), also other runs' (`lab clean`
/// after a run that was killed with SIGKILL). Returns the prefixes removed.
pub fn remove_all_leftovers() -> Vec<String> {
    let mut prefixes: Vec<String> = host::stdout_of("ip", &["netns", "list"])
        .lines()
        .filter_map(|line| line.split_whitespace().next())
        .chain(links_named("lab").iter().map(String::as_str))
        .filter_map(lab_prefix)
        .collect();
    prefixes.sort();
    prefixes.dedup();
    for prefix in &prefixes {
        remove(prefix);
    }
    prefixes
}

/// `lab1f2e` of a name like `lab1f2ec1`, if it is a lab name.
fn lab_prefix(name: &str) -> Option<String> {
    let prefix = name.get(..7)?;
    let hex = prefix.strip_prefix("lab")?;
    hex.chars()
        .all(|c| c.is_ascii_hexdigit())
        .then(|| prefix.to_string())
}

/// On SIGINT, SIGTERM or SIGHUP: remove every live LAN (and so its processes), exit 130.
pub fn install_signal_cleanup() -> Result<(), LabError> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
        .map_err(|e| LabError::command("signal-hook", &["register"], e.to_string()))?;
    std::thread::spawn(move || {
        if let Some(signal) = signals.forever().next() {
            eprintln!("lab: signal {signal}: removing the virtual LAN and its processes");
            let prefixes = LIVE_PREFIXES.lock().map(|l| l.clone()).unwrap_or_default();
            for prefix in prefixes {
                remove(&prefix);
            }
            std::process::exit(130);
        }
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_fit_linux_interface_names() {
        let lan = Lan {
            prefix: "labffff".into(),
        };
        for node in Node::all() {
            for net in [Net::A, Net::B] {
                assert!(lan.link(node, net).len() <= 15, "{}", lan.link(node, net));
            }
        }
        assert!(lan.bridge(Net::B).len() <= 15);
        std::mem::forget(lan);
    }

    #[test]
    fn a_node_has_the_same_host_byte_on_both_nets() {
        assert_eq!(
            Node::Controller(2).addrs(),
            ["10.201.1.2".to_string(), "10.202.1.2".to_string()]
        );
        assert_eq!(Node::Camera.addr(Net::B), "10.202.1.20");
        assert_eq!(Net::B.inside(), "b0");
    }

    #[test]
    fn only_lab_names_are_leftovers() {
        assert_eq!(lab_prefix("lab1f2ec1"), Some("lab1f2e".into()));
        assert_eq!(lab_prefix("lab1f2e"), Some("lab1f2e".into()));
        assert_eq!(lab_prefix("labzzzzc1"), None);
        assert_eq!(lab_prefix("eth0"), None);
    }
}
