//! The properties the checker verifies, each explained in docs/protocol.md.
//!
//! `always` properties are safety invariants; `sometimes` properties are witnesses that each
//! rule is exercised (non-vacuity). Liveness is stated as bounded response (`always`), because
//! stateright's `eventually` is unsound on the cyclic state graph of a heartbeat protocol.

use crate::state::State;
use crate::types::{Assignment, Phase, Role};
use crate::RlModel;
use stateright::{Expectation, Property};

/// Name, expectation, one-line meaning: the catalogue `check` prints and the docs explain.
pub struct PropertyInfo {
    pub name: &'static str,
    pub expectation: Expectation,
    pub meaning: &'static str,
    pub condition: fn(&RlModel, &State) -> bool,
}

impl PropertyInfo {
    /// Lost heartbeats the witness needs: a false detection takes `dead_after_rounds` of
    /// them; a minority that outlasts the grace takes the grace on top.
    pub fn losses_needed(&self, config: &crate::Config) -> u8 {
        match self.name {
            "re-vote after heartbeat loss" => config.dead_after_rounds,
            "minority voter FAILED" => config.losses_to_fail_minority(),
            // A cut splits the system without a lost heartbeat; otherwise a live peer is
            // declared lost after the dead-man deadline.
            "a two-sided split" if config.max_isolations >= 1 => 0,
            "a two-sided split" => config.dead_after_rounds,
            // Two founders that miss each other through the initialization window form apart.
            "a split at formation" => config.window_rounds,
            // A provisional Primary beside another result: a founder alone, formed while a
            // lost heartbeat hid the others.
            "a provisional Primary owns the actuator" => 1,
            // Declared lost, then one round past the hold every newly provisional Primary has.
            "a Primary no lost side can outrank keeps its strength" => config.dead_after_rounds + 1,
            _ => 0,
        }
    }

    /// Whether the configuration has the faults this property's witness needs at all.
    pub fn applies(&self, config: &crate::Config) -> bool {
        let faults = match self.name {
            "Primary crash promotes the Secondary" => config.max_crashes >= 1,
            "a Secondary takes over from a starved Primary" => config.max_starvations >= 1,
            "a Primary whose commands lapsed starts again" => {
                config.max_slowdowns >= 1 || (config.unnoticed_stalls && config.max_pauses >= 1)
            }
            "restarted controller takes the lowest role" => {
                config.max_crashes >= 1 && config.max_restarts >= 1
            }
            "fourth controller ignored" => config.controller_count() >= 4,
            "returning controller comes back below" => {
                config.max_pauses + config.max_isolations >= 1
            }
            _ => true,
        };
        faults && config.max_lost_heartbeats >= self.losses_needed(config)
    }

    /// Why `applies` is false, for the report.
    pub fn needs(&self, config: &crate::Config) -> String {
        match self.losses_needed(config) {
            0 => "needs a crash, a restart, a pause or a fourth controller in scope".to_string(),
            n => format!("needs {n} lost heartbeats"),
        }
    }
}

