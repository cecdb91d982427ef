//! Trace validation: a recorded run of real controllers checked to be a behaviour the model
//! allows.
//!
//! The other direction from the replays: instead of driving the implementation along the
//! model's traces, a run of the implementation (the JSON events of every controller,
//! [`crate::record`]) is explained by stepping the model (`model::protocol::next_state`)
//! round by round. Observations are taken at round boundaries (`t_ms / heartbeat period`):
//! what every controller reported of itself by then, mapped to the model's abstract state by
//! the one abstraction function ([`crate::abstraction`]). Controller lives are numbered per id
//! in start order, the model's incarnation counter.
//!
//! The search keeps every model state consistent with the observations so far. Between two
//! boundaries the environment may do anything the model allows in a round: a controller whose
//! process starts in the round joins (its first life) or restarts (a later one); a controller
//! that printed nothing since may crash (a killed process just stops printing); any heartbeat
//! may be lost (this is also how DDS discovery of a new participant looks to the model); then
//! the round ends (`Tick`) and due initialization windows expire (the model makes them
//! urgent, the implementation fires them at the boundary). Every resulting state is kept if
//! it agrees with what each controller reported at the next boundary.
//!
//! The round's end acts on each controller separately: its next state depends on its own state
//! and on what the others' heartbeats carry (incarnation, phase, role, strength, agreed
//! result, vote), never on the others' hidden counters. So the set of states is kept per
//! controller, as candidate sets that share what heartbeats carry, and the lost heartbeats are
//! chosen per receiver (2^(live senders) choices, not 2^(links)). A test checks this against
//! `next_state` on whole states.
//!
//! What is compared (the abstraction's fields): life, incarnation, phase, role, strength,
//! agreed result, vote and alarms exactly; `sees` and `failed` exactly, except that a peer
//! both seen and FAILED in the last report may since have been lost without a report (the
//! implementation reports membership changes, and losing a FAILED peer is none). A process
//! that printed nothing since round `r` may have crashed in any round from `r` on; a clean
//! stop (`stopped`) ends its life by the next round.
//!
//! Modules: `search` (the candidate histories, round by round), `round` (one controller's
//! round end under every choice of lost heartbeats, through the model's own round step),
//! `compare` (model state against report), `rejection` (the message when nothing agrees).
//!
//! Tolerance, exactly: (1) a process may join one round before the round of its `started`
//! event (the core starts before the event is printed); (2) a controller's report may lag the
//! model by one round: where no model state agrees with what a controller reported by
//! boundary `b`, the states that agree with what it reported by boundary `b + 1` are kept
//! instead (a report stamped after the boundary it belongs to, e.g. when the process was not
//! scheduled in time). The summary counts the reports only (2) explains. (3) A process that
//! replaces a life which stopped cleanly in the same round (a restart within one heartbeat
//! period) may start one round late: the old life's heartbeat timer may have fired in that
//! round before it stopped, and its peers heard it, which the model shows as the old life
//! lasting the round. (4) A controller that took over from a starved Primary (F17) may hear,
//! instead of that Primary's heartbeat of the round, the one of the round before: a starved
//! link delays what it carries, and the model's heartbeats are lost but never late.

mod compare;
mod rejection;
mod round;
mod search;
#[cfg(test)]
mod tests;

pub use compare::differences;
pub use round::round_end_of;

use crate::record::{round_of, Recording};
use model::Variant;
use search::Search;
use std::collections::BTreeMap;
use std::fmt::{self, Write};

/// Round lengths of the run, from its configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timing {
    pub period_ms: u64,
    pub dead_after_rounds: u8,
    pub window_rounds: u8,
}

impl Timing {
    /// The rounds `rl` derives from its configuration (impl/layer/src/config/timing.rs).
    pub fn from_config(timing: &rl_layer::config::Timing) -> Result<Timing, TimingError> {
        let rounds = |field: &'static str, rounds: u32| {
            u8::try_from(rounds).map_err(|_| TimingError::TooManyRounds { field, rounds })
        };
        Ok(Timing {
            period_ms: timing.heartbeat_period_ms.max(1),
            dead_after_rounds: rounds("timing.peer_deadline_ms", timing.dead_after_rounds())?,
            window_rounds: rounds("timing.init_window_ms", timing.window_rounds())?,
        })
    }

    /// The model's configuration for a run with ids `1..=controllers`: the default rules,
    /// this timing, and fault budgets that never run out.
    pub fn model_config(&self, controllers: u8) -> model::Config {
        model::Config {
            founders: controllers,
            late_joiners: 0,
            max_crashes: u8::MAX,
            max_restarts: u8::MAX,
            max_lost_heartbeats: u8::MAX,
            // A stall shows as a new life (a restart); a cut as lost heartbeats.
            max_pauses: 0,
            max_isolations: 0,
            // A starved link shows as lost heartbeats, and as a takeover (F17) where a
            // Secondary reports the takeover strength: the search then starves the Primary.
            max_starvations: 1,
            // A slowed process and an unnoticed stall show as lost heartbeats and a new life
            // (F18's restart), which the budgets above explain.
            max_slowdowns: 0,
            max_late_heartbeats: 0,
            unnoticed_stalls: false,
            // A round end a slowed loop slept through is the record's `round_ends_missed`
            // (the model's `Oversleep`), read by the search itself; its late hearing shows as
            // lost heartbeats.
            slowed_receivers: false,
            dead_after_rounds: self.dead_after_rounds,
            window_rounds: self.window_rounds,
            settle_within_rounds: model::Config::default().settle_within_rounds,
            variant: Variant::Default,
            mutation: None,
            reverted: Vec::new(),
        }
    }
}

