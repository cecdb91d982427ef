//! Which traces the DDS-level replay takes: a curated subset, every fault kind at least once,
//! chosen by purpose from `traces/index.json` (never by file name: the trace set is
//! regenerated), each with its own DDS domain.

use super::plan::{plan, Plan, PlanError};
use crate::trace::{self, FileError, Trace};
use crate::validate::Timing;
use model::{Action, Phase, Role};
use std::path::{Path, PathBuf};

/// A fault kind the curated subset must replay at least once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Need {
    /// A controller holding this role is killed.
    CrashOf(Role),
    /// A controller starts again as a new process (a new incarnation).
    Restart,
    /// A controller comes in after the others formed: still initializing while two others are
    /// steady with roles, and it ends with a role.
    LateJoin,
    /// Controller 4 starts and ends without a role.
    FourthController,
    /// A heartbeat lost one way (the reverse link delivers).
    OneWayLoss,
    /// One heartbeat of the steady Primary lost to the Secondary, with that link delivering
    /// in the rounds before and after: no failure (the dead-man deadline is two rounds).
    LoneLoss,
    /// A controller is marked FAILED for a minority vote.
    MinorityVote,
    /// A controller is stopped (SIGSTOP) for at least a stall and continued (SIGCONT): it
    /// comes back as a new incarnation (F12).
    PauseResumed,
    /// The Primary is stopped and continued within one round, past the command deadline and
    /// short of the peer deadline: the actuator noticed, its peers did not, and it comes back
    /// as a new incarnation all the same (F12), so the actuator stays with the Secondary.
    ShortPauseOfThePrimary,
    /// A controller is cut off from its peers (nftables on the virtual LAN) and the cut is
    /// healed later, in another round.
    CutHealed,
    /// The Primary's link is starved (its commands late) and its Secondary takes over (F17).
    StarvedTakeover,
}

/// Which scope of the trace set a curated entry takes its trace from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scope {
    /// `check`'s default scope (`model::Config::default()`).
    Default,
    /// The persistent link failure (`model::Config::link_failure()`).
    LinkFailure,
    /// Pauses and cuts of a running system (`model::Config::returns()`).
    Returns,
    /// Starved links (`model::Config::starved()`).
    Starved,
}

impl Scope {
    fn config(self) -> model::Config {
        match self {
            Scope::Default => model::Config::default(),
            Scope::LinkFailure => model::Config::link_failure(),
            Scope::Returns => model::Config::returns(),
            Scope::Starved => model::Config::starved(),
        }
    }
}

/// One entry of the curated subset: the fault it must show, the purposes (in
/// `traces/index.json`) a trace for it may have, in order of preference, and why it is in.
#[derive(Clone, Copy, Debug)]
pub struct Curated {
    pub name: &'static str,
    pub need: Need,
    pub scope: Scope,
    pub purposes: &'static [&'static str],
    /// The DDS domain its test runs on (each test its own, so they never hear each other).
    pub domain: u16,
    pub why: &'static str,
}

