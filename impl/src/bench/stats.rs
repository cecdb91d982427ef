//! The benchmark's arithmetic: order statistics of measured durations, and the seeded
//! generator that picks when in the heartbeat round each kill lands.

use serde::Serialize;

/// Order statistics of a sample of durations (ms).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Summary {
    pub count: usize,
    pub min: f64,
    pub p50: f64,
    pub p99: f64,
    pub max: f64,
}

impl Summary {
    /// Nearest-rank percentiles; NaN everywhere for an empty sample.
    pub fn of(values: &[f64]) -> Summary {
        let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
        sorted.sort_by(f64::total_cmp);
        let rank = |p: f64| -> f64 {
            if sorted.is_empty() {
                return f64::NAN;
            }
            let index = ((p * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1;
            sorted[index]
        };
        Summary {
            count: sorted.len(),
            min: sorted.first().copied().unwrap_or(f64::NAN),
            p50: rank(0.50),
            p99: rank(0.99),
            max: sorted.last().copied().unwrap_or(f64::NAN),
        }
    }

    /// The summary of the values that were measured (`None`s left out).
    pub fn of_measured(values: impl IntoIterator<Item = Option<u64>>) -> Summary {
        let measured: Vec<f64> = values.into_iter().flatten().map(|v| v as f64).collect();
        Summary::of(&measured)
    }
}

/// SplitMix64: a small, fast generator whose whole state is the seed, so a run's kill phases
/// are repeated exactly by passing its seed again.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    pub fn new(seed: u64) -> SplitMix64 {
        SplitMix64 { state: seed }
    }

    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A value in `0..bound` (0 when `bound` is 0); the modulo bias is below 2^-50 for the
    /// bounds used here (a heartbeat period in ms).
    pub fn below(&mut self, bound: u64) -> u64 {
        if bound == 0 {
            0
        } else {
            self.next_u64() % bound
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let values: Vec<f64> = (1..=100).map(f64::from).collect();
        let s = Summary::of(&values);
        assert_eq!(
            (s.count, s.min, s.p50, s.p99, s.max),
            (100, 1.0, 50.0, 99.0, 100.0)
        );
        let s = Summary::of(&[5.0, 1.0, 3.0]);
        assert_eq!((s.p50, s.p99), (3.0, 5.0));
        assert!(Summary::of(&[]).p50.is_nan());
        let s = Summary::of_measured([Some(4), None, Some(2)]);
        assert_eq!((s.count, s.min, s.max), (2, 2.0, 4.0));
    }

    #[test]
    fn a_seed_repeats_its_phases_and_they_cover_the_round() {
        let phases = |seed| {
            let mut rng = SplitMix64::new(seed);
            (0..400).map(|_| rng.below(250)).collect::<Vec<u64>>()
        };
        assert_eq!(phases(7), phases(7));
        assert_ne!(phases(7), phases(8));
        let drawn = phases(7);
        assert!(drawn.iter().all(|p| *p < 250));
        // Every 50 ms fifth of the round is hit: not all kills just after a boundary.
        for fifth in 0..5 {
            assert!(
                drawn.iter().any(|p| p / 50 == fifth),
                "no phase in {}..{} ms",
                fifth * 50,
                fifth * 50 + 50
            );
        }
        assert_eq!(SplitMix64::new(1).below(0), 0);
    }
}
