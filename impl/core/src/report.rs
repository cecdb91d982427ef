//! What a controller says of itself: one struct, sent as the heartbeat and shown as the
//! status, so the two can never disagree on a field.

use crate::types::{
    AlarmReason, Assignment, ControllerId, Holder, Incarnation, Phase, Role, Strength,
};
use serde::{Deserialize, Serialize};

/// A controller's own protocol state, as it announces it (paper: "the RLCHB topic should
/// contain the source Controller ID and its current state").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SelfReport {
    /// The controller's id.
    pub id: ControllerId,
    /// Its process life.
    pub incarnation: Incarnation,
    /// Where it is in the protocol.
    pub phase: Phase,
    /// The role it holds.
    pub role: Option<Role>,
    /// The ownership strength it commands with; `None` = it does not command.
    pub strength: Option<Strength>,
    /// Its last agreed result: `Some` makes it an incumbent of a running system.
    pub agreed: Option<Assignment>,
    /// Its current vote.
    pub vote: Option<Assignment>,
    /// The epoch of its agreed result (0 before it has one).
    #[serde(default)]
    pub epoch: u32,
    /// Its agreed result was agreed without a majority of the last result's members.
    #[serde(default)]
    pub provisional: bool,
    /// The strength of its established command writer: what every reader knows by now. A
    /// writer created in this round is not reported until the next.
    #[serde(default)]
    pub established_strength: Option<Strength>,
    /// F17: the Primary life it took over from, whose commands arrived late. That life, on
    /// hearing it, starts again as a new incarnation.
    #[serde(default)]
    pub took_over_from: Option<Holder>,
}

impl SelfReport {
    /// What a controller that has just started says of itself: initializing, nothing known.
    pub fn initial(id: ControllerId, incarnation: Incarnation) -> SelfReport {
        SelfReport {
            id,
            incarnation,
            phase: Phase::Initializing,
            role: None,
            strength: None,
            agreed: None,
            vote: None,
            epoch: 0,
            provisional: false,
            established_strength: None,
            took_over_from: None,
        }
    }
}

/// The controller heartbeat (paper: RLCHB), sent once per round. It carries the sender's state
/// as decided at its last round boundary, so every receiver decides from the same facts.
pub type Heartbeat = SelfReport;

/// A controller's status: its self-report and what it knows of its peers. LEDs, the console
/// line and the status topics are functions of this.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Status {
    /// What it says of itself.
    #[serde(flatten)]
    pub report: SelfReport,
    /// Peers believed alive (FAILED ones included).
    pub sees: Vec<ControllerId>,
    /// Peers marked FAILED.
    pub failed: Vec<ControllerId>,
    /// Peers with a raised controller alarm.
    pub alarms: Vec<(ControllerId, AlarmReason)>,
    /// Heartbeats that named this controller's id with another incarnation: another process
    /// is configured with the same id.
    #[serde(default)]
    pub duplicate_id_heartbeats: u64,
}

impl Status {
    /// The status of a controller that has just started and heard nothing.
    pub fn initial(id: ControllerId, incarnation: Incarnation) -> Status {
        Status {
            report: SelfReport::initial(id, incarnation),
            sees: Vec::new(),
            failed: Vec::new(),
            alarms: Vec::new(),
            duplicate_id_heartbeats: 0,
        }
    }
}
