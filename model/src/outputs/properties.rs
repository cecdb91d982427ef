//! What the output model must always hold and must sometimes show, each explained in
//! docs/protocol.md, "Output voting".
//!
//! "While at most one is wrong" properties read the ghost `two_wrong_at_once`: from the moment
//! two controllers were wrong together they say nothing (finding O1 is what happens then);
//! the others hold with any number of wrong controllers the scope allows, or are the finding.

use super::state::{Command, Fault, OutputState};
use super::{OutputConfig, OutputModel};
use crate::types::{Phase, Role};
use stateright::{Expectation, Property};

/// Name, expectation, one-line meaning, condition: the catalogue `check --outputs` prints.
pub struct OutputPropertyInfo {
    pub name: &'static str,
    pub expectation: Expectation,
    pub meaning: &'static str,
    pub condition: fn(&OutputModel, &OutputState) -> bool,
}

impl OutputPropertyInfo {
    /// Whether the scope has the faults this property's witness needs.
    pub fn applies(&self, config: &OutputConfig) -> bool {
        match self.name {
            "a voting receiver holds" => config.max_wrong >= 2,
            _ => config.max_wrong >= 1,
        }
    }

    /// Why `applies` is false, for the report.
    pub fn needs(&self) -> &'static str {
        match self.name {
            "a voting receiver holds" => "needs two wrong controllers (--wrong 2)",
            _ => "needs a wrong controller (--wrong 1)",
        }
    }
}

pub fn catalogue() -> Vec<OutputPropertyInfo> {
    use Expectation::{Always, Sometimes};
    let p = |name, expectation, meaning, condition| OutputPropertyInfo {
        name,
        expectation,
        meaning,
        condition,
    };
    vec![
        p("a voting receiver never accepts a wrong command", Always,
          "the value a voting receiver accepts for an input is the right command for it",
          accepts_only_right),
        p("a voting receiver accepts only what two sources sent", Always,
          "a voting receiver accepts a value for an input only once two fresh sources sent it",
          accepts_only_a_pair),
        p("every dissent is alarmed", Always,
          "a source whose command differs from the value accepted for the same input has its dissent alarm up",
          dissent_alarmed),
        p("a dissent alarm names only a wrong controller", Always,
          "a dissent alarm is up only about a controller that has sent a wrong value",
          dissent_names_wrong),
        p("a held input is alarmed", Always,
          "at the next input, the hold alarm is up exactly when the input before closed without two agreeing commands",
          hold_alarmed),
        p("every input is accepted while at most one is wrong", Always,
          "while at most one controller is wrong, a voting receiver never holds",
          accepts_every_input),
        p("a correct controller never leaves", Always,
          "no controller whose output is correct reports a local fault and leaves",
          correct_never_leaves),
        p("a wrong controller leaves within N wrong commands", Always,
          "while at most one is wrong, a controller that sent N wrong or missing commands in one life answers no further input in it",
          wrong_leaves_within_n),
        p("a masked wrong input is found within N inputs", Always,
          "while at most one is wrong, a controller that answered N inputs from a wrong input in one life (its output right, aligned) answers no further input in it",
          wrong_input_found_within_n),
        p("a controller that leaves for its input is alarmed by name", Always,
          "a controller that left with a wrong input has its input alarm about itself up until it restarts",
          wrong_input_alarmed),
        p("a masked wrong law is found within N inputs", Always,
          "while at most one is wrong, a controller that answered N inputs with a wrong law in one life (its output right, aligned) answers no further input in it",
          wrong_law_found_within_n),
        p("a controller that leaves for its law is alarmed by name", Always,
          "a controller that left with a wrong law has its law alarm about itself up until it restarts",
          wrong_law_alarmed),
        p("an exclusive receiver takes at most K wrong or missing commands", Always,
          "while at most one is wrong, an exclusive-ownership receiver takes at most K wrong or missing commands from one controller's life",
          exclusive_bounded),
        p("a wrong-value controller leaves", Sometimes,
          "a controller sending wrong values is the odd one out and leaves",
          left_with_wrong_values),
        p("a frozen controller leaves", Sometimes,
          "a controller whose output froze is the odd one out once the plant moves, and leaves",
          left_frozen),
        p("an omitting controller leaves", Sometimes,
          "a controller publishing nothing is the odd one out and leaves",
          left_omitting),
        p("an erratic controller leaves", Sometimes,
          "an intermittently wrong controller leaves after N odd-one-out inputs",
          left_erratic),
        p("a controller with a wrong input leaves", Sometimes,
          "a controller whose wrong input its aligned output masks is the odd one out on input and leaves, alarmed",
          left_with_wrong_input),
        p("a controller with a wrong law leaves", Sometimes,
          "a controller whose wrong law its aligned output masks is the odd one out on its raw answers and leaves, alarmed",
          left_with_wrong_law),
        p("a wrong Primary leaves and the exclusive receiver follows the next", Sometimes,
          "the Primary leaves with a local fault and the exclusive receiver's owner is another controller",
          wrong_primary_replaced),
        p("an exclusive receiver takes K wrong commands", Sometimes,
          "the bound K is reached: it is no larger than it must be",
          exclusive_reaches_k),
        p("an exclusive receiver misses a command", Sometimes,
          "an omitting Primary's missing command is counted against K",
          exclusive_misses),
        p("a dissent alarm is raised", Sometimes,
          "a voting receiver names a dissenting source",
          dissent_raised),
        p("a restarted controller agrees again", Sometimes,
          "a controller restarted correct has its command accepted, which clears its dissent alarm",
          restarted_agrees),
        p("a restarted wrong controller leaves again", Sometimes,
          "a controller restarted still wrong is the odd one out again and leaves again",
          restarted_wrong_leaves),
        p("a voting receiver holds", Sometimes,
          "an input closes without two agreeing commands: nothing is accepted, the hold alarm is up",
          holds),
    ]
}

