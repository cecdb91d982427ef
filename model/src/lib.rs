//! # RL's voting protocol, as a checkable specification
//!
//! This crate is the normative specification of the Redundancy Layer's three-way voting
//! protocol (docs/protocol.md). It is a hand-written [`stateright::Model`]:
//!
//! - [`types`]: the vocabulary shared with the implementation (roles, phases, assignments);
//! - [`config`]: how big a check is (controllers, fault budgets, timer lengths in rounds);
//! - [`fixes`]: the findings' fixes as switches (docs/findings.md), variants and mutations;
//! - [`action`]: the environment and timer events, which are also the trace vocabulary;
//! - [`state`]: what each controller knows, the network, and the ghost history;
//! - [`protocol`]: the rules, action by action;
//! - [`properties`]: what must always hold and what must sometimes happen;
//! - [`search`]: our own breadth-first search for shortest counterexamples and traces;
//! - [`simulate`]: seeded random walks, one seed reproducing one walk on any machine;
//! - [`traces`]: the committed trace set the conformance suite replays;
//! - [`render`]: readable states, steps and sequence diagrams;
//! - [`explore`]: the front of stateright's explorer UI that names the initial states;
//! - [`outputs`]: a second model beside the role model, sharing its vocabulary: output
//!   voting, where a controller's commands can go wrong while its heartbeats stay correct
//!   (`check --outputs`, docs/protocol.md "Output voting");
//! - [`architectures`]: the paper's two other architectures, the simple duplex and the
//!   lockstep pair in software, as models of their own in the same vocabulary
//!   (`check --architecture duplex|pair`, docs/protocol.md "Other architectures: the spec").
//!
//! Time is counted in rounds of one heartbeat period (docs/model.md explains why).

pub mod action;
pub mod architectures;
pub mod config;
pub mod explore;
pub mod fixes;
pub mod outputs;
pub mod properties;
pub mod protocol;
pub mod render;
pub mod search;
pub mod simulate;
pub mod state;
pub mod traces;
pub mod types;

pub use config::Config;
pub use fixes::{Fix, Mutation, Rules, Variant};
pub use state::{Action, ActionKind, Controller, State};
pub use types::{Assignment, Holder, Id, Life, Phase, Role};

use stateright::{Model, Path, Property};

/// The protocol under a configuration.
#[derive(Clone, Debug)]
pub struct RlModel {
    pub config: Config,
}

impl RlModel {
    pub fn new(config: Config) -> RlModel {
        RlModel { config }
    }
}

impl Model for RlModel {
    type State = State;
    type Action = Action;

    fn init_states(&self) -> Vec<State> {
        protocol::init_states(&self.config)
    }

    fn actions(&self, state: &State, actions: &mut Vec<Action>) {
        protocol::actions(&self.config, state, actions)
    }

    fn next_state(&self, state: &State, action: Action) -> Option<State> {
        protocol::next_state(&self.config, state, action)
    }

    fn format_action(&self, action: &Action) -> String {
        action.to_string()
    }

    fn format_step(&self, last_state: &State, action: Action) -> Option<String> {
        self.next_state(last_state, action)
            .map(|next| render::diff(last_state, &next))
    }

    fn as_svg(&self, path: Path<State, Action>) -> Option<String> {
        let pairs = path.into_vec();
        let init = pairs.first()?.0.clone();
        let steps: Vec<(Action, State)> = pairs
            .windows(2)
            .filter_map(|pair| pair[0].1.map(|action| (action, pair[1].0.clone())))
            .collect();
        Some(render::svg(&init, &steps))
    }

    fn properties(&self) -> Vec<Property<Self>> {
        properties::properties()
    }
}
