//! The command strength a controller's role entitles it to, and when it may move there.
//!
//! DDS exclusive ownership hands the actuator to the strongest writer a reader knows, and
//! equal strengths go by GUID, an order no controller chooses. So a strength is a claim on the
//! actuator, moved with care: a Primary whose predecessor still claims Primary holds the
//! Secondary strength (finding F8), a provisional Primary commands at 15 (F11) unless no side it lost could outrank it (F15), and a raise
//! waits until every role above reports an established strength above the new one (F13), so a
//! tie can never hand the actuator to a lower role. Lowering is at once. A Secondary that took
//! over from a late Primary commands at 35 until the takeover is released (F17). The model's rules of
//! the same names are in `model/src/protocol/agreement.rs`.

use crate::epochs::{hears_majority, lost_could_outvote};
use crate::state::ControllerState;
use crate::types::{Phase, Role, Strength, PROVISIONAL_PRIMARY_STRENGTH, TAKEOVER_STRENGTH};

/// The strength its role and result entitle it to now; `None` before a Primary exists or
/// without a role.
pub(crate) fn entitled_strength(c: &ControllerState) -> Option<Strength> {
    if c.took_over_from.is_some() {
        // F17: a takeover holds until it is released (crate::rules, `release_takeover`).
        return Some(TAKEOVER_STRENGTH);
    }
    let role = c.role?;
    if !matches!(c.phase, Phase::Voting | Phase::Steady) {
        return None;
    }
    c.agreed?.holder(Role::Primary)?;
    if c.provisional {
        if role != Role::Primary {
            return None;
        }
        // Newly provisional, the majority side elects its Primary in this round: dropping
        // before it raises would hand the actuator to a standby first. While it hears a
        // majority (a healed cut, a result not yet confirmed) it keeps its strength until the
        // merge or the confirmation is agreed. A Primary at full strength whose lost peers
        // cannot form a majority of the last backed result keeps it (F15): no side can elect
        // a Primary above it, and dropping would only hand the actuator to a standby that may
        // still hear it (a link down one way). A promoted standby has no such claim and drops.
        let unoutranked = c.output == Some(Role::Primary.strength()) && !lost_could_outvote(c);
        if c.output.is_some() && (c.provisional_rounds == 0 || hears_majority(c) || unoutranked) {
            // A takeover released meanwhile (F17) comes down to the Primary's strength.
            return c.output.map(|kept| kept.min(Role::Primary.strength()));
        }
        return Some(PROVISIONAL_PRIMARY_STRENGTH);
    }
    let contested = c
        .peers
        .values()
        .any(|p| p.alive.is_some() && p.claims_primary);
    if role == Role::Primary && contested {
        // A Primary already at full strength keeps it (dropping to 20 would tie with its
        // Secondary); a new one waits at the Secondary's strength.
        let primary = Role::Primary.strength();
        return Some(if c.output == Some(primary) {
            primary
        } else {
            Role::Secondary.strength()
        });
    }
    Some(role.strength())
}

/// Moves the command output to the entitled strength; a raise waits for the roles above.
pub(crate) fn apply_output(c: &mut ControllerState) {
    let target = entitled_strength(c);
    if let (old, Some(new)) = (c.output, target) {
        let raise = old.is_none_or(|old| new > old);
        if raise && !above_established(c, new) {
            return;
        }
    }
    c.set_output(target);
}

/// Every holder of a role above its own in its agreed result reported, in its last heartbeat,
/// an established strength above `strength` and at least its own role's.
fn above_established(c: &ControllerState, strength: Strength) -> bool {
    let (Some(agreed), Some(role)) = (c.agreed, c.role) else {
        return true;
    };
    Role::ALL[..role.rank()].iter().all(|above| {
        agreed.holder(*above).is_none_or(|holder| {
            holder == c.id
                || c.peers
                    .get(&holder)
                    .and_then(|p| p.heard_strength)
                    .is_some_and(|reported| reported > strength && reported >= above.strength())
        })
    })
}
