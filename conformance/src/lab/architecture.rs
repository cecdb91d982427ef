//! The redundancy architecture a lab run's controllers run (`lab run --architecture`): RL's
//! three-way voting (the default), the paper's simple duplex or its lockstep pair in software
//! (docs/architectures.md). What differs per architecture lives here: which controllers run,
//! the configuration they get, what "formed" and "settled" mean, and which controller a
//! scenario's target names. What each fault may cause under each is `super::expect`'s.
//!
//! The duplex runs with the paper's preemption (`preempt = true`, C1 Primary, C2 Standby),
//! the pair with members C1 and C2. The LAN keeps C3's node, with nothing on it: a fault
//! aimed at C3 (the clock scenarios' target, the voting Tertiary) falls on C2, the
//! controller the actuator does not follow at formation.

use super::lan::CONTROLLER_IDS;
pub use rl_layer::config::ArchitectureName as Architecture;
use rl_layer::core::{Phase, Role, Status, Strength};

/// The duplex's and the pair's two controllers.
const TWO: [u8; 2] = [1, 2];

/// The controllers `architecture` runs.
pub fn controller_ids(architecture: Architecture) -> &'static [u8] {
    match architecture {
        Architecture::Voting => &CONTROLLER_IDS,
        Architecture::Duplex | Architecture::Pair => &TWO,
    }
}

/// The name `lab` and the output use (`voting`, `duplex`, `pair`).
pub fn name(architecture: Architecture) -> &'static str {
    match architecture {
        Architecture::Voting => "voting",
        Architecture::Duplex => "duplex",
        Architecture::Pair => "pair",
    }
}

/// Parses `--architecture`'s value, naming the accepted ones when it is none of them.
pub fn parse(text: &str) -> Result<Architecture, String> {
    [
        Architecture::Voting,
        Architecture::Duplex,
        Architecture::Pair,
    ]
    .into_iter()
    .find(|a| name(*a) == text)
    .ok_or_else(|| format!("{text:?} is not an architecture: voting, duplex or pair"))
}

/// The configuration file the controllers get (`None`: the defaults, three-way voting).
pub fn config_text(architecture: Architecture) -> Option<&'static str> {
    match architecture {
        Architecture::Voting => None,
        Architecture::Duplex => {
            Some("architecture = \"duplex\"\n[duplex]\nprimary = 1\nstandby = 2\npreempt = true\n")
        }
        Architecture::Pair => Some("architecture = \"pair\"\n[pair]\nmembers = [1, 2]\n"),
    }
}

/// A scenario's controller id in `architecture`: C3, which the two-controller architectures
/// do not run, is C2 there.
pub fn controller_for(architecture: Architecture, id: u8) -> u8 {
    if controller_ids(architecture).contains(&id) {
        id
    } else {
        2
    }
}

/// The role and strength each controller reports at formation, in id order: P/S/T at
/// 30/20/10; the duplex's Primary at 30 and Standby at 20; both pair members at the pair's
/// strength, as the Primary (`rl_core::architectures::PAIR_ROLE`).
pub fn formation(architecture: Architecture) -> Vec<(u8, Role)> {
    match architecture {
        Architecture::Voting => vec![
            (1, Role::Primary),
            (2, Role::Secondary),
            (3, Role::Tertiary),
        ],
        Architecture::Duplex => vec![(1, Role::Primary), (2, Role::Secondary)],
        Architecture::Pair => vec![(1, Role::Primary), (2, Role::Primary)],
    }
}

/// The controllers whose commands the actuators follow when formed: voting's and the
/// duplex's Primary (C1); either pair member (DDS chooses between equal strengths).
pub fn formed_owners(architecture: Architecture) -> &'static [u8] {
    match architecture {
        Architecture::Voting | Architecture::Duplex => &[1],
        Architecture::Pair => &TWO,
    }
}

