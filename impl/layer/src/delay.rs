//! A writer's delay against its own best: how much later a sample arrived than the least delay
//! seen from the same writer within the last [`BASELINE_MS`].
//!
//! A sample's delay is the reader's wall clock at its arrival minus the writer's source
//! timestamp. The two clocks need not agree: a constant offset cancels against the baseline,
//! and a clock running fast or slow moves the baseline by its drift over the window only (a
//! crystal 1 % off: 20 ms; a Pi's, about 100 ppm: 0.2 ms). This is how DDS lets a reader judge
//! a sample's age "if the clocks are not synchronized and the Service can detect it" (DDS 1.4
//! 2.2.3.16 LIFESPAN). Two readers use it: a Secondary telling a starved Primary from a silent
//! one (`runtime::arrival`, F17), and every actuator view dropping a sample past its writer's
//! lifespan (crate::owner_feed).

use rustdds::Timestamp;
use std::collections::VecDeque;

/// How far back a writer's least delay is taken from.
pub const BASELINE_MS: u64 = 2_000;

/// The delay of a sample written at `written` (its source timestamp) and arrived at `arrived`,
/// in milliseconds on the two wall clocks (negative when the writer's clock is ahead).
pub fn delay_ms(arrived: Timestamp, written: Timestamp) -> i64 {
    (arrived - written).to_nanoseconds() / 1_000_000
}

/// One writer's delays of the last [`BASELINE_MS`].
#[derive(Debug, Default)]
pub struct DelayBaseline {
    /// (arrival on the reader's monotonic clock, delay) per sample, oldest first.
    recent: VecDeque<(u64, i64)>,
}

impl DelayBaseline {
    /// Takes in one sample's delay, arrived at `now_ms` (the reader's monotonic clock);
    /// returns how much later it came than the least delay of the window, itself included (a
    /// writer's first sample is its own baseline: 0).
    pub fn lateness_ms(&mut self, now_ms: u64, delay_ms: i64) -> i64 {
        while self
            .recent
            .front()
            .is_some_and(|(at_ms, _)| now_ms.saturating_sub(*at_ms) > BASELINE_MS)
        {
            self.recent.pop_front();
        }
        self.recent.push_back((now_ms, delay_ms));
        let baseline = self
            .recent
            .iter()
            .map(|(_, delay)| *delay)
            .min()
            .unwrap_or(delay_ms);
        delay_ms - baseline
    }

    /// When its last sample arrived (the reader's monotonic clock); `None` before any.
    pub fn last_ms(&self) -> Option<u64> {
        self.recent.back().map(|(at_ms, _)| *at_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_constant_clock_offset_cancels() {
        let mut baseline = DelayBaseline::default();
        assert_eq!(baseline.lateness_ms(0, -5_000), 0);
        assert_eq!(baseline.lateness_ms(33, -4_999), 1);
        assert_eq!(baseline.lateness_ms(66, -4_700), 300);
    }

    #[test]
    fn the_baseline_forgets_delays_older_than_the_window() {
        let mut baseline = DelayBaseline::default();
        baseline.lateness_ms(0, 1);
        // Within the window the old best still counts; past it a lasting delay becomes the
        // new normal.
        assert_eq!(baseline.lateness_ms(BASELINE_MS, 181), 180);
        assert_eq!(baseline.lateness_ms(BASELINE_MS + 1, 181), 0);
        assert_eq!(baseline.last_ms(), Some(BASELINE_MS + 1));
    }

    #[test]
    fn delays_are_whole_milliseconds_either_way() {
        let written = Timestamp::now();
        let later = written + rustdds::Duration::from_millis(250);
        assert_eq!(delay_ms(later, written), 250);
        assert_eq!(delay_ms(written, later), -250);
    }
}
