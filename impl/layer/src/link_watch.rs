//! Whether this controller is cut off at its own links: no carrier on any of its networks (a
//! pulled cable, a dead switch port, a transceiver gone).
//!
//! A Primary whose cable is pulled keeps commanding at 30 into a dead link. The actuator
//! follows the Secondary after the command deadline, and the peers make it Primary after the
//! peer deadline; when the cable is plugged back in, the old Primary's commands reach the
//! actuator at once, still at 30, before any heartbeat could tell it what happened meanwhile:
//! the actuator moves back, and away again when the merge puts it below (a flapping cable: a
//! switch at every flap). Only the controller itself can know, at once, that its links are
//! down, so it acts on that as on a stall (crate::stall): it starts again as a new
//! incarnation, silent until it has heard a round, and comes back below the controllers that
//! kept the system running. Loss, partitions and a dead link beyond the switch leave the
//! carrier up and are left to the voting (docs/protocol.md, "Partitions").
//!
//! The watched links are the configured networks' interfaces (`[networks]`, resolved to an
//! interface by address or name), or without them every other interface than loopback that
//! has an IPv4 address. A netlink socket subscribed to link changes wakes the voting loop the
//! moment a carrier goes, so the controller is silent before the actuator's command deadline
//! passes; without the socket (no netlink) the loop looks at every wake-up.
//!
//! What was sent while the cable was out must not arrive when it is back. Linux keeps the
//! datagrams for a neighbour whose address is not resolved (the link is down, ARP gets no
//! answer) and sends them all once it is: commands seconds old, of writers deleted since,
//! which a reader with the seed's QoS takes as new (measured: a Connext reader gave one such
//! sample the instance between two of the new Primary's). RL's hosts set that queue to
//! 0 bytes (`unres_qlen_bytes = 0`, the package's sysctl.d file), with which Linux keeps only
//! the newest datagram, a moment old while the controller keeps sending; [`LinkWatch::new`] warns at
//! start for every watched link that keeps one.
//!
//! The same holds after a dead switch (a net that carries nothing while carriers stay up): the
//! neighbour entries of the hosts it reached go unresolved, and Linux probes an unresolved
//! neighbour once per `retrans_time_ms`, 1000 ms by default. Every unicast datagram before the
//! probe after the heal is answered is dropped, discovery's repairs included, so a reader
//! cannot match a writer created meanwhile for up to a second (measured: `both-networks-down`
//! waited 590 ms past the heal, docs/faults.md). RL's hosts probe every
//! [`NEIGHBOUR_PROBE_MS`], and [`LinkWatch::new`] warns for a watched link that probes slower.

use crate::config::{NetworkName, Networks};
use nix::ifaddrs::getifaddrs;
use nix::net::if_::InterfaceFlags;
use nix::sys::socket::{
    bind, recv, socket, AddressFamily, MsgFlags, NetlinkAddr, SockFlag, SockProtocol, SockType,
};
use std::collections::BTreeSet;
use std::net::Ipv4Addr;
use std::os::fd::{AsRawFd, OwnedFd, RawFd};
use tracing::warn;

/// One interface as getifaddrs(3) shows it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Link {
    /// The interface's name (`eth0`).
    pub interface: String,
    /// Its IPv4 addresses.
    pub addresses: Vec<Ipv4Addr>,
    /// A loopback interface (`IFF_LOOPBACK`).
    pub loopback: bool,
    /// Up, with a carrier (`IFF_RUNNING`).
    pub running: bool,
}

/// Every interface of this host, in the kernel's order.
pub fn links() -> std::io::Result<Vec<Link>> {
    let mut found: Vec<Link> = Vec::new();
    for entry in getifaddrs().map_err(std::io::Error::from)? {
        let address = entry
            .address
            .as_ref()
            .and_then(|a| a.as_sockaddr_in())
            .map(|a| a.ip());
        let index = match found
            .iter()
            .position(|l| l.interface == entry.interface_name)
        {
            Some(index) => index,
            None => {
                found.push(Link {
                    interface: entry.interface_name.clone(),
                    addresses: Vec::new(),
                    loopback: entry.flags.contains(InterfaceFlags::IFF_LOOPBACK),
                    running: entry.flags.contains(InterfaceFlags::IFF_RUNNING),
                });
                found.len() - 1
            }
        };
        found[index].addresses.extend(address);
    }
    Ok(found)
}

/// Which interfaces a controller's traffic leaves by.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Watched {
    /// The configured networks, by address or interface.
    Networks(Vec<NetworkName>),
    /// No networks configured: every other interface than loopback with an IPv4 address.
    AllButLoopback,
}

impl Watched {
    /// The configured networks A and B that parse as an address or interface name, or
    /// every interface but loopback when neither does.
    pub fn from_config(networks: &Networks) -> Watched {
        let names: Vec<NetworkName> = [&networks.a, &networks.b]
            .into_iter()
            .filter_map(|text| NetworkName::parse(text))
            .collect();
        if names.is_empty() {
            Watched::AllButLoopback
        } else {
            Watched::Networks(names)
        }
    }

    /// The interfaces `links` shows for these networks.
    fn interfaces(&self, links: &[Link]) -> BTreeSet<String> {
        let is = |link: &Link, name: &NetworkName| match name {
            NetworkName::Address(address) => link.addresses.contains(address),
            NetworkName::Interface(interface) => link.interface == *interface,
        };
        links
            .iter()
            .filter(|link| match self {
                Watched::Networks(names) => names.iter().any(|name| is(link, name)),
                Watched::AllButLoopback => !link.loopback && !link.addresses.is_empty(),
            })
            .map(|link| link.interface.clone())
            .collect()
    }
}

