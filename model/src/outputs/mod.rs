//! # Output voting: a second model beside the role model
//!
//! The role model ([`crate::protocol`]) votes on *roles*: a Primary that keeps heartbeating
//! but computes wrong commands drives an exclusive-ownership actuator for as long as it lives.
//! This model specifies what catches it (docs/protocol.md, "Output voting"):
//!
//! - every controller with a role publishes its own command instance, tagged with the input
//!   it answers; a **voting receiver** accepts a value for an input only when two fresh
//!   sources agree on it, raises a `dissent` alarm about a source that disagrees with the
//!   agreeing pair, and holds (accepts nothing, hold alarm) when no two agree;
//! - the paper's **exclusive-ownership receiver** takes the strongest writer's commands;
//! - each controller **cross-checks** its command for an input against the two others', and
//!   the input digest and the raw answer (its law's step before alignment) each carries; the
//!   odd one out of three for N inputs of one life reports a local fault and leaves (FAILED),
//!   then restarts in the lowest free role, correct again or not.
//!
//! It shares the role model's vocabulary ([`crate::types`]: `Id`, `Role`, `Phase`) and
//! abstracts the role protocol to the strength order of the roles: a leaver's juniors move
//! up at once, a restarted controller comes in as the lowest role, which is what the role
//! model's properties guarantee ("restarted controller takes the lowest role", "one owner
//! change per fault"). Time is counted in inputs, not heartbeat rounds.
//!
//! - [`config`]: how many controllers may go wrong, whether two wrong ones may agree, the
//!   cross-check rule and N (K follows), mutations;
//! - [`state`]: controllers, receivers, faults, commands, actions, ghost counts;
//! - [`rules`]: the rules, action by action;
//! - [`properties`]: what must always hold and what must sometimes happen;
//! - [`check`]: the exhaustive check and the shortest counterexamples;
//! - [`render`]: readable states and paths.

pub mod check;
pub mod config;
pub mod properties;
pub mod render;
pub mod rules;
pub mod state;

pub use config::{CrossCheck, OutputConfig, OutputConfigError, OutputMutation};
pub use state::{Command, Controller, Fault, OutputAction, OutputState, Value};

use stateright::{Model, Property};

/// The output-voting rules under a configuration.
#[derive(Clone, Debug)]
pub struct OutputModel {
    pub config: OutputConfig,
}

impl OutputModel {
    pub fn new(config: OutputConfig) -> OutputModel {
        OutputModel { config }
    }

    /// The explorer's names of the initial states, in stateright's order.
    pub fn initial_state_names(&self) -> Vec<String> {
        self.init_states()
            .iter()
            .map(render::initial_state_name)
            .collect()
    }
}

impl Model for OutputModel {
    type State = OutputState;
    type Action = OutputAction;

    fn init_states(&self) -> Vec<OutputState> {
        rules::init_states(&self.config)
    }

    fn actions(&self, state: &OutputState, actions: &mut Vec<OutputAction>) {
        rules::actions(&self.config, state, actions)
    }

    fn next_state(&self, state: &OutputState, action: OutputAction) -> Option<OutputState> {
        rules::next_state(&self.config, state, action)
    }

    fn format_action(&self, action: &OutputAction) -> String {
        action.to_string()
    }

    fn format_step(&self, last_state: &OutputState, action: OutputAction) -> Option<String> {
        self.next_state(last_state, action)
            .map(|next| render::diff(last_state, &next))
    }

    fn properties(&self) -> Vec<Property<Self>> {
        properties::properties()
    }
}
