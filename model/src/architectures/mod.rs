//! # The paper's two other architectures, as models beside the voting ones
//!
//! The source paper weighs three redundancy architectures and concludes for three-way voting,
//! the one RL implements (the role model, [`crate::protocol`], and its output voting,
//! [`crate::outputs`]). The two others are specified here, in the same vocabulary
//! ([`crate::types`]: `Id`, `Role`, `Phase`, `Life`), so that the paper's comparison of them
//! rests on checked properties and counterexamples rather than on prose
//! (docs/protocol.md, "Other architectures: the spec"):
//!
//! - [`duplex`]: the **simple duplex**: a Primary and a Standby by configuration, commanding
//!   the actuator through DDS exclusive ownership at 30 and 20, each watching the other's
//!   heartbeats; a returning Primary takes the actuator back at once (`preempt`, the paper's
//!   rule: finding A1) or stays standby while the Standby commands;
//! - [`pair`]: the **lockstep pair in software**: two controllers without roles, both
//!   commanding at once, each running its control law in two diverse implementations and
//!   comparing every output before it writes; a mismatch removes the controller at once
//!   (findings A2 and A3 are what no comparison of this kind can catch).
//!
//! [`check`] holds what both share: the property catalogue's shape, the exhaustive check with
//! stateright's checker, our own breadth-first search for the shortest counterexamples, and
//! the report `model check --architecture duplex|pair` prints.

pub mod check;
pub mod duplex;
pub mod pair;

pub use duplex::{DuplexConfig, DuplexModel};
pub use pair::{BugReach, PairConfig, PairModel};

use crate::explore::{ExploreError, Front};
use check::{ArchitectureReport, Spec};
use serde::{Deserialize, Serialize};

/// The paper's three redundancy architectures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum Architecture {
    /// Three-way voting: RL's role model (and, with `--outputs`, its output voting).
    Voting,
    /// The simple duplex: a configured Primary and Standby, exclusive ownership at 30/20.
    Duplex,
    /// A lockstep pair in software: two controllers both commanding, each comparing two
    /// diverse implementations of its control law before every write.
    Pair,
}

impl Architecture {
    pub fn name(self) -> &'static str {
        match self {
            Architecture::Voting => "voting",
            Architecture::Duplex => "duplex",
            Architecture::Pair => "pair",
        }
    }
}

/// A deliberately broken rule of the duplex or the pair, to show the checker notices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "snake_case")]
pub enum ArchitectureMutation {
    /// Duplex: the actuator ignores ownership strength and follows the live writer with the
    /// lowest id.
    OwnerByLowestId,
    /// Duplex: a returning controller writes nothing until it has heard whether its partner
    /// commands, and nothing while it stays standby (a cold standby).
    SilentStandby,
    /// Duplex: a crashed controller may restart before its partner has noticed the crash (a
    /// bounce faster than the heartbeat deadline: the restart rule's timing assumption
    /// dropped).
    QuickRestart,
    /// Duplex: a preempting Primary that started again after a lapse takes its strength back
    /// at its first round end (no dwell).
    NoDwell,
    /// Pair: a controller writes its first implementation's output, then compares it with
    /// the second's.
    WriteBeforeCompare,
}

impl ArchitectureMutation {
    /// The architecture whose rule the mutation breaks.
    pub fn architecture(self) -> Architecture {
        match self {
            ArchitectureMutation::OwnerByLowestId
            | ArchitectureMutation::SilentStandby
            | ArchitectureMutation::QuickRestart
            | ArchitectureMutation::NoDwell => Architecture::Duplex,
            ArchitectureMutation::WriteBeforeCompare => Architecture::Pair,
        }
    }

    /// The flag's value.
    pub fn flag(self) -> &'static str {
        match self {
            ArchitectureMutation::OwnerByLowestId => "owner-by-lowest-id",
            ArchitectureMutation::SilentStandby => "silent-standby",
            ArchitectureMutation::QuickRestart => "quick-restart",
            ArchitectureMutation::NoDwell => "no-dwell",
            ArchitectureMutation::WriteBeforeCompare => "write-before-compare",
        }
    }
}