/// Why a run's configuration cannot be checked against the model.
#[derive(Debug, thiserror::Error)]
pub enum TimingError {
    /// A length in rounds beyond what the model counts.
    #[error("{field}: {rounds} rounds is more than 255")]
    TooManyRounds { field: &'static str, rounds: u32 },
    /// The configuration file could not be read.
    #[error(transparent)]
    Config(#[from] rl_layer::config::ConfigError),
}

/// A run the model explains, with the size of the search.
#[derive(Clone, Debug, Default)]
pub struct Accepted {
    pub controllers: u8,
    pub lives: usize,
    /// Round boundaries compared (from the first start to the last event).
    pub rounds_checked: u64,
    /// Model steps taken: one per (candidate state, lost-heartbeat choice) at every round end.
    pub states_explored: u64,
    /// The most candidate states one controller had at one boundary.
    pub candidates_max: usize,
    /// The most alternative histories (crash timing) kept at once.
    pub branches_max: usize,
    /// Reports only the lag tolerance explains: (controller, boundary) pairs at which no
    /// model state agreed with the report but some agreed with the next round's.
    pub lagged_reports: u64,
    /// Where the strict check (no lag) failed, when the tolerance was needed.
    pub strict_rejection_round: Option<u64>,
}

impl fmt::Display for Accepted {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "accepted: {} controller id(s), {} lives, {} round boundaries checked, {} model \
             states explored (at most {} candidates per controller, {} alternative histories); \
             {}",
            self.controllers,
            self.lives,
            self.rounds_checked,
            self.states_explored,
            self.candidates_max,
            self.branches_max,
            match self.strict_rejection_round {
                None => "strictly, without the lag tolerance".to_string(),
                Some(round) => format!(
                    "with the one-round lag tolerance ({} lagged report(s); the strict check \
                     fails at boundary {round})",
                    self.lagged_reports
                ),
            }
        )
    }
}

/// Why a run is not a behaviour of the model (or cannot be checked).
#[derive(Clone, Debug)]
pub struct Rejection {
    /// The boundary at which nothing matched, as a round number and relative to the first.
    pub round: Option<u64>,
    pub message: String,
}

impl fmt::Display for Rejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Rejection {}

pub(crate) fn reject(message: String) -> Box<Rejection> {
    Box::new(Rejection {
        round: None,
        message,
    })
}

/// Checks a recorded run against the model: strictly first, then, if that fails, with the
/// one-round lag tolerance (the summary says whether it was needed).
pub fn validate(recording: &Recording, timing: &Timing) -> Result<Accepted, Box<Rejection>> {
    let strict = match validate_strict(recording, timing) {
        Ok(accepted) => return Ok(accepted),
        Err(rejection) => rejection,
    };
    match Search::new(recording, timing, true)?.run() {
        Ok(mut accepted) => {
            accepted.strict_rejection_round = strict.round;
            Ok(accepted)
        }
        Err(mut tolerant) => {
            if let Some(round) = strict.round.filter(|r| Some(*r) != tolerant.round) {
                tolerant.message.push_str(&format!(
                    "  (without the lag tolerance the first disagreement is at boundary {round})\n"
                ));
            }
            Err(tolerant)
        }
    }
}

/// Checks a recorded run against the model without the lag tolerance: every report must
/// agree with the model at its own boundary (the DDS-level replay, whose harness controls the
/// timing, uses this).
pub fn validate_strict(recording: &Recording, timing: &Timing) -> Result<Accepted, Box<Rejection>> {
    Search::new(recording, timing, false)?.run()
}

/// As [`validate_strict`], with a boundary's reports taken as those printed within
/// `decided_within_ms` of it: the DDS-level replay, whose harness also times the faults, so
/// a report later in the round (a takeover from a starved Primary) is the next boundary's.
pub fn validate_replayed(
    recording: &Recording,
    timing: &Timing,
    decided_within_ms: u64,
) -> Result<Accepted, Box<Rejection>> {
    Search::new(recording, timing, false)?
        .decided_within(decided_within_ms)
        .run()
}

/// Reads a run's configuration: `path` if given, else `<dir>/rl.toml` if it exists, else
/// `rl`'s defaults.
pub fn run_timing(
    dir: &std::path::Path,
    path: Option<&std::path::Path>,
) -> Result<(Timing, String), TimingError> {
    let candidate = path
        .map(std::path::Path::to_path_buf)
        .or_else(|| Some(dir.join("rl.toml")).filter(|p| p.is_file()));
    let (config, source) = match candidate {
        Some(path) => (
            rl_layer::config::Config::load(&path)?,
            path.display().to_string(),
        ),
        None => (
            rl_layer::config::Config::default(),
            "rl's defaults".to_string(),
        ),
    };
    Ok((Timing::from_config(&config.timing)?, source))
}

/// Per controller id, the lives of a recording and their rounds: a summary line per life.
pub fn describe_lives(recording: &Recording, period_ms: u64) -> String {
    let numbers = recording.incarnation_numbers();
    let mut out = String::new();
    let lives: BTreeMap<_, _> = recording.lives.iter().collect();
    for (id, logs) in lives {
        for log in logs {
            let number = numbers.number(*id, log.incarnation).unwrap_or(0);
            let start = log.started_ms().map_or(0, |t| round_of(t, period_ms));
            let last = log.last_event_ms().map_or(0, |t| round_of(t, period_ms));
            let end = if log.stopped_ms().is_some() {
                "stopped"
            } else {
                "then silent (killed or still running)"
            };
            let _ = writeln!(
                out,
                "  C{id}#{number} ({}): rounds {start}..={last}, {} events, {end}",
                log.source,
                log.events.len()
            );
        }
    }
    out
}
