//! # The lockstep pair, in software
//!
//! The paper's second architecture without its custom hardware: two controllers with no
//! roles, both writing the command topic at once (the actuator receives up to two samples
//! per input). Each runs its control law twice, in two diverse implementations, and compares
//! the two outputs of every input before it writes; on a mismatch it removes itself at once:
//! it writes nothing more, goes FAILED with its local-fault alarm, and exits to be restarted.
//! Its partner, which no longer hears it, alarms the loss.
//!
//! The faults: a crash, and a bug: an implementation wrong at the inputs that trigger it. By
//! default a bug lies in one implementation of one controller, which its comparison catches;
//! `--bug-in` places it where no comparison of this kind can: in both implementations alike
//! (finding A2: the wrong output passes the comparison) or in one implementation both
//! controllers run (finding A3: both leave at once).
//!
//! - [`state`]: controllers, implementations, samples, actions, readable lines;
//! - [`rules`]: the rules, action by action;
//! - [`properties`]: what must always hold and what must sometimes happen.

pub mod properties;
pub mod rules;
pub mod state;

pub use state::{Answer, BugSite, Implementation, Output, PairAction, PairController, PairState};

use super::check::{self, PropertyInfo, Spec};
use super::{ArchitectureConfigError, ArchitectureMutation};
use serde::{Deserialize, Serialize};
use stateright::{Model, Property};

/// Where a bug may lie (`--bug-in`).
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    PartialOrd,
    Ord,
    Hash,
    Serialize,
    Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
pub enum BugReach {
    /// One implementation of one controller: the comparison catches it.
    OneImplementation,
    /// Both implementations of one controller, alike (finding A2).
    BothImplementations,
    /// One implementation that both controllers run (finding A3).
    BothControllers,
}

impl BugReach {
    /// The flag's value.
    pub fn flag(self) -> &'static str {
        match self {
            BugReach::OneImplementation => "one-implementation",
            BugReach::BothImplementations => "both-implementations",
            BugReach::BothControllers => "both-controllers",
        }
    }
}

/// The pair's scope.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PairConfig {
    /// Crashes over a run (`--bounces`); a crashed controller may restart after each.
    pub max_crashes: u8,
    /// Bugs that may appear over a run.
    pub max_bugs: u8,
    /// Where a bug may lie.
    pub bug_reach: BugReach,
    /// A deliberately broken rule (mutation tests only).
    pub mutation: Option<ArchitectureMutation>,
}

impl Default for PairConfig {
    /// The scope `check --architecture pair` runs: two crashes and two bugs, each in one
    /// implementation of one controller.
    fn default() -> Self {
        PairConfig {
            max_crashes: 2,
            max_bugs: 2,
            bug_reach: BugReach::OneImplementation,
            mutation: None,
        }
    }
}

/// The largest budgets the pair takes (each check stays within seconds).
const MAX_BUDGET: u8 = 3;

impl PairConfig {
    /// A bug of both implementations of a controller alike: finding A2.
    pub fn common_bug() -> PairConfig {
        PairConfig {
            bug_reach: BugReach::BothImplementations,
            ..PairConfig::default()
        }
    }

    /// A bug of one implementation that both controllers run: finding A3.
    pub fn shared_implementation() -> PairConfig {
        PairConfig {
            bug_reach: BugReach::BothControllers,
            ..PairConfig::default()
        }
    }

    pub fn validate(&self) -> Result<(), ArchitectureConfigError> {
        for (flag, value) in [("bounces", self.max_crashes), ("bugs", self.max_bugs)] {
            if value > MAX_BUDGET {
                return Err(ArchitectureConfigError::TooLarge {
                    flag,
                    value,
                    max: MAX_BUDGET,
                    architecture: "pair",
                });
            }
        }
        Ok(())
    }

    /// One line for the report.
    pub fn summary(&self) -> String {
        let mut line = format!(
            "lockstep pair in software: C1, C2 both commanding, implementations A and B compared before every write, {} crashes, {} bugs in {}",
            self.max_crashes,
            self.max_bugs,
            self.bug_reach.flag()
        );
        if let Some(mutation) = self.mutation {
            line.push_str(&format!(", MUTATION {mutation:?}"));
        }
        line
    }

    /// The flags that give this configuration.
    pub fn flags(&self) -> String {
        let mut flags = format!(
            "--architecture pair --bounces {} --bugs {} --bug-in {}",
            self.max_crashes,
            self.max_bugs,
            self.bug_reach.flag()
        );
        if let Some(mutation) = self.mutation {
            flags.push_str(&format!(" --architecture-mutation {}", mutation.flag()));
        }
        flags
    }
}

/// The pair's rules under a configuration.
#[derive(Clone, Debug)]
pub struct PairModel {
    pub config: PairConfig,
}

impl PairModel {
    pub fn new(config: PairConfig) -> PairModel {
        PairModel { config }
    }
}

impl Model for PairModel {
    type State = PairState;
    type Action = PairAction;

    fn init_states(&self) -> Vec<PairState> {
        rules::init_states(&self.config)
    }

    fn actions(&self, state: &PairState, actions: &mut Vec<PairAction>) {
        rules::actions(&self.config, state, actions)
    }

    fn next_state(&self, state: &PairState, action: PairAction) -> Option<PairState> {
        rules::next_state(&self.config, state, action)
    }

    fn format_action(&self, action: &PairAction) -> String {
        action.to_string()
    }

    fn format_step(&self, last_state: &PairState, action: PairAction) -> Option<String> {
        self.next_state(last_state, action)
            .map(|next| check::diff::<Self>(last_state, &next))
    }

    fn properties(&self) -> Vec<Property<Self>> {
        check::properties()
    }
}

impl Spec for PairModel {
    type SpecState = PairState;
    type SpecAction = PairAction;

    fn catalogue() -> Vec<PropertyInfo<Self>> {
        properties::catalogue()
    }

    fn summary(&self) -> String {
        self.config.summary()
    }

    fn flags(&self) -> String {
        self.config.flags()
    }

    fn state_lines(state: &PairState) -> Vec<String> {
        state::state_lines(state)
    }

    fn initial_state_name(&self, state: &PairState) -> String {
        let input = if state.triggers {
            "input 1 would trigger a bug"
        } else {
            "input 1 triggers no bug"
        };
        format!("C1, C2 in service, no bug yet; {input}")
    }
}