pub fn catalogue() -> Vec<PropertyInfo> {
    use Expectation::{Always, Sometimes};
    let p = |name, expectation, meaning, condition| PropertyInfo {
        name,
        expectation,
        meaning,
        condition,
    };
    vec![
        p("roles unique among agreeing controllers", Always,
          "two steady controllers that agree on the result never hold the same role",
          roles_unique_among_agreeing),
        p("actuator has a single owner", Always,
          "the actuator never knows two writers at Primary strength (DDS would pick one by GUID, not by vote), \
           outside a partition (from a live controller declared lost until the controllers settle again)",
          single_owner),
        p("no command output without a role", Always,
          "a controller publishes commands only with a role, never above its role's strength (but for a takeover from a starved Primary, F17), once a Primary exists",
          output_needs_role),
        p("one owner change per fault", Always,
          "the actuator changes owner at most once per fault episode (a crash, a pause, a cut, a starved link, a link failure however many heartbeats it loses), to or from a provisional Primary too: no failback, no blip",
          one_change_per_fault),
        p("owner changes only to the next Primary", Always,
          "every owner change between two settled states goes to the Primary that settles (or back to the owner before)",
          no_stray_owner),
        p("a returning controller never takes the Primary back", Always,
          "a controller back from a pause or a cut never takes Primary from a Primary that stayed with the system",
          primary_not_taken_back),
        p("a live Primary is never demoted", Always,
          "outside a partition a live Primary keeps its role (no oscillation, no failback)",
          heard_primary_never_demoted),
        p("a live role holder is never demoted", Always,
          "outside a partition no live role holder moves to a lower role (late joiners come in below)",
          heard_holder_never_demoted),
        p("at most three role holders", Always,
          "a controller beyond three never holds a role (partition sides excepted, as above)",
          at_most_three_holders),
        p("settled roles form a prefix", Always,
          "when the controllers have settled, no Tertiary without a Secondary, no Secondary without a Primary",
          settled_roles_prefix),
        p("FAILED only after heartbeat loss", Always,
          "with reliable heartbeats no controller is ever marked FAILED or fails itself",
          failed_only_after_loss),
        p("restarted controller enters below live holders", Always,
          "outside a partition, a restarted controller never lands above a live controller that held a role when it restarted",
          restart_enters_below),
        p("actuator follows the settled Primary", Always,
          "once settled, the actuator's owner is the agreed Primary",
          actuator_follows_primary),
        p("a sick controller is not made Primary again", Always,
          "a slowed controller that lost the Primary role does not hold it again while it is slowed (it came back below: the dwell is the episode)",
          sick_not_repromoted),
        p("settles after faults stop", Always,
          "bounded response: after settle_within_rounds fault-free rounds every live controller has settled",
          settles_after_faults),
        p("formation with 3 controllers", Sometimes,
          "three controllers started together settle as Primary, Secondary, Tertiary by id",
          formed_with_3),
        p("formation with 2 controllers", Sometimes,
          "two controllers started together settle as Primary and Secondary by id",
          formed_with_2),
        p("formation with 1 controller", Sometimes,
          "a controller alone settles as Primary",
          formed_with_1),
        p("Primary crash promotes the Secondary", Sometimes,
          "after a crash the Secondary is the settled Primary",
          primary_crash_promotes_secondary),
        p("late joiner becomes Tertiary", Sometimes,
          "a controller that joined a running system settles as Tertiary",
          late_joiner_tertiary),
        p("minority voter FAILED", Sometimes,
          "a controller in a voting minority is marked FAILED or fails itself",
          minority_voter_failed),
        p("fourth controller ignored", Sometimes,
          "four live controllers settle with one of them holding no role",
          fourth_ignored),
        p("re-vote after heartbeat loss", Sometimes,
          "lost heartbeats of a live peer cause a re-vote, and the system settles again",
          revote_after_loss),
        p("returning controller comes back below", Sometimes,
          "a controller back from a pause or a cut settles below the Primary elected meanwhile",
          returned_below),
        p("restarted controller takes the lowest role", Sometimes,
          "a restarted controller settles in the lowest held role, below two others",
          restart_lowest_role),
        p("a two-sided split", Sometimes,
          "two live controllers are each the steady Primary of a different result (the partition the exemptions above excuse)",
          two_sided_split),
        p("a split at formation", Sometimes,
          "a two-sided split before any backed result (the formation split \"one owner change per fault\" excuses)",
          split_at_formation),
        p("a provisional Primary owns the actuator", Sometimes,
          "the actuator follows a Primary commanding at the provisional strength while another controller holds another result",
          provisional_primary_owns),
        p("a Primary no lost side can outrank keeps its strength", Sometimes,
          "a provisional Primary still commands at 30 a round after losing peers that are no majority of its backed result (F15), beside a live one",
          unoutranked_primary_holds),
        p("a Secondary takes over from a starved Primary", Sometimes,
          "the actuator follows a Secondary commanding at the takeover strength above a Primary whose commands arrive late (F17)",
          starved_primary_taken_over),
        p("a Primary whose commands lapsed starts again", Sometimes,
          "a slowed Primary, or one back from a stall it did not notice, doubted itself and the system settled with it below (F18)",
          doubted_primary_below),
    ]
}

pub fn properties() -> Vec<Property<RlModel>> {
    catalogue()
        .into_iter()
        .map(|info| match info.expectation {
            Expectation::Always => Property::always(info.name, info.condition),
            Expectation::Sometimes => Property::sometimes(info.name, info.condition),
            Expectation::Eventually => Property::eventually(info.name, info.condition),
        })
        .collect()
}

/// The agreed result when every active controller is steady on the same result, that result
/// has a Primary, and its members are exactly the active controllers it has room for.
pub fn settled(state: &State) -> Option<Assignment> {
    let mut active = state.up().filter(|c| c.phase != Phase::Failed).peekable();
    active.peek()?;
    let mut result: Option<Assignment> = None;
    let mut count = 0;
    for c in active {
        count += 1;
        if c.phase != Phase::Steady || c.agreed.is_none() || c.agreed != result.or(c.agreed) {
            return None;
        }
        result = c.agreed;
    }
    let agreed = result?;
    agreed.holder(Role::Primary)?;
    // Every member commands at its role's strength (a new Primary may still be holding 20).
    let members_active = agreed.members().all(|id| {
        let c = state.controller(id);
        c.is_active() && c.output == full_strength(c)
    });
    let room = agreed.len() == count || agreed.len() == crate::types::ROLE_COUNT;
    (members_active && room).then_some(agreed)
}

