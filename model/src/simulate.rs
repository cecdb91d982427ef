//! Seeded random walks over the model: one seed reproduces one walk, on any machine.
//!
//! stateright 0.31's simulation checker cannot be relied on here (docs/model.md), so walks
//! pick among `Model::actions` with our own generator (SplitMix64, fixed forever so that
//! committed traces stay byte-identical).

use crate::search::Path;
use crate::RlModel;
use stateright::Model;

/// SplitMix64: tiny, well distributed, and stable across platforms and releases.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> SplitMix64 {
        SplitMix64(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A number in `0..bound` (`bound` > 0).
    pub fn below(&mut self, bound: usize) -> usize {
        (self.next_u64() % bound as u64) as usize
    }
}

/// A random walk of at most `steps` actions; it stops early at a state with no action.
pub fn walk(model: &RlModel, seed: u64, steps: usize) -> Path {
    let mut rng = SplitMix64::new(seed);
    let inits = model.init_states();
    let init_index = rng.below(inits.len());
    let mut path = Path::replay(model, init_index, &[]);
    let mut actions = Vec::new();
    for _ in 0..steps {
        actions.clear();
        model.actions(path.last(), &mut actions);
        if actions.is_empty() {
            break;
        }
        let action = actions[rng.below(actions.len())];
        path.push(model, action);
    }
    path
}