/// Whether `reports` (one per live controller) have settled under `architecture`. Voting:
/// every one steady, one agreed assignment naming them all, each at its role's strength. The
/// duplex: every one steady at its configured role's strength (the Primary back at 30: the
/// paper's preemption). The pair: every one steady at its role's strength (the pair's, or
/// yielded below a partner that commands) and at least one commanding at the pair's. Under
/// both, each also hears the other: they are steady from their first round, before a
/// restarted one has discovered its partner, and a fault then would meet a controller not yet
/// back (voting's agreed assignment already says every one hears the others).
pub fn settled(architecture: Architecture, reports: &[&Status]) -> bool {
    if reports.is_empty() {
        return false;
    }
    let steady_at_role = |s: &Status| {
        s.report.phase == Phase::Steady
            && s.report
                .role
                .is_some_and(|role| Some(role.strength()) == s.report.strength)
    };
    match architecture {
        Architecture::Voting => {
            let agreed = &reports[0].report.agreed;
            reports.iter().all(|s| {
                steady_at_role(s)
                    && s.report.agreed == *agreed
                    && agreed.as_ref().is_some_and(|a| {
                        a.role_of(s.report.id) == s.report.role && a.len() == reports.len()
                    })
            })
        }
        Architecture::Duplex => {
            hear_each_other(reports)
                && reports.iter().all(|s| {
                    steady_at_role(s)
                        && formation(architecture)
                            .iter()
                            .any(|(id, role)| *id == s.report.id && s.report.role == Some(*role))
                })
        }
        Architecture::Pair => {
            hear_each_other(reports)
                && reports.iter().all(|s| steady_at_role(s))
                && reports
                    .iter()
                    .any(|s| s.report.strength == Some(Strength(30)))
        }
    }
}

/// Whether every one of `reports` sees every other alive.
fn hear_each_other(reports: &[&Status]) -> bool {
    reports.iter().all(|s| {
        reports
            .iter()
            .all(|other| other.report.id == s.report.id || s.sees.contains(&other.report.id))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(id: u8, role: Role, strength: i32) -> Status {
        let mut s = Status::initial(id, 1);
        s.report.phase = Phase::Steady;
        s.report.role = Some(role);
        s.report.strength = Some(Strength(strength));
        s
    }

    #[test]
    fn a_duplex_has_settled_only_with_its_primary_back_at_30() {
        let mut primary = status(1, Role::Primary, 30);
        let mut standby = status(2, Role::Secondary, 20);
        // Steady from the first round, before they have heard each other: not yet.
        assert!(!settled(Architecture::Duplex, &[&primary, &standby]));
        primary.sees = vec![2];
        standby.sees = vec![1];
        assert!(settled(Architecture::Duplex, &[&primary, &standby]));
        // The Primary back without preemption, or yielded: not the paper's duplex settled.
        let yielded = status(1, Role::Secondary, 20);
        assert!(!settled(Architecture::Duplex, &[&yielded, &standby]));
    }

    #[test]
    fn a_pair_has_settled_with_one_member_commanding_and_the_other_at_its_role() {
        let mut commanding = status(1, Role::Primary, 30);
        let mut yielded = status(2, Role::Secondary, 20);
        commanding.sees = vec![2];
        yielded.sees = vec![1];
        assert!(settled(Architecture::Pair, &[&commanding, &yielded]));
        assert!(!settled(Architecture::Pair, &[&yielded]));
        let mut starting = status(2, Role::Primary, 30);
        starting.report.phase = Phase::Initializing;
        starting.sees = vec![1];
        assert!(!settled(Architecture::Pair, &[&commanding, &starting]));
        let deaf = status(2, Role::Secondary, 20);
        assert!(!settled(Architecture::Pair, &[&commanding, &deaf]));
    }

    #[test]
    fn c3_is_c2_in_the_two_controller_architectures() {
        assert_eq!(controller_for(Architecture::Duplex, 3), 2);
        assert_eq!(controller_for(Architecture::Pair, 1), 1);
        assert_eq!(controller_for(Architecture::Voting, 3), 3);
        assert!(parse("lockstep")
            .unwrap_err()
            .contains("voting, duplex or pair"));
        assert_eq!(parse("pair"), Ok(Architecture::Pair));
    }
}