/// The strength a settled controller commands at: its role's, or for a provisional result
/// (F11) 15 for its Primary and nothing for its standbys; a Primary that no side it lost can
/// outrank keeps its full strength (F15); the backed Primary that took over from a starved
/// Primary holds the takeover strength until that Primary's commands stop arriving late (F17).
fn full_strength(c: &crate::Controller) -> Option<u8> {
    let primary = Role::Primary.strength();
    if c.took_over_from.is_some() && c.role == Some(Role::Primary) && !c.provisional {
        return Some(crate::types::TAKEOVER_STRENGTH);
    }
    match (c.provisional, c.role) {
        (true, Some(Role::Primary)) if c.output == Some(primary) && !c.lost_could_outvote() => {
            Some(primary)
        }
        (true, Some(Role::Primary)) => Some(crate::types::PROVISIONAL_PRIMARY_STRENGTH),
        (true, _) => None,
        (false, role) => role.map(Role::strength),
    }
}

fn roles_unique_among_agreeing(_: &RlModel, s: &State) -> bool {
    let steady: Vec<_> = s
        .up()
        .filter(|c| c.phase == Phase::Steady && c.role.is_some())
        .collect();
    steady.iter().enumerate().all(|(i, a)| {
        steady[i + 1..]
            .iter()
            .all(|b| a.agreed != b.agreed || a.role != b.role)
    })
}

/// From a lost heartbeat until the controllers next settle, they may be split in two systems:
/// a controller that hears nobody cannot tell a dead peer from a dead link, and the paper keeps
/// a lone survivor driving. "settles after faults stop" bounds how long that can last.
pub fn partitioned(_: &RlModel, s: &State) -> bool {
    s.history.partition_open
}

fn single_owner(model: &RlModel, s: &State) -> bool {
    partitioned(model, s)
        || s.controllers
            .iter()
            .filter(|c| c.visible_strength() == Some(Role::Primary.strength()))
            .count()
            <= 1
}

/// Owner changes against fault episodes (`History::faults`); only the GUID order between two
/// systems formed apart before any backed result is not counted (`actuator::change_owner`,
/// backed by the witness "a split at formation").
fn one_change_per_fault(_: &RlModel, s: &State) -> bool {
    s.history.owner_changes <= s.history.faults
}

fn no_stray_owner(_: &RlModel, s: &State) -> bool {
    !s.history.stray_owner
}

fn primary_not_taken_back(_: &RlModel, s: &State) -> bool {
    !s.history.primary_taken_back
}

fn returned_below(_: &RlModel, s: &State) -> bool {
    s.history.returned_below
}

fn output_needs_role(_: &RlModel, s: &State) -> bool {
    s.up().all(|c| match c.output {
        None => true,
        Some(strength) => {
            matches!(c.phase, Phase::Voting | Phase::Steady)
                && c.role.is_some_and(|r| {
                    strength <= r.strength()
                        || (c.took_over_from.is_some()
                            && strength == crate::types::TAKEOVER_STRENGTH)
                })
                && c.agreed.is_some_and(|a| a.holder(Role::Primary).is_some())
        }
    })
}

fn heard_primary_never_demoted(_: &RlModel, s: &State) -> bool {
    s.history.demoted_outside_partition != Some(Role::Primary)
}

fn heard_holder_never_demoted(_: &RlModel, s: &State) -> bool {
    s.history.demoted_outside_partition.is_none()
}

fn at_most_three_holders(model: &RlModel, s: &State) -> bool {
    partitioned(model, s) || s.up().filter(|c| c.role.is_some()).count() <= crate::types::ROLE_COUNT
}

fn settled_roles_prefix(_: &RlModel, s: &State) -> bool {
    match settled(s) {
        Some(agreed) => {
            agreed.is_prefix()
                && Role::ALL.iter().all(|role| {
                    let holders = s.up().filter(|c| c.role == Some(*role)).count();
                    holders == usize::from(agreed.holder(*role).is_some())
                })
        }
        None => true,
    }
}

fn failed_only_after_loss(_: &RlModel, s: &State) -> bool {
    s.history.losses > 0
        || s.history.late_heartbeats > 0
        || s.up()
            .all(|c| c.phase != Phase::Failed && c.peers.iter().all(|p| !p.failed))
}

fn sick_not_repromoted(_: &RlModel, s: &State) -> bool {
    !s.history.sick_repromoted
}

fn restart_enters_below(_: &RlModel, s: &State) -> bool {
    !s.history.restart_jumped_queue
}

