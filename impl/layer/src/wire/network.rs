//! The network monitor's topics: the network heartbeat (the paper's RLNHB), which each
//! controller's Network Alarm Participant publishes on each network with its row of the link
//! matrix, and the network alarm, raised and cleared about a network or one controller's
//! transceiver on one network.

use super::codes::controller_id;
use super::{WireError, WireSample};
use crate::core::network::{AlarmSubject, Hearing, LinkState, Network, NetworkHeartbeat};
use crate::core::types::{ControllerId, Incarnation};
use rustdds::dds::key::{CdrEncodingMaxSize, CdrEncodingSize, Key};
use rustdds::Keyed;
use serde::{Deserialize, Serialize};

/// DDS type name of the network heartbeat topic.
pub const NETWORK_HEARTBEAT_TYPE_NAME: &str = "rl::NetworkHeartbeatSample";
/// DDS type name of the network alarm topic.
pub const NETWORK_ALARM_TYPE_NAME: &str = "rl::NetworkAlarmSample";
/// The number of redundant networks.
pub const NETWORK_COUNT: u8 = 2;
/// The longest alarm cause accepted from the wire, in bytes: a cause names a few findings.
pub const CAUSE_MAX_BYTES: usize = 512;

/// `heard_on_a` / `heard_on_b` codes: what the sender hears of peer id `slot + 1`.
pub const LINK_UNKNOWN: u8 = 0;
/// Link code: the sender heard that peer's network heartbeat within the deadline.
pub const LINK_GOOD: u8 = 1;
/// Link code: the sender missed the deadline for that peer's network heartbeat.
pub const LINK_FAIL: u8 = 2;

/// The network heartbeat, keyed by the sender's id. The network it stands for is the
/// network it arrived on (each network has its own participant and domain), never a field.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetworkHeartbeatSample {
    /// The sender's controller id (0 is refused): the key.
    pub from_id: u8,
    /// What the sender hears of controllers 1, 2, 3 on network A (`LINK_*` codes).
    pub heard_on_a: [u8; 3],
    /// The same on network B.
    pub heard_on_b: [u8; 3],
}

impl Keyed for NetworkHeartbeatSample {
    type K = u8;
    fn key(&self) -> u8 {
        self.from_id
    }
}

fn link_code(state: LinkState) -> u8 {
    match state {
        LinkState::Unknown => LINK_UNKNOWN,
        LinkState::Good => LINK_GOOD,
        LinkState::Fail => LINK_FAIL,
    }
}

fn link_from_code(field: &'static str, code: u8) -> Result<LinkState, WireError> {
    match code {
        LINK_UNKNOWN => Ok(LinkState::Unknown),
        LINK_GOOD => Ok(LinkState::Good),
        LINK_FAIL => Ok(LinkState::Fail),
        other => Err(WireError::new(field, format!("unknown link code {other}"))),
    }
}

impl WireSample for NetworkHeartbeatSample {
    type Value = NetworkHeartbeat;
    const TYPE_NAME: &'static str = NETWORK_HEARTBEAT_TYPE_NAME;

    fn decode(self) -> Result<NetworkHeartbeat, WireError> {
        let from = controller_id("network_heartbeat.from_id", self.from_id)?;
        let mut hearing = Hearing::default();
        for slot in 0..3 {
            hearing.heard[slot] = [
                link_from_code("network_heartbeat.heard_on_a", self.heard_on_a[slot])?,
                link_from_code("network_heartbeat.heard_on_b", self.heard_on_b[slot])?,
            ];
        }
        Ok(NetworkHeartbeat { from, hearing })
    }

    fn encode(heartbeat: &NetworkHeartbeat) -> NetworkHeartbeatSample {
        let row = |network: Network| {
            heartbeat
                .hearing
                .heard
                .map(|s| link_code(s[network.index()]))
        };
        NetworkHeartbeatSample {
            from_id: heartbeat.from,
            heard_on_a: row(Network::A),
            heard_on_b: row(Network::B),
        }
    }
}

/// How sure the reporter is of a network alarm.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Certainty {
    /// Every smallest explanation of the failed links holds it.
    Concluded,
    /// Some smallest explanations hold it, others do not (the cause lists them).
    Suspected,
    /// Links failed that no small set of faults explains.
    Unexplained,
}

impl Certainty {
    fn code(self) -> u8 {
        match self {
            Certainty::Concluded => 1,
            Certainty::Suspected => 2,
            Certainty::Unexplained => 3,
        }
    }

    fn from_code(code: u8) -> Result<Certainty, WireError> {
        match code {
            1 => Ok(Certainty::Concluded),
            2 => Ok(Certainty::Suspected),
            3 => Ok(Certainty::Unexplained),
            other => Err(WireError::new(
                "network_alarm.certainty",
                format!("unknown certainty code {other}"),
            )),
        }
    }

    /// As written in events and `rl status`.
    pub fn name(self) -> &'static str {
        match self {
            Certainty::Concluded => "concluded",
            Certainty::Suspected => "suspected",
            Certainty::Unexplained => "unexplained",
        }
    }
}

