//! Seed derivation. Every random choice in a trial comes from a ChaCha stream keyed by
//! (suite seed, objective id, optimizer id, trial index); an optimizer that needs several
//! independent streams (one per MSGA membrane) uses ChaCha's stream number. The derivation
//! uses a fixed hash (FNV-1a, then SplitMix64), never `std`'s unstable `Hasher`, so a seed
//! means the same bytes on every platform and release.

use super::hash::{FNV_OFFSET, fnv1a};
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The random-number key of one trial.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TrialSeed {
    key: [u8; 32],
}

/// SplitMix64 step: advances `state` and returns a well-mixed output.
fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl TrialSeed {
    /// The key for one trial. Names are separated by 0xFF, a byte UTF-8 never contains, so
    /// distinct (objective, optimizer) pairs cannot collide by concatenation.
    pub fn derive(suite_seed: u64, objective: &str, optimizer: &str, trial: u64) -> Self {
        let mut h = fnv1a(FNV_OFFSET, &suite_seed.to_le_bytes());
        h = fnv1a(h, &[0xff]);
        h = fnv1a(h, objective.as_bytes());
        h = fnv1a(h, &[0xff]);
        h = fnv1a(h, optimizer.as_bytes());
        h = fnv1a(h, &[0xff]);
        h = fnv1a(h, &trial.to_le_bytes());
        let mut state = h ^ suite_seed.rotate_left(32);
        let mut key = [0u8; 32];
        for chunk in key.chunks_exact_mut(8) {
            chunk.copy_from_slice(&splitmix64(&mut state).to_le_bytes());
        }
        TrialSeed { key }
    }

    /// A key from a plain number, for code outside suites (benches, examples, tests).
    pub fn from_u64(seed: u64) -> Self {
        Self::derive(seed, "", "", 0)
    }

    /// The generator of stream `stream` (0 for the optimizer itself, 1.. for its parts).
    pub fn rng(&self, stream: u64) -> ChaCha8Rng {
        let mut rng = ChaCha8Rng::from_seed(self.key);
        rng.set_stream(stream);
        rng
    }

    /// The key as hex, stored with each trial so any trial can be rerun alone.
    pub fn hex(&self) -> String {
        self.key.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// A standard normal draw (Box-Muller; one of the pair is discarded to keep the stream
/// position independent of call history).
pub fn standard_normal(rng: &mut impl Rng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>(); // (0, 1]
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    #[test]
    fn derivation_is_frozen() {
        // A change here silently changes every published result: keep the golden value.
        let s = TrialSeed::derive(42, "griewank-2d", "MSGA", 7);
        assert_eq!(&s.hex()[..16], GOLDEN);
        // The generator itself is frozen too (a rand_chacha upgrade must not move streams).
        let x: u64 = s.rng(0).random();
        let y: u64 = s.rng(3).random();
        assert_eq!((x, y), GOLDEN_DRAWS);
    }

    const GOLDEN: &str = "fdeb9580024b1436";
    const GOLDEN_DRAWS: (u64, u64) = (11_201_550_010_510_894_699, 11_615_254_694_034_790_808);

    #[test]
    fn every_component_changes_the_key() {
        let base = TrialSeed::derive(1, "a", "b", 0);
        assert_ne!(base, TrialSeed::derive(2, "a", "b", 0));
        assert_ne!(base, TrialSeed::derive(1, "a2", "b", 0));
        assert_ne!(base, TrialSeed::derive(1, "a", "b2", 0));
        assert_ne!(base, TrialSeed::derive(1, "a", "b", 1));
        // No ambiguity from moving a character between the names.
        assert_ne!(
            TrialSeed::derive(1, "ab", "c", 0),
            TrialSeed::derive(1, "a", "bc", 0)
        );
    }

    #[test]
    fn streams_are_independent() {
        let s = TrialSeed::from_u64(5);
        let a: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(s.rng(1), |r, _: u64| Some(r.random()))
            .collect();
        let b: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(s.rng(2), |r, _: u64| Some(r.random()))
            .collect();
        assert_ne!(a, b);
    }
}
