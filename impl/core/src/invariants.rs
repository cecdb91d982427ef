//! The state's invariants, asserted (in debug builds) at the end of every step.

use crate::state::ControllerState;
use crate::types::{Phase, Role, PROVISIONAL_PRIMARY_STRENGTH, TAKEOVER_STRENGTH};

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
    // A strength is a role's or the provisional Primary's, never above its own role's: a held
    // Primary commands at 20 (F8), a provisional one at 15 (F11), and a standby whose raise
    // waits for the roles above (F13) keeps its lower strength. The takeover strength goes
    // with a takeover (F17), and with nothing else.
    debug_assert!(
        c.output
            .is_none_or(
                |strength| (strength == TAKEOVER_STRENGTH) == c.took_over_from.is_some()
                    && (strength == TAKEOVER_STRENGTH
                        || c.role.is_some_and(|role| strength <= role.strength()
                            && (Role::from_strength(strength).is_some()
                                || strength == PROVISIONAL_PRIMARY_STRENGTH)))
            ),
        "C{}: commands at {:?}, which is not a strength its role ({:?}) allows",
        c.id,
        c.output,
        c.role
    );
}
