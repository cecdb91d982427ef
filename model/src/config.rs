//! The size of a check: how many controllers, which faults, how many rounds the timers span,
//! and which rules (variant and reverted fixes).
//!
//! Every fault is bounded by a budget so the state space is finite; the defaults are the
//! configuration `check` runs (three founders, one late joiner, one crash, one restart and one
//! lost heartbeat). Timer lengths derived from others (the minority grace, the losses a
//! minority witness needs) are defined here once.

use crate::fixes::{Fix, Rules, Variant};
use crate::types::{Id, MAX_CONTROLLERS, ROLE_COUNT};

/// The peers of one controller among three voters.
const ROLE_COUNT_PEERS: u8 = ROLE_COUNT as u8 - 1;
use crate::Mutation;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Config {
    /// Controllers that may start at system initialization (ids `1..=founders`). The first
    /// k of them, for every k, is an initial state; the others may join later.
    pub founders: u8,
    /// Further controllers (the next ids) that only ever join a running system.
    pub late_joiners: u8,
    /// Crashes in total over a run.
    pub max_crashes: u8,
    /// Restarts (of a crashed or FAILED controller) in total over a run.
    pub max_restarts: u8,
    /// Lost heartbeats in total over a run (0 = reliable heartbeats).
    pub max_lost_heartbeats: u8,
    /// Pauses (a stopped process that resumes with its memory) in total over a run.
    #[serde(default)]
    pub max_pauses: u8,
    /// Cuts of one controller from its peers (the actuator still hears it) over a run.
    #[serde(default)]
    pub max_isolations: u8,
    /// Starved links of one controller (a rate limit: late, partly dropped datagrams, the
    /// carrier up) over a run.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub max_starvations: u8,
    /// Slowdowns of one controller's process (starved of CPU, throttled: it runs, late) over
    /// a run. Each is one lasting episode: any of its heartbeats may be late (missed by the
    /// round's end) in any round until it heals, and the actuator may miss its commands.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub max_slowdowns: u8,
    /// Late heartbeats of slowed controllers over a run (a slowdown's length; the search
    /// needs a bound, see `Config::late_heartbeats_per_slowdown`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub max_late_heartbeats: u8,
    /// A pause may end unnoticed: the controller runs again with its memory, no signal and
    /// no clock telling it that it stopped ([`crate::Action::Thaw`]), within the peers'
    /// dead-man deadline (a longer stop is noticed: docs/findings.md, F18).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub unnoticed_stalls: bool,
    /// A slowed controller's loop may also take its peers' heartbeats in after its round's
    /// end ([`crate::Action::HearLate`]) or sleep through a round's end
    /// ([`crate::Action::Oversleep`]): a slowed receiver (F18, docs/findings.md).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub slowed_receivers: bool,
    /// A peer is declared lost after this many rounds without its heartbeat (deadline 2x period).
    pub dead_after_rounds: u8,
    /// The initialization window closes after this many rounds without a new peer (paper: 10 s;
    /// abstracted, see docs/model.md) unless three distinct controllers are heard first.
    pub window_rounds: u8,
    /// Bounded response: after this many fault-free rounds every live controller has settled.
    pub settle_within_rounds: u8,
    pub variant: Variant,
    /// Fixes of docs/findings.md taken out of the variant's rules (`check --revert fN`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub reverted: Vec<Fix>,
    /// A deliberately broken rule (mutation tests only).
    pub mutation: Option<Mutation>,
}

/// A configuration outside the model's bounds; each names the field (as `check` spells it).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// No controller starts the system.
    #[error("controllers: at least one controller must start the system")]
    NoFounder,
    /// More controllers than the model's state holds.
    #[error(
        "controllers + late joiners: {count} exceeds the model's maximum of {MAX_CONTROLLERS}"
    )]
    TooManyControllers { count: usize },
    /// A zero dead-man deadline would declare every peer lost at once.
    #[error("dead-after-rounds: must be at least 1")]
    ZeroDeadAfter,
    /// A zero window would close before any peer is heard.
    #[error("window-rounds: must be at least 1")]
    ZeroWindow,
    /// `--revert` with the paper variant, which has no fix left to revert.
    #[error("revert {fix}: the paper variant already reverts every fix")]
    RevertInPaper { fix: String },
}

impl Default for Config {
    fn default() -> Self {
        Config {
            founders: 3,
            late_joiners: 1,
            max_crashes: 1,
            max_restarts: 1,
            max_lost_heartbeats: 1,
            max_pauses: 0,
            max_isolations: 0,
            max_starvations: 0,
            max_slowdowns: 0,
            max_late_heartbeats: 0,
            unnoticed_stalls: false,
            slowed_receivers: false,
            dead_after_rounds: 2,
            window_rounds: 2,
            settle_within_rounds: 10,
            variant: Variant::Default,
            reverted: Vec::new(),
            mutation: None,
        }
    }
}

impl Config {
    /// The larger configuration of `check --full`: four founders, two crashes and restarts.
    pub fn full() -> Config {
        Config {
            founders: 4,
            late_joiners: 0,
            max_crashes: 2,
            max_restarts: 2,
            ..Config::default()
        }
    }

