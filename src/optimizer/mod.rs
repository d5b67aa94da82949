//! Optimizers. An optimizer transforms its own state one iteration at a time and spends
//! evaluations only through the [`Evaluator`] it is handed; the harness owns the loop, the
//! budget, the trace and the random streams. Optimizers know nothing of files or suites.

pub mod cmaes;
pub mod de;
pub mod ga;
pub mod gradient;
pub mod lbfgs;
pub mod levenberg_marquardt;
pub mod msga;
pub mod nelder_mead;
pub mod operators;
pub mod pso;
pub mod random_search;

use crate::base::TrialSeed;
use crate::harness::Evaluator;
use crate::objective::Bounds;
use std::fmt;

/// `Σ aᵢ bᵢ`, in order (the local searches' inner products).
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

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

/// The local search named by a suite's `polish_with` (None: Nelder-Mead).
pub fn polish_method(name: Option<&str>) -> Result<nelder_mead::LocalSearch, String> {
    match name {
        None | Some("nelder-mead") => Ok(nelder_mead::LocalSearch::default()),
        Some("lbfgs") => Ok(nelder_mead::LocalSearch::Lbfgs(
            lbfgs::LbfgsConfig::default(),
        )),
        Some(other) => Err(format!(
            "`polish_with` = \"{other}\": expected \"nelder-mead\" or \"lbfgs\""
        )),
    }
}
