//! What the judges expect of each scenario, in one place, so a protocol change tightens the
//! figures here and nowhere else.
//!
//! Every fault of a schedule is judged on its own: the owner changes it caused at each reader
//! (at most its [`OwnerChanges`]), and a schedule passes only if every fault does. The whole
//! run is judged on the largest command gap at each reader (its deadline-derived bound, plus
//! what a fault argues the actuator cannot hear through), the time two controllers claimed top
//! strength at once (the sum of what each fault argues), the rounds from the last heal to
//! settled (the model's bound, [`SETTLE_ROUNDS`]), the recorded events against the model, and
//! every process alive with no panic. Each bound is argued from the protocol, the model or the
//! readers' deadlines, not from a run; a run that misses one fails, and the bound stays.

use super::architecture::Architecture;
use super::faults::{Fault, Target};
use super::scenario::Step;
use super::session::CONNEXT_DEADLINE_MS;
use rl_layer::config::Timing;

/// The model's bound: 10 fault-free rounds after the last fault every live controller has
/// settled ("settles after faults stop", docs/protocol.md; `model::Config`'s
/// `settle_within_rounds`, which a test keeps this equal to).
pub const SETTLE_ROUNDS: u64 = 10;

/// Slack on a reader's gap: both readers and the lab timestamp samples in processes on a
/// shared two-core machine, where a sample can be taken in some milliseconds late.
pub const GAP_SLACK_MS: f64 = 20.0;

/// How many owner changes one fault may cause, at each reader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OwnerChanges {
    AtMost(usize),
    /// None while the fault holds (the actuator hears no controller, so nothing can take it)
    /// and none once the controllers have settled after its heal; in between every controller
    /// is a provisional Primary of its own side, and the model does not bound owner changes
    /// between provisional Primaries (docs/findings.md F9, "Protocol v2").
    OnlyWhileMerging,
    /// Measured, not bounded, for the reason given: random loss or a starved link at the
    /// owner under the duplex or the pair (`architectures`).
    Unbounded(&'static str),
}

/// What one fault, on its own, may cause.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaultExpected {
    pub owner_changes: OwnerChanges,
    /// Time two controllers may claim strength 30 at once because of it.
    pub two_at_top_ms: f64,
    /// How much longer than a reader's own bound the actuator may hear no command because of
    /// it: the time a lone controller needs to start commanding.
    pub silent_ms: f64,
}

/// What one schedule's judges accept.
#[derive(Clone, Debug, PartialEq)]
pub struct Expected {
    /// One per fault, in schedule order (the order the faults are applied).
    pub faults: Vec<FaultExpected>,
    pub servo_gap_ms: f64,
    pub connext_gap_ms: f64,
    /// Both gap bounds grow by the time every fault of the schedule held at once: both nets
    /// down, when the actuator hears nobody for as long as that lasts.
    pub silent_while_all_hold: bool,
    pub two_at_top_ms: f64,
}

/// Why a scenario has no expectations: a name `scenario.rs` does not define (misspelled), or a
/// new scenario nobody has argued bounds for yet.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("no expectations for a scenario named {name:?}: every named scenario needs its own arm in expect::for_scenario")]
pub struct UnknownScenario {
    pub name: String,
}

/// The timing every process in the lab runs with: `rl` is started without a configuration
/// file, so with the defaults.
fn timing() -> Timing {
    Timing::default()
}

/// One protocol round (the heartbeat period).
fn round_ms() -> f64 {
    timing().heartbeat_period_ms as f64
}

/// `rl servo`'s largest gap: the owner silent for the command deadline, then the next
/// writer's sample within the republish period (every role holder re-publishes its last
/// command that often), and the slack.
pub fn servo_gap_ms() -> f64 {
    let t = timing();
    (t.command_deadline_ms + t.command_republish_ms) as f64 + GAP_SLACK_MS
}