/// A network alarm raised or cleared by one controller's network monitor.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetworkAlarm {
    /// The controller whose monitor raised or cleared it.
    pub reporter: ControllerId,
    /// The reporter's life: a new value at every start.
    pub reporter_incarnation: Incarnation,
    /// What it is about: a whole network, or one controller's transceiver on one network.
    pub subject: AlarmSubject,
    /// `Some` while raised (how sure), `None` once cleared.
    pub raised: Option<Certainty>,
    /// Why, in words (empty when cleared).
    pub cause: String,
}

/// `cause` as it fits on the wire: unchanged up to [`CAUSE_MAX_BYTES`], otherwise cut at a
/// character boundary and ended with `…`. A suspected verdict can list many alternatives
/// (the monitor's longest cause is almost 2 KB); the alarm must be published all the same,
/// and the event and console line carry the whole text.
pub fn fit_cause(cause: &str) -> String {
    const CUT: &str = "…";
    if cause.len() <= CAUSE_MAX_BYTES {
        return cause.to_string();
    }
    let mut end = CAUSE_MAX_BYTES - CUT.len();
    while !cause.is_char_boundary(end) {
        end -= 1;
    }
    format!("{}{CUT}", &cause[..end])
}

/// One instance of the network alarm topic per reporter and subject, so a late reader
/// (transient local) gets each alarm's latest state: raised with its cause, or cleared.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct NetworkAlarmKey {
    /// The reporter's controller id.
    pub reporter_id: u8,
    /// The network: 0 = A, 1 = B.
    pub network: u8,
    /// 0 for a whole network.
    pub controller_id: u8,
}

impl CdrEncodingSize for NetworkAlarmKey {
    fn cdr_encoding_max_size() -> CdrEncodingMaxSize {
        CdrEncodingMaxSize::Bytes(3)
    }
}

impl Key for NetworkAlarmKey {}

/// The network alarm sample. `controller_id` 0 means the whole network; otherwise the alarm
/// is about that controller's transceiver on `network`. `certainty` 0 means cleared.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetworkAlarmSample {
    /// The reporter's controller id (0 is refused).
    pub reporter_id: u8,
    /// The network the alarm is about: 0 = A, 1 = B (others are rejected).
    pub network: u8,
    /// The controller whose transceiver it is about; 0 = the whole network.
    pub controller_id: u8,
    /// The reporter's incarnation.
    pub reporter_incarnation: u64,
    /// 0 cleared, 1 concluded, 2 suspected, 3 unexplained (others are rejected).
    pub certainty: u8,
    /// Why, in words: at most [`CAUSE_MAX_BYTES`] (see [`fit_cause`]), empty when cleared.
    pub cause: String,
}

impl Keyed for NetworkAlarmSample {
    type K = NetworkAlarmKey;
    fn key(&self) -> NetworkAlarmKey {
        NetworkAlarmKey {
            reporter_id: self.reporter_id,
            network: self.network,
            controller_id: self.controller_id,
        }
    }
}

fn network_from_code(code: u8) -> Result<Network, WireError> {
    match code {
        0 => Ok(Network::A),
        1 => Ok(Network::B),
        other => Err(WireError::new(
            "network_alarm.network",
            format!("network {other} (there are {NETWORK_COUNT})"),
        )),
    }
}

impl WireSample for NetworkAlarmSample {
    type Value = NetworkAlarm;
    const TYPE_NAME: &'static str = NETWORK_ALARM_TYPE_NAME;

    fn decode(self) -> Result<NetworkAlarm, WireError> {
        let network = network_from_code(self.network)?;
        let subject = match self.controller_id {
            0 => AlarmSubject::Network(network),
            id => AlarmSubject::Transceiver {
                controller: controller_id("network_alarm.controller_id", id)?,
                network,
            },
        };
        let raised = match self.certainty {
            0 => None,
            code => Some(Certainty::from_code(code)?),
        };
        if self.cause.len() > CAUSE_MAX_BYTES {
            return Err(WireError::new(
                "network_alarm.cause",
                format!("{} bytes (at most {CAUSE_MAX_BYTES})", self.cause.len()),
            ));
        }
        Ok(NetworkAlarm {
            reporter: controller_id("network_alarm.reporter_id", self.reporter_id)?,
            reporter_incarnation: self.reporter_incarnation,
            subject,
            raised,
            cause: self.cause,
        })
    }

    fn encode(alarm: &NetworkAlarm) -> NetworkAlarmSample {
        let (network, controller_id) = match alarm.subject {
            AlarmSubject::Network(network) => (network, 0),
            AlarmSubject::Transceiver {
                controller,
                network,
            } => (network, controller),
        };
        NetworkAlarmSample {
            reporter_id: alarm.reporter,
            network: network.index() as u8,
            controller_id,
            reporter_incarnation: alarm.reporter_incarnation,
            certainty: alarm.raised.map_or(0, Certainty::code),
            cause: alarm.cause.clone(),
        }
    }
}