    /// A stalled or cut-off controller that comes back: three controllers, no crash, one
    /// pause and one cut (the scope of "a returning controller never takes the Primary back").
    pub fn returns() -> Config {
        Config {
            late_joiners: 0,
            max_crashes: 0,
            max_restarts: 0,
            max_lost_heartbeats: 0,
            max_pauses: 1,
            max_isolations: 1,
            ..Config::default()
        }
    }

    /// A starved link (F17): three controllers, no crash, one starvation and enough lost
    /// heartbeats for the peers to declare a starved controller lost (its heartbeats come
    /// late or not at all) and for it to miss the takeover's heartbeat once.
    pub fn starved() -> Config {
        let base = Config::default();
        Config {
            late_joiners: 0,
            max_crashes: 0,
            max_restarts: 0,
            max_lost_heartbeats: base.dead_after_rounds,
            max_starvations: 1,
            ..base
        }
    }

    /// The gray process faults (F18): three controllers, no crash, no lost heartbeat, and one
    /// slowed process, a lasting episode (the scope of `check --gray`).
    pub fn gray() -> Config {
        let base = Config::default();
        Config {
            late_joiners: 0,
            max_crashes: 0,
            max_restarts: 0,
            max_lost_heartbeats: 0,
            max_slowdowns: 1,
            max_late_heartbeats: base.late_heartbeats_per_slowdown(),
            ..base
        }
    }

    /// The gray scope with slowed receivers (F18): the slowed controller's loop may also
    /// hear its peers late or sleep through a round's end (`check --gray --slowed-receivers`).
    pub fn slowed_receiver() -> Config {
        Config {
            slowed_receivers: true,
            ..Config::gray()
        }
    }

    /// A stall that may end unnoticed (F18): three controllers, no crash, no lost heartbeat,
    /// one pause (`check --late-joiners 0 --crashes 0 --restarts 0 --lost-heartbeats 0
    /// --pauses 1 --unnoticed-stalls`).
    pub fn unnoticed_stall() -> Config {
        Config {
            max_slowdowns: 0,
            max_late_heartbeats: 0,
            max_pauses: 1,
            unnoticed_stalls: true,
            ..Config::gray()
        }
    }

    /// A link that stays broken: three controllers, no other fault, enough lost heartbeats
    /// for a one-way loss to outlast the minority grace (the scope of the minority witness).
    pub fn link_failure() -> Config {
        let base = Config::default();
        Config {
            late_joiners: 0,
            max_crashes: 0,
            max_restarts: 0,
            max_lost_heartbeats: base.losses_to_fail_minority(),
            ..base
        }
    }

    /// Scopes searched only for the (action kind x stage) pairs they reach: the denominator
    /// of the transition coverage is taken beyond the scopes the traces are cut from, so
    /// pairs no trace exercises show. A returning controller that also crashes and restarts
    /// (a cut one heals while down or initializing), and a link failure that outlasts the
    /// minority grace with a loss and a restart to spare (a FAILED controller loses a
    /// heartbeat, restarts), at a one-round dead-man deadline to keep the search small
    /// (shorter timers change how many rounds pass, not which events can happen).
    pub fn coverage_scopes() -> Vec<(&'static str, Config)> {
        let returns_and_restart = Config {
            max_crashes: 1,
            max_restarts: 1,
            ..Config::returns()
        };
        let short = Config {
            dead_after_rounds: 1,
            ..Config::link_failure()
        };
        let failed_and_restart = Config {
            max_lost_heartbeats: short.losses_to_fail_minority() + 1,
            max_restarts: 1,
            ..short
        };
        vec![
            ("coverage-returns-restart", returns_and_restart),
            ("coverage-failed-restart", failed_and_restart),
        ]
    }

    /// The paper-variant scopes of docs/findings.md, without network faults, each with the
    /// finding whose counterexample it shows (F2, F3, F4).
    pub fn paper_findings() -> Vec<(Fix, Config)> {
        let paper = Config {
            max_lost_heartbeats: 0,
            variant: Variant::Paper,
            ..Config::default()
        };
        vec![
            (
                Fix::KeepStandbyOrder,
                Config {
                    late_joiners: 0,
                    max_crashes: 0,
                    max_restarts: 0,
                    ..paper.clone()
                },
            ),
            (
                Fix::IncarnationAware,
                Config {
                    late_joiners: 0,
                    ..paper.clone()
                },
            ),
            (
                Fix::QuorumOfView,
                Config {
                    max_crashes: 0,
                    max_restarts: 0,
                    ..paper
                },
            ),
        ]
    }

    pub fn controller_count(&self) -> usize {
        usize::from(self.founders) + usize::from(self.late_joiners)
    }

    pub fn ids(&self) -> impl Iterator<Item = Id> + Clone {
        1..=self.controller_count() as Id
    }

    /// The variant's rules without the reverted fixes.
    pub fn rules(&self) -> Rules {
        Rules::of(self.variant).reverting(&self.reverted)
    }

