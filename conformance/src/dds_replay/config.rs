//! The replay's `rl` configuration and its timing on the wall clock: when processes start,
//! when a round's faults are applied, when a boundary is observed, and the window in which
//! the servo's owner must be settled.
//!
//! One round is one heartbeat period (250 ms); within real round `r` (from `r * 250` ms):
//!
//! ```text
//!  +0     boundary: the controllers decide (status, output, strength) within milliseconds
//!  +10    processes started at start
//!  +20    the round's faults applied (kill -9, new processes, drop/accept control, SIGSTOP
//!         and SIGCONT, nftables cuts and links down), at the latest +50, in force before
//!         the heartbeats go out at +62 (a quarter period); SIGCONT no sooner than a peer
//!         deadline after the SIGSTOP, the stall the model's resume stands for
//!  +180   from here the servo's owner must be settled: a crash at +50 at the latest stops the
//!         owner's commands, the servo gives up on it after the command deadline (100 ms) and
//!         takes the next writer's command within a republish period (10 ms), plus 20 ms
//!  +230   the boundary observed: every controller's reports, and the commands the servo
//!         accepted since +180, all from the model's owner (none if it has none)
//!  +250   the next boundary
//! ```

use super::error::ReplayError;
use crate::validate::Timing;
use std::time::Duration;

/// Processes start this long after a round boundary.
pub const START_OFFSET_MS: u64 = 10;
/// A round's faults are applied this long after its boundary (heartbeats go out at a quarter
/// period).
pub const APPLY_OFFSET_MS: u64 = 20;
/// Applying later than this after the boundary would miss the round's heartbeats.
pub const APPLY_LATEST_MS: u64 = 50;
/// A boundary is observed this long after it: its reports are printed within milliseconds,
/// and the servo's owner has settled (see [`RunTiming::owner_from_ms`]).
pub const OBSERVE_OFFSET_MS: u64 = 230;
/// A paused process is continued no sooner than this long after a peer deadline of standing
/// still, so its loop surely finds the stall.
pub const STALL_MARGIN_MS: u64 = 5;
/// Scheduling slack added to the owner's settling time.
pub const OWNER_MARGIN_MS: u64 = 20;
/// The first reports must come within this long of the start.
pub const FIRST_REPORT_TIMEOUT: Duration = Duration::from_secs(10);
/// Bounded wait for a quiescent or settled boundary.
pub const SETTLE_TIMEOUT: Duration = Duration::from_secs(10);
/// The settled end must hold this many more boundaries.
pub const HOLD_ROUNDS: u64 = 2;
/// Attempts when the processes' timing does not line up with the trace.
pub const ATTEMPTS: usize = 3;

/// The `rl` configuration the replay runs with: the model's heartbeat period and dead-man
/// deadline, an initialization window one round longer than the model's (3 rounds, not 2),
/// and the command deadline and republish period written out (the owner window depends on
/// them). A controller that fails itself stays up for the longest delay allowed: in the model
/// it stays up until a restart, which is a fault of its own. With a 2-round window, DDS discovery of a late process decides in which round its
/// window expires, which the late-join and fourth-controller traces depend on; the plan
/// checks against the model that every replayed trace reaches the same states with 3.
pub const CONFIG_TOML: &str = "\
# The DDS-level replay's timing (conformance/src/dds_replay/config.rs): one round = 250 ms.
[timing]
heartbeat_period_ms = 250
peer_deadline_ms = 500
init_window_ms = 750
command_deadline_ms = 100
command_republish_ms = 10
# In the model a FAILED controller stays up until a restart (a fault of its own), so here too.
failed_exit_delay_ms = 3600000
";

/// The run's timing: its rounds (as trace validation reads them) and where in a round the
/// servo's owner is settled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunTiming {
    pub rounds: Timing,
    /// From this long after a boundary until [`OBSERVE_OFFSET_MS`] every command the servo
    /// accepts must come from the model's owner.
    pub owner_from_ms: u64,
}

/// The run's round lengths, read back through `rl`'s own configuration code.
pub fn timing() -> Result<Timing, ReplayError> {
    run_timing().map(|t| t.rounds)
}

/// The run's timing, read back through `rl`'s own configuration code, checked to leave room
/// for a settled owner before the observation and for the observation before the next
/// round's faults.
pub fn run_timing() -> Result<RunTiming, ReplayError> {
    let config = rl_layer::config::Config::from_toml_str(CONFIG_TOML, "replay configuration")
        .map_err(|e| ReplayError::Config(e.to_string()))?;
    let rounds =
        Timing::from_config(&config.timing).map_err(|e| ReplayError::Config(e.to_string()))?;
    let owner_from_ms = APPLY_LATEST_MS
        + config.timing.command_deadline_ms
        + config.timing.command_republish_ms
        + OWNER_MARGIN_MS;
    if owner_from_ms >= OBSERVE_OFFSET_MS || OBSERVE_OFFSET_MS >= rounds.period_ms {
        return Err(ReplayError::Config(format!(
            "timing.command_deadline_ms: the owner settles {owner_from_ms} ms after a \
             boundary, not before the observation at {OBSERVE_OFFSET_MS} ms of a \
             {} ms round",
            rounds.period_ms
        )));
    }
    Ok(RunTiming {
        rounds,
        owner_from_ms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_configuration_is_the_plans_timing_and_leaves_an_owner_window() {
        let timing = run_timing().expect("the replay configuration is valid");
        assert_eq!(timing.rounds, super::super::plan::replay_timing());
        assert_eq!(timing.owner_from_ms, 180);
        assert!(timing.owner_from_ms + 40 <= OBSERVE_OFFSET_MS);
    }
}
