//! Back-propagation baseline: gradient descent with a momentum term,
//! `dp(k) = -eta * grad J(p(k)) + mu * dp(k-1)` (the update of dissertation eq. 4.6-4.8), on the
//! objective's analytic gradient, one full-data gradient per iteration. Each iteration is
//! charged `1 + d` evaluations, the value and the `d` forward differences its gradient is
//! worth to a black-box method (see `harness/evaluator.rs`): at equal evaluations BP gets a
//! `1 + d`-th of the iterations a population method gets points, and the remainder of a
//! budget too small for a gradient is spent on plain values of the last point, so the
//! budget is spent exactly. The start point is uniform in the box (from the trial's stream); steps
//! that leave the box are clipped to it. The rate adapts by the classic "bold driver" rule
//! for back-propagation (Vogl et al. 1988): a step that increases the cost is undone, the
//! rate halved and the momentum reset; a step that decreases it grows the rate by 5 %. The
//! dissertation uses a fixed rate; without the adaptation a fixed rate either diverges or crawls, and
//! a baseline should be a fair one.

use crate::base::TrialSeed;
use crate::harness::{Evaluator, Optimizer, OptimizerConfig};
use crate::objective::Bounds;

/// Settings of the gradient-descent (BP) baseline.
#[derive(Debug, Clone)]
pub struct GradientConfig {
    pub learning_rate: f64,
    pub momentum: f64,
}

impl Default for GradientConfig {
    fn default() -> Self {
        GradientConfig {
            learning_rate: 0.01,
            momentum: 0.9,
        }
    }
}

impl OptimizerConfig for GradientConfig {
    fn batch_size(&self) -> usize {
        1
    }

    fn needs_gradient(&self) -> bool {
        true
    }

    fn start(&self, bounds: &Bounds, _budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        let mut rng = seed.rng(0);
        let mut x = vec![0.0; bounds.dim()];
        bounds.sample(&mut rng, &mut x);
        Box::new(Gradient {
            bounds: bounds.clone(),
            eta: self.learning_rate,
            mu: self.momentum,
            step: vec![0.0; x.len()],
            grad: vec![0.0; x.len()],
            last: f64::INFINITY,
            prev_x: x.clone(),
            x,
        })
    }
}

struct Gradient {
    bounds: Bounds,
    eta: f64,
    mu: f64,
    x: Vec<f64>,
    prev_x: Vec<f64>,
    step: Vec<f64>,
    grad: Vec<f64>,
    last: f64,
}

impl Optimizer for Gradient {
    fn step(&mut self, ev: &mut Evaluator) {
        let Some(f) = ev.evaluate_with_gradient(&self.x, &mut self.grad) else {
            // Fewer evaluations left than a gradient costs (or no gradient): spend them as
            // plain values, so the run ends on its budget.
            ev.evaluate(&self.x);
            return;
        };
        if f > self.last {
            // Overshoot: go back, halve the rate, forget the momentum.
            self.x.copy_from_slice(&self.prev_x);
            self.eta *= 0.5;
            self.step.fill(0.0);
            return;
        }
        if f < self.last {
            self.eta *= 1.05;
        }
        self.last = f;
        self.prev_x.copy_from_slice(&self.x);
        for i in 0..self.x.len() {
            self.step[i] = -self.eta * self.grad[i] + self.mu * self.step[i];
            self.x[i] += self.step[i];
        }
        self.bounds.clamp(&mut self.x);
    }
}