    pub fn mutated(&self, mutation: Mutation) -> bool {
        self.mutation == Some(mutation)
    }

    /// Rounds a dissent must persist before its voter is marked FAILED (F10): the detection
    /// skew between voters (`dead_after_rounds`) plus one round of vote delay; 0 without F10.
    pub fn minority_grace_rounds(&self) -> u8 {
        if self.rules().f10_minority_grace {
            self.dead_after_rounds + 1
        } else {
            0
        }
    }

    /// The late heartbeats of `Config::gray`'s slowdown: enough for both peers to declare
    /// the slowed controller lost, or for one to lose it, hear it again and lose it once
    /// more. A longer episode repeats the same rules with later epochs (numbers the search
    /// cannot fold): `check --gray --late-heartbeats 6` holds too (docs/findings.md, F18).
    pub fn late_heartbeats_per_slowdown(&self) -> u8 {
        2 * ROLE_COUNT_PEERS * self.dead_after_rounds
    }

    /// Lost heartbeats on one link before its receiver can mark a live sender FAILED: the
    /// dead-man deadline, then a dissent that outlasts the minority grace.
    pub fn losses_to_fail_minority(&self) -> u8 {
        self.dead_after_rounds + self.minority_grace_rounds()
    }

    /// Checks the bounds; the error names the field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let count = self.controller_count();
        if self.founders == 0 {
            return Err(ConfigError::NoFounder);
        }
        if count > MAX_CONTROLLERS {
            return Err(ConfigError::TooManyControllers { count });
        }
        if self.dead_after_rounds == 0 {
            return Err(ConfigError::ZeroDeadAfter);
        }
        if self.window_rounds == 0 {
            return Err(ConfigError::ZeroWindow);
        }
        if let (Variant::Paper, Some(fix)) = (self.variant, self.reverted.first()) {
            return Err(ConfigError::RevertInPaper {
                fix: fix.label().to_lowercase(),
            });
        }
        Ok(())
    }

    /// The `model` flags that select this configuration (for `explore` and `check` command
    /// lines printed with a counterexample).
    pub fn flags(&self) -> String {
        let mut flags = format!(
            "--controllers {} --late-joiners {} --crashes {} --restarts {} --lost-heartbeats {} \
             --pauses {} --cuts {} --variant {}",
            self.founders,
            self.late_joiners,
            self.max_crashes,
            self.max_restarts,
            self.max_lost_heartbeats,
            self.max_pauses,
            self.max_isolations,
            match self.variant {
                crate::Variant::Default => "default",
                crate::Variant::V1 => "v1",
                crate::Variant::Paper => "paper",
            }
        );
        for (flag, _) in self.optional_faults() {
            flags.push_str(&format!(" {flag}"));
        }
        for fix in &self.reverted {
            flags.push_str(&format!(" --revert {}", fix.label().to_lowercase()));
        }
        flags
    }

    /// The faults that only some scopes enable, as the check's flags and as the summary
    /// names them: absent when off, so the configurations before them read as they did.
    fn optional_faults(&self) -> Vec<(String, String)> {
        let mut faults = Vec::new();
        if self.max_starvations > 0 {
            faults.push((
                format!("--starvations {}", self.max_starvations),
                format!("starvations {}", self.max_starvations),
            ));
        }
        if self.max_slowdowns > 0 {
            faults.push((
                format!(
                    "--slowdowns {} --late-heartbeats {}",
                    self.max_slowdowns, self.max_late_heartbeats
                ),
                format!(
                    "slowdowns {} (late heartbeats {})",
                    self.max_slowdowns, self.max_late_heartbeats
                ),
            ));
        }
        if self.unnoticed_stalls {
            faults.push(("--unnoticed-stalls".into(), "unnoticed stalls".into()));
        }
        if self.slowed_receivers {
            faults.push(("--slowed-receivers".into(), "slowed receivers".into()));
        }
        faults
    }

    /// One line naming the configuration, for reports and trace headers.
    pub fn summary(&self) -> String {
        let mut line = format!(
            "{} controllers + {} late joiner(s), crashes {}, restarts {}, lost heartbeats {}, \
             pauses {}, cuts {}, dead after {} rounds, window {} rounds, variant {:?}",
            self.founders,
            self.late_joiners,
            self.max_crashes,
            self.max_restarts,
            self.max_lost_heartbeats,
            self.max_pauses,
            self.max_isolations,
            self.dead_after_rounds,
            self.window_rounds,
            self.variant
        );
        for (_, label) in self.optional_faults() {
            line.push_str(&format!(", {label}"));
        }
        if !self.reverted.is_empty() {
            let labels: Vec<String> = self.reverted.iter().map(|fix| fix.label()).collect();
            line.push_str(&format!(", reverted {}", labels.join(" ")));
        }
        if let Some(mutation) = self.mutation {
            line.push_str(&format!(", MUTATION {mutation:?}"));
        }
        line
    }
}

fn is_zero(value: &u8) -> bool {
    *value == 0
}