/// What the links say now.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Links {
    /// At least one watched link has a carrier, or none is known yet.
    Attached,
    /// Every watched link is there and none has a carrier.
    Detached,
}

/// The watched links and the netlink socket that says when they change.
#[derive(Debug)]
pub struct LinkWatch {
    watched: Watched,
    /// The interfaces seen for `watched` so far: an address a DHCP client removes when the
    /// carrier goes must not make the interface disappear from the watch.
    known: BTreeSet<String>,
    socket: Option<OwnedFd>,
    last: Links,
}

impl LinkWatch {
    /// Watches `watched`; a netlink socket that cannot be had is one warning (the loop then
    /// looks at every wake-up).
    pub fn new(watched: Watched) -> LinkWatch {
        let socket = link_change_socket()
            .inspect_err(|e| {
                warn!("no netlink socket for link changes ({e}): looking at the links at every wake-up")
            })
            .ok();
        let mut watch = LinkWatch {
            watched,
            known: BTreeSet::new(),
            socket,
            last: Links::Attached,
        };
        watch.last = watch.look();
        for interface in &watch.known {
            if let Some(bytes) = unresolved_queue_bytes(interface).filter(|b| *b > 0) {
                warn!(
                    "{interface} keeps up to {bytes} bytes of datagrams for an unresolved \
                     neighbour and sends them when its link is back: stale commands after a \
                     pulled cable; set net.ipv4.neigh.{interface}.unres_qlen_bytes = 0 \
                     (docs/deploy-pi.md)"
                );
            }
            if let Some(probe_ms) =
                neighbour_probe_ms(interface).filter(|ms| *ms > NEIGHBOUR_PROBE_MS)
            {
                warn!(
                    "{interface} probes an unresolved neighbour every {probe_ms} ms: after a \
                     dead switch comes back, unicast (discovery's repairs) waits up to that \
                     long; set net.ipv4.neigh.{interface}.retrans_time_ms = \
                     {NEIGHBOUR_PROBE_MS} (docs/deploy-pi.md)"
                );
            }
        }
        watch
    }

    /// The socket to wait on for link changes, if there is one.
    pub fn fd(&self) -> Option<RawFd> {
        self.socket.as_ref().map(AsRawFd::as_raw_fd)
    }

    /// Looks at the links when something may have changed (`woke`: the socket said so, or
    /// there is no socket); returns `Some(Detached)` when they have all just gone down and
    /// `Some(Attached)` when one has just come back.
    pub fn changed(&mut self, woke: bool) -> Option<Links> {
        if self.socket.is_some() && !woke {
            return None;
        }
        self.drain();
        let now = self.look();
        (now != self.last).then(|| {
            self.last = now;
            now
        })
    }

    fn look(&mut self) -> Links {
        let links = match links() {
            Ok(links) => links,
            Err(error) => {
                warn!("cannot read this host's interfaces: {error}");
                return self.last;
            }
        };
        self.known.extend(self.watched.interfaces(&links));
        detached(&self.known, &links)
    }

    /// Reads what the socket holds: the messages only say that something changed.
    fn drain(&self) {
        let Some(socket) = &self.socket else {
            return;
        };
        let mut buffer = [0u8; 8192];
        // ENOBUFS (the kernel dropped messages) and EAGAIN both end the drain; the links are
        // read whole afterwards either way.
        while recv(socket.as_raw_fd(), &mut buffer, MsgFlags::MSG_DONTWAIT).is_ok_and(|n| n > 0) {}
    }
}

/// Detached when every one of `known` is among `links` and none is running. An interface
/// that has gone away (a USB adapter unplugged) counts as down.
pub fn detached(known: &BTreeSet<String>, links: &[Link]) -> Links {
    let running = |name: &String| links.iter().any(|l| l.interface == *name && l.running);
    if !known.is_empty() && !known.iter().any(running) {
        Links::Detached
    } else {
        Links::Attached
    }
}

/// How often, at most, RL's hosts probe an unresolved neighbour, in ms (`retrans_time_ms`,
/// the package's sysctl.d file): the wait after a dead net comes back before unicast flows.
pub const NEIGHBOUR_PROBE_MS: u64 = 50;

/// Where Linux keeps how often an interface probes an unresolved neighbour.
pub fn neighbour_probe_setting(interface: &str) -> String {
    format!("/proc/sys/net/ipv4/neigh/{interface}/retrans_time_ms")
}

/// How often that interface probes, in ms, if it can be read.
pub fn neighbour_probe_ms(interface: &str) -> Option<u64> {
    std::fs::read_to_string(neighbour_probe_setting(interface))
        .ok()?
        .trim()
        .parse()
        .ok()
}

/// Where Linux keeps the size of an interface's queue for unresolved neighbours.
pub fn unresolved_queue_setting(interface: &str) -> String {
    format!("/proc/sys/net/ipv4/neigh/{interface}/unres_qlen_bytes")
}

/// The size of that queue, if it can be read.
pub fn unresolved_queue_bytes(interface: &str) -> Option<u64> {
    std::fs::read_to_string(unresolved_queue_setting(interface))
        .ok()?
        .trim()
        .parse()
        .ok()
}

/// A non-blocking netlink socket in the group of link changes (RTMGRP_LINK).
fn link_change_socket() -> nix::Result<OwnedFd> {
    let socket = socket(
        AddressFamily::Netlink,
        SockType::Raw,
        SockFlag::SOCK_NONBLOCK | SockFlag::SOCK_CLOEXEC,
        SockProtocol::NetlinkRoute,
    )?;
    let groups = u32::try_from(libc::RTMGRP_LINK).unwrap_or(1);
    bind(socket.as_raw_fd(), &NetlinkAddr::new(0, groups))?;
    Ok(socket)
}

#[cfg(test)]
mod tests;
