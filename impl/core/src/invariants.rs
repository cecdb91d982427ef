//! The state's invariants, asserted (in debug builds) at the end of every step.

use crate::state::ControllerState;
use crate::types::{Phase, Role};

/// Panics (debug builds only) when `c` breaks an invariant of the protocol state.
pub fn debug_check(c: &ControllerState) {
    debug_assert!(
        c.agreed.is_none_or(|a| a.is_prefix()),
        "C{}: agreed result {:?} has a hole",
        c.id,
        c.agreed
    );
    debug_assert!(
        c.vote.is_none_or(|v| v.is_prefix()),
        "C{}: vote {:?} has a hole",
        c.id,
        c.vote
    );
    debug_assert!(
        c.phase != Phase::Steady || c.agreed.map(|a| a.role_of_holder(c.holder())) == Some(c.role),
        "C{}: steady in role {:?}, but the agreed result {:?} says otherwise",
        c.id,
        c.role,
        c.agreed
    );
    debug_assert!(
        c.phase != Phase::Failed || (c.output.is_none() && c.vote.is_none() && c.role.is_none()),
        "C{}: FAILED but still commanding ({:?}) or voting ({:?})",
        c.id,
        c.output,
        c.vote
    );
    debug_assert!(
        c.output.is_none_or(
            |strength| c.role.is_some_and(|role| strength == role.strength()
                || (role == Role::Primary && strength == Role::Secondary.strength()))
        ),
        "C{}: commands at {:?}, which is neither its role's ({:?}) strength nor the held one",
        c.id,
        c.output,
        c.role
    );
}