pub fn properties() -> Vec<Property<OutputModel>> {
    catalogue()
        .into_iter()
        .map(|info| match info.expectation {
            Expectation::Always => Property::always(info.name, info.condition),
            Expectation::Sometimes => Property::sometimes(info.name, info.condition),
            Expectation::Eventually => Property::eventually(info.name, info.condition),
        })
        .collect()
}

fn accepts_only_right(_: &OutputModel, state: &OutputState) -> bool {
    state
        .voting
        .accepted
        .is_none_or(|value| value == state.right)
}

fn accepts_only_a_pair(_: &OutputModel, state: &OutputState) -> bool {
    state
        .voting
        .accepted
        .is_none_or(|value| state.senders_of(value) >= 2)
}

fn dissent_alarmed(_: &OutputModel, state: &OutputState) -> bool {
    let Some(accepted) = state.voting.accepted else {
        return true;
    };
    state
        .controllers
        .iter()
        .zip(state.voting.dissent)
        .all(|(c, alarm)| match c.command {
            Command::Sent(value) if value != accepted => alarm,
            _ => true,
        })
}

fn dissent_names_wrong(_: &OutputModel, state: &OutputState) -> bool {
    state
        .controllers
        .iter()
        .zip(state.voting.dissent)
        .all(|(c, alarm)| !alarm || c.ever_sent_wrong)
}

fn hold_alarmed(_: &OutputModel, state: &OutputState) -> bool {
    !state.input_fresh() || state.voting.hold_alarm == state.closed_without_pair
}

fn accepts_every_input(_: &OutputModel, state: &OutputState) -> bool {
    state.two_wrong_at_once || !state.voting.hold_alarm
}

fn correct_never_leaves(_: &OutputModel, state: &OutputState) -> bool {
    state
        .controllers
        .iter()
        .all(|c| c.phase != Phase::Failed || c.fault.is_some())
}

fn wrong_leaves_within_n(model: &OutputModel, state: &OutputState) -> bool {
    let limit = model.config.odd_limit;
    state.two_wrong_at_once
        || state
            .controllers
            .iter()
            .all(|c| c.command != Command::Pending || c.wrong_in_life < limit)
}

fn wrong_input_found_within_n(model: &OutputModel, state: &OutputState) -> bool {
    let limit = model.config.odd_limit;
    state.two_wrong_at_once
        || state
            .controllers
            .iter()
            .all(|c| c.command != Command::Pending || c.wrong_input_in_life < limit)
}

