//! The stored result of one trial, as the trial loop writes it and every stage after it
//! (store, statistics, report) reads it.

use crate::objective::Presentation;
use serde::{Deserialize, Deserializer, Serialize};

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
    pub fn presented(&self, p: &Presentation) -> TrialRecord {
        let mut r = self.clone();
        r.best = p.apply(r.best);
        r.optimum = None;
        for v in r.improvements.iter_mut().chain(r.checkpoints.iter_mut()) {
            v.1 = p.apply(v.1);
        }
        r
    }
}
