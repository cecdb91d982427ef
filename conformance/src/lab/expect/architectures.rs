//! What each fault may cause under the paper's two other architectures (`lab run
//! --architecture duplex|pair`), argued from their rules (`rl_core::architectures`, the
//! model's `architectures`: docs/protocol.md, "Other architectures: the spec") as the voting
//! bounds are argued from the protocol. The gap bounds are voting's: all three fail the
//! actuator over by DDS exclusive ownership at the readers' deadlines, and in both other
//! architectures the controller the actuator does not follow writes all the time (the
//! duplex's Standby at 20; the pair's other member at 30, or at 20 while it yields).
//!
//! What moves the actuator here is only its deadline and DDS's choice by strength (equal
//! strengths: the lower writer GUID, `rl_layer::arbiter`): no vote takes the actuator from a
//! controller, and none keeps a returning one below. So:
//! - The duplex (the paper's preemption, C1 Primary at 30, C2 Standby at 20): every time the
//!   actuator stops hearing the Primary it moves to the Standby, and back as soon as it hears
//!   the Primary again: a *bounce*, two changes (finding A1). A fault of the Standby moves
//!   nothing, and so does a wrong output: nothing compares. The Primary's commands at 30 are
//!   the only ones at top strength.
//! - The pair (both members at 30): losing the owner moves the actuator once, to the other
//!   member; a member whose two implementations disagree leaves the bus, as lost. A member that comes back as a new process (a restart, a resume, a replugged
//!   cable) hears its partner commanding and writes at 20 beside it: no second change. One
//!   that never stopped (it was only cut off) is still at 30, and if its writer has the lower
//!   GUID it takes the actuator back at once: a bounce. Both members are at 30 by design, so
//!   "two at top strength" is the pair's normal state, not a fault's effect.
//! - Random loss above [`super::UNFELT_LOSS_PERCENT`] and a starved link: each time the
//!   actuator misses the Primary's (the owner's) commands for its deadline is a bounce, and
//!   neither architecture has anything that stops the next one: the paper's caveat about the
//!   duplex (A1), which holds for the pair's owner too. Their owner changes are measured and
//!   not bounded ([`OwnerChanges::Unbounded`]); every other judge still applies.

use super::{for_fault as voting, FaultExpected, OwnerChanges, UNFELT, UNFELT_LOSS_PERCENT};
use crate::lab::architecture::Architecture;
use crate::lab::faults::{flap_downs, Fault, Target};

/// One fault that takes the actuator from its owner and gives it back: away at the
/// deadline, back when the owner is heard again.
const BOUNCE: FaultExpected = FaultExpected {
    owner_changes: OwnerChanges::AtMost(2),
    ..UNFELT
};

/// The owner lost once, the actuator on the other controller for good.
const ONCE: FaultExpected = FaultExpected {
    owner_changes: OwnerChanges::AtMost(1),
    ..UNFELT
};

/// Why loss and a starved link are not bounded under the two other architectures.
const NOT_BOUNDED: &str = "every deadline the actuator misses is a bounce, and nothing stops the next (A1: the duplex moves the actuator at every bounce of its Primary)";

/// What `fault`, lasting `lasts_ms`, may cause under `architecture`.
pub fn for_fault(architecture: Architecture, fault: &Fault, lasts_ms: u64) -> FaultExpected {
    let expected = match architecture {
        Architecture::Voting => return voting(fault),
        Architecture::Duplex => duplex(fault),
        Architecture::Pair => pair(fault),
    };
    match (fault, expected.owner_changes) {
        // A flapping link: what one down may cause, once per down.
        (Fault::Flap(_, seed), OwnerChanges::AtMost(per_down)) => FaultExpected {
            owner_changes: OwnerChanges::AtMost(per_down * flap_downs(*seed, lasts_ms)),
            ..expected
        },
        _ => expected,
    }
}

/// Whether `target` is the duplex's configured Primary (C1; a role target is its holder, and
/// the duplex's roles are configured).
fn is_duplex_primary(target: Option<Target>) -> bool {
    matches!(target, Some(Target::Primary | Target::Id(1)))
}