/// The curated subset: every fault kind at least once. Domains 185-187, 190-197, 218, 220 and
/// 225 (198 is the recorded `rl demo` of trace validation, 199 the broken replay and
/// `dds-replay-all`, 188, 189, 219, 221-224 and 226 the mutation checks).
pub const CURATED: &[Curated] = &[
    Curated {
        name: "crash of the Primary",
        need: Need::CrashOf(Role::Primary),
        scope: Scope::Default,
        purposes: &[
            "transition: crash by a steady controller (primary) -> down (none)",
            "witness: Primary crash promotes the Secondary",
        ],
        domain: 190,
        why: "kill -9 of the steady Primary: the survivors lose it after the dead-man \
              deadline, re-vote, and the Secondary is promoted",
    },
    Curated {
        name: "crash of the Secondary",
        need: Need::CrashOf(Role::Secondary),
        scope: Scope::Default,
        purposes: &["transition: crash by a steady controller (secondary) -> down (none)"],
        domain: 191,
        why: "kill -9 of the steady Secondary: the Tertiary moves up, the Primary stays",
    },
    Curated {
        name: "crash of the Tertiary",
        need: Need::CrashOf(Role::Tertiary),
        scope: Scope::Default,
        purposes: &["transition: crash by a steady controller (tertiary) -> down (none)"],
        domain: 192,
        why: "kill -9 of the steady Tertiary: Primary and Secondary keep their roles",
    },
    Curated {
        name: "restart",
        need: Need::Restart,
        scope: Scope::Default,
        purposes: &[
            "witness: restarted controller takes the lowest role",
            "transition: restart by a down controller (none) -> initializing (none)",
            "random walk, seed 1",
            "random walk, seed 2",
            "random walk, seed 4",
            "random walk, seed 5",
        ],
        domain: 193,
        why: "a killed controller comes back as a new process, a new incarnation that the \
              others must not confuse with the old one, and takes the lowest role",
    },
    Curated {
        name: "restart of a low id",
        need: Need::Restart,
        scope: Scope::Default,
        purposes: &[
            "random walk, seed 9",
            "random walk, seed 15",
            "random walk, seed 11",
        ],
        domain: 225,
        why: "a random walk (the curated restart's C3 holds its role by id anyway): C1 is \
              killed early and comes back after C2, C3 and C4 have formed without it; its new \
              incarnation stays a spare below them (P=2 S=3 T=4) instead of taking Primary by \
              its id",
    },
    Curated {
        name: "late join",
        need: Need::LateJoin,
        scope: Scope::LinkFailure,
        purposes: &["witness: late joiner becomes Tertiary"],
        domain: 194,
        why: "C3 does not hear C1 while C1 and C2 form (its heartbeats dropped), then joins \
              the running system below them",
    },
    Curated {
        name: "fourth controller",
        need: Need::FourthController,
        scope: Scope::Default,
        purposes: &["witness: fourth controller ignored"],
        domain: 195,
        why: "a fourth process joins and stays a spare: it never holds a role or commands",
    },
    Curated {
        name: "one-way heartbeat loss",
        need: Need::OneWayLoss,
        scope: Scope::LinkFailure,
        purposes: &["witness: re-vote after heartbeat loss"],
        domain: 196,
        why: "C2 drops C1's heartbeats for two rounds (C1 still hears C2): C2 loses C1, \
              raises an alarm and re-votes, and the two reunite when the heartbeats return",
    },
    Curated {
        name: "lone lost heartbeat",
        need: Need::LoneLoss,
        scope: Scope::Default,
        purposes: &[
            "transition: lose_heartbeat by a steady controller (primary) -> steady (primary)",
        ],
        domain: 220,
        why: "C2 misses one heartbeat of the steady Primary C1 (C1 still hears C2): one loss \
              is no failure (the dead-man deadline is two rounds), and nothing changes",
    },
    Curated {
        name: "minority vote",
        need: Need::MinorityVote,
        scope: Scope::LinkFailure,
        purposes: &["witness: minority voter FAILED"],
        domain: 197,
        why: "the link-failure scope's minority-voter witness: a link broken past the \
              minority grace, the minority voter marked FAILED and then failing itself",
    },
    Curated {
        name: "pause and resume",
        need: Need::PauseResumed,
        scope: Scope::Returns,
        purposes: &[
            "transition: tick by a voting controller (primary) -> voting (primary)",
            "transition: tick by a voting controller (secondary) -> voting (secondary)",
        ],
        domain: 186,
        why: "SIGSTOP of the steady Secondary for two rounds: its peers lose it and re-vote; \
              SIGCONT, its loop finds itself stalled for a peer deadline and it comes back as \
              a new incarnation, hearing the round it resumes in, and joins below the others",
    },
    Curated {
        name: "short pause of the Primary",
        need: Need::ShortPauseOfThePrimary,
        scope: Scope::Returns,
        purposes: &["transition: resume by a paused controller (primary) -> initializing (none)"],
        domain: 218,
        why: "SIGSTOP of the steady Primary, SIGCONT 120 ms later in the same round: the \
              servo has moved to the Secondary's commands, the peers never lost C1; its loop \
              finds a continued stop of a command deadline and it starts again as a new \
              incarnation, silent, so the actuator stays with the Secondary",
    },
    Curated {
        name: "cut healed",
        need: Need::CutHealed,
        scope: Scope::Returns,
        purposes: &[
            "transition: tick by a voting controller (primary) -> steady (tertiary)",
            "witness: re-vote after heartbeat loss",
        ],
        domain: 187,
        why: "nftables cut the Tertiary off from its peers (the actuator still hears it) for \
              two rounds on the virtual LAN: it agrees alone meanwhile, and at the heal the \
              majority's newer epoch ranks first (F11), so it comes back below them",
    },
    Curated {
        name: "starved Primary taken over",
        need: Need::StarvedTakeover,
        scope: Scope::Starved,
        purposes: &["witness: a Secondary takes over from a starved Primary"],
        domain: 185,
        why: "the steady Primary's commands reach everyone 70 ms late: its Secondary finds \
              them late beside the Tertiary's on time, takes over at the takeover strength \
              before the actuator's deadline (F17), and the deposed Primary, hearing it at the \
              round's end, starts again below",
    },
];

