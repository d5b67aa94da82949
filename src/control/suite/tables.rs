//! What a control suite's numbers become: each cell's statistics over the trials, the
//! paper-layout tables with the published numbers beside ours, the CSV of every cell and
//! the pairwise comparisons.

use super::ControlSuite;
use super::cell_index;
use super::run::{ControlResults, RunRecord};
use crate::base::TrialSeed;
use crate::pipeline::suite::PaperTable;
use crate::render::latex::{booktabs, latex_escape, latex_num, latex_sup, sentence};
use crate::render::table::{markdown, sig};
use crate::report::paper::layout_markdown;
use crate::stats::{a12, bootstrap_median_ci, describe, mann_whitney, wilcoxon};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;

/// Statistics of one cell (controller x plant x reference) over the trials.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellStats {
    pub controller: String,
    pub plant: String,
    pub reference: String,
    pub trials: usize,
    pub failures: usize,
    /// Median failure time (s) of the failed runs.
    pub median_failure_s: Option<f64>,
    pub rmse: MetricStats,
    pub rmse_steady: MetricStats,
}

/// Median [95 % bootstrap CI], quartiles and extremes of one metric; failed runs count as
/// +inf (so a median is finite only when fewer than half the runs failed).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MetricStats {
    pub median: f64,
    pub ci: (f64, f64),
    pub q1: f64,
    pub q3: f64,
    pub min: f64,
    pub max: f64,
}

/// Bootstrap resamples for the median intervals (as the report's).
pub(super) const RESAMPLES: usize = 2000;

fn metric_stats(values: &[f64], rng_key: TrialSeed) -> MetricStats {
    let d = describe(values);
    let ci = bootstrap_median_ci(values, 0.95, RESAMPLES, &mut rng_key.rng(0));
    MetricStats {
        median: d.median,
        ci,
        q1: d.q1,
        q3: d.q3,
        min: d.min,
        max: d.max,
    }
}

/// JSON has no infinity: failed runs' +inf is written as null.
pub(super) fn finite_or_inf(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::INFINITY)
}

/// Statistics of every (plant, controller, reference) cell, in plan order.
pub(super) fn cell_stats(suite: &ControlSuite, runs: &[RunRecord]) -> Vec<CellStats> {
    let mut cells = Vec::new();
    for p in &suite.plants {
        for &ci in &p.controllers {
            for &ri in &p.references {
                let (c, r) = (&suite.controllers[ci].id, &suite.references[ri].name);
                let v: Vec<&RunRecord> = runs
                    .iter()
                    .filter(|x| &x.controller == c && x.plant == p.id && &x.reference == r)
                    .collect();
                let key = |m: &str| {
                    TrialSeed::derive(
                        suite.seed,
                        &format!("bootstrap:{m}"),
                        &format!("{c}/{}/{r}", p.id),
                        0,
                    )
                };
                let rmse: Vec<f64> = v.iter().map(|x| finite_or_inf(x.metrics.rmse_mm)).collect();
                let steady: Vec<f64> = v
                    .iter()
                    .map(|x| finite_or_inf(x.metrics.rmse_steady_mm))
                    .collect();
                let mut fail_t: Vec<f64> = v
                    .iter()
                    .filter_map(|x| x.metrics.failure.as_ref().map(|f| f.time_s))
                    .collect();
                fail_t.sort_by(f64::total_cmp);
                cells.push(CellStats {
                    controller: c.to_string(),
                    plant: p.id.to_string(),
                    reference: r.clone(),
                    trials: v.len(),
                    failures: fail_t.len(),
                    median_failure_s: (!fail_t.is_empty())
                        .then(|| crate::stats::quantile_sorted(&fail_t, 0.5)),
                    rmse: metric_stats(&rmse, key("rmse")),
                    rmse_steady: metric_stats(&steady, key("rmse_steady")),
                });
            }
        }
    }
    cells
}

fn find_cell<'a>(res: &'a ControlResults, c: &str, p: &str, r: &str) -> Option<&'a CellStats> {
    res.cells
        .iter()
        .find(|x| x.controller == c && x.plant == p && x.reference == r)
}

