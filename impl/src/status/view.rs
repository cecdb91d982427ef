//! What `rl status --json` prints for one redundancy group, and what `/status.json` and
//! `/groups.json` serve: [`StatusView`] and the views it is made of. These are the stable
//! interface (docs/architecture.md, "`rl status --json`"); the [`Board`](super::Board) builds
//! them, the table and the page only read them.

use rl_layer::core::network::Network;
use rl_layer::core::types::{AlarmReason, ControllerId};
use rl_layer::core::SelfReport;
use rl_layer::wire::Certainty;
use serde::Serialize;

/// One controller as the board last heard it: its last self-report (the heartbeat's fields,
/// flattened: id, incarnation, phase, role, strength, agreed, vote) and how long ago.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ControllerView {
    #[serde(flatten)]
    pub report: SelfReport,
    /// Heard within the dead-man deadline.
    pub alive: bool,
    /// Milliseconds since its last heartbeat.
    pub last_heard_ms: u64,
}

/// A raised controller alarm and who raised it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct AlarmView {
    pub about: ControllerId,
    pub reason: AlarmReason,
    pub raised_by: Vec<ControllerId>,
    /// When the first of them raised it (Unix milliseconds, the raising sample's source
    /// timestamp); `null` if no reporter stamped it.
    pub since_ms: Option<u64>,
}

/// A raised network alarm: about `network` as a whole (`controller` null) or controller
/// `controller`'s transceiver on it; how sure and why, as its first reporter says, and who
/// raised it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct NetworkAlarmView {
    pub network: Network,
    pub controller: Option<ControllerId>,
    pub certainty: Certainty,
    pub cause: String,
    pub raised_by: Vec<ControllerId>,
}

/// What `rl status --json` prints for one group (one line per group and refresh).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StatusView {
    /// The redundancy group it shows (`dds.group`; "" for the group without a name).
    pub group: String,
    pub controllers: Vec<ControllerView>,
    pub alarms: Vec<AlarmView>,
    pub network_alarms: Vec<NetworkAlarmView>,
}
