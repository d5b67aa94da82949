//! The numbers of a report, computed from stored traces only (no rerun).
//!
//! Per objective x optimizer: the final errors' summary (type-7 quartiles), a seeded 95 %
//! percentile-bootstrap confidence interval of the median, and for each target the success
//! rate and ERT. Per objective: every pair of optimizers compared by a two-sided
//! Mann-Whitney U test with Holm's correction over the pairs, and the Vargha-Delaney A12
//! effect size. Across objectives: average ranks of the medians and Friedman's test.
//!
//! "Error" is the final value minus the known optimum (clipped at 0 against rounding in
//! the optimum), or the value itself where no optimum is known (fitting costs).

use crate::base::{SafeName, TrialSeed};
use crate::harness::TrialRecord;
use crate::objective::Metric;
use crate::stats::{
    Describe, Ert, Friedman, RunToTarget, a12, bootstrap_median_ci, describe, ert, friedman, holm,
    mann_whitney,
};
use serde::Serialize;

/// Confidence level of the bootstrap intervals.
pub const CI_LEVEL: f64 = 0.95;
/// Bootstrap resamples per interval.
pub const RESAMPLES: usize = 2000;
/// Significance level for markers in tables (after Holm).
pub const ALPHA: f64 = 0.05;

/// What the report needs to know of each objective beyond the traces.
#[derive(Debug, Clone)]
pub struct ObjectiveInfo {
    pub id: SafeName,
    pub dim: usize,
    pub targets: Vec<f64>,
    /// What the values are (e.g. `train free-run RMSE [mm]`); None: the objective's value.
    pub label: Option<String>,
}

/// Metrics of one trial's final point, keyed by (objective, optimizer, trial).
pub type TrialMetrics = std::collections::BTreeMap<(String, String, usize), Vec<Metric>>;

/// Median and 95 % interval of one metric over a cell's trials.
#[derive(Debug, Clone, Serialize)]
pub struct MetricStats {
    pub name: String,
    pub stats: Describe,
    pub median_ci: (f64, f64),
}

/// The error of a value with respect to an optional optimum.
pub fn error_of(value: f64, optimum: Option<f64>) -> f64 {
    match optimum {
        Some(o) => (value - o).max(0.0),
        None => value,
    }
}

/// Best-so-far of a trace after exactly `evals` evaluations (+inf before the first).
pub fn best_at(improvements: &[(u64, f64)], evals: u64) -> f64 {
    let i = improvements.partition_point(|&(e, _)| e <= evals);
    if i == 0 {
        f64::INFINITY
    } else {
        improvements[i - 1].1
    }
}

/// One optimizer on one objective.
#[derive(Debug, Clone, Serialize)]
pub struct CellStats {
    pub optimizer: String,
    pub errors: Vec<f64>,
    pub stats: Describe,
    /// 95 % bootstrap interval of the median error.
    pub median_ci: (f64, f64),
    /// Per target (in the objective's order): success rate and ERT.
    pub targets: Vec<Ert>,
    pub evaluations: u64,
    pub wall_s: f64,
    /// Statistics of the objective's metrics at the trials' final points.
    pub metrics: Vec<MetricStats>,
    /// Wall seconds per trial ([`FIT_TIME`], for paper tables that ask for it); left out of
    /// the analysis files, which stay identical from run to run.
    #[serde(skip)]
    pub fit_time: MetricStats,
}
pub use crate::pipeline::suite::FIT_TIME;

/// A comparison of two optimizers on one objective.
#[derive(Debug, Clone, Serialize)]
pub struct PairTest {
    pub a: String,
    pub b: String,
    pub p_value: f64,
    /// Holm-adjusted over all pairs of the objective.
    pub p_holm: f64,
    /// P(error_a > error_b) + 0.5 P(equal): below 0.5, `a` tends to be better.
    pub a12: f64,
}

/// Everything about one objective.
#[derive(Debug, Clone, Serialize)]
pub struct ObjectiveStats {
    pub id: SafeName,
    pub dim: usize,
    pub label: Option<String>,
    pub optimum: Option<f64>,
    pub budget: u64,
    pub targets: Vec<f64>,
    pub cells: Vec<CellStats>,
    pub pairs: Vec<PairTest>,
    /// Index in `cells` of the lowest median error (ties: the lower mean).
    pub best: usize,
    /// Evaluation counts of the fixed-budget view and, per cell, the median error there.
    pub fixed_budgets: Vec<u64>,
    pub fixed_budget_medians: Vec<Vec<f64>>,
}