/// The Connext reader's largest gap, argued as `rl servo`'s: its deadline (the lab starts it
/// with `--deadline-ms CONNEXT_DEADLINE_MS`), then the next writer's sample within the
/// republish period, and the slack. The republish term is inherent, not slack: every role
/// holder republishes in phase with the others (10 ms after each camera frame, as the
/// recordings show), so the next writer's sample that meets the expired deadline is the one
/// about a period after the owner's last, and failovers measure up to deadline + one period
/// (204-211 ms in twelve idle `kill-primary` runs; 104-110 ms at `rl servo`). Leaving the term to
/// the slack left Connext 10 ms for scheduling where `rl servo` has 20 (docs/faults.md).
pub fn connext_gap_ms() -> f64 {
    (CONNEXT_DEADLINE_MS + timing().command_republish_ms) as f64 + GAP_SLACK_MS
}

/// A split (F9, docs/findings.md): the side cut off from the majority keeps its strength for
/// the round in which the majority elects its Primary, then commands at 15, below the
/// majority's Secondary, and after the heal it comes back below (no failback). So one owner
/// change (to the majority's Primary, where the actuator hears it) and at most one round with
/// two controllers at 30 (the old Primary's last round beside the new one's first).
fn split() -> FaultExpected {
    FaultExpected {
        owner_changes: OwnerChanges::AtMost(1),
        two_at_top_ms: round_ms(),
        silent_ms: 0.0,
    }
}

/// A crash, a stall or a restart: the actuator moves once, to the Secondary, which the
/// majority makes Primary; the restarted or resumed controller comes back below (a new
/// incarnation, no failback) and writes nothing before its voting loop has put its new status
/// in place (`impl/layer/src/stall.rs`). Nobody else claims 30 meanwhile.
const CRASH: FaultExpected = FaultExpected {
    owner_changes: OwnerChanges::AtMost(1),
    two_at_top_ms: 0.0,
    silent_ms: 0.0,
};

/// Nothing moves: RL's traffic rides it out.
const UNFELT: FaultExpected = FaultExpected {
    owner_changes: OwnerChanges::AtMost(0),
    two_at_top_ms: 0.0,
    silent_ms: 0.0,
};

/// The highest random loss at a controller that must move nothing: with RL's datagrams sent
/// once per net, a peer is lost only when both copies of two heartbeats in a row are.
pub const UNFELT_LOSS_PERCENT: u8 = 20;

/// What one fault, on its own, may cause.
pub fn for_fault(fault: &Fault) -> FaultExpected {
    match fault {
        // Controllers follow the Primary's round phase (rl_layer::round_clock), whatever their wall
        // clocks say or however fast their crystals run: a clock fault is a restart.
        Fault::Kill(_) | Fault::Pause(_) | Fault::ClockOffset(..) | Fault::ClockRate(..) => CRASH,
        // A freeze is a stop without a signal, a starvation a lasting slowness; each is seen
        // by the controller itself (impl/layer/src/stall.rs) and costs a stall's one move.
        Fault::Freeze(_) | Fault::Starve(..) => CRASH,
        // A controller that sees every link lose its carrier starts again as a new incarnation
        // at once, as after a stall (F16).
        Fault::Unplug(_) => CRASH,
        Fault::Loss(_, percent) if *percent <= UNFELT_LOSS_PERCENT => UNFELT,
        // Heavier loss, a flapping or a starved link: see [`lossy_link`].
        Fault::Loss(..) | Fault::Flap(..) | Fault::RateLimit(..) => lossy_link(),
        // Multicast carries the heartbeats: without it the controller is split as in a cut.
        Fault::Cut(_) | Fault::MulticastOnly(_) => split(),
        Fault::Partition {
            actuator_with_alone: false,
            ..
        } => split(),
        Fault::Partition {
            alone,
            actuator_with_alone: true,
        } => actuator_with_one(*alone),
        Fault::OneWay(..) => one_way(),
        // One net, or one controller's link into one, lost: RL's own participant sends every
        // datagram on both nets (docs/protocol.md, "RL's own traffic on two networks").
        Fault::LinkDown(..) | Fault::NetworkDown(_) => UNFELT,
        // The wrong controller leaves (the cross-check: FAILED, exit 75) and is restarted
        // below: to the role model a crash and a restart (docs/protocol.md, "Output voting").
        // Its strength goes with its writers, so nobody else is at 30 meanwhile.
        Fault::WrongCommands(..) => CRASH,
    }
}

