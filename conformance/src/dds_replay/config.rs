//! The replay's `rl` configuration and its timing on the wall clock: when processes start,
//! when a round's faults are applied, when a boundary is observed, and the window in which
//! the servo's owner must be settled.
//!
//! One round is one heartbeat period (250 ms). Every controller process of the trace, the
//! ones that join or restart later included, is started before round 0, held before its
//! clock starts (`RL_HOLD_START`), until all have discovered each other over DDS; each is
//! let go (`start-voting` on its stdin) in the round the trace starts it. Within real round
//! `r` (from `r * 250` ms):
//!
//! ```text
//!  +0     boundary: the controllers decide (status, output, strength) within milliseconds
//!  +10    at the start: round 0's faults applied
//!  +20    the round's faults applied (kill -9, drop/accept control, SIGSTOP and SIGCONT,
//!         nftables cuts and links down, commands late or held back), at the latest +50, in force before the heartbeats
//!         go out at +62 (a quarter period); SIGCONT no sooner than a peer deadline after the
//!         SIGSTOP, the stall the model's resume stands for
//!  +55    the round's starts, joins and restarts: held processes let go, so that their first
//!         heartbeat, which goes out at once, is on the round's phase (+62)
//!  +180   from here the servo's owner must be settled: a crash at +50 at the latest stops the
//!         owner's commands, the servo gives up on it after the command deadline (100 ms) and
//!         takes the next writer's command within a republish period (10 ms), plus 20 ms
//!  +200   the next round's starved links begin (their late commands arrive from +20 of the
//!         next round)
//!  +230   the boundary observed: every controller's reports printed before +20 (the
//!         boundary's decisions; a takeover from a starved Primary comes later in the
//!         round), and the commands the servo accepted since +180, all from the model's
//!         owner (none if it has none)
//!  +250   the next boundary
//! ```

use super::error::ReplayError;
use crate::validate::Timing;
use std::time::Duration;

/// Round 0's faults are applied this long after the start's boundary.
pub const START_OFFSET_MS: u64 = 10;
/// A round's faults are applied this long after its boundary (heartbeats go out at a quarter
/// period).
pub const APPLY_OFFSET_MS: u64 = 20;
/// Held processes are let go this long after a boundary: a controller's first heartbeat goes
/// out at once, and a peer with no Primary to follow takes its round phase from it (rl-core's
/// `phase`), so it goes out a few milliseconds before the round's heartbeats at a quarter
/// period, within the phase's dead zone (a sixteenth of a period).
pub const LET_GO_OFFSET_MS: u64 = 55;
/// A starved controller's commands reach the others this late (its `delay-commands`): past
/// the lateness bound by which a Secondary finds them late (half the command deadline,
/// impl/layer/src/runtime/arrival.rs), within the command deadline and the commands'
/// lifespan (one command deadline), so the actuator still takes them; a republish period
/// (10 ms) may add to it.
pub const STARVED_DELAY_MS: u64 = 70;
/// A boundary's reports are what the controllers printed before this long into its round:
/// they decide within milliseconds of it, and nothing the round's faults do changes a
/// report sooner (they are applied from +20; a takeover from a starved Primary comes at
/// +30 at the earliest, see [`STARVE_ONSET_MS`]).
pub const DECIDED_BY_MS: u64 = APPLY_OFFSET_MS;
/// A starved link of round `k` begins this long into round `k - 1`, after the servo took
/// that round's owner window's first commands: its first late command reaches the others
/// 70 ms later, at +20 of round `k`, so the Secondary takes over (two late samples and a
/// Tertiary sample on time after them) before round `k`'s heartbeats at +62 announce it, as
/// the model's takeover comes with the starved link, before its round's end.
pub const STARVE_ONSET_MS: u64 = 200;
/// A missed deadline in the round a peer takes over from the starved controller is applied
/// this long after the boundary: the starved link's late commands (from +20, 70 ms late)
/// have reached the Secondary, which takes over on two of them and a Tertiary sample on
/// time after them, and the takeover writer owns the actuator before the owner window
/// (+180).
pub const LAG_AFTER_TAKEOVER_MS: u64 = 130;
/// Applying later than this after the boundary would miss the round's heartbeats.
pub const APPLY_LATEST_MS: u64 = 50;
/// A boundary is observed this long after it: its reports are printed within milliseconds,
/// and the servo's owner has settled (see [`RunTiming::owner_from_ms`]).
pub const OBSERVE_OFFSET_MS: u64 = 230;
/// A paused process is continued no sooner than this long after a peer deadline of standing
/// still, so its loop surely finds the stall.
pub const STALL_MARGIN_MS: u64 = 5;
/// A pause the trace resumes before its peers could lose it is continued no sooner than this
/// long after a command deadline of standing still, so its commands have surely lapsed and
/// its loop finds the stop (impl/layer/src/stall.rs): scheduling slack, as the owner's.
pub const STOP_NOTICED_MARGIN_MS: u64 = 20;
/// Scheduling slack added to the owner's settling time.
pub const OWNER_MARGIN_MS: u64 = 20;
/// The held processes must all have discovered each other within this long of their start.
pub const DISCOVERY_TIMEOUT: Duration = Duration::from_secs(10);
/// Bounded wait for a quiescent or settled boundary.
pub const SETTLE_TIMEOUT: Duration = Duration::from_secs(10);
/// The settled end must hold this many more boundaries.
pub const HOLD_ROUNDS: u64 = 2;
/// Attempts when the processes' timing does not line up with the trace.
pub const ATTEMPTS: usize = 3;