/// The duplex with the paper's preemption.
fn duplex(fault: &Fault) -> FaultExpected {
    let primary = is_duplex_primary(fault.target());
    let bounce_if_primary = if primary { BOUNCE } else { UNFELT };
    match fault {
        // The Primary stops and comes back (a restarted, resumed or replugged process):
        // preempting, it takes the actuator back at once, or, back from a stall of its own
        // loop (a freeze, a starved CPU), after its dwell, however often the episode stalls
        // it (finding A4): one bounce.
        Fault::Kill(_)
        | Fault::Pause(_)
        | Fault::Freeze(_)
        | Fault::Starve(..)
        | Fault::Unplug(_)
        | Fault::Flap(..) => bounce_if_primary,
        // A clock fault restarts the controller twice, with its clock set wrong and, at the
        // heal, right again: two bounces of the Primary.
        Fault::ClockOffset(..) | Fault::ClockRate(..) if primary => FaultExpected {
            owner_changes: OwnerChanges::AtMost(4),
            ..BOUNCE
        },
        Fault::ClockOffset(..) | Fault::ClockRate(..) => UNFELT,
        // The actuator keeps hearing both controllers: the peers only alarm each other.
        Fault::Cut(_) | Fault::OneWay(..) | Fault::LinkDown(..) | Fault::NetworkDown(_) => UNFELT,
        Fault::Loss(_, percent) if *percent <= UNFELT_LOSS_PERCENT => UNFELT,
        // Whether the actuator hears commands without multicast is DDS's locators' business:
        // at worst it loses the Primary until the heal.
        Fault::MulticastOnly(_) => bounce_if_primary,
        Fault::Partition {
            alone,
            actuator_with_alone,
        } => {
            // The actuator away from the Primary while it holds: a bounce.
            let actuator_with_primary = is_duplex_primary(Some(*alone)) == *actuator_with_alone;
            if actuator_with_primary {
                UNFELT
            } else {
                BOUNCE
            }
        }
        Fault::Loss(..) | Fault::RateLimit(..) if primary => not_bounded(),
        Fault::Loss(..) | Fault::RateLimit(..) => UNFELT,
        // Nothing compares: a wrong controller keeps its role and its writers
        // (`crate::lab::wrong_output::architectures`).
        Fault::WrongCommands(..) => UNFELT,
    }
}

/// The lockstep pair: the target's role is the owner's (the Primary: the member `rl servo`
/// follows) or the other member's; an id may be either.
fn pair(fault: &Fault) -> FaultExpected {
    let owner_or_either = !matches!(fault.target(), Some(Target::Secondary));
    let if_owner = |expected: FaultExpected| {
        if owner_or_either {
            expected
        } else {
            UNFELT
        }
    };
    match fault {
        // A new process: it writes at 20 beside its commanding partner.
        Fault::Kill(_)
        | Fault::Pause(_)
        | Fault::Freeze(_)
        | Fault::Starve(..)
        | Fault::ClockOffset(..)
        | Fault::ClockRate(..)
        | Fault::Unplug(_) => if_owner(ONCE),
        // Each down past the partner deadline leaves the restarted member alone, at 30, with
        // a new writer that may have the lower GUID when the link comes back: a bounce.
        Fault::Flap(..) => if_owner(BOUNCE),
        Fault::Cut(_) | Fault::OneWay(..) | Fault::LinkDown(..) | Fault::NetworkDown(_) => UNFELT,
        Fault::Loss(_, percent) if *percent <= UNFELT_LOSS_PERCENT => UNFELT,
        // The owner unheard until the heal, still at 30 with its writer: it may take the
        // actuator back.
        Fault::MulticastOnly(_) => if_owner(BOUNCE),
        Fault::Partition {
            alone,
            actuator_with_alone,
        } => match (alone, actuator_with_alone) {
            // The owner keeps the actuator, and at the heal it still has the lower GUID.
            (Target::Primary, true) => UNFELT,
            // The actuator with the other member while it holds, the owner back at the heal.
            (Target::Primary, false) => BOUNCE,
            (Target::Secondary, false) => UNFELT,
            (Target::Secondary, true) | (Target::Id(_), _) => BOUNCE,
        },
        Fault::Loss(..) | Fault::RateLimit(..) if owner_or_either => not_bounded(),
        Fault::Loss(..) | Fault::RateLimit(..) => UNFELT,
        // Its compare takes the wrong member off the bus at its first wrong frame, and it
        // comes back as a new process: as a crash of it.
        Fault::WrongCommands(..) => if_owner(ONCE),
    }
}

