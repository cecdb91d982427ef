//! The abstraction function: from the implementation's state to the model's abstract state.
//!
//! This is the one place that knows both crates. Every conformance check (the core-level
//! replay here, the DDS-level replay) abstracts what it observes of RL with these functions
//! and compares the result with the `traces::AbstractState` the model recorded, field for
//! field. The input is what a controller reports of itself, `rl_layer::core::Status` (the core's
//! `status()`, also what the status topic carries), plus the one fact a controller cannot
//! report: whether its process runs.
//!
//! Mapping decisions (docs/conformance.md repeats them):
//!
//! - **life**: supplied by the observer ([`Observed`]): a running process is `up`, a killed one
//!   `down`, one never started `not_started`. A core cannot know it is dead.
//! - **incarnation**: the implementation's incarnations are opaque start stamps (only equality
//!   matters); the model counts lives 0, 1, 2, ... per id. [`IncarnationNumbers`] numbers the
//!   lives of each id in the order they started, so a stamp maps to the model's counter, in
//!   the controller's own field and in every holder named by a vote or agreed result.
//! - **phase**, **role**: the same four phases and three roles, mapped by name.
//! - **strength**: the ownership strength the controller commands with (`None` = silent).
//! - **sees**: peers believed alive, FAILED ones included, as the model's trace records them.
//! - **failed**: peers marked FAILED.
//! - **alarms**: peers with a raised controller-failed alarm. The implementation also keeps
//!   the reason (lost or FAILED); the model keeps a flag, so the reason is dropped.
//! - **agreed**, **vote**: rendered as the model's `Assignment` displays them (`P=1 S=2 T=3#1`),
//!   with holder incarnations mapped as above.
//! - Fields of a controller that is not up (phase, role, strength, views, results) are empty,
//!   as in the model's trace.
//! - **actuator owner**: DDS exclusive ownership: among the live controllers that command, the
//!   highest strength wins and a tie goes to the lowest id (the model's `actuator_owner`).
//! - Not abstracted: counters (silent, dissent and quiet rounds), the late-joiner flag, what
//!   each peer's last heartbeat carried, the round's inbox and durable vote records. They are
//!   hidden state in the model's trace too; a difference in them shows in a later step.

use model::traces::{AbstractController, AbstractState};
use model::{Life, Phase, Role};
use rl_layer::core::{self as core, ControllerId, Incarnation, Status};
use std::collections::BTreeMap;
use std::fmt;

/// What an observer knows of one controller id.
#[derive(Clone, Debug)]
pub enum Observed {
    /// Never started.
    NotStarted,
    /// Its process was stopped; `incarnation` is the stamp of the life that ended.
    Down { incarnation: Incarnation },
    /// Its process is paused (SIGSTOP, a stall); `incarnation` is the stamp of its life.
    Paused { incarnation: Incarnation },
    /// Running: what it reports of itself.
    Up(Box<Status>),
}

/// Numbers the lives of each controller id 0, 1, 2, ... in the order they started: the
/// model's incarnation counter.
#[derive(Clone, Debug, Default)]
pub struct IncarnationNumbers {
    numbers: BTreeMap<(ControllerId, Incarnation), u8>,
    lives: BTreeMap<ControllerId, u8>,
}

impl IncarnationNumbers {
    pub fn new() -> IncarnationNumbers {
        IncarnationNumbers::default()
    }

    /// Records that controller `id` started a life stamped `incarnation`; returns its number.
    /// Recording the same life again returns the same number.
    pub fn started(&mut self, id: ControllerId, incarnation: Incarnation) -> u8 {
        if let Some(number) = self.numbers.get(&(id, incarnation)) {
            return *number;
        }
        let lives = self.lives.entry(id).or_insert(0);
        let number = *lives;
        *lives = lives.saturating_add(1);
        self.numbers.insert((id, incarnation), number);
        number
    }

    /// The model's number of a recorded life.
    pub fn number(&self, id: ControllerId, incarnation: Incarnation) -> Option<u8> {
        self.numbers.get(&(id, incarnation)).copied()
    }
}

/// The implementation names a life the observer never saw start: the abstraction cannot
/// give it a model number.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownIncarnation {
    /// Whose state named it.
    pub observer: ControllerId,
    pub id: ControllerId,
    pub incarnation: Incarnation,
}

impl fmt::Display for UnknownIncarnation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "C{}'s state names C{} incarnation {}, a life that was never recorded as started",
            self.observer, self.id, self.incarnation
        )
    }
}

