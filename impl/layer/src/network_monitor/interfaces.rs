//! Which IPv4 address this host has on a configured network: the address itself, checked to
//! be one of this host's, or the interface's first IPv4 address.
//!
//! Read with getifaddrs(3) (through nix) each time, so a USB Ethernet adapter that comes up after the
//! controller started is found on the next try.

use super::error::Unresolved;
use crate::config::NetworkName;
use std::net::Ipv4Addr;

/// One interface address of this host.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InterfaceAddress {
    /// The interface's name (`eth0`, `lo`).
    pub interface: String,
    /// One IPv4 address it has.
    pub address: Ipv4Addr,
}

/// Every IPv4 address of this host's interfaces, in the kernel's order.
pub fn ipv4_addresses() -> std::io::Result<Vec<InterfaceAddress>> {
    let list = nix::ifaddrs::getifaddrs().map_err(std::io::Error::from)?;
    Ok(list
        .filter_map(|entry| {
            let address = entry.address.as_ref()?.as_sockaddr_in()?.ip();
            Some(InterfaceAddress {
                interface: entry.interface_name,
                address,
            })
        })
        .collect())
}

/// The address to bind for `name` among `addresses`, or why there is none.
pub fn resolve(name: &NetworkName, addresses: &[InterfaceAddress]) -> Result<Ipv4Addr, Unresolved> {
    match name {
        NetworkName::Address(address) => addresses
            .iter()
            .any(|a| a.address == *address)
            .then_some(*address)
            .ok_or(Unresolved::NoSuchAddress(*address)),
        NetworkName::Interface(interface) => addresses
            .iter()
            .find(|a| a.interface == *interface)
            .map(|a| a.address)
            .ok_or_else(|| Unresolved::NoAddressOnInterface(interface.clone())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_resolve_to_this_hosts_addresses_only() {
        let host = [
            InterfaceAddress {
                interface: "lo".into(),
                address: Ipv4Addr::LOCALHOST,
            },
            InterfaceAddress {
                interface: "eth1".into(),
                address: Ipv4Addr::new(10, 202, 1, 2),
            },
        ];
        let eth1 = NetworkName::Interface("eth1".into());
        assert_eq!(resolve(&eth1, &host), Ok(Ipv4Addr::new(10, 202, 1, 2)));
        let by_address = NetworkName::Address(Ipv4Addr::new(10, 202, 1, 2));
        assert_eq!(
            resolve(&by_address, &host),
            Ok(Ipv4Addr::new(10, 202, 1, 2))
        );
        let missing = NetworkName::Address(Ipv4Addr::new(10, 202, 1, 9));
        let no_such = Unresolved::NoSuchAddress(Ipv4Addr::new(10, 202, 1, 9));
        assert_eq!(resolve(&missing, &host), Err(no_such.clone()));
        assert!(no_such.to_string().contains("10.202.1.9"));
        let absent = NetworkName::Interface("eth7".into());
        let no_address = Unresolved::NoAddressOnInterface("eth7".into());
        assert_eq!(resolve(&absent, &host), Err(no_address.clone()));
        assert!(no_address.to_string().contains("eth7"));
    }

    #[test]
    fn this_host_has_loopback() {
        let addresses = ipv4_addresses().unwrap();
        assert!(
            addresses.iter().any(|a| a.address == Ipv4Addr::LOCALHOST),
            "{addresses:?}"
        );
    }
}