impl ObjectiveStats {
    /// The test between the best optimizer and cell `i` (None for the best itself).
    pub fn versus_best(&self, i: usize) -> Option<&PairTest> {
        if i == self.best {
            return None;
        }
        let (a, b) = (&self.cells[self.best].optimizer, &self.cells[i].optimizer);
        self.pairs
            .iter()
            .find(|p| (&p.a == a && &p.b == b) || (&p.a == b && &p.b == a))
    }
}

/// The whole analysis of a results folder.
#[derive(Debug, Clone, Serialize)]
pub struct Analysis {
    pub suite: String,
    pub seed: u64,
    pub optimizers: Vec<String>,
    pub objectives: Vec<ObjectiveStats>,
    /// Average rank of each optimizer over the objectives (by median error), and Friedman's
    /// test; None with fewer than two objectives or optimizers.
    pub friedman: Option<Friedman>,
}

/// Fixed-budget evaluation counts: 1 %, 10 % and 100 % of the budget (distinct, >= 1).
pub fn fixed_budgets(budget: u64) -> Vec<u64> {
    let mut v: Vec<u64> = [budget / 100, budget / 10, budget]
        .into_iter()
        .map(|b| b.max(1))
        .collect();
    v.dedup();
    v
}

/// Analyses `records` (any order) of a suite with the given objectives.
pub fn analyse(
    suite: &str,
    seed: u64,
    objectives: &[ObjectiveInfo],
    records: &[TrialRecord],
    metrics: &TrialMetrics,
) -> Analysis {
    let mut optimizers: Vec<String> = Vec::new();
    for r in records {
        if !optimizers.contains(&r.optimizer) {
            optimizers.push(r.optimizer.clone());
        }
    }
    let mut out = Vec::new();
    for info in objectives {
        let of_obj: Vec<&TrialRecord> = records.iter().filter(|r| r.objective == info.id).collect();
        if of_obj.is_empty() {
            continue;
        }
        // Each run's own optimum: with an `instances` list every trial has its instance's.
        let optimum = of_obj[0].optimum;
        let budget = of_obj.iter().map(|r| r.budget).max().unwrap_or(0);
        let fixed = fixed_budgets(budget);
        let mut cells = Vec::new();
        let mut fixed_medians = Vec::new();
        for opt in &optimizers {
            let mut runs: Vec<&TrialRecord> = of_obj
                .iter()
                .copied()
                .filter(|r| &r.optimizer == opt)
                .collect();
            if runs.is_empty() {
                continue;
            }
            runs.sort_by_key(|r| r.trial);
            let errors: Vec<f64> = runs.iter().map(|r| error_of(r.best, r.optimum)).collect();
            let mut rng = TrialSeed::derive(seed, &format!("report:{}", info.id), opt, 0).rng(0);
            let median_ci = bootstrap_median_ci(&errors, CI_LEVEL, RESAMPLES, &mut rng);
            let targets = info
                .targets
                .iter()
                .map(|&t| {
                    let rt: Vec<RunToTarget> = runs
                        .iter()
                        .map(|r| RunToTarget::from_record(r, r.optimum.unwrap_or(0.0) + t))
                        .collect();
                    ert(&rt)
                })
                .collect();
            let metric_stats = cell_metrics(seed, &info.id, opt, &runs, metrics);
            fixed_medians.push(
                fixed
                    .iter()
                    .map(|&b| {
                        let at: Vec<f64> = runs
                            .iter()
                            .map(|r| error_of(best_at(&r.improvements, b), r.optimum))
                            .collect();
                        describe(&at).median
                    })
                    .collect(),
            );
            cells.push(CellStats {
                optimizer: opt.clone(),
                stats: describe(&errors),
                errors,
                median_ci,
                targets,
                evaluations: runs.iter().map(|r| r.evaluations).sum(),
                wall_s: runs.iter().map(|r| r.wall_s).sum(),
                metrics: metric_stats,
                fit_time: wall_stats(seed, &info.id, opt, &runs),
            });
        }
        let mut pairs = Vec::new();
        for i in 0..cells.len() {
            for j in i + 1..cells.len() {
                let mw = mann_whitney(&cells[i].errors, &cells[j].errors);
                pairs.push(PairTest {
                    a: cells[i].optimizer.clone(),
                    b: cells[j].optimizer.clone(),
                    p_value: mw.p_value,
                    p_holm: f64::NAN,
                    a12: a12(&cells[i].errors, &cells[j].errors),
                });
            }
        }
        let adjusted = holm(&pairs.iter().map(|p| p.p_value).collect::<Vec<_>>());
        for (p, h) in pairs.iter_mut().zip(adjusted) {
            p.p_holm = h;
        }
        let best = (0..cells.len())
            .min_by(|&a, &b| {
                let (x, y) = (&cells[a].stats, &cells[b].stats);
                x.median
                    .total_cmp(&y.median)
                    .then(x.mean.total_cmp(&y.mean))
            })
            .unwrap_or(0);
        out.push(ObjectiveStats {
            id: info.id.clone(),
            dim: info.dim,
            label: info.label.clone(),
            optimum,
            budget,
            targets: info.targets.clone(),
            cells,
            pairs,
            best,
            fixed_budgets: fixed,
            fixed_budget_medians: fixed_medians,
        });
    }
    let complete = out.iter().all(|o| o.cells.len() == optimizers.len());
    let friedman = (out.len() >= 2 && optimizers.len() >= 2 && complete).then(|| {
        let blocks: Vec<Vec<f64>> = out
            .iter()
            .map(|o| o.cells.iter().map(|c| c.stats.median).collect())
            .collect();
        friedman(&blocks)
    });
    Analysis {
        suite: suite.to_string(),
        seed,
        optimizers,
        objectives: out,
        friedman,
    }
}

