//! The controller alarm topic: a controller lost or failed, raised and cleared (network
//! alarms are in `network`).

use super::codes::{controller_id, reason_code, reason_from_code};
use super::{WireError, WireSample};
use crate::core::types::{AlarmReason, ControllerId, Incarnation};
use rustdds::dds::key::{CdrEncodingMaxSize, CdrEncodingSize, Key};
use rustdds::Keyed;
use serde::{Deserialize, Serialize};

/// DDS type name of the controller alarm topic.
pub const ALARM_TYPE_NAME: &str = "rl::AlarmSample";

/// A controller alarm raised or cleared by a controller about another (or itself).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ControllerAlarm {
    /// The controller that raised or cleared it.
    pub reporter: ControllerId,
    /// The reporter's life: a new value at every start.
    pub reporter_incarnation: Incarnation,
    /// The controller the alarm is about (may be the reporter itself).
    pub about: ControllerId,
    /// The life of the controller the alarm is about, when the reporter knows it.
    pub about_incarnation: Option<Incarnation>,
    /// Lost (heartbeats stopped), failed (minority vote or own fault) or impostor (forged sender).
    pub reason: AlarmReason,
    /// true = raised, false = cleared.
    pub raised: bool,
}

/// The controller alarm sample: one instance per reporter, controller and kind (impostor or
/// not).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AlarmSample {
    /// The reporter's controller id (0 is refused).
    pub reporter_id: u8,
    /// The reporter's incarnation.
    pub reporter_incarnation: u64,
    /// The controller id the alarm is about (0 is refused).
    pub about_id: u8,
    /// Whether `about_incarnation` is known; false = not known, and it must be 0.
    pub about_incarnation_valid: bool,
    /// The incarnation of the controller the alarm is about; 0 when not valid.
    pub about_incarnation: u64,
    /// Reason code: 1 lost, 2 failed, 3 impostor (`REASON_*`; 0 is rejected).
    pub reason: u8,
    /// true = raised, false = cleared.
    pub raised: bool,
}

/// One instance of the controller alarm topic per reporter, controller and kind (an impostor
/// alarm stands beside the protocol's Lost/Failed one), so a late reader (transient local) gets
/// each alarm's latest state: raised, or cleared.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct AlarmKey {
    pub reporter_id: u8,
    pub about_id: u8,
    pub impostor: bool,
}

impl CdrEncodingSize for AlarmKey {
    fn cdr_encoding_max_size() -> CdrEncodingMaxSize {
        CdrEncodingMaxSize::Bytes(3)
    }
}

impl Key for AlarmKey {}

impl Keyed for AlarmSample {
    type K = AlarmKey;
    fn key(&self) -> AlarmKey {
        AlarmKey {
            reporter_id: self.reporter_id,
            about_id: self.about_id,
            impostor: self.reason == super::codes::REASON_IMPOSTOR,
        }
    }
}

impl WireSample for AlarmSample {
    type Value = ControllerAlarm;
    const TYPE_NAME: &'static str = ALARM_TYPE_NAME;

    fn decode(self) -> Result<ControllerAlarm, WireError> {
        let about_incarnation = if self.about_incarnation_valid {
            Some(self.about_incarnation)
        } else if self.about_incarnation == 0 {
            None
        } else {
            return Err(WireError::new(
                "alarm.about_incarnation",
                "marked not valid but not 0",
            ));
        };
        Ok(ControllerAlarm {
            reporter: controller_id("alarm.reporter_id", self.reporter_id)?,
            reporter_incarnation: self.reporter_incarnation,
            about: controller_id("alarm.about_id", self.about_id)?,
            about_incarnation,
            reason: reason_from_code("alarm.reason", self.reason)?,
            raised: self.raised,
        })
    }

    fn encode(alarm: &ControllerAlarm) -> AlarmSample {
        AlarmSample {
            reporter_id: alarm.reporter,
            reporter_incarnation: alarm.reporter_incarnation,
            about_id: alarm.about,
            about_incarnation_valid: alarm.about_incarnation.is_some(),
            about_incarnation: alarm.about_incarnation.unwrap_or(0),
            reason: reason_code(alarm.reason),
            raised: alarm.raised,
        }
    }
}