/// The curated entry named `name`.
pub fn curated(name: &str) -> Option<&'static Curated> {
    CURATED.iter().find(|c| c.name == name)
}

/// Whether a plan shows the fault a curated entry needs.
pub fn shows(plan: &Plan, need: Need) -> bool {
    let lifecycle = || {
        plan.rounds
            .iter()
            .enumerate()
            .flat_map(|(k, r)| r.lifecycle.iter().map(move |a| (k, *a)))
    };
    let last = &plan.boundaries[plan.last()];
    match need {
        Need::CrashOf(role) => lifecycle().any(|(k, action)| match action {
            Action::Crash { controller } => {
                plan.boundaries[k].controller(controller).role == Some(role)
            }
            _ => false,
        }),
        Need::Restart => lifecycle().any(|(_, a)| matches!(a, Action::Restart { .. })),
        Need::LateJoin => plan.boundaries.iter().any(|s| {
            s.controllers.iter().any(|late| {
                late.is_up()
                    && late.phase == Phase::Initializing
                    && s.controllers
                        .iter()
                        .filter(|c| c.is_up() && c.phase == Phase::Steady && c.role.is_some())
                        .count()
                        >= 2
                    && last.controller(late.id).role.is_some()
            })
        }),
        Need::FourthController => {
            lifecycle().any(|(_, a)| a == Action::Join { controller: 4 })
                && last
                    .controllers
                    .get(3)
                    .is_some_and(|c| c.is_up() && c.role.is_none())
        }
        Need::OneWayLoss => plan.rounds.iter().any(|r| {
            r.lost
                .iter()
                .any(|(from, to)| !r.lost.contains(&(*to, *from)))
        }),
        Need::LoneLoss => plan.rounds.iter().enumerate().any(|(k, round)| {
            round.lost.iter().any(|&(from, to)| {
                let receiver = plan.boundaries[k].controller(to);
                let delivers = |j: usize| {
                    plan.rounds
                        .get(j)
                        .is_none_or(|other| !other.lost.contains(&(from, to)))
                };
                receiver.phase == Phase::Steady
                    && receiver.role == Some(Role::Secondary)
                    && receiver.agreed.and_then(|a| a.holder(Role::Primary)) == Some(from)
                    && delivers(k + 1)
                    && (k == 0 || delivers(k - 1))
            })
        }),
        Need::MinorityVote => plan.boundaries.iter().any(|s| {
            s.up()
                .any(|c| c.phase == Phase::Failed || c.peers.iter().any(|p| p.failed))
        }),
        Need::PauseResumed => lifecycle().any(|(_, a)| matches!(a, Action::Resume { .. })),
        Need::ShortPauseOfThePrimary => plan.rounds.iter().enumerate().any(|(k, round)| {
            round.lifecycle.iter().any(|a| match *a {
                Action::Resume { controller } if round.resumes_within(*a) => {
                    plan.boundaries[k].controller(controller).role == Some(Role::Primary)
                }
                _ => false,
            })
        }),
        Need::CutHealed => lifecycle().any(|(k, a)| match a {
            Action::Heal { controller } => {
                let state = &plan.boundaries[k];
                state.isolated & 1 << (controller - 1) != 0
                    && state.unplugged & 1 << (controller - 1) == 0
            }
            _ => false,
        }),
        Need::StarvedTakeover => plan.rounds.iter().any(|r| !r.takeovers.is_empty()),
    }
}