fn actuator_follows_primary(_: &RlModel, s: &State) -> bool {
    // A writer created this round may not be discovered yet (the timing assumption gives
    // discovery until the round ends).
    if s.up().any(|c| c.undiscovered) {
        return true;
    }
    match settled(s) {
        Some(agreed) => s.actuator_owner() == agreed.holder(Role::Primary),
        None => true,
    }
}

fn settles_after_faults(model: &RlModel, s: &State) -> bool {
    s.history.quiet_rounds < model.config.settle_within_rounds
        || s.isolated != 0
        || s.up().all(|c| c.phase == Phase::Failed)
        || settled(s).is_some()
}

fn formed(s: &State, size: usize) -> bool {
    settled(s).is_some_and(|agreed| {
        agreed.len() == size
            && s.history.crashes == 0
            && s.history.restarts == 0
            && s.up().count() == size
            && s.up().all(|c| !c.late_joiner && c.incarnation == 0)
    })
}

fn formed_with_3(_: &RlModel, s: &State) -> bool {
    formed(s, 3)
}

fn formed_with_2(_: &RlModel, s: &State) -> bool {
    formed(s, 2)
}

fn formed_with_1(_: &RlModel, s: &State) -> bool {
    formed(s, 1)
}

fn primary_crash_promotes_secondary(_: &RlModel, s: &State) -> bool {
    s.history.secondary_promoted && s.history.crashes > 0 && settled(s).is_some()
}

fn late_joiner_tertiary(_: &RlModel, s: &State) -> bool {
    settled(s).is_some()
        && s.up()
            .any(|c| c.late_joiner && c.role == Some(Role::Tertiary))
}

fn minority_voter_failed(_: &RlModel, s: &State) -> bool {
    s.up()
        .any(|c| c.phase == Phase::Failed || c.peers.iter().any(|p| p.failed))
}

fn fourth_ignored(_: &RlModel, s: &State) -> bool {
    settled(s).is_some()
        && s.up().filter(|c| c.is_active()).count() == 4
        && s.up().any(|c| c.phase == Phase::Steady && c.role.is_none())
}

fn revote_after_loss(_: &RlModel, s: &State) -> bool {
    s.history.revoted_after_loss && settled(s).is_some()
}

fn restart_lowest_role(_: &RlModel, s: &State) -> bool {
    settled(s).is_some_and(|agreed| {
        agreed.len() >= 2
            && s.up()
                .any(|c| c.incarnation > 0 && c.role.is_some_and(|r| r.rank() + 1 == agreed.len()))
    })
}

/// Two live controllers each the steady Primary of its own result: the two sides of a split.
fn two_sided_split(_: &RlModel, s: &State) -> bool {
    let primaries: Vec<_> = s
        .up()
        .filter(|c| c.phase == Phase::Steady && c.role == Some(Role::Primary))
        .collect();
    primaries
        .iter()
        .enumerate()
        .any(|(i, a)| primaries[i + 1..].iter().any(|b| a.agreed != b.agreed))
}

fn split_at_formation(model: &RlModel, s: &State) -> bool {
    !s.history.formed && two_sided_split(model, s)
}

fn provisional_primary_owns(_: &RlModel, s: &State) -> bool {
    let Some(owner) = s.actuator_owner().map(|id| s.controller(id)) else {
        return false;
    };
    owner.provisional
        && owner.role == Some(Role::Primary)
        && owner.visible_strength() == Some(crate::types::PROVISIONAL_PRIMARY_STRENGTH)
        && s.up().any(|c| {
            c.id != owner.id && c.is_active() && c.agreed.is_some() && c.agreed != owner.agreed
        })
}

/// F15: past the hold of its first provisional round, a Primary that lost no majority of its
/// backed result still commands at full strength while another controller runs (a link down,
/// not a lone survivor).
fn unoutranked_primary_holds(_: &RlModel, s: &State) -> bool {
    s.up().any(|c| {
        c.provisional
            && c.provisional_rounds >= 1
            && c.role == Some(Role::Primary)
            && c.output == Some(Role::Primary.strength())
            // Still apart: it does not hear a majority of its backed result.
            && c.members().count() * 2 <= c.quorum_base.count_ones() as usize
            && s.up().any(|other| other.id != c.id)
    })
}

fn starved_primary_taken_over(_: &RlModel, s: &State) -> bool {
    s.history.took_over
        && s.actuator_owner().is_some_and(|owner| {
            s.controller(owner).visible_strength() == Some(crate::types::TAKEOVER_STRENGTH)
        })
}

fn doubted_primary_below(_: &RlModel, s: &State) -> bool {
    s.history.doubted
        && settled(s).is_some_and(|agreed| {
            s.up().any(|c| {
                c.incarnation > 0 && agreed.role_of(c.id).is_some_and(|r| r != Role::Primary)
            })
        })
}