/// A flag or a configuration outside the models' bounds; each names the flag.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ArchitectureConfigError {
    /// A flag of one architecture given with another.
    #[error("--{flag}: only with --architecture {belongs_to}")]
    WrongArchitecture {
        flag: &'static str,
        belongs_to: &'static str,
    },
    /// A flag of the role or output model given with `--architecture duplex|pair`.
    #[error(
        "--{flag}: not a flag of --architecture {architecture} (check --help lists its flags)"
    )]
    NotOfArchitecture {
        flag: String,
        architecture: &'static str,
    },
    /// A fault budget beyond what the model takes in seconds.
    #[error("--{flag}: {value} exceeds the {architecture} model's maximum of {max}")]
    TooLarge {
        flag: &'static str,
        value: u8,
        max: u8,
        architecture: &'static str,
    },
}

/// The command line's flags of the two architectures (`check` and `explore`).
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ArchitectureArgs {
    /// Which of the paper's redundancy architectures: voting (the default: RL's three-way
    /// voting, the role model, and with --outputs its output voting), duplex (the simple
    /// duplex: a configured Primary and Standby at ownership strengths 30/20), pair (a
    /// lockstep pair in software: both controllers command, each compares two diverse
    /// implementations before every write). docs/protocol.md, "Other architectures: the spec".
    #[arg(long, value_enum)]
    pub architecture: Option<Architecture>,
    /// Duplex: whether a returning Primary takes the actuator back at once (true: the paper's
    /// rule, finding A1) or stays standby while the Standby commands (false, the default).
    #[arg(long, requires = "architecture", value_name = "true|false")]
    pub preempt: Option<bool>,
    /// Duplex and pair: crashes over a run, each controller restarting after a crash (a
    /// bounce); default 3 for the duplex, 2 for the pair.
    #[arg(long, requires = "architecture", value_name = "N")]
    pub bounces: Option<u8>,
    /// Duplex: heartbeats lost over a run, one round of one direction each; default 3, one
    /// more than the heartbeat deadline (2 rounds), so a loss can raise a false alarm.
    #[arg(long, requires = "architecture", value_name = "N")]
    pub heartbeat_losses: Option<u8>,
    /// Duplex: gray-fault episodes of the Primary over a run (default 0): its loop starved or
    /// stalling, lapsing while the episode lasts; with preemption a Primary that started again
    /// after a lapse dwells before it takes the actuator back (finding A4).
    #[arg(long, requires = "architecture", value_name = "N")]
    pub sick_episodes: Option<u8>,
    /// Duplex: lapses of a sick Primary's loop over a run (default 3).
    #[arg(long, requires = "architecture", value_name = "N")]
    pub lapses: Option<u8>,
    /// Pair: bugs that may appear over a run (default 2).
    #[arg(long, requires = "architecture", value_name = "N")]
    pub bugs: Option<u8>,
    /// Pair: where a bug lies: in one implementation of one controller (the default); in both
    /// implementations of a controller alike (finding A2); in one implementation that both
    /// controllers run (finding A3).
    #[arg(long, requires = "architecture", value_enum)]
    pub bug_in: Option<BugReach>,
    /// Duplex or pair: a deliberately broken rule, to see the checker catch it.
    #[arg(long, requires = "architecture", value_enum, hide = true)]
    pub architecture_mutation: Option<ArchitectureMutation>,
}

