//! The `[networks]` section: the two redundant networks and the network monitor's timing.
//!
//! Each network is named by this controller's IPv4 address on it or by its interface
//! (`eth0`, `eth1`: resolved to the interface's IPv4 address when the monitor starts). With
//! neither set the controller runs on whatever networks the host has and no network monitor
//! runs; with both, it sends every datagram on both networks and runs the Network Alarm
//! Participant (one DDS participant per network, on domains `dds.domain + 1` for A and
//! `dds.domain + 2` for B, docs/protocol.md "Network monitoring").

use super::error::{check, quoted, InvalidValue};
use super::DOMAIN_MAX;
use serde::{Deserialize, Serialize};
use std::net::Ipv4Addr;

/// Linux's limit on an interface name's length.
const INTERFACE_NAME_MAX: usize = 15;

/// One network as configured: an address or an interface.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NetworkName {
    /// This controller's IPv4 address on the network, which must be one of the host's.
    Address(Ipv4Addr),
    /// An interface name (`eth1`), resolved to its first IPv4 address when the monitor starts.
    Interface(String),
}

impl NetworkName {
    /// Reads `eth1` or `10.202.1.2`; `None` for text that is neither.
    pub fn parse(text: &str) -> Option<NetworkName> {
        if let Ok(address) = text.parse::<Ipv4Addr>() {
            return Some(NetworkName::Address(address));
        }
        let is_interface = !text.is_empty()
            && text.len() <= INTERFACE_NAME_MAX
            && text
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | '@'))
            && !text.chars().all(|c| c.is_ascii_digit() || c == '.');
        is_interface.then(|| NetworkName::Interface(text.to_string()))
    }
}

impl std::fmt::Display for NetworkName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NetworkName::Address(address) => write!(f, "{address}"),
            NetworkName::Interface(name) => f.write_str(name),
        }
    }
}

/// The two networks and the monitor's timing (paper: 4 Hz, deadline two periods).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Networks {
    /// Network A: this controller's IPv4 address on it, or its interface. Empty: not set.
    pub a: String,
    /// Network B, the same.
    pub b: String,
    /// The network heartbeat period.
    pub heartbeat_period_ms: u64,
    /// A link fails after this many periods without its heartbeat.
    pub deadline_periods: u32,
    /// An alarm is raised once its subject has been implicated this long: more than one
    /// period, so the conclusions seen while a dead network's links miss their deadlines one
    /// after another (over one period) raise nothing.
    pub raise_after_ms: u64,
    /// An alarm clears once its links have been good this many periods in a row.
    pub clear_after_periods: u32,
}

impl Default for Networks {
    fn default() -> Networks {
        Networks {
            a: String::new(),
            b: String::new(),
            heartbeat_period_ms: 250,
            deadline_periods: 2,
            raise_after_ms: 375,
            clear_after_periods: 4,
        }
    }
}

impl Networks {
    /// Both networks, parsed, when both are set (validation guarantees both or neither).
    pub fn pair(&self) -> Option<(NetworkName, NetworkName)> {
        Some((NetworkName::parse(&self.a)?, NetworkName::parse(&self.b)?))
    }

    /// Whether two networks are configured.
    pub fn configured(&self) -> bool {
        !self.a.is_empty() || !self.b.is_empty()
    }

    /// The monitor's DDS domains, A then B, next to RL's own `domain`.
    pub fn monitor_domains(domain: u16) -> [u16; 2] {
        [domain.saturating_add(1), domain.saturating_add(2)]
    }

    /// Checks both networks (both or neither, and different), the monitor's timing, and that
    /// RL's `domain` leaves room for the monitor's two domains.
    pub fn validate(&self, domain: u16) -> Result<(), InvalidValue> {
        for (field, text) in [("networks.a", &self.a), ("networks.b", &self.b)] {
            check(
                text.is_empty() || NetworkName::parse(text).is_some(),
                field,
                quoted(text),
                || {
                    "must be an IPv4 address (\"10.202.1.2\") or an interface name (\"eth1\")"
                        .into()
                },
            )?;
        }
        if self.a.is_empty() != self.b.is_empty() {
            let (field, text) = if self.a.is_empty() {
                ("networks.a", &self.a)
            } else {
                ("networks.b", &self.b)
            };
            return Err(InvalidValue::new(
                field,
                quoted(text),
                "must be set too: the network monitor needs both networks (or neither)",
            ));
        }
        check(
            self.a.is_empty() || self.a != self.b,
            "networks.b",
            quoted(&self.b),
            || "must differ from networks.a".into(),
        )?;
        check(
            (10..=10_000).contains(&self.heartbeat_period_ms),
            "networks.heartbeat_period_ms",
            self.heartbeat_period_ms,
            || "must be 10..=10000".into(),
        )?;
        for (field, periods) in [
            ("networks.deadline_periods", self.deadline_periods),
            ("networks.clear_after_periods", self.clear_after_periods),
        ] {
            check((1..=100).contains(&periods), field, periods, || {
                "must be 1..=100 periods".into()
            })?;
        }
        check(
            self.raise_after_ms > self.heartbeat_period_ms && self.raise_after_ms <= 600_000,
            "networks.raise_after_ms",
            self.raise_after_ms,
            || {
                format!(
                    "must be more than networks.heartbeat_period_ms ({}) and at most 600000",
                    self.heartbeat_period_ms
                )
            },
        )?;
        let [_, domain_b] = Networks::monitor_domains(domain);
        check(
            !self.configured() || domain_b <= DOMAIN_MAX,
            "dds.domain",
            domain,
            || {
                format!(
                    "must be at most {} with [networks] set (the network monitor uses the next two domains)",
                    DOMAIN_MAX - 2
                )
            },
        )
    }
}
