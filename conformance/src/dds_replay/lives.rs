//! The controller processes of one attempt, one [`Life`] per life of a process (a restart is
//! a new process; a process that starts again as a new incarnation after a stall or a pulled
//! cable has a new life too, [`Life::next_incarnation`]), and what they reported at a round
//! boundary, abstracted.
//!
//! A life's state at a boundary is its last `status` event with the later `alarm` events
//! applied ([`crate::record`]); its life (up, down, not started) comes from the harness,
//! which started and killed the processes. The actuator owner is not taken from here: the
//! servo reports it ([`super::servo`]).

use crate::abstraction::{self, IncarnationNumbers, Observed, UnknownIncarnation};
use crate::record::LifeLog;
use model::traces::AbstractState;
use rl_layer::core::ControllerId;
use std::collections::BTreeSet;

/// One controller process.
#[derive(Clone, Debug)]
pub struct Life {
    pub log: LifeLog,
    /// The real round it was started in (it is up from the next boundary on).
    pub spawned_round: u64,
    /// The wall-clock time it was started.
    pub started_wall_ms: u64,
    /// The real round it was killed in (down from the next boundary on).
    pub killed_round: Option<u64>,
    /// Whether its stamp came from its own output yet.
    pub stamped: bool,
    /// Peers whose heartbeats it drops now.
    pub dropping: BTreeSet<ControllerId>,
    /// The real round it was stopped in (SIGSTOP), and the one it was continued in
    /// (SIGCONT): paused at the boundaries after the first up to the second.
    pub paused_round: Option<u64>,
    pub resumed_round: Option<u64>,
    /// The wall-clock time of its SIGSTOP.
    pub paused_wall_ms: Option<u64>,
    /// Its process went on as a new incarnation: a later life.
    pub replaced: bool,
}

impl Life {
    /// A process just started; `number` counts the earlier lives of its id.
    pub fn new(id: ControllerId, number: u8, spawned_round: u64, started_wall_ms: u64) -> Life {
        Life {
            log: LifeLog {
                id,
                // Until it prints its stamp: a placeholder no real start produces.
                incarnation: u64::MAX - (u64::from(id) << 8) - u64::from(number),
                source: source_name(id, number),
                events: Vec::new(),
            },
            spawned_round,
            started_wall_ms,
            killed_round: None,
            stamped: false,
            dropping: BTreeSet::new(),
            paused_round: None,
            resumed_round: None,
            paused_wall_ms: None,
            replaced: false,
        }
    }

    /// The life its process goes on with when it reports incarnation `incarnation` (a new
    /// life after a stall or a pulled cable), first heard in real round `round`; this one is
    /// marked replaced.
    pub fn next_incarnation(&mut self, incarnation: u64, round: u64, wall_ms: u64) -> Life {
        self.replaced = true;
        Life {
            log: LifeLog {
                id: self.log.id,
                incarnation,
                source: self.log.source.clone(),
                events: Vec::new(),
            },
            spawned_round: round,
            started_wall_ms: wall_ms,
            killed_round: None,
            stamped: true,
            dropping: self.dropping.clone(),
            paused_round: None,
            resumed_round: None,
            paused_wall_ms: None,
            replaced: false,
        }
    }

    /// Whether it is stopped at the boundary of real round `real`.
    pub fn paused_at(&self, real: u64) -> bool {
        self.paused_round.is_some_and(|p| p < real) && self.resumed_round.is_none_or(|r| r >= real)
    }

    /// Its process runs (or is stopped) as this life.
    pub fn is_running(&self) -> bool {
        self.killed_round.is_none() && !self.replaced
    }
}

/// `C3` for a first life, `C3#1` for the next.
pub fn source_name(id: ControllerId, number: u8) -> String {
    if number == 0 {
        format!("C{id}")
    } else {
        format!("C{id}#{number}")
    }
}

/// The life its process `source` runs as now.
pub fn of_process_mut<'l>(lives: &'l mut [Life], source: &str) -> Option<&'l mut Life> {
    lives.iter_mut().rev().find(|l| l.log.source == source)
}

/// The latest life of `id`.
pub fn current_mut(lives: &mut [Life], id: ControllerId) -> Option<&mut Life> {
    lives.iter_mut().rev().find(|l| l.log.id == id)
}

/// How many lives `id` had so far.
pub fn lives_of(lives: &[Life], id: ControllerId) -> u8 {
    lives.iter().filter(|l| l.log.id == id).count() as u8
}

/// What the processes reported by the boundary of real round `real`, abstracted, for
/// controller ids `1..=count`: what they printed before `decided_by_ms` into the round (the
/// boundary's decisions, not what the round's faults changed since); the owner is filled in
/// by the caller.
pub fn observe(
    lives: &[Life],
    count: usize,
    real: u64,
    period_ms: u64,
    decided_by_ms: u64,
) -> Result<AbstractState, UnknownIncarnation> {
    let mut numbers = IncarnationNumbers::new();
    for life in lives {
        numbers.started(life.log.id, life.log.incarnation);
    }
    let observed: Vec<Observed> = (1..=count as ControllerId)
        .map(|id| {
            let life = lives
                .iter()
                .rev()
                .find(|l| l.log.id == id && l.spawned_round < real);
            match life {
                None => Observed::NotStarted,
                Some(life) if life.killed_round.is_some_and(|k| k < real) => Observed::Down {
                    incarnation: life.log.incarnation,
                },
                Some(life) if life.paused_at(real) => Observed::Paused {
                    incarnation: life.log.incarnation,
                },
                Some(life) => Observed::Up(Box::new(
                    life.log.status_before(real * period_ms + decided_by_ms),
                )),
            }
        })
        .collect();
    abstraction::abstract_state(&observed, &numbers)
}
