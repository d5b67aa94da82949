//! What an optimizer is: a configuration that starts a running state per trial, and the
//! state's one step. Beside the [`Evaluator`] the step is handed, below both the
//! optimizers that implement it and the trial loop that drives it.

use super::Evaluator;
use crate::base::TrialSeed;
use crate::objective::Bounds;
use std::fmt;

/// The running state of one optimizer in one trial.
pub trait Optimizer: Send {
    /// One iteration (generation). Must spend at least one evaluation unless
    /// [`Evaluator::done`]; stopping is the harness's decision, not the optimizer's.
    fn step(&mut self, ev: &mut Evaluator);
}

/// A validated optimizer configuration: the recipe for a fresh [`Optimizer`] per trial.
pub trait OptimizerConfig: Send + Sync + fmt::Debug {
    /// Evaluations spent per iteration, to translate budgets into iterations.
    fn batch_size(&self) -> usize;

    /// Whether the optimizer needs the objective's gradient (a suite pairing it with a
    /// black-box objective is refused before anything runs).
    fn needs_gradient(&self) -> bool {
        false
    }

    /// A new optimizer for one trial over `bounds`, drawing every random number from
    /// `seed`'s streams. `budget` lets schedules (PSO's inertia) span the whole run.
    fn start(&self, bounds: &Bounds, budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer>;
}
