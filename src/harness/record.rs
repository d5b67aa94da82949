//! The stored result of one trial, as the trial loop writes it and every stage after it
//! (store, statistics, report) reads it.

use crate::objective::Presentation;
use serde::{Deserialize, Serialize};

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
    /// +inf while no finite value was seen; infinities are stored as "inf"/"-inf" (see
    /// [`crate::base::json_float`]).
    #[serde(with = "crate::base::json_float::one")]
    pub best: f64,
    #[serde(with = "crate::base::json_float::many")]
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
    #[serde(with = "crate::base::json_float::pairs")]
    pub improvements: Vec<(u64, f64)>,
    /// (evaluation, best-so-far) at log-spaced evaluation counts and at the end (+inf
    /// before the first value: a gradient method's first value comes after its gradient's
    /// evaluations).
    #[serde(with = "crate::base::json_float::pairs")]
    pub checkpoints: Vec<(u64, f64)>,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn infinite_values_survive_json() {
        let r = TrialRecord {
            objective: "o".into(),
            optimizer: "bp".into(),
            trial: 0,
            seed: "00".into(),
            budget: 8,
            evaluations: 8,
            best: 0.5,
            best_x: vec![0.0],
            optimum: None,
            stopped_at_target: false,
            nonfinite: 0,
            penalised: 0,
            wall_s: 0.0,
            improvements: vec![(4, 0.5)],
            checkpoints: vec![(1, f64::INFINITY), (4, 0.5), (8, 0.5)],
        };
        let line = serde_json::to_string(&r).unwrap();
        assert!(line.contains(r#"[1,"inf"]"#), "{line}");
        assert_eq!(serde_json::from_str::<TrialRecord>(&line).unwrap(), r);
        // An objective that overflows downwards: -inf keeps its sign and reads back.
        let r = TrialRecord {
            best: f64::NEG_INFINITY,
            improvements: vec![(1, f64::NEG_INFINITY)],
            checkpoints: vec![(1, f64::NEG_INFINITY), (8, f64::NEG_INFINITY)],
            ..r
        };
        let line = serde_json::to_string(&r).unwrap();
        assert!(line.contains(r#""best":"-inf""#), "{line}");
        assert_eq!(serde_json::from_str::<TrialRecord>(&line).unwrap(), r);
    }
}
