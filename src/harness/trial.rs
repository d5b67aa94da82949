//! One trial: an optimizer against an objective for a budget, from one seed.

use super::{Evaluator, Stall};
use crate::base::TrialSeed;
use crate::objective::Objective;
use crate::optimizer::OptimizerConfig;
use serde::{Deserialize, Deserializer, Serialize};
use std::sync::Arc;
use std::time::Instant;

/// Everything a trial needs.
pub struct TrialSpec<'a> {
    pub objective_id: &'a str,
    pub optimizer_id: &'a str,
    pub trial: usize,
    pub objective: Arc<dyn Objective>,
    pub optimizer: &'a dyn OptimizerConfig,
    pub budget: u64,
    /// End the trial once a value <= this is seen.
    pub stop_value: Option<f64>,
    /// End the trial once the best value has stalled (a local polish that has converged).
    pub stall: Option<Stall>,
    pub seed: TrialSeed,
}

/// The stored result of one trial: one line of `traces.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrialRecord {
    pub objective: String,
    pub optimizer: String,
    pub trial: usize,
    /// Hex key of the trial's random streams.
    pub seed: String,
    pub budget: u64,
    pub evaluations: u64,
    #[serde(deserialize_with = "f64_or_inf")]
    pub best: f64,
    pub best_x: Vec<f64>,
    /// Known optimum of the objective, if any.
    pub optimum: Option<f64>,
    pub stopped_at_target: bool,
    /// Evaluations that returned NaN or an infinity.
    pub nonfinite: u64,
    /// Evaluations answered with a penalty (unstable model parameters and the like).
    #[serde(default)]
    pub penalised: u64,
    /// Wall-clock seconds; recorded, never used as a budget.
    pub wall_s: f64,
    /// (evaluation, best-so-far) at every improvement.
    pub improvements: Vec<(u64, f64)>,
    /// (evaluation, best-so-far) at log-spaced evaluation counts and at the end.
    pub checkpoints: Vec<(u64, f64)>,
}

/// JSON has no infinity: serde_json writes it as null, so null reads back as +inf.
fn f64_or_inf<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
}

impl TrialRecord {
    /// This record with every value mapped by `p` (e.g. a fitting cost shown as an RMSE);
    /// the optimum is then unknown in the new units.
    pub fn presented(&self, p: &crate::objective::Presentation) -> TrialRecord {
        let mut r = self.clone();
        r.best = p.apply(r.best);
        r.optimum = None;
        for v in r.improvements.iter_mut().chain(r.checkpoints.iter_mut()) {
            v.1 = p.apply(v.1);
        }
        r
    }
}

/// Runs one trial: the executor loop. The optimizer steps until the evaluator says done.
pub fn run_trial(spec: TrialSpec<'_>) -> TrialRecord {
    let start = Instant::now();
    let mut optimizer = spec
        .optimizer
        .start(spec.objective.bounds(), spec.budget, &spec.seed);
    let mut ev = Evaluator::new(Arc::clone(&spec.objective), spec.budget, spec.stop_value)
        .with_stall(spec.stall);
    while !ev.done() {
        let before = ev.used();
        optimizer.step(&mut ev);
        assert!(
            ev.used() > before || ev.done(),
            "optimizer {} spent no evaluation in a step",
            spec.optimizer_id
        );
    }
    drop(optimizer);
    let trace = ev.finish();
    TrialRecord {
        objective: spec.objective_id.to_string(),
        optimizer: spec.optimizer_id.to_string(),
        trial: spec.trial,
        seed: spec.seed.hex(),
        budget: spec.budget,
        evaluations: trace.evaluations,
        best: trace.best,
        best_x: trace.best_x,
        optimum: spec.objective.optimum(),
        stopped_at_target: trace.stopped_at_target,
        nonfinite: trace.nonfinite,
        penalised: trace.penalised,
        wall_s: start.elapsed().as_secs_f64(),
        improvements: trace.improvements,
        checkpoints: trace.checkpoints,
    }
}