/// How soon an alarm must name the controller of a gray process fault (a freeze without a
/// signal, a starved CPU), under voting: while it stays stopped its peers declare it lost
/// after the peer deadline, at their next round's end (`lost`); once it runs again it finds
/// its stall, or its writer its own lapse as the owner, within a command deadline and starts
/// again, its new life raising `stalled` about itself (F12, F18; rl-core's
/// `STALL_ALARM_ROUNDS`). Whichever comes first, it is within the peer deadline, a round and
/// a command deadline of the fault, and the slack of a shared machine. A fault no reader saw
/// (no owner change: a starvation the controller absorbs, 10 % of a core) left nothing to name
/// and is not judged on it (judge::failures). The duplex and the pair have no bound argued yet
/// (`None`: not judged).
pub fn alarm_within_ms(fault: &Fault, architecture: Architecture) -> Option<f64> {
    let gray = matches!(fault, Fault::Freeze(_) | Fault::Starve(..));
    let t = timing();
    (gray && architecture == Architecture::Voting).then(|| {
        (t.peer_deadline_ms + t.heartbeat_period_ms + t.command_deadline_ms) as f64 + GAP_SLACK_MS
    })
}

/// A partition that leaves the actuator alone with one controller, `alone` (the minority
/// side). While it holds the actuator hears only that controller; at the heal the other
/// side's Primary (30) and Secondary (20) both outrank it (a provisional Primary at 15, F9)
/// and each can take the actuator once as the actuator hears it: the heal removes the drop
/// rules one namespace after another, and DDS matches each writer on its own. Neither can
/// lose it back to the lone controller, which comes back below them (no failback). So:
/// - alone with the Primary: no change while it holds, at most 2 at the heal;
/// - alone with another controller: the actuator first moves to it once the Primary's
///   commands stop reaching it (1), then at most 2 at the heal, 3 in all. A controller named
///   by id may have just been restarted and hold no role, so no writer: it commands only
///   once it has found its peers lost (the peer deadline), decided at that round's end and,
///   as a provisional Primary, reached its second round (F11: it commands at 15 from there),
///   so the actuator may hear nothing for the peer deadline and two rounds more.
fn actuator_with_one(alone: Target) -> FaultExpected {
    match alone {
        Target::Primary => FaultExpected {
            owner_changes: OwnerChanges::AtMost(2),
            ..split()
        },
        Target::Secondary => FaultExpected {
            owner_changes: OwnerChanges::AtMost(3),
            ..split()
        },
        Target::Id(_) => FaultExpected {
            owner_changes: OwnerChanges::AtMost(3),
            silent_ms: timing().peer_deadline_ms as f64 + 2.0 * round_ms(),
            ..split()
        },
    }
}

/// One-way loss between a controller and its peers: the deaf or unheard one is outvoted
/// (the actuator moves once, to the majority's new Primary) and fails itself, and is
/// restarted below. Until it fails itself an outvoted Primary keeps 30 beside the majority's
/// new one: a round for the majority's new votes to reach it, then the minority grace
/// (`dead_after_rounds + 1` rounds, F10) before it takes itself out.
fn one_way() -> FaultExpected {
    let grace = timing().rounds().minority_grace_rounds();
    FaultExpected {
        owner_changes: OwnerChanges::AtMost(1),
        two_at_top_ms: f64::from(grace + 1) * round_ms(),
        silent_ms: 0.0,
    }
}

