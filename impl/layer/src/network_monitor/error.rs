//! Why the network monitor could not start or stopped: each case typed, so the supervisor's
//! retry log and a test name the network, the address and the cause.

use crate::core::network::Network;
use crate::dds::DdsError;
use std::net::Ipv4Addr;

/// A network name of the configuration that is not an IPv4 address of this host.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Unresolved {
    /// `networks.a`/`b` is an address no interface has.
    #[error("no interface of this host has the address {0}")]
    NoSuchAddress(Ipv4Addr),
    /// `networks.a`/`b` names an interface without an IPv4 address, or none by that name.
    #[error("interface {0} has no IPv4 address (or does not exist)")]
    NoAddressOnInterface(String),
}

/// Why the monitor is not running; the supervisor retries every few seconds.
#[derive(Debug, thiserror::Error)]
pub enum MonitorError {
    /// `networks.a` and `networks.b` are not both set.
    #[error("both networks must be configured")]
    NotConfigured,
    /// The host's interface addresses could not be listed.
    #[error("cannot list this host's addresses: {0}")]
    Addresses(#[source] std::io::Error),
    /// A network's name is not an address of this host (an interface down, a cable out).
    #[error("network {network}: {problem}")]
    Unresolved {
        /// Which network.
        network: Network,
        /// Why its name did not resolve.
        problem: Unresolved,
    },
    /// The participant of a network could not be created on its address.
    #[error("network {network} ({address}): {source}")]
    Bind {
        /// Which network.
        network: Network,
        /// The address it was bound to.
        address: Ipv4Addr,
        /// What DDS said.
        source: DdsError,
    },
    /// The monitor's event poll failed (`doing` says at which step).
    #[error("{doing}: {source}")]
    Poll {
        /// What the monitor was doing.
        doing: &'static str,
        /// What the system said.
        source: std::io::Error,
    },
    /// The monitor's thread panicked; it is restarted.
    #[error("the network monitor panicked; restarting it")]
    Panicked,
}
