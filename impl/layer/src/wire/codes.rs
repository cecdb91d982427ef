//! The codes of the RL topics' enumerations (phase, role, alarm reason, strength) and their
//! checked decoding. 0 never means a valid phase or reason, so an all-zero sample is rejected
//! rather than read as "initializing".

use super::WireError;
use crate::core::types::{AlarmReason, ControllerId, Phase, Role};

/// Phase codes.
pub const PHASE_INITIALIZING: u8 = 1;
/// Phase code of a controller that has voted and waits for a majority of identical votes.
pub const PHASE_VOTING: u8 = 2;
/// Phase code of a controller holding the agreed result (with a role, or none as a spare).
pub const PHASE_STEADY: u8 = 3;
/// Phase code of a controller in a voting minority (or faulty itself): it neither commands
/// nor votes until restarted.
pub const PHASE_FAILED: u8 = 4;

/// Role codes: 0 = no role.
pub const ROLE_NONE: u8 = 0;
/// Role code of the Primary (commands at strength 30).
pub const ROLE_PRIMARY: u8 = 1;
/// Role code of the Secondary (commands at strength 20).
pub const ROLE_SECONDARY: u8 = 2;
/// Role code of the Tertiary (commands at strength 10).
pub const ROLE_TERTIARY: u8 = 3;

/// Alarm reason codes.
pub const REASON_LOST: u8 = 1;
/// Alarm reason code: the controller cast a minority vote or announced its own failure.
pub const REASON_FAILED: u8 = 2;
/// Alarm reason code: samples in the controller's name came from another participant.
pub const REASON_IMPOSTOR: u8 = 3;
/// Alarm reason code: the controller's input disagreed with two agreeing peers' (raised by
/// the controller about itself as it leaves).
pub const REASON_INPUT_DISAGREES: u8 = 4;
/// Alarm reason code: the controller stood still or was starved and started again (raised by
/// its new life about itself).
pub const REASON_STALLED: u8 = 5;
/// Alarm reason code: the controller's raw answers disagreed with two agreeing peers' while
/// its output agreed (a wrong law; raised by the controller about itself as it leaves).
pub const REASON_LAW_DISAGREES: u8 = 6;

/// Strength 0 on the wire: the controller does not command.
pub const STRENGTH_NONE: u8 = 0;

/// The wire code of `phase` (`PHASE_*`, never 0).
pub fn phase_code(phase: Phase) -> u8 {
    match phase {
        Phase::Initializing => PHASE_INITIALIZING,
        Phase::Voting => PHASE_VOTING,
        Phase::Steady => PHASE_STEADY,
        Phase::Failed => PHASE_FAILED,
    }
}

pub(super) fn phase_from_code(field: &'static str, code: u8) -> Result<Phase, WireError> {
    match code {
        PHASE_INITIALIZING => Ok(Phase::Initializing),
        PHASE_VOTING => Ok(Phase::Voting),
        PHASE_STEADY => Ok(Phase::Steady),
        PHASE_FAILED => Ok(Phase::Failed),
        other => Err(WireError::new(field, format!("unknown phase code {other}"))),
    }
}

/// The wire code of `role`: `ROLE_*`, [`ROLE_NONE`] (0) for `None`.
pub fn role_code(role: Option<Role>) -> u8 {
    match role {
        None => ROLE_NONE,
        Some(Role::Primary) => ROLE_PRIMARY,
        Some(Role::Secondary) => ROLE_SECONDARY,
        Some(Role::Tertiary) => ROLE_TERTIARY,
    }
}

pub(super) fn role_from_code(field: &'static str, code: u8) -> Result<Option<Role>, WireError> {
    match code {
        ROLE_NONE => Ok(None),
        ROLE_PRIMARY => Ok(Some(Role::Primary)),
        ROLE_SECONDARY => Ok(Some(Role::Secondary)),
        ROLE_TERTIARY => Ok(Some(Role::Tertiary)),
        other => Err(WireError::new(field, format!("unknown role code {other}"))),
    }
}

/// The wire code of `reason` (`REASON_*`, never 0).
pub fn reason_code(reason: AlarmReason) -> u8 {
    match reason {
        AlarmReason::Lost => REASON_LOST,
        AlarmReason::Failed => REASON_FAILED,
        AlarmReason::Impostor => REASON_IMPOSTOR,
        AlarmReason::InputDisagrees => REASON_INPUT_DISAGREES,
        AlarmReason::Stalled => REASON_STALLED,
        AlarmReason::LawDisagrees => REASON_LAW_DISAGREES,
    }
}

pub(super) fn reason_from_code(field: &'static str, code: u8) -> Result<AlarmReason, WireError> {
    match code {
        REASON_LOST => Ok(AlarmReason::Lost),
        REASON_FAILED => Ok(AlarmReason::Failed),
        REASON_IMPOSTOR => Ok(AlarmReason::Impostor),
        REASON_INPUT_DISAGREES => Ok(AlarmReason::InputDisagrees),
        REASON_STALLED => Ok(AlarmReason::Stalled),
        REASON_LAW_DISAGREES => Ok(AlarmReason::LawDisagrees),
        other => Err(WireError::new(
            field,
            format!("unknown alarm reason code {other}"),
        )),
    }
}

/// A controller id from the wire: 0 is none.
pub(super) fn controller_id(field: &'static str, id: u8) -> Result<ControllerId, WireError> {
    if id == 0 {
        Err(WireError::new(field, "0 is not a controller id"))
    } else {
        Ok(id)
    }
}