impl std::error::Error for UnknownIncarnation {}

/// The abstract state of the whole system: `observed` holds one entry per controller id,
/// in id order starting at 1 (the model's controller list).
pub fn abstract_state(
    observed: &[Observed],
    numbers: &IncarnationNumbers,
) -> Result<AbstractState, UnknownIncarnation> {
    let controllers = observed
        .iter()
        .enumerate()
        .map(|(index, controller)| {
            let id = ControllerId::try_from(index + 1).unwrap_or(ControllerId::MAX);
            abstract_controller(id, controller, numbers)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let actuator_owner = actuator_owner(&controllers);
    Ok(AbstractState {
        controllers,
        actuator_owner,
    })
}

/// A controller that knows nothing: not running (`phase: None`), or a life that has just
/// started (`Some(Initializing)`).
pub fn blank(
    id: ControllerId,
    life: Life,
    incarnation: u8,
    phase: Option<Phase>,
) -> AbstractController {
    AbstractController {
        id,
        life,
        incarnation,
        phase,
        role: None,
        strength: None,
        sees: vec![],
        failed: vec![],
        alarms: vec![],
        agreed: None,
        vote: None,
    }
}

/// One controller's abstract state.
pub fn abstract_controller(
    id: ControllerId,
    observed: &Observed,
    numbers: &IncarnationNumbers,
) -> Result<AbstractController, UnknownIncarnation> {
    let number = |named: ControllerId, incarnation: Incarnation| {
        numbers
            .number(named, incarnation)
            .ok_or(UnknownIncarnation {
                observer: id,
                id: named,
                incarnation,
            })
    };
    let not_up = |life: Life, incarnation: u8| blank(id, life, incarnation, None);
    let status = match observed {
        Observed::NotStarted => return Ok(not_up(Life::NotStarted, 0)),
        Observed::Down { incarnation } => {
            return Ok(not_up(Life::Down, number(id, *incarnation)?));
        }
        Observed::Paused { incarnation } => {
            return Ok(not_up(Life::Paused, number(id, *incarnation)?));
        }
        Observed::Up(status) => status,
    };
    let assignment = |a| render_assignment(id, a, numbers);
    let mut sees: Vec<u8> = status.sees.iter().copied().filter(|p| *p != id).collect();
    sees.sort_unstable();
    let mut failed: Vec<u8> = status.failed.iter().copied().filter(|p| *p != id).collect();
    failed.sort_unstable();
    let mut alarms: Vec<u8> = status
        .alarms
        .iter()
        .map(|(about, _reason)| *about)
        .filter(|p| *p != id)
        .collect();
    alarms.sort_unstable();
    alarms.dedup();
    Ok(AbstractController {
        id,
        life: Life::Up,
        incarnation: number(id, status.report.incarnation)?,
        phase: Some(phase(status.report.phase)),
        role: status.report.role.map(role),
        strength: status.report.strength.map(strength),
        sees,
        failed,
        alarms,
        agreed: assignment(status.report.agreed)?,
        vote: assignment(status.report.vote)?,
    })
}

/// DDS exclusive ownership: the highest strength among live controllers that command, ties
/// to the lowest id (the model's `State::actuator_owner`).
pub fn actuator_owner(controllers: &[AbstractController]) -> Option<u8> {
    controllers
        .iter()
        .filter(|c| c.life == Life::Up)
        .filter_map(|c| c.strength.map(|s| (std::cmp::Reverse(s), c.id)))
        .min()
        .map(|(_, id)| id)
}

pub fn phase(phase: core::Phase) -> Phase {
    match phase {
        core::Phase::Initializing => Phase::Initializing,
        core::Phase::Voting => Phase::Voting,
        core::Phase::Steady => Phase::Steady,
        core::Phase::Failed => Phase::Failed,
    }
}

pub fn role(role: core::Role) -> Role {
    match role {
        core::Role::Primary => Role::Primary,
        core::Role::Secondary => Role::Secondary,
        core::Role::Tertiary => Role::Tertiary,
    }
}

/// A command strength as the model counts it (RL's strengths are 10 to 35; the model's
/// are the same numbers in a byte). One outside a byte cannot be RL's: it maps to 255, above
/// every strength the model knows, so any comparison that sees it fails.
pub fn strength(strength: core::Strength) -> u8 {
    u8::try_from(strength.value()).unwrap_or(u8::MAX)
}

/// A vote or agreed result that controller `observer` holds, as the model renders it
/// (`P=1 S=2 T=3#1`), holder incarnations numbered as the model counts them.
pub fn render_assignment(
    observer: ControllerId,
    a: Option<core::Assignment>,
    numbers: &IncarnationNumbers,
) -> Result<Option<String>, UnknownIncarnation> {
    let Some(a) = a else {
        return Ok(None);
    };
    let mut slots = [None; model::types::ROLE_COUNT];
    for (slot, holder) in slots.iter_mut().zip(a.0.iter()) {
        if let Some(holder) = holder {
            let incarnation =
                numbers
                    .number(holder.id, holder.incarnation)
                    .ok_or(UnknownIncarnation {
                        observer,
                        id: holder.id,
                        incarnation: holder.incarnation,
                    })?;
            *slot = Some(model::Holder {
                id: holder.id,
                incarnation,
            });
        }
    }
    Ok(Some(model::Assignment(slots).to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rl_layer::core::{AlarmReason, Holder, Strength};

    fn status(id: ControllerId, incarnation: Incarnation) -> Status {
        let mut status = Status::initial(id, incarnation);
        status.report.phase = core::Phase::Steady;
        status.report.role = Some(core::Role::Secondary);
        status.report.strength = Some(Strength(20));
        status.sees = vec![3, 1];
        status.alarms = vec![(3, AlarmReason::Lost), (1, AlarmReason::Failed)];
        status
    }

    #[test]
    fn lives_are_numbered_per_id_in_start_order() {
        let mut numbers = IncarnationNumbers::new();
        assert_eq!(numbers.started(2, 1_700_000), 0);
        assert_eq!(numbers.started(1, 1_700_000), 0, "ids count separately");
        assert_eq!(
            numbers.started(2, 1_650_000),
            1,
            "start order, not stamp order"
        );
        assert_eq!(numbers.started(2, 1_700_000), 0, "a life keeps its number");
        assert_eq!(numbers.number(2, 1_650_000), Some(1));
        assert_eq!(numbers.number(3, 5), None);
    }

    #[test]
    fn holders_render_with_the_models_incarnation_numbers() {
        let mut numbers = IncarnationNumbers::new();
        for (id, stamp) in [(1, 100), (2, 200), (3, 300), (2, 900)] {
            numbers.started(id, stamp);
        }
        let holder = |id, incarnation| Holder { id, incarnation };
        let vote = core::Assignment::from_ranked([holder(1, 100), holder(2, 900), holder(3, 300)]);
        let mut reported = status(2, 900);
        reported.report.vote = Some(vote);
        let c = abstract_controller(2, &Observed::Up(Box::new(reported)), &numbers)
            .expect("every life is known");
        assert_eq!(c.incarnation, 1);
        assert_eq!(c.vote.as_deref(), Some("P=1 S=2#1 T=3"));
        assert_eq!(c.sees, vec![1, 3], "sorted");
        assert_eq!(c.alarms, vec![1, 3], "reasons dropped");
        assert_eq!(c.role, Some(Role::Secondary));
    }

    #[test]
    fn an_unrecorded_life_is_an_error_naming_it() {
        let numbers = IncarnationNumbers::new();
        let error = abstract_controller(1, &Observed::Up(Box::new(status(1, 42))), &numbers)
            .expect_err("nothing recorded");
        assert_eq!(
            error.to_string(),
            "C1's state names C1 incarnation 42, a life that was never recorded as started"
        );
    }

    #[test]
    fn the_actuator_follows_the_strongest_live_writer_and_ties_go_to_the_lowest_id() {
        let mut numbers = IncarnationNumbers::new();
        for id in 1..=3 {
            numbers.started(id, 0);
        }
        let up = |id, strength| {
            let mut s = status(id, 0);
            s.report.strength = strength;
            Observed::Up(Box::new(s))
        };
        let state = abstract_state(
            &[
                up(1, Some(Strength(20))),
                up(2, Some(Strength(30))),
                up(3, Some(Strength(30))),
            ],
            &numbers,
        )
        .expect("known lives");
        assert_eq!(state.actuator_owner, Some(2));
        let state = abstract_state(
            &[
                Observed::Down { incarnation: 0 },
                up(2, Some(Strength(10))),
                up(3, None),
            ],
            &numbers,
        )
        .expect("known lives");
        assert_eq!(state.actuator_owner, Some(2));
        assert_eq!(state.controllers[0].life, Life::Down);
        assert_eq!(state.controllers[0].phase, None);
    }
}