fn wrong_input_alarmed(_: &OutputModel, state: &OutputState) -> bool {
    state.two_wrong_at_once
        || state.controllers.iter().all(|c| {
            !(c.phase == Phase::Failed && c.fault == Some(Fault::WrongInput)) || c.input_alarm
        })
}

fn left_with_wrong_input(_: &OutputModel, state: &OutputState) -> bool {
    state
        .controllers
        .iter()
        .any(|c| c.phase == Phase::Failed && c.fault == Some(Fault::WrongInput) && c.input_alarm)
}

fn wrong_law_found_within_n(model: &OutputModel, state: &OutputState) -> bool {
    let limit = model.config.odd_limit;
    state.two_wrong_at_once
        || state
            .controllers
            .iter()
            .all(|c| c.command != Command::Pending || c.wrong_law_in_life < limit)
}

fn wrong_law_alarmed(_: &OutputModel, state: &OutputState) -> bool {
    state.two_wrong_at_once
        || state
            .controllers
            .iter()
            .all(|c| !(c.phase == Phase::Failed && c.fault == Some(Fault::WrongLaw)) || c.law_alarm)
}

fn left_with_wrong_law(_: &OutputModel, state: &OutputState) -> bool {
    state
        .controllers
        .iter()
        .any(|c| c.phase == Phase::Failed && c.fault == Some(Fault::WrongLaw) && c.law_alarm)
}

fn exclusive_bounded(model: &OutputModel, state: &OutputState) -> bool {
    let bound = model.config.exclusive_bound();
    state.two_wrong_at_once
        || state
            .controllers
            .iter()
            .all(|c| c.exclusive_wrong + c.exclusive_missed <= bound)
}

/// Some controller has left with a fault that `matches`.
fn left_with(state: &OutputState, matches: fn(Fault) -> bool) -> bool {
    state
        .controllers
        .iter()
        .any(|c| c.phase == Phase::Failed && c.fault.is_some_and(matches))
}

fn left_with_wrong_values(_: &OutputModel, state: &OutputState) -> bool {
    left_with(state, |fault| fault == Fault::WrongValue)
}

fn left_frozen(_: &OutputModel, state: &OutputState) -> bool {
    left_with(state, |fault| matches!(fault, Fault::Frozen(_)))
}

fn left_omitting(_: &OutputModel, state: &OutputState) -> bool {
    left_with(state, |fault| fault == Fault::Omitted)
}

fn left_erratic(_: &OutputModel, state: &OutputState) -> bool {
    left_with(state, |fault| fault == Fault::Erratic)
}

fn wrong_primary_replaced(_: &OutputModel, state: &OutputState) -> bool {
    state.controllers.iter().any(|c| {
        c.phase == Phase::Failed
            && c.fault.is_some()
            && c.left_as == Some(Role::Primary)
            && state.exclusive.owner.is_some_and(|owner| owner != c.id)
    })
}

fn exclusive_reaches_k(model: &OutputModel, state: &OutputState) -> bool {
    let bound = model.config.exclusive_bound();
    state.controllers.iter().any(|c| c.exclusive_wrong == bound)
}

fn exclusive_misses(_: &OutputModel, state: &OutputState) -> bool {
    state.controllers.iter().any(|c| c.exclusive_missed >= 1)
}

fn dissent_raised(_: &OutputModel, state: &OutputState) -> bool {
    state.voting.dissent.contains(&true)
}

fn restarted_agrees(_: &OutputModel, state: &OutputState) -> bool {
    state
        .controllers
        .iter()
        .zip(state.voting.dissent)
        .any(|(c, alarm)| {
            c.restarted
                && c.ever_sent_wrong
                && c.fault.is_none()
                && !alarm
                && c.command.value().is_some()
                && c.command.value() == state.voting.accepted
        })
}

fn restarted_wrong_leaves(_: &OutputModel, state: &OutputState) -> bool {
    state
        .controllers
        .iter()
        .any(|c| c.restarted && c.phase == Phase::Failed && c.fault.is_some())
}

fn holds(_: &OutputModel, state: &OutputState) -> bool {
    state.voting.hold_alarm
}
