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
    pub reporter: ControllerId,
    pub reporter_incarnation: Incarnation,
    pub about: ControllerId,
    /// The life of the controller the alarm is about, when the reporter knows it.
    pub about_incarnation: Option<Incarnation>,
    pub reason: AlarmReason,
    /// true = raised, false = cleared.
    pub raised: bool,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AlarmSample {
    pub reporter_id: u8,
    pub reporter_incarnation: u64,
    pub about_id: u8,
    pub about_incarnation_valid: bool,
    pub about_incarnation: u64,
    pub reason: u8,
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