fn not_bounded() -> FaultExpected {
    FaultExpected {
        owner_changes: OwnerChanges::Unbounded(NOT_BOUNDED),
        ..UNFELT
    }
}

/// How long two controllers may claim top strength at once under `architecture`, beyond
/// what its faults cause: the pair's members both command at 30 by design.
pub fn two_at_top_by_design(architecture: Architecture) -> f64 {
    match architecture {
        Architecture::Pair => f64::INFINITY,
        Architecture::Voting | Architecture::Duplex => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lab::faults::{Direction, WrongAnswer};

    fn changes(architecture: Architecture, fault: Fault) -> OwnerChanges {
        for_fault(architecture, &fault, 3000).owner_changes
    }

    /// Each fault with what `architecture` may let it cause.
    fn check(architecture: Architecture, cases: Vec<(Fault, OwnerChanges)>) {
        for (fault, expected) in cases {
            let label = fault.to_string();
            assert_eq!(changes(architecture, fault), expected, "{label}");
        }
    }

    #[test]
    fn the_duplex_bounces_for_its_primary_and_not_for_its_standby() {
        let with_two = Fault::Partition {
            alone: Target::Primary,
            actuator_with_alone: false,
        };
        check(
            Architecture::Duplex,
            vec![
                (Fault::Kill(Target::Primary), OwnerChanges::AtMost(2)),
                (Fault::Kill(Target::Id(2)), OwnerChanges::AtMost(0)),
                (
                    Fault::ClockOffset(Target::Id(2), 10.0),
                    OwnerChanges::AtMost(0),
                ),
                (Fault::Cut(Target::Primary), OwnerChanges::AtMost(0)),
                (
                    Fault::ClockOffset(Target::Id(1), 0.1),
                    OwnerChanges::AtMost(4),
                ),
                (with_two, OwnerChanges::AtMost(2)),
                (Fault::Loss(Target::Primary, 20), OwnerChanges::AtMost(0)),
                (
                    Fault::WrongCommands(Target::Primary, WrongAnswer::Offset(300)),
                    OwnerChanges::AtMost(0),
                ),
            ],
        );
        assert!(matches!(
            changes(Architecture::Duplex, Fault::Loss(Target::Primary, 40)),
            OwnerChanges::Unbounded(_)
        ));
    }

    #[test]
    fn the_pair_moves_once_for_a_new_process_and_bounces_for_a_cut_off_owner() {
        let owner_alone = Fault::Partition {
            alone: Target::Primary,
            actuator_with_alone: false,
        };
        check(
            Architecture::Pair,
            vec![
                (Fault::Kill(Target::Primary), OwnerChanges::AtMost(1)),
                (Fault::Pause(Target::Secondary), OwnerChanges::AtMost(0)),
                (owner_alone, OwnerChanges::AtMost(2)),
                (
                    Fault::OneWay(Target::Primary, Direction::Out),
                    OwnerChanges::AtMost(0),
                ),
                (
                    Fault::WrongCommands(Target::Primary, WrongAnswer::Random),
                    OwnerChanges::AtMost(1),
                ),
                (
                    Fault::WrongCommands(Target::Secondary, WrongAnswer::Frozen),
                    OwnerChanges::AtMost(0),
                ),
            ],
        );
        assert_eq!(two_at_top_by_design(Architecture::Pair), f64::INFINITY);
    }

    #[test]
    fn a_flapping_primary_may_bounce_once_per_down_under_both() {
        let downs = flap_downs(7, 10_000);
        assert!(downs >= 1, "seed 7's flapping goes down within 10 s");
        for architecture in [Architecture::Duplex, Architecture::Pair] {
            let expected = for_fault(architecture, &Fault::Flap(Target::Primary, 7), 10_000);
            assert_eq!(expected.owner_changes, OwnerChanges::AtMost(2 * downs));
        }
        let standby = for_fault(Architecture::Duplex, &Fault::Flap(Target::Id(2), 7), 10_000);
        assert_eq!(standby.owner_changes, OwnerChanges::AtMost(0));
        assert_eq!(
            for_fault(
                Architecture::Voting,
                &Fault::Flap(Target::Primary, 7),
                10_000
            )
            .owner_changes,
            OwnerChanges::AtMost(1)
        );
    }
}