/// Per metric name (in first-trial order): statistics over the cell's trials.
/// Median and interval of a cell's wall seconds per trial.
fn wall_stats(seed: u64, objective: &str, optimizer: &str, runs: &[&TrialRecord]) -> MetricStats {
    let values: Vec<f64> = runs.iter().map(|r| r.wall_s).collect();
    let mut rng = TrialSeed::derive(seed, &format!("wall:{objective}"), optimizer, 0).rng(0);
    MetricStats {
        name: FIT_TIME.into(),
        stats: describe(&values),
        median_ci: bootstrap_median_ci(&values, CI_LEVEL, RESAMPLES, &mut rng),
    }
}

fn cell_metrics(
    seed: u64,
    objective: &str,
    optimizer: &str,
    runs: &[&TrialRecord],
    metrics: &TrialMetrics,
) -> Vec<MetricStats> {
    let per_trial: Vec<&Vec<Metric>> = runs
        .iter()
        .filter_map(|r| metrics.get(&(objective.to_string(), optimizer.to_string(), r.trial)))
        .collect();
    let Some(first) = per_trial.first() else {
        return Vec::new();
    };
    first
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let values: Vec<f64> = per_trial.iter().map(|t| t[i].value).collect();
            let mut rng = TrialSeed::derive(
                seed,
                &format!("metric:{objective}:{}", m.name),
                optimizer,
                0,
            )
            .rng(0);
            MetricStats {
                name: m.name.clone(),
                stats: describe(&values),
                median_ci: bootstrap_median_ci(&values, CI_LEVEL, RESAMPLES, &mut rng),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn best_so_far_at_any_count() {
        let imp = [(1, 9.0), (5, 4.0), (9, 1.0)];
        assert_eq!(best_at(&imp, 0), f64::INFINITY);
        assert_eq!(best_at(&imp, 1), 9.0);
        assert_eq!(best_at(&imp, 8), 4.0);
        assert_eq!(best_at(&imp, 100), 1.0);
    }

    #[test]
    fn errors_clip_rounding_below_the_optimum() {
        assert_eq!(
            error_of(-837.965_775_454_867_4, Some(-837.965_775_454_867_3)),
            0.0
        );
        assert_eq!(error_of(2.5, None), 2.5);
        assert_eq!(fixed_budgets(40_000), vec![400, 4000, 40_000]);
        assert_eq!(fixed_budgets(50), vec![1, 5, 50]);
    }

    /// Trials of one objective that ran different instances (COCO's `instances`) are
    /// measured against their own optimum: errors, targets and fixed budgets alike.
    #[test]
    fn each_trial_is_measured_against_its_own_optimum() {
        let rec = |trial: usize, optimum: f64, best: f64| TrialRecord {
            objective: "o".into(),
            optimizer: "p".into(),
            trial,
            seed: String::new(),
            budget: 10,
            evaluations: 10,
            best,
            best_x: vec![],
            optimum: Some(optimum),
            stopped_at_target: false,
            nonfinite: 0,
            penalised: 0,
            wall_s: 0.0,
            improvements: vec![(1, best + 5.0), (4, best)],
            checkpoints: vec![],
        };
        let info = ObjectiveInfo {
            id: SafeName::new("o").unwrap(),
            dim: 2,
            targets: vec![1.0],
            label: None,
        };
        let records = [rec(0, 10.0, 10.5), rec(1, -300.0, -299.0)];
        let a = analyse("s", 1, &[info], &records, &TrialMetrics::new());
        let cell = &a.objectives[0].cells[0];
        assert_eq!(cell.errors, [0.5, 1.0]);
        assert_eq!(cell.targets[0].successes, 2, "{:?}", cell.targets[0]);
        assert_eq!(a.objectives[0].fixed_budget_medians[0], [5.75, 0.75]);
    }
}
