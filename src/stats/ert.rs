//! Success rate and expected running time (ERT) to a target value, as defined by COCO
//! (Hansen et al., "COCO: Performance Assessment", arXiv:1605.03560).
//!
//! ERT answers "how many evaluations does this optimizer need, on average, to reach the
//! target, counting restarts after failures": unlike a median of final values, it combines
//! speed and reliability in one number that stays comparable across budgets.

use crate::harness::TrialRecord;
use serde::{Deserialize, Serialize};

/// One run's outcome against one target.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunToTarget {
    /// Evaluation (1-based count) at which the target was first reached, if it was.
    pub hit_at: Option<u64>,
    /// Evaluations the run spent in total (at least `hit_at`).
    pub evaluations: u64,
}

impl RunToTarget {
    /// The outcome of a stored trial against `threshold_value`, a value of the objective
    /// (e.g. `optimum + 1e-8`), not an error.
    pub fn from_record(record: &TrialRecord, threshold_value: f64) -> Self {
        RunToTarget {
            hit_at: first_hit(&record.improvements, threshold_value),
            evaluations: record.evaluations,
        }
    }
}

/// Success rate and ERT of a set of runs on one target.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ert {
    pub successes: usize,
    pub trials: usize,
    /// `successes / trials`.
    pub success_rate: f64,
    /// Expected evaluations to reach the target; `None` (infinite) when no run reached it.
    pub ert: Option<f64>,
}

/// ERT = (evaluations to the target summed over successful runs + all evaluations of the
/// failed runs) / number of successes, and the success rate.
///
/// Failed runs are charged their whole budget because ERT models restarting the optimizer
/// until it succeeds; with every run successful it is the mean hitting time. With no success
/// it is infinite (`None`), which orders after every finite ERT. Panics if `runs` is empty or
/// a run's `hit_at` exceeds its `evaluations`.
pub fn ert(runs: &[RunToTarget]) -> Ert {
    assert!(!runs.is_empty(), "ERT of no runs");
    let mut successes = 0;
    let mut spent: u128 = 0;
    for r in runs {
        match r.hit_at {
            Some(h) => {
                assert!(
                    h <= r.evaluations,
                    "run hit the target at evaluation {h} but spent only {}",
                    r.evaluations
                );
                successes += 1;
                spent += u128::from(h);
            }
            None => spent += u128::from(r.evaluations),
        }
    }
    Ert {
        successes,
        trials: runs.len(),
        success_rate: successes as f64 / runs.len() as f64,
        ert: (successes > 0).then(|| spent as f64 / successes as f64),
    }
}

/// The evaluation at which a best-so-far trace first reached `<= threshold_value`, or `None`.
///
/// `improvements` is `(evaluation, best-so-far)` in ascending evaluations, as
/// [`TrialRecord::improvements`]; since it records every improvement, the first entry at or
/// below the threshold is exactly when the run hit it.
pub fn first_hit(improvements: &[(u64, f64)], threshold_value: f64) -> Option<u64> {
    improvements
        .iter()
        .find(|&&(_, v)| v <= threshold_value)
        .map(|&(e, _)| e)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(hit_at: Option<u64>, evaluations: u64) -> RunToTarget {
        RunToTarget {
            hit_at,
            evaluations,
        }
    }

    #[test]
    fn ert_with_failures() {
        // Successes at 100, 250, 400; two failures of 1000 evaluations each:
        // (100 + 250 + 400 + 1000 + 1000) / 3 = 2750 / 3.
        let runs = [
            run(Some(100), 180),
            run(Some(250), 250),
            run(None, 1000),
            run(None, 1000),
            run(Some(400), 1000),
        ];
        let e = ert(&runs);
        assert_eq!((e.successes, e.trials), (3, 5));
        assert_eq!(e.success_rate, 0.6);
        assert_eq!(e.ert, Some(2750.0 / 3.0));
    }

    #[test]
    fn ert_all_successes_is_mean_hitting_time() {
        let e = ert(&[run(Some(10), 10), run(Some(30), 50)]);
        assert_eq!((e.success_rate, e.ert), (1.0, Some(20.0)));
    }

    #[test]
    fn ert_without_success_is_infinite() {
        let e = ert(&[run(None, 500), run(None, 500)]);
        assert_eq!((e.successes, e.trials, e.success_rate), (0, 2, 0.0));
        assert_eq!(e.ert, None);
    }

    #[test]
    #[should_panic(expected = "spent only")]
    fn ert_refuses_hit_after_the_end() {
        ert(&[run(Some(11), 10)]);
    }

    #[test]
    fn first_hit_on_a_trace() {
        let trace = [(1, 9.0), (2, 4.0), (7, 1e-3), (40, 1e-9)];
        assert_eq!(first_hit(&trace, 5.0), Some(2));
        assert_eq!(first_hit(&trace, 4.0), Some(2)); // <= includes equality
        assert_eq!(first_hit(&trace, 1e-2), Some(7));
        assert_eq!(first_hit(&trace, 1e-8), Some(40));
        assert_eq!(first_hit(&trace, 1e-10), None);
        assert_eq!(first_hit(&trace, 100.0), Some(1));
        assert_eq!(first_hit(&[], 1.0), None);
    }

    #[test]
    fn from_a_trial_record() {
        let record = TrialRecord {
            objective: "sphere-2d".into(),
            optimizer: "GA".into(),
            trial: 0,
            seed: String::new(),
            budget: 100,
            evaluations: 100,
            best: 1e-9,
            best_x: vec![0.0, 0.0],
            optimum: Some(0.0),
            stopped_at_target: false,
            nonfinite: 0,
            penalised: 0,
            wall_s: 0.0,
            improvements: vec![(1, 3.0), (5, 0.5), (60, 1e-9)],
            checkpoints: vec![],
        };
        let hit = RunToTarget::from_record(&record, 1e-8);
        assert_eq!(hit, run(Some(60), 100));
        let miss = RunToTarget::from_record(&record, 1e-12);
        assert_eq!(miss, run(None, 100));
        let e = ert(&[hit, miss]);
        assert_eq!(e.ert, Some(160.0));
    }
}
