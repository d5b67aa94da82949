//! Variation and selection operators shared by GA and MSGA.

use crate::base::standard_normal;
use crate::objective::Bounds;
use rand::{Rng, RngExt};

/// Fitness-proportional (roulette-wheel) selection for minimisation.
///
/// Roulette needs non-negative fitness that grows as the objective falls. We use linear
/// windowing: `fitness_i = (f_max - f_i) + eps`, with `f_max` the worst finite value in the
/// population and `eps = 1 %` of the population's spread, so the worst individual keeps a
/// small chance and the transform does not depend on the objective's offset (Schwefel is
/// negative). Non-finite values get fitness 0; a population of equal values is uniform.
#[derive(Debug, Clone, Default)]
pub struct Roulette {
    cumulative: Vec<f64>,
}

impl Roulette {
    /// Builds the wheel for objective values `f` (lower is better).
    pub fn new(f: &[f64]) -> Self {
        let mut wheel = Roulette::default();
        wheel.rebuild(f);
        wheel
    }

    /// Rebuilds in place (reuses the allocation across generations).
    pub fn rebuild(&mut self, f: &[f64]) {
        let finite = f.iter().copied().filter(|v| v.is_finite());
        let (lo, hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        let spread = hi - lo;
        let eps = if spread > 0.0 { 0.01 * spread } else { 1.0 };
        self.cumulative.clear();
        let mut acc = 0.0;
        for &v in f {
            let w = if v.is_finite() { (hi - v) + eps } else { 0.0 };
            acc += w;
            self.cumulative.push(acc);
        }
        if acc <= 0.0 || !acc.is_finite() {
            // Nothing finite: select uniformly.
            for (i, c) in self.cumulative.iter_mut().enumerate() {
                *c = (i + 1) as f64;
            }
        }
    }

    /// Selection probability of individual `i` (for tests and diagnostics).
    pub fn probability(&self, i: usize) -> f64 {
        let total = *self.cumulative.last().expect("empty wheel");
        let prev = if i == 0 { 0.0 } else { self.cumulative[i - 1] };
        (self.cumulative[i] - prev) / total
    }

    /// Spins the wheel once.
    pub fn pick(&self, rng: &mut impl Rng) -> usize {
        let total = *self.cumulative.last().expect("empty wheel");
        let r = rng.random::<f64>() * total;
        // First index whose cumulative weight exceeds r.
        self.cumulative
            .partition_point(|&c| c <= r)
            .min(self.cumulative.len() - 1)
    }
}

/// How a gene is mutated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mutation {
    /// Replace the gene by a uniform draw from its interval (dissertation eq. 3.5, v' = eta).
    Uniform,
    /// Add N(0, (sigma * width)^2) and clip to the interval.
    Gaussian { sigma: f64 },
}

impl Mutation {
    /// Mutates each gene of `x` independently with probability `pm`.
    pub fn apply(&self, x: &mut [f64], bounds: &Bounds, pm: f64, rng: &mut impl Rng) {
        for (i, v) in x.iter_mut().enumerate() {
            if rng.random::<f64>() < pm {
                *v = match *self {
                    Mutation::Uniform => bounds.sample_coord(rng, i),
                    Mutation::Gaussian { sigma } => {
                        let z = standard_normal(rng);
                        (*v + z * sigma * bounds.width(i))
                            .clamp(bounds.lower()[i], bounds.upper()[i])
                    }
                };
            }
        }
    }
}

/// Arithmetic crossover (dissertation eq. 3.6): `c1 = a p1 + (1 - a) p2`, `c2 = (1 - a) p1 + a p2`.
/// A convex combination, so children of in-bounds parents are in bounds.
pub fn arithmetic_crossover(a: f64, p1: &[f64], p2: &[f64], c1: &mut [f64], c2: &mut [f64]) {
    for i in 0..p1.len() {
        c1[i] = a * p1[i] + (1.0 - a) * p2[i];
        c2[i] = (1.0 - a) * p1[i] + a * p2[i];
    }
}

/// Indices of `f` sorted from best (lowest) to worst; ties keep index order, so the result
/// is deterministic. Non-finite values sort last.
pub fn ranking(f: &[f64]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..f.len()).collect();
    idx.sort_by(|&a, &b| f[a].total_cmp(&f[b]).then(a.cmp(&b)));
    idx
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::TrialSeed;

    #[test]
    fn roulette_favours_low_values_and_keeps_the_worst_alive() {
        let w = Roulette::new(&[0.0, 10.0, 5.0]);
        // Fitness = (10 - f) + 0.1: 10.1, 0.1, 5.1 out of 15.3.
        assert!((w.probability(0) - 10.1 / 15.3).abs() < 1e-12);
        assert!((w.probability(1) - 0.1 / 15.3).abs() < 1e-12);
        assert!(w.probability(1) > 0.0);
    }

    #[test]
    fn roulette_is_invariant_to_offset() {
        let a = Roulette::new(&[1.0, 2.0, 4.0]);
        let b = Roulette::new(&[-1001.0, -1000.0, -998.0]);
        for i in 0..3 {
            assert!((a.probability(i) - b.probability(i)).abs() < 1e-12);
        }
    }

    #[test]
    fn roulette_frequencies_match_probabilities() {
        let w = Roulette::new(&[0.0, 3.0, 1.0, f64::INFINITY]);
        let mut rng = TrialSeed::from_u64(1).rng(0);
        let mut counts = [0usize; 4];
        let n = 200_000;
        for _ in 0..n {
            counts[w.pick(&mut rng)] += 1;
        }
        assert_eq!(counts[3], 0, "non-finite values are never selected");
        for (i, &c) in counts.iter().enumerate().take(3) {
            let p = w.probability(i);
            let sd = (p * (1.0 - p) / n as f64).sqrt();
            assert!(((c as f64 / n as f64) - p).abs() < 5.0 * sd, "{i}: {c}");
        }
    }

    #[test]
    fn roulette_with_nothing_finite_is_uniform() {
        let w = Roulette::new(&[f64::INFINITY; 4]);
        assert!((w.probability(2) - 0.25).abs() < 1e-12);
    }

    #[test]
    fn crossover_is_convex() {
        let (mut c1, mut c2) = ([0.0; 2], [0.0; 2]);
        arithmetic_crossover(0.25, &[0.0, 4.0], &[8.0, 0.0], &mut c1, &mut c2);
        assert_eq!(c1, [6.0, 1.0]);
        assert_eq!(c2, [2.0, 3.0]);
    }

    #[test]
    fn mutation_respects_bounds_and_rate() {
        let b = Bounds::uniform(1000, -1.0, 2.0).unwrap();
        let mut rng = TrialSeed::from_u64(2).rng(0);
        for m in [Mutation::Uniform, Mutation::Gaussian { sigma: 0.5 }] {
            let mut x = vec![1.5; 1000];
            m.apply(&mut x, &b, 0.1, &mut rng);
            assert!(b.contains(&x));
            let changed = x.iter().filter(|&&v| v != 1.5).count();
            assert!((60..=140).contains(&changed), "{m:?}: {changed}");
        }
    }

    #[test]
    fn ranking_is_stable_and_puts_nan_last() {
        assert_eq!(ranking(&[2.0, f64::INFINITY, 1.0, 2.0]), vec![2, 0, 3, 1]);
    }
}
