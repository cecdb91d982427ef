//! What the duplex must always hold and must sometimes show, each explained in
//! docs/protocol.md, "Other architectures: the spec".
//!
//! "One owner change per fault" is the property the paper's caveat is about: with preemption
//! a Primary that bounces moves the actuator twice per crash (finding A1). "One bounce per
//! fault" is what preemption can keep: twice per fault, however long a gray fault's episode
//! lasts (finding A4, the dwell).

use super::state::{DuplexState, PartnerView, Writing, DEADLINE_ROUNDS};
use super::DuplexModel;
use crate::architectures::check::{always_applies, PropertyInfo};
use crate::types::Id;
use stateright::Expectation;

/// The configured Primary and Standby.
const PRIMARY: Id = 1;
const STANDBY: Id = 2;

pub fn catalogue() -> Vec<PropertyInfo<DuplexModel>> {
    use Expectation::{Always, Sometimes};
    let p = |name, expectation, meaning, condition, lacking| PropertyInfo {
        name,
        expectation,
        meaning,
        condition,
        lacking,
    };
    vec![
        p("the actuator has a writer unless both are down", Always,
          "while a controller is up, the actuator follows one of them",
          has_writer, always_applies),
        p("the actuator follows the strongest live writer", Always,
          "the actuator's owner is the live writer with the highest ownership strength (DDS exclusive ownership)",
          follows_strongest, always_applies),
        p("no two writers at one strength", Always,
          "the two controllers never write at the same strength, where DDS would choose by GUID",
          no_tie, always_applies),
        p("one owner change per fault", Always,
          "the actuator moves from one controller to the other at most once per fault (a crash, an episode of lost heartbeats)",
          one_change_per_fault, always_applies),
        p("one bounce per fault", Always,
          "the actuator moves at most twice per fault (away and back: a crash, an episode of lost heartbeats, a gray fault's episode however many lapses it holds)",
          one_bounce_per_fault, always_applies),
        p("a failed partner is alarmed within the deadline", Always,
          "a controller up for the heartbeat deadline whose partner has been down for the deadline has its alarm up",
          failed_partner_alarmed, always_applies),
        p("an alarm names only a partner that went missing", Always,
          "a controller's alarm is up only if its partner was down, or a heartbeat of it was lost, since it was last heard (or since the controller started)",
          alarm_only_after_missing, always_applies),
        p("the Standby takes over from a crashed Primary", Sometimes,
          "the Primary is down and the actuator follows the Standby",
          standby_takes_over, needs_crash),
        p("the survivor alarms a crashed partner", Sometimes,
          "a controller whose partner is down has its alarm up",
          survivor_alarms, needs_crash),
        p("a returning Primary takes the actuator back", Sometimes,
          "the restarted Primary owns the actuator while the Standby still writes (the paper's rule)",
          primary_takes_back, needs_preemption),
        p("a returned Primary stays standby while the Standby commands", Sometimes,
          "the restarted Primary has heard the commanding Standby and yields to it",
          primary_stays_standby, needs_no_preemption),
        p("a yielded Primary takes the actuator when the Standby fails", Sometimes,
          "the Standby is down and the actuator follows the yielded Primary at once, before its deadline",
          yielded_primary_takes_over, needs_no_preemption_two_crashes),
        p("lost heartbeats hand the actuator to a yielded Primary", Sometimes,
          "a restarted Primary that lost the Standby's heartbeats for the deadline takes its strength back while the Standby lives",
          loss_moves_actuator, needs_no_preemption_and_losses),
        p("a lapsed Primary takes the actuator back once healthy", Sometimes,
          "the Primary that started again after lapses of its sick loop owns the actuator again, its episode over, beside the commanding Standby",
          lapsed_primary_takes_back, needs_preemption_and_sickness),
        p("a false alarm from lost heartbeats", Sometimes,
          "a controller alarms about a partner that has been up all along",
          false_alarm, needs_losses),
        p("both down: the actuator has no writer", Sometimes,
          "both controllers are down at once (the exemption of the first property is reachable)",
          both_down, needs_two_crashes),
    ]
}

fn has_writer(_: &DuplexModel, state: &DuplexState) -> bool {
    state.owner.is_some() || state.controllers.iter().all(|c| !c.is_up())
}

fn follows_strongest(_: &DuplexModel, state: &DuplexState) -> bool {
    state.owner == state.strongest_writer()
}

fn no_tie(_: &DuplexModel, state: &DuplexState) -> bool {
    match state.controllers.map(|c| c.strength()) {
        [Some(a), Some(b)] => a != b,
        _ => true,
    }
}

fn one_change_per_fault(_: &DuplexModel, state: &DuplexState) -> bool {
    state.owner_changes <= state.faults
}

