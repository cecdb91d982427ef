//! Which IPv4 address this host has on a configured network: the address itself, checked to
//! be one of this host's, or the interface's first IPv4 address.
//!
//! Read with getifaddrs(3) each time, so a USB Ethernet adapter that comes up after the
//! controller started is found on the next try.

use super::error::Unresolved;
use crate::config::NetworkName;
use std::ffi::CStr;
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
    let mut list: *mut libc::ifaddrs = std::ptr::null_mut();
    // SAFETY: getifaddrs fills `list` with a linked list we free below with freeifaddrs.
    if unsafe { libc::getifaddrs(&mut list) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    let mut found = Vec::new();
    let mut cursor = list;
    while !cursor.is_null() {
        // SAFETY: `cursor` is a node of the list getifaddrs returned, not yet freed.
        let entry = unsafe { &*cursor };
        cursor = entry.ifa_next;
        if entry.ifa_addr.is_null() || entry.ifa_name.is_null() {
            continue;
        }
        // SAFETY: ifa_addr points at a sockaddr whose family says its real type.
        let family = i32::from(unsafe { (*entry.ifa_addr).sa_family });
        if family != libc::AF_INET {
            continue;
        }
        // SAFETY: an AF_INET address is a sockaddr_in.
        let sin = unsafe { &*(entry.ifa_addr as *const libc::sockaddr_in) };
        let address = Ipv4Addr::from(u32::from_be(sin.sin_addr.s_addr));
        // SAFETY: ifa_name is a NUL-terminated string owned by the list.
        let interface = unsafe { CStr::from_ptr(entry.ifa_name) }
            .to_string_lossy()
            .into_owned();
        found.push(InterfaceAddress { interface, address });
    }
    // SAFETY: `list` came from getifaddrs and is freed once.
    unsafe { libc::freeifaddrs(list) };
    Ok(found)
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
