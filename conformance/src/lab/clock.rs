//! The lab clock: milliseconds since the run started, one clock for every observation. Lines
//! are stamped when read; controller events carry wall-clock times (their round clock) and the
//! Connext reader Unix times, both mapped here (a controller's own clock offset taken off).

use std::time::{Instant, SystemTime, UNIX_EPOCH};

#[derive(Clone, Copy, Debug)]
pub struct LabClock {
    started: Instant,
    started_wall_ms: f64,
}

impl LabClock {
    pub fn start() -> LabClock {
        LabClock {
            started: Instant::now(),
            started_wall_ms: wall_ms(),
        }
    }

    /// Milliseconds since the run started.
    pub fn now_ms(&self) -> f64 {
        self.started.elapsed().as_secs_f64() * 1000.0
    }

    /// A wall-clock time (Unix ms) on the lab clock.
    pub fn of_wall_ms(&self, wall_ms: f64) -> f64 {
        wall_ms - self.started_wall_ms
    }
}

/// Unix milliseconds now.
pub fn wall_ms() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() * 1000.0)
}