/// Heavy random loss, a flapping or a starved link at one controller: it may split the
/// controllers once ([`split`]), and since the loss falls on each direction on its own it may
/// as well leave the peers without the controller's heartbeats while it still hears theirs,
/// or the reverse ([`one_way`]). Either takes the Primary role from it once, after which it
/// comes back below and the later losses hit a controller the actuator does not follow: one
/// owner change, and as long at top strength as one-way loss allows (measured at 40% loss:
/// the peers lost C1's heartbeats, promoted C2, and C1, hearing them, adopted the new result
/// at its next boundary and lowered at the one after: 500 ms beside C2 at 30).
fn lossy_link() -> FaultExpected {
    FaultExpected {
        owner_changes: OwnerChanges::AtMost(1),
        two_at_top_ms: split().two_at_top_ms.max(one_way().two_at_top_ms),
        silent_ms: 0.0,
    }
}

/// A schedule of faults, each judged on its own bound. The gaps: each reader's bound plus
/// the longest a fault may keep the actuator without a command (one gap is one silence); two
/// at top strength: what each fault may cause, added up (each split is a round of its own).
pub fn for_faults<'a>(faults: impl IntoIterator<Item = &'a Fault>) -> Expected {
    let faults: Vec<FaultExpected> = faults.into_iter().map(for_fault).collect();
    from_each(faults)
}

fn from_each(faults: Vec<FaultExpected>) -> Expected {
    let silent_ms = faults.iter().map(|f| f.silent_ms).fold(0.0, f64::max);
    Expected {
        servo_gap_ms: servo_gap_ms() + silent_ms,
        connext_gap_ms: connext_gap_ms() + silent_ms,
        silent_while_all_hold: false,
        two_at_top_ms: faults.iter().map(|f| f.two_at_top_ms).sum(),
        faults,
    }
}