/// "median [lo, hi]", with the failures when there are any.
pub(super) fn cell_text(s: &CellStats, steady: bool) -> String {
    let m = if steady { &s.rmse_steady } else { &s.rmse };
    let value = if m.median.is_finite() {
        let hi = if m.ci.1.is_finite() {
            sig(m.ci.1, 3)
        } else {
            "∞".into()
        };
        format!("{} [{}, {hi}]", sig(m.median, 3), sig(m.ci.0, 3))
    } else {
        "diverged".into()
    };
    if s.failures > 0 {
        let t = s
            .median_failure_s
            .map(|t| format!(", median at {} s", sig(t, 2)))
            .unwrap_or_default();
        format!("{value}; {}/{} diverged{t}", s.failures, s.trials)
    } else {
        value
    }
}

fn table_stats<'a>(
    suite: &ControlSuite,
    res: &'a ControlResults,
    c: &str,
) -> Option<&'a CellStats> {
    let (p, ci, ri) = cell_index(c, &suite.controllers, &suite.plants, &suite.references).ok()?;
    find_cell(
        res,
        &suite.controllers[ci].id,
        &suite.plants[p].id,
        &suite.references[ri].name,
    )
}

fn table_cell(
    t: &PaperTable,
    suite: &ControlSuite,
    res: &ControlResults,
    c: &str,
) -> Option<String> {
    let s = table_stats(suite, res, c)?;
    Some(cell_text(s, t.value.as_deref() == Some("rmse_steady")))
}

/// A cell for LaTeX, short enough for a printed column: the median, and as a superscript
/// `k/n` the runs that diverged (the interval and failure times are in the Markdown and
/// `cells.csv`).
fn latex_cell(s: &CellStats, steady: bool) -> String {
    let m = if steady { &s.rmse_steady } else { &s.rmse };
    let value = if m.median.is_finite() {
        latex_num(m.median)
    } else {
        "diverged".into()
    };
    if s.failures > 0 {
        latex_sup(&value, &format!("{}/{}", s.failures, s.trials))
    } else {
        value
    }
}

/// A paper-layout table: our median [95 % CI] over trials, the dissertation's number beside it.
pub fn table_markdown(t: &PaperTable, suite: &ControlSuite, res: &ControlResults) -> String {
    let what = if t.value.as_deref() == Some("rmse_steady") {
        format!("RMSE [mm] after the first {} s", suite.transient)
    } else {
        "RMSE [mm] over the whole run".to_string()
    };
    let heading = format!(
        "**{}** ({what}; ours: median [95% CI] over {} noise realisations and model fits, failed runs counted as +inf; the dissertation's single run in brackets)",
        t.title, suite.trials
    );
    layout_markdown(t, &heading, |c| table_cell(t, suite, res, c))
}

/// The same table in LaTeX (booktabs): ours, and the dissertation's number in parentheses.
pub fn table_latex(t: &PaperTable, suite: &ControlSuite, res: &ControlResults) -> String {
    let caption = format!(
        "{} Ours: median RMSE over {} trials, failed runs counted as $+\\infty$, with the \
         runs that diverged as a superscript $k/n$; the dissertation's single run in \
         parentheses.",
        latex_escape(&sentence(&t.title)),
        suite.trials
    );
    let mut body = String::new();
    for row in &t.rows {
        let cells: Vec<String> = row
            .cells
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let steady = t.value.as_deref() == Some("rmse_steady");
                let ours = table_stats(suite, res, c)
                    .map_or_else(|| "--".into(), |s| latex_cell(s, steady));
                match row.seed.get(i).copied().filter(|v| v.is_finite()) {
                    Some(v) => format!("{ours} ({})", latex_num(v)),
                    None => ours,
                }
            })
            .collect();
        writeln!(
            body,
            "{} & {} \\\\",
            latex_escape(&row.label),
            cells.join(" & ")
        )
        .unwrap();
    }
    booktabs(
        &format!("{} ({})", t.id, suite.name),
        &caption,
        &t.columns,
        &body,
    )
}

pub(super) fn cells_csv(cells: &[CellStats]) -> String {
    let mut s = String::from(
        "controller,plant,reference,trials,failures,rmse_median_mm,rmse_ci_lo,rmse_ci_hi,rmse_q1,rmse_q3,rmse_steady_median_mm,rmse_steady_ci_lo,rmse_steady_ci_hi\n",
    );
    for c in cells {
        writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{}",
            c.controller,
            c.plant,
            c.reference,
            c.trials,
            c.failures,
            c.rmse.median,
            c.rmse.ci.0,
            c.rmse.ci.1,
            c.rmse.q1,
            c.rmse.q3,
            c.rmse_steady.median,
            c.rmse_steady.ci.0,
            c.rmse_steady.ci.1
        )
        .unwrap();
    }
    s
}

