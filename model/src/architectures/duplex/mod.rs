//! # The simple duplex
//!
//! The paper's first architecture: two off-the-shelf controllers with static roles from
//! configuration, C1 the Primary and C2 the Standby, both computing and writing the command
//! topic through DDS exclusive ownership at strengths 30 and 20, so the actuator follows the
//! Primary while it lives and the Standby at once when it dies. Each watches the other's
//! heartbeats against a deadline and alarms a partner it lost.
//!
//! On the Primary's return the paper has DDS "instantly resume" its samples (strength 30
//! wins): `preempt`. Without preemption (the default scope) a returning controller writes at
//! a yielded strength, 10, until its first heartbeat from the partner: if the partner
//! commands at a lower configured strength it keeps yielding (the returned Primary stays
//! standby), otherwise, or when the partner is lost at the deadline, it takes its own.
//!
//! - [`state`]: controllers, actuator, lost heartbeats, actions, readable lines;
//! - [`rules`]: the rules, action by action;
//! - [`properties`]: what must always hold and what must sometimes happen.

pub mod properties;
pub mod rules;
pub mod state;

pub use state::{DuplexAction, DuplexController, DuplexState, PartnerView, Writing};

use super::check::{self, PropertyInfo, Spec};
use super::{ArchitectureConfigError, ArchitectureMutation};
use serde::{Deserialize, Serialize};
use stateright::{Model, Property};

/// The duplex's scope and rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct DuplexConfig {
    /// A returning controller writes at its configured strength at once (the paper's rule).
    pub preempt: bool,
    /// Crashes over a run; a crashed controller may restart after each (`--bounces`).
    pub max_crashes: u8,
    /// Heartbeats lost over a run, one round of one direction each.
    pub max_lost_heartbeats: u8,
    /// Gray-fault episodes of the Primary over a run (`--sick-episodes`): its loop starved
    /// or stalling, lapsing again and again while the episode lasts (finding A4).
    pub max_sick_episodes: u8,
    /// Lapses of a sick Primary's loop over a run.
    pub max_lapses: u8,
    /// A deliberately broken rule (mutation tests only).
    pub mutation: Option<ArchitectureMutation>,
}

impl Default for DuplexConfig {
    /// The scope `check --architecture duplex` runs: no preemption, three crashes (each
    /// controller can bounce, one of them twice), three lost heartbeats (one more than the
    /// deadline: an episode that is taken for a failure, and another loss).
    fn default() -> Self {
        DuplexConfig {
            preempt: false,
            max_crashes: 3,
            max_lost_heartbeats: 3,
            max_sick_episodes: 0,
            max_lapses: 3,
            mutation: None,
        }
    }
}

/// The largest budgets the duplex takes (each check stays within seconds).
const MAX_BUDGET: u8 = 4;

impl DuplexConfig {
    /// The paper's rule: a returning Primary preempts (finding A1).
    pub fn paper() -> DuplexConfig {
        DuplexConfig {
            preempt: true,
            ..DuplexConfig::default()
        }
    }

    /// The scope of finding A4: the preempting duplex whose Primary is starved once, lapsing
    /// up to three times in the episode, beside one crash and the deadline's lost heartbeats.
    pub fn sick_primary() -> DuplexConfig {
        DuplexConfig {
            preempt: true,
            max_crashes: 1,
            max_lost_heartbeats: 2,
            max_sick_episodes: 1,
            max_lapses: 3,
            mutation: None,
        }
    }

    pub fn validate(&self) -> Result<(), ArchitectureConfigError> {
        for (flag, value) in [
            ("bounces", self.max_crashes),
            ("heartbeat-losses", self.max_lost_heartbeats),
            ("sick-episodes", self.max_sick_episodes),
            ("lapses", self.max_lapses),
        ] {
            if value > MAX_BUDGET {
                return Err(ArchitectureConfigError::TooLarge {
                    flag,
                    value,
                    max: MAX_BUDGET,
                    architecture: "duplex",
                });
            }
        }
        Ok(())
    }

    /// One line for the report.
    pub fn summary(&self) -> String {
        let mut line = format!(
            "simple duplex: C1 Primary (30), C2 Standby (20), preemption {}, {} crashes, {} lost heartbeats, deadline {} rounds",
            if self.preempt { "on" } else { "off" },
            self.max_crashes,
            self.max_lost_heartbeats,
            state::DEADLINE_ROUNDS
        );
        if self.max_sick_episodes > 0 {
            line.push_str(&format!(
                ", {} sick episodes of the Primary ({} lapses, dwell {} rounds)",
                self.max_sick_episodes,
                self.max_lapses,
                state::DWELL_ROUNDS
            ));
        }
        if let Some(mutation) = self.mutation {
            line.push_str(&format!(", MUTATION {mutation:?}"));
        }
        line
    }

    /// The flags that give this configuration.
    pub fn flags(&self) -> String {
        let mut flags = format!(
            "--architecture duplex --preempt {} --bounces {} --heartbeat-losses {}",
            self.preempt, self.max_crashes, self.max_lost_heartbeats
        );
        if self.max_sick_episodes > 0 {
            flags.push_str(&format!(
                " --sick-episodes {} --lapses {}",
                self.max_sick_episodes, self.max_lapses
            ));
        }
        if let Some(mutation) = self.mutation {
            flags.push_str(&format!(" --architecture-mutation {}", mutation.flag()));
        }
        flags
    }
}

/// The duplex's rules under a configuration.
#[derive(Clone, Debug)]
pub struct DuplexModel {
    pub config: DuplexConfig,
}

impl DuplexModel {
    pub fn new(config: DuplexConfig) -> DuplexModel {
        DuplexModel { config }
    }
}

impl Model for DuplexModel {
    type State = DuplexState;
    type Action = DuplexAction;

    fn init_states(&self) -> Vec<DuplexState> {
        rules::init_states(&self.config)
    }

    fn actions(&self, state: &DuplexState, actions: &mut Vec<DuplexAction>) {
        rules::actions(&self.config, state, actions)
    }

    fn next_state(&self, state: &DuplexState, action: DuplexAction) -> Option<DuplexState> {
        rules::next_state(&self.config, state, action)
    }

    fn format_action(&self, action: &DuplexAction) -> String {
        action.to_string()
    }

    fn format_step(&self, last_state: &DuplexState, action: DuplexAction) -> Option<String> {
        self.next_state(last_state, action)
            .map(|next| check::diff::<Self>(last_state, &next))
    }

    fn properties(&self) -> Vec<Property<Self>> {
        check::properties()
    }
}

impl Spec for DuplexModel {
    type SpecState = DuplexState;
    type SpecAction = DuplexAction;

    fn catalogue() -> Vec<PropertyInfo<Self>> {
        properties::catalogue()
    }

    fn summary(&self) -> String {
        self.config.summary()
    }

    fn flags(&self) -> String {
        self.config.flags()
    }

    fn state_lines(state: &DuplexState) -> Vec<String> {
        state::state_lines(state)
    }

    fn initial_state_name(&self, _state: &DuplexState) -> String {
        "C1 Primary commands at 30, C2 Standby writes at 20".to_string()
    }
}