/// The `rl` configuration the replay runs with: the model's heartbeat period, dead-man
/// deadline and initialization window (2 rounds), and the command deadline and republish
/// period written out (the owner window depends on them). The processes discover each other
/// before they vote (held, see above), so the window is the model's: no round of it goes to
/// discovery. A controller that fails itself stays up for the longest delay allowed: in the
/// model it stays up until a restart, which is a fault of its own.
pub const CONFIG_TOML: &str = "\
# The DDS-level replay's timing (conformance/src/dds_replay/config.rs): one round = 250 ms.
[timing]
heartbeat_period_ms = 250
peer_deadline_ms = 500
init_window_ms = 500
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
    /// A pause resumed sooner than a peer deadline is continued this long after its SIGSTOP:
    /// the command deadline and [`STOP_NOTICED_MARGIN_MS`]. Within one round the resume then
    /// comes before the owner window, at the latest `APPLY_LATEST_MS` + this.
    pub stop_noticed_ms: u64,
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
    let deadline_ms = config.timing.command_deadline_ms;
    let latest_ms = STARVED_DELAY_MS + config.timing.command_republish_ms;
    if STARVED_DELAY_MS <= deadline_ms / 2 || latest_ms >= deadline_ms {
        return Err(ReplayError::Config(format!(
            "timing.command_deadline_ms: a starved link's {STARVED_DELAY_MS} ms delay (up to \
             {latest_ms} ms) must be past half of it and within it ({deadline_ms} ms)"
        )));
    }
    let stop_noticed_ms = deadline_ms + STOP_NOTICED_MARGIN_MS;
    if APPLY_LATEST_MS + stop_noticed_ms >= owner_from_ms {
        return Err(ReplayError::Config(format!(
            "timing.command_deadline_ms: a pause resumed within its round ends up to {} ms \
             after the boundary, not before the owner window at {owner_from_ms} ms",
            APPLY_LATEST_MS + stop_noticed_ms
        )));
    }
    Ok(RunTiming {
        rounds,
        owner_from_ms,
        stop_noticed_ms,
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
        assert_eq!(timing.stop_noticed_ms, 120);
        assert!(timing.owner_from_ms + 40 <= OBSERVE_OFFSET_MS);
    }
}