/// The first controller of each plant against every other, on each reference: ratio of
/// median RMSEs, the two-sided Wilcoxon signed-rank p over trials (paired: both controllers
/// of a trial see the same noise realisation), the unpaired Mann-Whitney p beside it, A12
/// (probability that the first has the larger RMSE), and in how many paired trials the first
/// is better.
pub fn comparison_markdown(suite: &ControlSuite, res: &ControlResults) -> String {
    let mut rows = Vec::new();
    for p in &suite.plants {
        for &ri in &p.references {
            let r = &suite.references[ri].name;
            // The plant's first controller against each of the others.
            if let Some((&a, others)) = p.controllers.split_first() {
                for &b in others {
                    let (ca, cb) = (&suite.controllers[a].id, &suite.controllers[b].id);
                    let get = |c: &str| -> Vec<(usize, f64)> {
                        let mut v: Vec<&RunRecord> = res
                            .runs
                            .iter()
                            .filter(|x| x.controller == c && x.plant == p.id && &x.reference == r)
                            .collect();
                        v.sort_by_key(|x| x.trial);
                        v.iter()
                            .map(|x| (x.trial, finite_or_inf(x.metrics.rmse_mm)))
                            .collect()
                    };
                    let (ta, tb) = (get(ca), get(cb));
                    if ta.is_empty() || tb.is_empty() {
                        continue;
                    }
                    let va: Vec<f64> = ta.iter().map(|x| x.1).collect();
                    let vb: Vec<f64> = tb.iter().map(|x| x.1).collect();
                    // Pairs: the trials both controllers ran (all of them in a suite's plan).
                    let (pa, pb): (Vec<f64>, Vec<f64>) = ta
                        .iter()
                        .filter_map(|&(k, x)| tb.iter().find(|y| y.0 == k).map(|y| (x, y.1)))
                        .unzip();
                    let (ma, mb) = (describe(&va).median, describe(&vb).median);
                    let ratio = if ma.is_finite() && mb.is_finite() && ma > 0.0 {
                        sig(mb / ma, 3)
                    } else {
                        "—".into()
                    };
                    let mw = mann_whitney(&va, &vb);
                    let paired = if pa.is_empty() {
                        "—".into()
                    } else {
                        sig(wilcoxon(&pa, &pb).p_value, 2)
                    };
                    let wins = pa.iter().zip(&pb).filter(|(x, y)| x < y).count();
                    rows.push(vec![
                        p.id.to_string(),
                        r.clone(),
                        format!("{ca} vs {cb}"),
                        ratio,
                        paired,
                        sig(mw.p_value, 2),
                        format!("{:.2}", a12(&va, &vb)),
                        format!("{wins}/{}", pa.len()),
                    ]);
                }
            }
        }
    }
    let mut s = String::from(
        "**Pairwise comparisons** (RMSE over the whole run; ratio = median of the second / median of the first; p (Wilcoxon) = two-sided signed-rank test over the paired trials, the test to read: both controllers of a trial see the same noise realisation; p (MW) = unpaired Mann-Whitney, for comparison; A12 = P(first's RMSE > second's); wins = paired trials where the first is lower)\n\n",
    );
    s += &markdown(
        &[
            "plant",
            "reference",
            "pair",
            "ratio",
            "p (Wilcoxon)",
            "p (MW)",
            "A12",
            "first wins",
        ],
        &rows,
        &[false, false, false, true, true, true, true, true],
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::suite::SMALL;
    use std::path::Path;

    fn stats(median: f64) -> MetricStats {
        MetricStats {
            median,
            ci: (median * 0.9, median * 1.1),
            q1: median,
            q3: median,
            min: median,
            max: median,
        }
    }

    fn cell(c: &str, p: &str, failures: usize, rmse: f64) -> CellStats {
        CellStats {
            controller: c.into(),
            plant: p.into(),
            reference: "sine5".into(),
            trials: 3,
            failures,
            median_failure_s: (failures > 0).then_some(0.25),
            rmse: stats(rmse),
            rmse_steady: stats(rmse / 2.0),
        }
    }

    #[test]
    fn failed_runs_count_as_infinite_in_the_median_and_its_interval() {
        let key = TrialSeed::derive(1, "a", "b", 0);
        let s = metric_stats(&[1.0, 2.0, f64::INFINITY], key);
        assert_eq!((s.median, s.max), (2.0, f64::INFINITY));
        let s = metric_stats(&[1.0, f64::INFINITY, f64::INFINITY], key);
        assert_eq!(s.median, f64::INFINITY);
        assert_eq!(finite_or_inf(None), f64::INFINITY);
    }

    #[test]
    fn a_cell_reads_median_interval_and_failures() {
        assert_eq!(
            cell_text(&cell("P", "twin", 0, 0.02), false),
            "0.0200 [0.0180, 0.0220]"
        );
        assert_eq!(
            cell_text(&cell("P", "twin", 0, 0.02), true),
            "0.0100 [0.00900, 0.0110]"
        );
        assert_eq!(
            cell_text(&cell("P", "twin", 1, 0.02), false),
            "0.0200 [0.0180, 0.0220]; 1/3 diverged, median at 0.25 s"
        );
        assert_eq!(
            cell_text(&cell("P", "twin", 3, f64::INFINITY), false),
            "diverged; 3/3 diverged, median at 0.25 s"
        );
    }

    #[test]
    fn the_paper_table_puts_the_published_number_beside_ours() {
        let suite = ControlSuite::parse(SMALL, Path::new("c.toml")).unwrap();
        let res = ControlResults {
            runs: Vec::new(),
            models: Vec::new(),
            cells: vec![cell("PI", "twin", 0, 0.02)],
        };
        let md = table_markdown(&suite.tables[0], &suite, &res);
        assert!(
            md.starts_with(
                "**Table 1** (RMSE [mm] over the whole run; ours: median [95% CI] over 3 noise"
            ),
            "{md}"
        );
        // The first cell ran and has a published number; the second ran nowhere in `res`.
        let row = md.lines().find(|l| l.starts_with("| PI")).unwrap();
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        assert_eq!(
            cells[2..4],
            ["0.0200 [0.0180, 0.0220] (dissertation 0.0100)", "not run"],
            "{md}"
        );
        let tex = table_latex(&suite.tables[0], &suite, &res);
        assert!(tex.contains("$0.0200$ ($0.0100$) & --"), "{tex}");
        let failed = cell("PI", "twin", 3, f64::INFINITY);
        assert_eq!(latex_cell(&failed, false), "diverged$^{3/3}$");
        assert_eq!(
            latex_cell(&cell("PI", "twin", 1, 0.02), true),
            "${0.0100}^{1/3}$"
        );
        let csv = cells_csv(&res.cells);
        assert_eq!(csv.lines().count(), 2);
        assert!(
            csv.lines()
                .nth(1)
                .unwrap()
                .starts_with("PI,twin,sine5,3,0,0.02,")
        );
    }

    fn run(controller: &str, trial: usize, rmse: f64) -> RunRecord {
        RunRecord {
            controller: controller.into(),
            plant: "twin".into(),
            reference: "sine5".into(),
            trial,
            noise_seed: trial as u64,
            model_seed: None,
            metrics: crate::control::run::Metrics {
                rmse_mm: Some(rmse),
                rmse_steady_mm: Some(rmse),
                max_error_steady_mm: Some(rmse),
                feedback_rms_mm: 0.0,
                transient_s: 0.2,
                failure: None,
                model_free_run_rmse_mm: None,
            },
        }
    }

    #[test]
    fn comparisons_test_the_pairs_that_share_a_noise_realisation() {
        let text = SMALL.replace("trials = 3", "trials = 8");
        let suite = ControlSuite::parse(&text, Path::new("c.toml")).unwrap();
        // Trials spread widely (the noise), PI a little better in every one: a paired test
        // sees it, an unpaired one does not. Stored out of trial order on purpose.
        let mut runs = Vec::new();
        for k in (0..8).rev() {
            let level = 0.01 * (1 + k * k) as f64;
            runs.push(run("P", k, level + 0.001 * (k + 1) as f64));
            runs.push(run("PI", k, level));
        }
        let res = ControlResults {
            runs,
            models: Vec::new(),
            cells: Vec::new(),
        };
        let md = comparison_markdown(&suite, &res);
        let row = md.lines().find(|l| l.contains("P vs PI")).unwrap();
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        // plant, reference, pair, ratio, p (Wilcoxon), p (MW), A12, wins
        assert_eq!(cells[1..4], ["twin", "sine5", "P vs PI"], "{md}");
        // Exact: all 8 signs agree, 2 / 2^8.
        assert_eq!(cells[5], "0.0078", "{md}");
        let mw: f64 = cells[6].parse().unwrap();
        assert!(mw > 0.5, "{md}");
        assert_eq!(cells[8], "0/8", "the first (P) is never lower: {md}");
    }
}
