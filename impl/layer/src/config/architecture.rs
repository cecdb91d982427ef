//! `architecture` and its sections: which of the paper's three redundancy architectures the
//! controllers run. Three-way voting (the default) needs nothing more; the simple duplex names
//! its Primary and Standby (`[duplex]`), the lockstep pair its two members (`[pair]`).
//!
//! ```toml
//! architecture = "duplex"
//! [duplex]
//! primary = 1
//! standby = 2
//! preempt = false   # a returning Primary stays standby while the Standby commands
//! ```

use super::error::{check, InvalidValue};
use rl_core::architectures::{Duplex, Pair};
use rl_core::{Architecture, ControllerId};
use serde::{Deserialize, Serialize};

/// The architecture's name, as rl.toml writes it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ArchitectureName {
    /// Three controllers vote roles (RL's protocol).
    #[default]
    Voting,
    /// Two controllers, a Primary and a Standby by configuration.
    Duplex,
    /// Two controllers without roles, both commanding, each comparing two implementations of
    /// its control law.
    Pair,
}

/// `[duplex]`: who is Primary, who is Standby, and whether a returning Primary takes over.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DuplexSection {
    /// The Primary's controller id (commands at 30).
    pub primary: ControllerId,
    /// The Standby's controller id (commands at 20).
    pub standby: ControllerId,
    /// The paper's rule (true): a returning Primary takes the actuator back at once. False:
    /// it stays standby while the Standby commands (keepalived's `nopreempt`).
    pub preempt: bool,
}

impl Default for DuplexSection {
    fn default() -> DuplexSection {
        DuplexSection {
            primary: 1,
            standby: 2,
            preempt: true,
        }
    }
}

/// `[pair]`: the two controllers of a lockstep pair.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PairSection {
    /// The two controller ids.
    pub members: [ControllerId; 2],
}

impl Default for PairSection {
    fn default() -> PairSection {
        PairSection { members: [1, 2] }
    }
}

impl DuplexSection {
    /// Two different ids, neither 0.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        check(self.primary != 0, "duplex.primary", self.primary, || {
            "must be a controller id, 1 to 255".into()
        })?;
        check(self.standby != 0, "duplex.standby", self.standby, || {
            "must be a controller id, 1 to 255".into()
        })?;
        check(
            self.primary != self.standby,
            "duplex.standby",
            self.standby,
            || format!("must differ from duplex.primary ({})", self.primary),
        )
    }
}

impl PairSection {
    /// Two different ids, neither 0.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        let [first, second] = self.members;
        check(
            first != 0 && second != 0 && first != second,
            "pair.members",
            format!("[{first}, {second}]"),
            || "must be two different controller ids, 1 to 255".into(),
        )
    }
}

/// The core's architecture for this configuration.
pub fn core_architecture(
    name: ArchitectureName,
    duplex: &DuplexSection,
    pair: &PairSection,
) -> Architecture {
    match name {
        ArchitectureName::Voting => Architecture::Voting,
        ArchitectureName::Duplex => Architecture::Duplex(Duplex {
            primary: duplex.primary,
            standby: duplex.standby,
            preempt: duplex.preempt,
        }),
        ArchitectureName::Pair => Architecture::Pair(Pair {
            members: pair.members,
        }),
    }
}

/// Whether controller `id` belongs to the configured architecture: any id votes, but a duplex
/// or a pair has exactly its two. The error names the field that lists the members.
pub fn check_member(
    name: ArchitectureName,
    duplex: &DuplexSection,
    pair: &PairSection,
    id: ControllerId,
) -> Result<(), InvalidValue> {
    match name {
        ArchitectureName::Voting => Ok(()),
        ArchitectureName::Duplex => check(
            id == duplex.primary || id == duplex.standby,
            "duplex.primary",
            duplex.primary,
            || {
                format!(
                    "controller {id} is not in the duplex: it is neither duplex.primary nor \
                     duplex.standby ({})",
                    duplex.standby
                )
            },
        ),
        ArchitectureName::Pair => check(
            pair.members.contains(&id),
            "pair.members",
            format!("[{}, {}]", pair.members[0], pair.members[1]),
            || format!("controller {id} is not a member of the pair"),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::super::Config;
    use rl_core::architectures::Duplex;
    use rl_core::Architecture;

    fn error_of(text: &str) -> (Option<String>, String) {
        let error = Config::from_toml_str(text, "rl.toml").expect_err("an invalid configuration");
        (error.field().map(str::to_string), error.to_string())
    }

    #[test]
    fn an_empty_file_votes_and_a_duplex_reads_its_members_and_preemption() {
        let empty = Config::from_toml_str("", "rl.toml").expect("the defaults");
        assert_eq!(empty.core_architecture(), Architecture::Voting);
        assert!(empty.check_member(3).is_ok());

        let text =
            "architecture = \"duplex\"\n[duplex]\nprimary = 2\nstandby = 3\npreempt = false\n";
        let config = Config::from_toml_str(text, "rl.toml").expect("a duplex");
        assert_eq!(
            config.core_architecture(),
            Architecture::Duplex(Duplex {
                primary: 2,
                standby: 3,
                preempt: false
            })
        );
        let written = config.to_toml_string().expect("written out");
        assert_eq!(Config::from_toml_str(&written, "back").ok(), Some(config));
    }

    #[test]
    fn bad_members_name_their_field() {
        let (field, message) = error_of("[duplex]\nprimary = 1\nstandby = 1\n");
        assert_eq!(field.as_deref(), Some("duplex.standby"));
        assert_eq!(
            message,
            "rl.toml: duplex.standby = 1: must differ from duplex.primary (1)"
        );
        let (field, _) = error_of("[pair]\nmembers = [2, 2]\n");
        assert_eq!(field.as_deref(), Some("pair.members"));
        let (field, message) = error_of("architecture = \"triplex\"\n");
        assert_eq!(field.as_deref(), Some("architecture"));
        assert!(
            message.contains("expected one of `voting`, `duplex`, `pair`"),
            "{message}"
        );
    }

    #[test]
    fn a_controller_outside_the_duplex_or_the_pair_is_refused_by_name() {
        let duplex = Config::from_toml_str("architecture = \"duplex\"\n", "rl.toml").expect("ok");
        assert!(duplex.check_member(1).is_ok() && duplex.check_member(2).is_ok());
        let refused = duplex.check_member(3).expect_err("not a member");
        assert_eq!(
            refused.to_string(),
            "duplex.primary = 1: controller 3 is not in the duplex: it is neither \
             duplex.primary nor duplex.standby (2)"
        );
        let pair = Config::from_toml_str("architecture = \"pair\"\n", "rl.toml").expect("ok");
        assert_eq!(
            pair.check_member(3).expect_err("not a member").field,
            "pair.members"
        );
    }
}
