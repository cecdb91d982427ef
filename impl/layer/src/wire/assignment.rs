//! Role assignments on the wire: three holder slots (Primary, Secondary, Tertiary), validated
//! on the way in (empty slots all zero, holes only at the end, no controller twice).

use super::WireError;
use crate::core::types::{Assignment, Holder, ROLE_COUNT};
use serde::{Deserialize, Serialize};

/// One role slot of an assignment: `id` 0 = empty (then `incarnation` must be 0 too).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct HolderSlot {
    /// The holder's controller id; 0 = the slot is empty.
    pub id: u8,
    /// The holder's incarnation; 0 in an empty slot.
    pub incarnation: u64,
}

/// Primary, Secondary, Tertiary holders, in that order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct WireAssignment {
    /// The holders by role rank (0 Primary, 1 Secondary, 2 Tertiary); empty ones only at the end.
    pub slots: [HolderSlot; ROLE_COUNT],
}

impl WireAssignment {
    /// The slots of `assignment`: a role nobody holds is an all-zero slot.
    pub fn encode(assignment: &Assignment) -> WireAssignment {
        let mut slots = [HolderSlot::default(); ROLE_COUNT];
        for (slot, holder) in slots.iter_mut().zip(assignment.0.iter()) {
            if let Some(holder) = holder {
                *slot = HolderSlot {
                    id: holder.id,
                    incarnation: holder.incarnation,
                };
            }
        }
        WireAssignment { slots }
    }

    fn is_blank(&self) -> bool {
        *self == WireAssignment::default()
    }

    /// Validates: empty slots are all zero, holes only at the end, no controller twice.
    pub fn decode(&self, field: &'static str) -> Result<Assignment, WireError> {
        let mut holders = [None; ROLE_COUNT];
        let mut hole_seen = false;
        for (rank, slot) in self.slots.iter().enumerate() {
            if slot.id == 0 {
                if slot.incarnation != 0 {
                    return Err(WireError::new(
                        field,
                        format!(
                            "slot {rank} is empty but carries incarnation {}",
                            slot.incarnation
                        ),
                    ));
                }
                hole_seen = true;
                continue;
            }
            if hole_seen {
                return Err(WireError::new(
                    field,
                    format!("slot {rank} is filled after an empty slot (holes only at the end)"),
                ));
            }
            if holders.iter().flatten().any(|h: &Holder| h.id == slot.id) {
                return Err(WireError::new(
                    field,
                    format!("controller {} holds two roles", slot.id),
                ));
            }
            holders[rank] = Some(Holder {
                id: slot.id,
                incarnation: slot.incarnation,
            });
        }
        Ok(Assignment(holders))
    }
}

/// An optional assignment as its `valid` flag and slots (blank when absent).
pub(super) fn encode_optional(assignment: &Option<Assignment>) -> (bool, WireAssignment) {
    match assignment {
        Some(a) => (true, WireAssignment::encode(a)),
        None => (false, WireAssignment::default()),
    }
}

/// The assignment a `valid` flag and slots stand for; slots must be blank when not valid.
pub(super) fn decode_optional(
    field: &'static str,
    valid: bool,
    assignment: &WireAssignment,
) -> Result<Option<Assignment>, WireError> {
    if valid {
        assignment.decode(field).map(Some)
    } else if assignment.is_blank() {
        Ok(None)
    } else {
        Err(WireError::new(
            field,
            "marked not valid but has filled slots",
        ))
    }
}