/// The expectations of the scenario named `name` whose faults are `faults` (`random`: each
/// fault's own). A name without its own arm here is refused, so a misspelled or new scenario
/// is never judged by someone else's bounds.
pub fn for_scenario(name: &str, faults: &[Fault]) -> Result<Expected, UnknownScenario> {
    match name {
        "random" | "kill-primary" | "pause-primary" => Ok(for_faults(faults)),
        // Each group's kill of its Primary on its own (`super::two_groups`): a crash's bounds,
        // the same as `kill-primary`'s, at that group's readers.
        "two-groups" => Ok(for_faults(faults)),
        "partition-actuator-with-primary"
        | "partition-actuator-with-two"
        | "cut-primary"
        | "cut-secondary"
        | "multicast-drop" => Ok(for_faults(faults)),
        // The outvoted Primary is restarted (exit 75) while the loss lasts; it must still be
        // back and settled within the model's bound after the heal.
        "one-way-out" | "one-way-in" => Ok(for_faults(faults)),
        "loss-5" | "loss-20" | "loss-40" | "flap-primary" | "tbf-primary" => Ok(for_faults(faults)),
        "unplug-primary" => Ok(for_faults(faults)),
        // Each freeze past the command deadline, and each starvation however long, a stall's
        // one move (the controller steps down, impl/layer/src/stall.rs).
        "freeze-primary" | "starve-primary" | "starve-primary-long" => Ok(for_faults(faults)),
        // One controller frozen again and again is one episode: its first freeze deposes it
        // (one move), the later ones hit a controller the actuator no longer follows.
        "stutter-primary" => {
            let later = faults.len().saturating_sub(1);
            let first = faults.first().map(for_fault).into_iter();
            Ok(from_each(first.chain(vec![UNFELT; later]).collect()))
        }
        "clock-0.1s" | "clock-period" | "clock-10s" | "clock-minus-1h" | "clock-drift" => {
            Ok(for_faults(faults))
        }
        // Voting and the actuators ride it out; the network alarms are judged by
        // `super::network_alarms`.
        "net-b-down" | "c2-transceiver-a-down" => Ok(for_faults(faults)),
        // C2's links into both nets, applied one after the other: together C2 alone, the
        // actuator on the two's side, a partition of one. Each link's owner changes (a change
        // counts for the fault applied or healed last before it) are that partition's; its
        // round at top strength happens once.
        "c2-both-links-down" => {
            let partition = for_fault(&Fault::Partition {
                alone: Target::Id(2),
                actuator_with_alone: false,
            });
            let mut expected = from_each(vec![partition; faults.len()]);
            expected.two_at_top_ms = partition.two_at_top_ms;
            Ok(expected)
        }
        // Both nets down: every controller and the actuator alone. The actuator hears no
        // command while both are down, so each gap bound grows by that time; each controller
        // is a side of its own and keeps its strength for one round, then commands at 15 (F9),
        // so at most one round with two at 30, once.
        "both-networks-down" => {
            let merging = FaultExpected {
                owner_changes: OwnerChanges::OnlyWhileMerging,
                ..split()
            };
            let mut expected = from_each(vec![merging; faults.len()]);
            expected.silent_while_all_hold = true;
            expected.two_at_top_ms = merging.two_at_top_ms;
            Ok(expected)
        }
        // A wrong Primary leaves as a crashed one does: one change, to the Secondary
        // (`super::wrong_output::verdict` holds it to exactly that, and to the wrong commands
        // the readers may take).
        // A drifting Primary, one reading another camera and one with a wrong law leave as a
        // wrong one does.
        "wrong-primary"
        | "wrong-primary-vote-camera"
        | "frozen-primary"
        | "random-primary"
        | "drift-primary"
        | "wrong-input-primary"
        | "wrong-law-primary" => Ok(for_faults(faults)),
        // A wrong Secondary leaves as a crashed Secondary: the readers follow the Primary, so
        // nothing moves at them.
        "wrong-secondary" => Ok(from_each(vec![UNFELT; faults.len()])),
        // Two wrong that never agree: nobody is the odd one out, nobody leaves, no role moves.
        "two-wrong" => Ok(from_each(vec![UNFELT; faults.len()])),
        _ => Err(UnknownScenario {
            name: name.to_string(),
        }),
    }
}

/// The expectations of scenario `name` with schedule `steps` under `architecture`: voting's
/// are [`for_scenario`]'s; the other two architectures' each fault's own
/// ([`architectures::for_fault`]), with the net scenarios' faults taken together as voting
/// takes them, and the pair's top strength shared by design.
pub fn for_scenario_in(
    architecture: Architecture,
    name: &str,
    steps: &[Step],
) -> Result<Expected, UnknownScenario> {
    let faults: Vec<Fault> = steps.iter().map(|s| s.fault.clone()).collect();
    let voting = for_scenario(name, &faults)?;
    if architecture == Architecture::Voting {
        return Ok(voting);
    }
    let each =
        |fault: &Fault, lasts_ms: u64| architectures::for_fault(architecture, fault, lasts_ms);
    let faults: Vec<FaultExpected> = match name {
        // C2's two links down together: C2 alone, the actuator with the other controller.
        "c2-both-links-down" => {
            let alone = Fault::Partition {
                alone: Target::Id(2),
                actuator_with_alone: false,
            };
            vec![each(&alone, 0); steps.len()]
        }
        // Nobody hears anybody: as under voting, changes only between the fault and settled.
        "both-networks-down" => voting.faults.clone(),
        _ => steps.iter().map(|s| each(&s.fault, s.lasts_ms)).collect(),
    };
    let mut expected = from_each(faults);
    expected.silent_while_all_hold = voting.silent_while_all_hold;
    expected.two_at_top_ms += architectures::two_at_top_by_design(architecture);
    Ok(expected)
}

pub mod architectures;
#[cfg(test)]
mod tests;
