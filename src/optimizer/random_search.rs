//! Uniform random search: the floor every method must beat.

use crate::base::TrialSeed;
use crate::harness::{Evaluator, Optimizer, OptimizerConfig};
use crate::objective::Bounds;
use rand_chacha::ChaCha8Rng;

/// Random search settings: points are drawn and evaluated in batches of `batch`.
#[derive(Debug, Clone)]
pub struct RandomSearchConfig {
    pub batch: usize,
}

impl Default for RandomSearchConfig {
    fn default() -> Self {
        RandomSearchConfig { batch: 200 }
    }
}

impl OptimizerConfig for RandomSearchConfig {
    fn batch_size(&self) -> usize {
        self.batch
    }

    fn start(&self, bounds: &Bounds, _budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        Box::new(RandomSearch {
            bounds: bounds.clone(),
            rng: seed.rng(0),
            points: vec![0.0; self.batch * bounds.dim()],
            values: vec![0.0; self.batch],
        })
    }
}

struct RandomSearch {
    bounds: Bounds,
    rng: ChaCha8Rng,
    points: Vec<f64>,
    values: Vec<f64>,
}

impl Optimizer for RandomSearch {
    fn step(&mut self, ev: &mut Evaluator) {
        for x in self.points.chunks_exact_mut(self.bounds.dim()) {
            self.bounds.sample(&mut self.rng, x);
        }
        ev.evaluate_batch(&self.points, &mut self.values);
    }
}