fn one_bounce_per_fault(_: &DuplexModel, state: &DuplexState) -> bool {
    state.owner_changes <= 2 * state.faults
}

fn lapsed_primary_takes_back(_: &DuplexModel, state: &DuplexState) -> bool {
    let primary = state.controller(PRIMARY);
    let standby = state.controller(STANDBY);
    primary.lapsed
        && !primary.sick
        && state.owner == Some(PRIMARY)
        && standby.is_up()
        && standby.writing == Writing::Configured
}

fn failed_partner_alarmed(_: &DuplexModel, state: &DuplexState) -> bool {
    state.controllers.iter().all(|c| {
        let partner = state.partner(c.id);
        let due = c.is_up()
            && c.up_rounds >= DEADLINE_ROUNDS
            && !partner.is_up()
            && partner.down_rounds >= DEADLINE_ROUNDS;
        !due || c.alarm
    })
}

fn alarm_only_after_missing(_: &DuplexModel, state: &DuplexState) -> bool {
    state
        .controllers
        .iter()
        .all(|c| !c.alarm || c.partner_missed)
}

fn standby_takes_over(_: &DuplexModel, state: &DuplexState) -> bool {
    !state.controller(PRIMARY).is_up() && state.owner == Some(STANDBY)
}

fn survivor_alarms(_: &DuplexModel, state: &DuplexState) -> bool {
    state
        .controllers
        .iter()
        .any(|c| c.is_up() && c.alarm && !state.partner(c.id).is_up())
}

fn primary_takes_back(model: &DuplexModel, state: &DuplexState) -> bool {
    let standby = state.controller(STANDBY);
    model.config.preempt
        && state.controller(PRIMARY).restarted
        && state.owner == Some(PRIMARY)
        && standby.is_up()
        && standby.writing == Writing::Configured
}

fn primary_stays_standby(_: &DuplexModel, state: &DuplexState) -> bool {
    let primary = state.controller(PRIMARY);
    primary.is_up()
        && primary.restarted
        && primary.writing != Writing::Configured
        && primary.view == PartnerView::Heard
        && state.owner == Some(STANDBY)
}

fn yielded_primary_takes_over(_: &DuplexModel, state: &DuplexState) -> bool {
    let primary = state.controller(PRIMARY);
    primary.writing == Writing::Yielded
        && !state.controller(STANDBY).is_up()
        && state.owner == Some(PRIMARY)
}

fn loss_moves_actuator(model: &DuplexModel, state: &DuplexState) -> bool {
    let primary = state.controller(PRIMARY);
    let standby = state.controller(STANDBY);
    !model.config.preempt
        && primary.restarted
        && primary.view == PartnerView::Lost
        && state.owner == Some(PRIMARY)
        && standby.is_up()
        && standby.writing == Writing::Configured
}

fn false_alarm(_: &DuplexModel, state: &DuplexState) -> bool {
    state.controllers.iter().any(|c| {
        let partner = state.partner(c.id);
        c.alarm && partner.is_up() && partner.up_rounds >= DEADLINE_ROUNDS
    })
}

fn both_down(_: &DuplexModel, state: &DuplexState) -> bool {
    state.controllers.iter().all(|c| !c.is_up())
}

fn needs_crash(model: &DuplexModel) -> Option<&'static str> {
    (model.config.max_crashes == 0).then_some("needs a crash (--bounces 1)")
}

fn needs_two_crashes(model: &DuplexModel) -> Option<&'static str> {
    (model.config.max_crashes < 2).then_some("needs two crashes (--bounces 2)")
}

fn needs_preemption(model: &DuplexModel) -> Option<&'static str> {
    if !model.config.preempt {
        return Some("needs preemption (--preempt true)");
    }
    needs_crash(model)
}

fn needs_preemption_and_sickness(model: &DuplexModel) -> Option<&'static str> {
    if !model.config.preempt {
        return Some("needs preemption (--preempt true)");
    }
    (model.config.max_sick_episodes == 0).then_some("needs a sick Primary (--sick-episodes 1)")
}

fn needs_no_preemption(model: &DuplexModel) -> Option<&'static str> {
    if model.config.preempt {
        return Some("a returning Primary preempts (--preempt false)");
    }
    needs_crash(model)
}

fn needs_no_preemption_two_crashes(model: &DuplexModel) -> Option<&'static str> {
    needs_no_preemption(model).or_else(|| needs_two_crashes(model))
}

fn needs_losses(model: &DuplexModel) -> Option<&'static str> {
    (model.config.max_lost_heartbeats < DEADLINE_ROUNDS)
        .then_some("needs the deadline's lost heartbeats (--heartbeat-losses 2)")
}

fn needs_no_preemption_and_losses(model: &DuplexModel) -> Option<&'static str> {
    needs_no_preemption(model).or_else(|| needs_losses(model))
}
