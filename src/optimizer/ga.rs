//! Real-coded genetic algorithm, the dissertation's "classical GA" (section 2.3.3): roulette-wheel
//! selection ([`Roulette`]), arithmetic crossover with probability `pc`, per-gene mutation
//! with probability `pm`, and optional elitism. Generational: each generation replaces the
//! whole population except the `elite` best, which are carried over unevaluated.

use super::operators::{Mutation, Roulette, arithmetic_crossover, ranking};
use crate::base::TrialSeed;
use crate::harness::{Evaluator, Optimizer, OptimizerConfig};
use crate::objective::Bounds;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// GA settings. Defaults follow the dissertation's Table 3.1 (which the dissertation applies to GA too).
#[derive(Debug, Clone)]
pub struct GaConfig {
    pub population: usize,
    pub pc: f64,
    pub pm: f64,
    pub elite: usize,
    pub mutation: Mutation,
}

impl Default for GaConfig {
    fn default() -> Self {
        GaConfig {
            population: 200,
            pc: 0.9,
            pm: 0.1,
            elite: 1,
            mutation: Mutation::Uniform,
        }
    }
}

impl OptimizerConfig for GaConfig {
    fn batch_size(&self) -> usize {
        self.population - self.elite
    }

    fn start(&self, bounds: &Bounds, _budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        Box::new(Ga {
            cfg: self.clone(),
            bounds: bounds.clone(),
            rng: seed.rng(0),
            pop: Vec::new(),
            fit: Vec::new(),
            next: Vec::new(),
            next_fit: Vec::new(),
            wheel: Roulette::default(),
            c1: vec![0.0; bounds.dim()],
            c2: vec![0.0; bounds.dim()],
        })
    }
}

struct Ga {
    cfg: GaConfig,
    bounds: Bounds,
    rng: ChaCha8Rng,
    pop: Vec<f64>,
    fit: Vec<f64>,
    next: Vec<f64>,
    next_fit: Vec<f64>,
    wheel: Roulette,
    /// Crossover children, reused across generations.
    c1: Vec<f64>,
    c2: Vec<f64>,
}

impl Optimizer for Ga {
    fn step(&mut self, ev: &mut Evaluator) {
        let d = self.bounds.dim();
        let n = self.cfg.population;
        if self.pop.is_empty() {
            self.pop = vec![0.0; n * d];
            for x in self.pop.chunks_exact_mut(d) {
                self.bounds.sample(&mut self.rng, x);
            }
            self.fit = vec![0.0; n];
            ev.evaluate_batch(&self.pop, &mut self.fit);
            return;
        }

        self.wheel.rebuild(&self.fit);
        self.next.clear();
        self.next_fit.clear();
        for &i in ranking(&self.fit).iter().take(self.cfg.elite) {
            self.next.extend_from_slice(&self.pop[i * d..(i + 1) * d]);
            self.next_fit.push(self.fit[i]);
        }
        let (c1, c2) = (&mut self.c1, &mut self.c2);
        while self.next.len() < n * d {
            let a = self.wheel.pick(&mut self.rng);
            let b = self.wheel.pick(&mut self.rng);
            let (pa, pb) = (&self.pop[a * d..(a + 1) * d], &self.pop[b * d..(b + 1) * d]);
            if self.rng.random::<f64>() < self.cfg.pc {
                let alpha: f64 = self.rng.random();
                arithmetic_crossover(alpha, pa, pb, c1, c2);
            } else {
                c1.copy_from_slice(pa);
                c2.copy_from_slice(pb);
            }
            for c in [&mut *c1, &mut *c2] {
                self.cfg
                    .mutation
                    .apply(c, &self.bounds, self.cfg.pm, &mut self.rng);
            }
            self.next.extend_from_slice(c1);
            if self.next.len() < n * d {
                self.next.extend_from_slice(c2);
            }
        }
        let e = self.cfg.elite;
        self.next_fit.resize(n, 0.0);
        ev.evaluate_batch(&self.next[e * d..], &mut self.next_fit[e..]);
        std::mem::swap(&mut self.pop, &mut self.next);
        std::mem::swap(&mut self.fit, &mut self.next_fit);
    }
}
