//! The `[timing]` section: the heartbeat period (one protocol round), the peer deadline and
//! initialization window counted in whole rounds, the command topic's deadline and
//! republish period, and how long a controller that has failed itself waits before it exits
//! to be restarted.

use super::error::{check, InvalidValue};
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// Protocol and command timing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Timing {
    /// Heartbeat period = one protocol round (paper: 4 Hz).
    pub heartbeat_period_ms: u64,
    /// The dead-man deadline: a peer silent this long is lost (paper: 2 x period). A whole
    /// number of periods, at least two.
    pub peer_deadline_ms: u64,
    /// Initialization window: it closes this long after the last new controller was heard,
    /// or when three controllers are heard (paper: 10 s). A whole number of periods, longer
    /// than the peer deadline.
    pub init_window_ms: u64,
    /// Deadline of the command topic (paper: 100 ms): the actuator switches to the next
    /// writer when the owner is silent this long.
    pub command_deadline_ms: u64,
    /// How often the tracker re-publishes its last command when the camera is quiet, so an
    /// aperiodic command topic never misses its deadline (less than the deadline). The
    /// actuator's gap after the owner dies is at most the deadline plus this period: the
    /// default (a tenth of the deadline) keeps it within 1.1 x the deadline.
    pub command_republish_ms: u64,
    /// How long a controller that has voted itself FAILED (outvoted, or a local fault) stays
    /// up before it exits to be restarted (paper: it "will take itself offline and/or
    /// restart"). 0 (the default): as soon as a heartbeat has announced FAILED to the peers.
    /// A longer delay keeps the FAILED LEDs and status visible for longer, and keeps the
    /// controller out for longer.
    pub failed_exit_delay_ms: u64,
}

impl Default for Timing {
    fn default() -> Timing {
        Timing {
            heartbeat_period_ms: 250,
            peer_deadline_ms: 500,
            init_window_ms: 10_000,
            command_deadline_ms: 100,
            command_republish_ms: 10,
            failed_exit_delay_ms: 0,
        }
    }
}

/// Heartbeat periods outside this range are either busier than a Pi should be or too slow to
/// notice a failure within a useful time.
pub const HEARTBEAT_PERIOD_MS_RANGE: std::ops::RangeInclusive<u64> = 10..=10_000;

/// Longest duration any timing field may hold (one hour): long enough for any real use, and
/// short enough that `Instant + duration` and round counts never overflow.
pub const DURATION_MS_MAX: u64 = 3_600_000;

impl Timing {
    /// Checks the timing rules. The heartbeat period comes first: the others are measured in it.
    pub fn validate(&self) -> Result<(), InvalidValue> {
        self.validate_bounds()?;
        self.validate_rounds()?;
        self.validate_command_timing()
    }

    /// The period's range, and the one-hour bound on every other duration.
    fn validate_bounds(&self) -> Result<(), InvalidValue> {
        let period_ms = self.heartbeat_period_ms;
        check(
            HEARTBEAT_PERIOD_MS_RANGE.contains(&period_ms),
            "timing.heartbeat_period_ms",
            period_ms,
            || {
                format!(
                    "must be between {} and {} ms",
                    HEARTBEAT_PERIOD_MS_RANGE.start(),
                    HEARTBEAT_PERIOD_MS_RANGE.end()
                )
            },
        )?;
        for (field, value_ms) in [
            ("timing.peer_deadline_ms", self.peer_deadline_ms),
            ("timing.init_window_ms", self.init_window_ms),
            ("timing.command_deadline_ms", self.command_deadline_ms),
            ("timing.command_republish_ms", self.command_republish_ms),
            ("timing.failed_exit_delay_ms", self.failed_exit_delay_ms),
        ] {
            check(value_ms <= DURATION_MS_MAX, field, value_ms, || {
                format!("must be at most {DURATION_MS_MAX} ms (one hour)")
            })?;
        }
        Ok(())
    }