/// A curated entry resolved to a trace.
#[derive(Clone, Debug)]
pub struct Selected {
    pub curated: Curated,
    pub trace: Trace,
    pub plan: Plan,
}

/// Why a curated entry resolves to no trace.
#[derive(Debug, thiserror::Error)]
pub enum SelectError {
    /// The index or one of its traces cannot be read.
    #[error(transparent)]
    Unreadable(#[from] FileError),
    /// No trace with one of the entry's purposes can be replayed and shows its fault.
    #[error(
        "the DDS-level replay's \"{name}\" needs a trace in {}/index.json with one of the \
         purposes {purposes:?} (scope {scope:?}) that can be replayed on real processes; {}. If \
         the trace set was regenerated with other purposes, update \
         conformance/src/dds_replay/curated.rs (CURATED).",
        traces_dir.display(),
        describe_tried(tried)
    )]
    NoTrace {
        name: &'static str,
        traces_dir: PathBuf,
        purposes: &'static [&'static str],
        scope: Scope,
        /// Each candidate looked at, and why it was refused.
        tried: Vec<(String, Refused)>,
    },
}

/// Why a candidate trace was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Refused {
    #[error("from another scope")]
    OtherScope,
    #[error("does not show {0:?}")]
    DoesNotShow(Need),
    #[error("not replayable: {0}")]
    NotReplayable(PlanError),
}

fn describe_tried(tried: &[(String, Refused)]) -> String {
    if tried.is_empty() {
        return "no entry has these purposes".to_string();
    }
    let each: Vec<String> = tried
        .iter()
        .map(|(file, refused)| format!("{file}: {refused}"))
        .collect();
    format!("tried: {}", each.join("; "))
}

/// Resolves one curated entry: the first trace (in `index.json` order) with one of its
/// purposes, from its scope, that can be replayed and shows its fault.
pub fn select(
    traces_dir: &Path,
    curated: &Curated,
    timing: &Timing,
) -> Result<Selected, SelectError> {
    let entries = trace::read_index_entries(&traces_dir.join("index.json"))?;
    let mut tried = Vec::new();
    for purpose in curated.purposes {
        for entry in entries.iter().filter(|e| e.purpose == *purpose) {
            let trace = trace::read_trace(&traces_dir.join(&entry.file))?;
            if trace.config != curated.scope.config() {
                tried.push((entry.file.clone(), Refused::OtherScope));
                continue;
            }
            match plan(&trace, timing) {
                Ok(plan) if shows(&plan, curated.need) => {
                    return Ok(Selected {
                        curated: *curated,
                        trace,
                        plan,
                    })
                }
                Ok(_) => tried.push((entry.file.clone(), Refused::DoesNotShow(curated.need))),
                Err(reason) => tried.push((entry.file.clone(), Refused::NotReplayable(reason))),
            }
        }
    }
    Err(SelectError::NoTrace {
        name: curated.name,
        traces_dir: traces_dir.to_path_buf(),
        purposes: curated.purposes,
        scope: curated.scope,
        tried,
    })
}

#[cfg(test)]
mod tests {
    use super::super::plan::replay_timing;
    use super::*;
    use std::collections::BTreeSet;

    #[test]
    fn every_curated_entry_resolves_to_a_replayable_trace() {
        let dir = trace::default_dir();
        let mut files = BTreeSet::new();
        for curated in CURATED {
            let selected =
                select(&dir, curated, &replay_timing()).unwrap_or_else(|e| panic!("{e}"));
            assert!(shows(&selected.plan, curated.need));
            files.insert(selected.trace.file.clone());
        }
        assert_eq!(files.len(), CURATED.len(), "one trace per entry");
        let domains: BTreeSet<u16> = CURATED.iter().map(|c| c.domain).collect();
        assert_eq!(domains.len(), CURATED.len(), "one domain per entry");
    }

    #[test]
    fn a_missing_purpose_names_what_was_looked_for() {
        let missing = Curated {
            purposes: &["witness: no such purpose"],
            ..CURATED[0]
        };
        let error = select(&trace::default_dir(), &missing, &replay_timing())
            .expect_err("no trace has this purpose");
        let message = error.to_string();
        assert!(message.contains("no such purpose"), "{message}");
        assert!(message.contains("no entry has these purposes"), "{message}");
    }
}