impl ArchitectureArgs {
    /// The duplex or pair configuration the flags give; `None` for the voting architecture
    /// (the role and output models, configured by their own flags).
    pub fn config(&self) -> Result<Option<ArchitectureConfig>, ArchitectureConfigError> {
        let architecture = self.architecture.unwrap_or(Architecture::Voting);
        let duplex_flags = [
            ("preempt", self.preempt.is_some()),
            ("heartbeat-losses", self.heartbeat_losses.is_some()),
            ("sick-episodes", self.sick_episodes.is_some()),
            ("lapses", self.lapses.is_some()),
        ];
        let pair_flags = [
            ("bugs", self.bugs.is_some()),
            ("bug-in", self.bug_in.is_some()),
        ];
        let shared_flags = [("bounces", self.bounces.is_some())];
        let refuse = |flags: &[(&'static str, bool)], belongs_to| match flags
            .iter()
            .find(|(_, given)| *given)
        {
            Some((flag, _)) => Err(ArchitectureConfigError::WrongArchitecture { flag, belongs_to }),
            None => Ok(()),
        };
        if let Some(mutation) = self.architecture_mutation {
            if mutation.architecture() != architecture {
                return Err(ArchitectureConfigError::WrongArchitecture {
                    flag: "architecture-mutation",
                    belongs_to: mutation.architecture().name(),
                });
            }
        }
        match architecture {
            Architecture::Voting => {
                refuse(&duplex_flags, "duplex")?;
                refuse(&pair_flags, "pair")?;
                refuse(&shared_flags, "duplex or --architecture pair")?;
                Ok(None)
            }
            Architecture::Duplex => {
                refuse(&pair_flags, "pair")?;
                let defaults = DuplexConfig::default();
                let config = DuplexConfig {
                    preempt: self.preempt.unwrap_or(defaults.preempt),
                    max_crashes: self.bounces.unwrap_or(defaults.max_crashes),
                    max_lost_heartbeats: self
                        .heartbeat_losses
                        .unwrap_or(defaults.max_lost_heartbeats),
                    max_sick_episodes: self.sick_episodes.unwrap_or(defaults.max_sick_episodes),
                    max_lapses: self.lapses.unwrap_or(defaults.max_lapses),
                    mutation: self.architecture_mutation,
                };
                config.validate()?;
                Ok(Some(ArchitectureConfig::Duplex(config)))
            }
            Architecture::Pair => {
                refuse(&duplex_flags, "duplex")?;
                let defaults = PairConfig::default();
                let config = PairConfig {
                    max_crashes: self.bounces.unwrap_or(defaults.max_crashes),
                    max_bugs: self.bugs.unwrap_or(defaults.max_bugs),
                    bug_reach: self.bug_in.unwrap_or(defaults.bug_reach),
                    mutation: self.architecture_mutation,
                };
                config.validate()?;
                Ok(Some(ArchitectureConfig::Pair(config)))
            }
        }
    }
}

/// A duplex or a pair to check or explore.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ArchitectureConfig {
    Duplex(DuplexConfig),
    Pair(PairConfig),
}

/// The ids of the flags the duplex and the pair take (the rest belong to the role and
/// output models).
const OWN_FLAGS: [&str; 11] = [
    "architecture",
    "preempt",
    "bounces",
    "heartbeat_losses",
    "sick_episodes",
    "lapses",
    "bugs",
    "bug_in",
    "architecture_mutation",
    "threads",
    "addr",
];

impl ArchitectureConfig {
    pub fn architecture(&self) -> Architecture {
        match self {
            ArchitectureConfig::Duplex(_) => Architecture::Duplex,
            ArchitectureConfig::Pair(_) => Architecture::Pair,
        }
    }

    /// Refuses, rather than ignores, a flag of the role or output model given on the command
    /// line (`given`: the ids of the flags given, as clap names them).
    pub fn refuse_foreign_flags(&self, given: &[String]) -> Result<(), ArchitectureConfigError> {
        match given.iter().find(|id| !OWN_FLAGS.contains(&id.as_str())) {
            Some(id) => Err(ArchitectureConfigError::NotOfArchitecture {
                flag: id.replace('_', "-"),
                architecture: self.architecture().name(),
            }),
            None => Ok(()),
        }
    }

    /// One line for the report.
    pub fn summary(&self) -> String {
        match self {
            ArchitectureConfig::Duplex(config) => config.summary(),
            ArchitectureConfig::Pair(config) => config.summary(),
        }
    }

    /// Runs stateright's checker exhaustively with `threads` threads.
    pub fn check(&self, threads: usize) -> ArchitectureReport {
        match self {
            ArchitectureConfig::Duplex(config) => check::check(&DuplexModel::new(*config), threads),
            ArchitectureConfig::Pair(config) => check::check(&PairModel::new(*config), threads),
        }
    }

    /// The shortest counterexample of every failure in `report`, with the `explore` command
    /// that opens it.
    pub fn render_failures(&self, report: &ArchitectureReport) -> String {
        match self {
            ArchitectureConfig::Duplex(config) => {
                check::render_failures(&DuplexModel::new(*config), report)
            }
            ArchitectureConfig::Pair(config) => {
                check::render_failures(&PairModel::new(*config), report)
            }
        }
    }

    /// stateright's explorer of the model behind the front that names its initial states.
    pub fn explorer(&self, addr: &str) -> Result<Front, ExploreError> {
        fn start<M: Spec>(model: M, addr: &str) -> Result<Front, ExploreError> {
            let names = model
                .init_states()
                .iter()
                .map(|state| model.initial_state_name(state))
                .collect();
            Front::start_named(&model, names, addr)
        }
        match self {
            ArchitectureConfig::Duplex(config) => start(DuplexModel::new(*config), addr),
            ArchitectureConfig::Pair(config) => start(PairModel::new(*config), addr),
        }
    }
}