    /// The peer deadline and the initialization window in whole rounds.
    fn validate_rounds(&self) -> Result<(), InvalidValue> {
        let period_ms = self.heartbeat_period_ms;
        // Fewer than two periods would declare a peer lost after a single late heartbeat.
        check(
            whole_periods(self.peer_deadline_ms, period_ms)
                && self.peer_deadline_ms >= 2 * period_ms,
            "timing.peer_deadline_ms",
            self.peer_deadline_ms,
            || {
                format!(
                    "must be a whole number of heartbeat periods ({period_ms} ms) and at least 2 of them"
                )
            },
        )?;
        // A window shorter than the deadline could close before a slow peer is even missed;
        // the checked model uses a window as long as the deadline (2 rounds each).
        check(
            whole_periods(self.init_window_ms, period_ms)
                && self.init_window_ms >= self.peer_deadline_ms,
            "timing.init_window_ms",
            self.init_window_ms,
            || {
                format!(
                    "must be a whole number of heartbeat periods ({period_ms} ms) and at least \
                     timing.peer_deadline_ms ({} ms)",
                    self.peer_deadline_ms
                )
            },
        )
    }

    /// The command topic's deadline, and a republish period within it.
    fn validate_command_timing(&self) -> Result<(), InvalidValue> {
        check(
            self.command_deadline_ms >= 1,
            "timing.command_deadline_ms",
            self.command_deadline_ms,
            || "must be at least 1 ms".to_string(),
        )?;
        // Republishing no faster than the deadline would let the command topic miss it.
        check(
            self.command_republish_ms >= 1 && self.command_republish_ms < self.command_deadline_ms,
            "timing.command_republish_ms",
            self.command_republish_ms,
            || {
                format!(
                    "must be at least 1 ms and less than timing.command_deadline_ms ({} ms)",
                    self.command_deadline_ms
                )
            },
        )
    }

    /// Rounds without a heartbeat after which a peer is lost (`peer_deadline / period`).
    pub fn dead_after_rounds(&self) -> u32 {
        rounds(self.peer_deadline_ms, self.heartbeat_period_ms)
    }

    /// Rounds without a new controller after which the initialization window closes
    /// (`init_window / period`).
    pub fn window_rounds(&self) -> u32 {
        rounds(self.init_window_ms, self.heartbeat_period_ms)
    }

    /// The core's round lengths (the rules derived from them, such as the minority grace,
    /// are defined once, in `rl_core::Rounds`).
    pub fn rounds(&self) -> crate::core::Rounds {
        crate::core::Rounds {
            dead_after_rounds: self.dead_after_rounds(),
            window_rounds: self.window_rounds(),
        }
    }

    /// The heartbeat period, which is one protocol round.
    pub fn heartbeat_period(&self) -> Duration {
        Duration::from_millis(self.heartbeat_period_ms)
    }

    /// The dead-man deadline after which a silent peer is lost.
    pub fn peer_deadline(&self) -> Duration {
        Duration::from_millis(self.peer_deadline_ms)
    }

    /// The initialization window at start-up.
    pub fn init_window(&self) -> Duration {
        Duration::from_millis(self.init_window_ms)
    }

    /// The command topic's deadline, after which the actuator follows the next writer.
    pub fn command_deadline(&self) -> Duration {
        Duration::from_millis(self.command_deadline_ms)
    }

    /// How often the last command is re-published while the camera is quiet.
    pub fn command_republish(&self) -> Duration {
        Duration::from_millis(self.command_republish_ms)
    }

    /// How long a controller that has failed itself waits before it exits; zero: as soon as
    /// its heartbeat has announced FAILED.
    pub fn failed_exit_delay(&self) -> Duration {
        Duration::from_millis(self.failed_exit_delay_ms)
    }
}

/// Whether a duration is a whole number of periods (`period_ms` > 0).
fn whole_periods(duration_ms: u64, period_ms: u64) -> bool {
    duration_ms.checked_rem(period_ms) == Some(0)
}

/// Whole periods in a duration; validation keeps both in range, so the fallbacks never apply.
fn rounds(duration_ms: u64, period_ms: u64) -> u32 {
    let count = duration_ms.checked_div(period_ms).unwrap_or(0);
    u32::try_from(count).unwrap_or(u32::MAX)
}
