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
    /// (evaluation, best-so-far) at log-spaced evaluation counts and at the end (+inf
    /// before the first value: a gradient method's first value comes after its gradient's
    /// evaluations).
    #[serde(deserialize_with = "pairs_or_inf")]
    pub checkpoints: Vec<(u64, f64)>,
}

/// JSON has no infinity: serde_json writes it as null, so null reads back as +inf.
fn f64_or_inf<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
}

/// [`f64_or_inf`] for the values of (evaluation, value) pairs.
fn pairs_or_inf<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<(u64, f64)>, D::Error> {
    Ok(Vec::<(u64, Option<f64>)>::deserialize(d)?
        .into_iter()
        .map(|(e, v)| (e, v.unwrap_or(f64::INFINITY)))
        .collect())
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
        assert!(line.contains("[1,null]"), "{line}");
        assert_eq!(serde_json::from_str::<TrialRecord>(&line).unwrap(), r);
    }
}
