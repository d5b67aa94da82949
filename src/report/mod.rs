//! What optbench shows people, regenerated from a results folder's stored traces alone:
//! `report.md` and `tables/` (Markdown, LaTeX, CSV), `plots/` (SVG and PNG), `ioh/` (an
//! IOHprofiler export) and `analysis.json`. The same folder always gives the same bytes.

pub mod analysis;
pub mod coco;
pub mod html;
pub mod ioh;
pub mod paper;

use crate::base::error::{Error, Result};
use crate::base::{SafeName, atomic_write};
use crate::harness::TrialRecord;
use crate::pipeline::store::{FreshFolder, Provenance, read_traces};
use crate::pipeline::suite::Suite;
use crate::render::{
    self,
    table::{markdown, sig},
};
use crate::stats::{a12, describe, holm, mann_whitney};
use analysis::{Analysis, ObjectiveInfo, analyse, error_of};
use std::path::Path;

/// Number of log-spaced targets for the runtime ECDF when the suite gives none.
const DEFAULT_ECDF_TARGETS: usize = 31;

fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::Input(format!("{}: cannot read: {e}", path.display())))?;
    serde_json::from_str(&text).map_err(|e| Error::at(path, e.line(), e))
}

/// A results folder read back: the suite as run, its provenance and every trace.
pub struct StoredRun {
    pub suite: Suite,
    pub provenance: Provenance,
    /// The traces as stored (raw objective values).
    pub records: Vec<TrialRecord>,
    /// The traces in the units a reader sees: values mapped through the objective's
    /// presentation (a fitting cost becomes an RMSE), optimum then unknown.
    pub presented: Vec<TrialRecord>,
    /// Metrics of every trial's final point.
    pub metrics: analysis::TrialMetrics,
}

impl StoredRun {
    /// Reads `dir` as written by `optbench run`.
    pub fn load(dir: &Path) -> Result<StoredRun> {
        if !dir.is_dir() {
            return Err(Error::Input(format!(
                "{}: not a results folder (run `optbench run SUITE` first)",
                dir.display()
            )));
        }
        let suite = Suite::load(&dir.join("suite.toml"))?;
        let provenance: Provenance = read_json(&dir.join("provenance.json"))?;
        let records = read_traces(dir)?;
        let mut presented = Vec::with_capacity(records.len());
        let mut metrics = analysis::TrialMetrics::new();
        for r in &records {
            let Some(obj) = suite.objectives.iter().find(|o| o.id == r.objective) else {
                return Err(Error::Input(format!(
                    "{}: a trace names objective `{}`, which the suite does not have",
                    dir.display(),
                    r.objective
                )));
            };
            if !suite.optimizers.iter().any(|o| o.id == r.optimizer) {
                return Err(Error::Input(format!(
                    "{}: a trace names optimizer `{}`, which the suite does not have",
                    dir.display(),
                    r.optimizer
                )));
            }
            presented.push(match obj.objective.presentation() {
                Some(p) => r.presented(&p),
                None => r.clone(),
            });
            let m = obj.objective.metrics(&r.best_x);
            if !m.is_empty() {
                metrics.insert((r.objective.clone(), r.optimizer.clone(), r.trial), m);
            }
        }
        Ok(StoredRun {
            suite,
            provenance,
            records,
            presented,
            metrics,
        })
    }

    /// The objectives as the analysis needs them.
    pub fn objective_infos(&self) -> Vec<ObjectiveInfo> {
        self.suite
            .objectives
            .iter()
            .map(|o| ObjectiveInfo {
                id: o.id.clone(),
                dim: o.objective.dim(),
                targets: o.targets.clone(),
                label: o.objective.presentation().map(|p| p.label),
            })
            .collect()
    }

    pub fn analyse(&self) -> Analysis {
        analyse(
            &self.suite.name,
            self.provenance.seed,
            &self.objective_infos(),
            &self.presented,
            &self.metrics,
        )
    }
}

/// How many evaluations each objective x optimizer spent on penalised parameters (an
/// unstable model), in plan order; empty when none were.
fn penalised_markdown(records: &[TrialRecord]) -> String {
    let mut cells: Vec<(&str, &str, u64, u64)> = Vec::new();
    for r in records {
        match cells
            .iter_mut()
            .find(|c| c.0 == r.objective && c.1 == r.optimizer)
        {
            Some(c) => {
                c.2 += r.penalised;
                c.3 += r.evaluations;
            }
            None => cells.push((&r.objective, &r.optimizer, r.penalised, r.evaluations)),
        }
    }
    if cells.iter().all(|c| c.2 == 0) {
        return String::new();
    }
    let mut s = String::from(
        "## Penalised evaluations\n\nEvaluations whose parameters were unusable (e.g. an unstable model) and were answered with the objective's finite penalty instead of a fit, summed over trials:\n\n| objective | optimizer | penalised | of evaluations | share |\n| --- | --- | ---: | ---: | ---: |\n",
    );
    for (o, p, k, n) in cells.iter().filter(|c| c.2 > 0) {
        s += &format!(
            "| {o} | {p} | {k} | {n} | {:.2} % |\n",
            100.0 * *k as f64 / (*n).max(1) as f64
        );
    }
    s.push('\n');
    s
}

/// Writes every report file into `dir` and returns the main table (Markdown) to print.
pub fn generate(dir: &Path) -> Result<String> {
    let run = StoredRun::load(dir)?;
    let a = run.analyse();

    // Generated folders are written afresh and swapped in: nothing of an earlier report
    // (an objective no longer in the suite, an optimizer removed) survives.
    let fresh_tables = FreshFolder::begin(dir, "tables")?;
    let tables = fresh_tables.path().to_path_buf();
    let mut md = String::new();
    if !run.suite.tables.is_empty() {
        md += "## Tables with reference numbers\n\n";
        for t in &run.suite.tables {
            let table = paper::paper_table_markdown(t, &a);
            md += &table;
            md.push('\n');
            atomic_write(&tables.join(format!("{}.md", t.id)), table.as_bytes())?;
            atomic_write(
                &tables.join(format!("{}.tex", t.id)),
                paper::paper_table_latex(t, &a).as_bytes(),
            )?;
        }
    }
    md += &penalised_markdown(&run.records);
    let bbob = bbob_ecdfs(&run);
    md += &bbob_markdown(&bbob);
    let report = paper::report_markdown(&a);
    let report = match report.split_once("\n## ") {
        // The paper tables go after the main table, before the details.
        Some((head, rest)) if !md.is_empty() => format!("{head}\n{md}## {rest}"),
        _ => report,
    };
    atomic_write(&dir.join("report.md"), report.as_bytes())?;
    atomic_write(
        &tables.join("summary.md"),
        paper::summary_markdown(&a).as_bytes(),
    )?;
    atomic_write(
        &tables.join("summary.tex"),
        paper::summary_latex(&a).as_bytes(),
    )?;
    for (name, text) in paper::csv_tables(&a) {
        atomic_write(&tables.join(name), text.as_bytes())?;
    }
    let mut json = serde_json::to_vec_pretty(&a).expect("serialisable");
    json.push(b'\n');
    atomic_write(&dir.join("analysis.json"), &json)?;

    let fresh_plots = FreshFolder::begin(dir, "plots")?;
    write_plots(fresh_plots.path(), &run, &a)?;
    write_bbob_ecdfs(fresh_plots.path(), &bbob)?;

    let fresh_ioh = FreshFolder::begin(dir, "ioh")?;
    let optimizers: Vec<(&SafeName, &str)> = run
        .suite
        .optimizers
        .iter()
        .map(|o| (&o.id, o.kind))
        .collect();
    ioh::export(
        fresh_ioh.path(),
        &run.suite.name,
        &ioh::objectives(&run.suite)?,
        &optimizers,
        &run.records,
    )?;
    let mut fresh = vec![fresh_tables, fresh_plots, fresh_ioh];
    if !bbob.is_empty() {
        let fresh_coco = FreshFolder::begin(dir, "coco")?;
        coco::export(fresh_coco.path(), &run.suite, &run.records)?;
        fresh.push(fresh_coco);
    }
    for f in fresh {
        f.commit()?;
    }
    // Last, once the fresh folders are in place: the page embeds the figures just drawn.
    let mut groups: Vec<String> = a.objectives.iter().map(|o| o.id.to_string()).collect();
    if !bbob.is_empty() {
        groups.insert(0, BBOB_GROUP.into());
    }
    html::write(
        dir,
        &html::Page {
            title: &format!("optbench report: {} (seed {})", a.suite, a.seed),
            markdown: &report,
            statistics: &html::benchmark_statistics(),
            figures: &dir.join("plots"),
            figures_link: "plots/",
            figure_groups: &groups,
            provenance: &dir.join("provenance.json"),
        },
    )?;
    Ok(paper::summary_markdown(&a))
}

/// Log-spaced targets between the median first value and the best value reached.
fn ecdf_targets(errors_first: f64, best: f64) -> Vec<f64> {
    let hi = errors_first.max(f64::MIN_POSITIVE);
    let lo = best.max(hi * 1e-12).min(hi);
    if lo >= hi {
        return vec![hi];
    }
    let n = DEFAULT_ECDF_TARGETS;
    (0..n)
        .map(|i| hi * (lo / hi).powf(i as f64 / (n - 1) as f64))
        .collect()
}

/// What the figures of one objective plot, before drawing: the same values the tables
/// show (the traces as presented: a fitting cost as an RMSE in the recording's units; the
/// error to the optimum where it is known; the value otherwise).
pub struct ObjectivePlots {
    pub id: String,
    /// What the values are, with their unit: the presented label (`train RMSE [mm]`),
    /// `error to optimum f − f*` or `value f`.
    pub quantity: String,
    /// Trials per optimizer (of the first).
    pub trials: usize,
    pub convergence: Vec<render::ConvergenceSeries>,
    /// Whether the values fit a log axis.
    pub log_y: bool,
    /// Final values per optimizer (the table's errors, trial order).
    pub finals: Vec<(String, Vec<f64>)>,
    /// Targets of the runtime ECDF, in the units of `quantity`.
    pub targets: Vec<f64>,
    /// Per optimizer, the evaluations to reach each (trial, target) pair (+inf: never).
    pub runtimes: Vec<(String, Vec<f64>)>,
    pub budget: u64,
}

impl ObjectivePlots {
    /// Y label of the convergence figure.
    pub fn convergence_label(&self) -> String {
        format!("best-so-far {}", self.quantity)
    }

    /// Y label of the box plot.
    pub fn final_label(&self) -> String {
        format!("final {}", self.quantity)
    }
}

/// The figures' data of every objective, from the presented traces (see [`StoredRun`]).
pub fn plot_data(run: &StoredRun, a: &Analysis) -> Vec<ObjectivePlots> {
    let mut out = Vec::new();
    for o in &a.objectives {
        let of_obj: Vec<&TrialRecord> = run
            .presented
            .iter()
            .filter(|r| r.objective == o.id)
            .collect();
        let by_opt = |opt: &str| -> Vec<&TrialRecord> {
            of_obj
                .iter()
                .copied()
                .filter(|r| r.optimizer == opt)
                .collect()
        };
        let quantity = match (&o.label, o.optimum) {
            (Some(l), _) => l.clone(),
            (None, Some(_)) => "error to optimum f − f*".into(),
            (None, None) => "value f".into(),
        };
        let targets = if o.targets.is_empty() {
            let first: Vec<f64> = of_obj
                .iter()
                .map(|r| {
                    error_of(
                        r.improvements.first().map(|i| i.1).unwrap_or(f64::INFINITY),
                        r.optimum,
                    )
                })
                .collect();
            let best = o
                .cells
                .iter()
                .map(|c| c.stats.min)
                .fold(f64::INFINITY, f64::min);
            ecdf_targets(describe(&first).median, best)
        } else {
            o.targets.clone()
        };
        // Runtime ECDF over (trial x target) pairs.
        let runtimes = o
            .cells
            .iter()
            .map(|c| {
                let mut v = Vec::new();
                for r in by_opt(&c.optimizer) {
                    for &t in &targets {
                        let threshold = r.optimum.unwrap_or(0.0) + t;
                        v.push(
                            crate::stats::first_hit(&r.improvements, threshold)
                                .map(|e| e as f64)
                                .unwrap_or(f64::INFINITY),
                        );
                    }
                }
                (c.optimizer.clone(), v)
            })
            .collect();
        out.push(ObjectivePlots {
            id: o.id.to_string(),
            quantity,
            trials: o.cells.first().map(|c| c.stats.n).unwrap_or(0),
            convergence: o
                .cells
                .iter()
                .map(|c| render::convergence_series(&c.optimizer, &by_opt(&c.optimizer)))
                .collect(),
            log_y: o.cells.iter().all(|c| c.stats.min > 0.0) || o.optimum.is_some(),
            finals: o
                .cells
                .iter()
                .map(|c| (c.optimizer.clone(), c.errors.clone()))
                .collect(),
            targets,
            runtimes,
            budget: o.budget,
        });
    }
    out
}

fn write_plots(dir: &Path, run: &StoredRun, a: &Analysis) -> Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::io(format!("creating {}", dir.display()), e))?;
    for p in plot_data(run, a) {
        let (id, n) = (&p.id, p.trials);
        render::convergence(
            &dir.join(format!("convergence_{id}")),
            &format!("{id}: median and IQR over {n} trials"),
            &p.convergence,
            &p.convergence_label(),
            p.log_y,
        )?;
        render::boxplot(
            &dir.join(format!("box_{id}")),
            &format!("{id}: {} ({n} trials)", p.final_label()),
            &p.finals,
            &p.final_label(),
            p.log_y,
        )?;
        let (first, last) = (p.targets[0], p.targets[p.targets.len() - 1]);
        render::ecdf(
            &dir.join(format!("ecdf_{id}")),
            &format!(
                "{id}: runtime ECDF, {} targets on {}, {}..{}",
                p.targets.len(),
                p.quantity,
                sig(first, 2),
                sig(last, 2)
            ),
            &p.runtimes,
            "function evaluations",
            (1.0, p.budget as f64),
        )?;
    }
    Ok(())
}

/// The figure group (and stem suffix) of the BBOB aggregates, shown first.
const BBOB_GROUP: &str = "bbob";

/// COCO's runtime ECDF of one dimension, aggregated over its BBOB functions.
pub struct BbobEcdf {
    pub dim: usize,
    pub functions: usize,
    /// Runs of the first optimizer (the figure's title).
    pub runs: usize,
    /// Largest budget / dim of the runs.
    pub budget_per_dim: f64,
    /// Per optimizer (suite order), for every (run, target): evaluations / dim to reach
    /// f − f_opt <= target (+inf: never).
    pub series: Vec<(String, Vec<f64>)>,
}

impl BbobEcdf {
    /// Fraction of the (function, instance, target) triples an optimizer reached.
    pub fn reached(&self, values: &[f64]) -> f64 {
        values.iter().filter(|v| v.is_finite()).count() as f64 / values.len().max(1) as f64
    }
}

/// The runtime ECDFs cocopp draws per dimension: every run of every BBOB function against
/// COCO's 51 targets 10^2..10^-8 of f − f_opt (its instance's), x = evaluations / dim.
/// Empty when the suite has no BBOB objective.
pub fn bbob_ecdfs(run: &StoredRun) -> Vec<BbobEcdf> {
    let runs = coco::bbob_runs(&run.suite, &run.records);
    let targets = coco::targets();
    let mut dims: Vec<usize> = runs.iter().map(|r| r.dim).collect();
    dims.sort_unstable();
    dims.dedup();
    dims.into_iter()
        .map(|dim| {
            let of_dim: Vec<&coco::BbobRun<'_>> = runs.iter().filter(|r| r.dim == dim).collect();
            let mut functions: Vec<usize> = of_dim.iter().map(|r| r.function).collect();
            functions.sort_unstable();
            functions.dedup();
            let series: Vec<(String, Vec<f64>)> = run
                .suite
                .optimizers
                .iter()
                .map(|opt| {
                    let mut v = Vec::new();
                    for r in of_dim.iter().filter(|r| r.record.optimizer == *opt.id) {
                        for &t in &targets {
                            // As cocopp compares: the error f − f_opt against the target.
                            let hit = r.record.improvements.iter().find(|i| i.1 - r.fopt <= t);
                            v.push(hit.map_or(f64::INFINITY, |i| i.0 as f64 / dim as f64));
                        }
                    }
                    (opt.id.to_string(), v)
                })
                .filter(|(_, v)| !v.is_empty())
                .collect();
            BbobEcdf {
                dim,
                functions: functions.len(),
                runs: series.first().map_or(0, |s| s.1.len() / targets.len()),
                budget_per_dim: of_dim
                    .iter()
                    .map(|r| r.record.budget as f64 / dim as f64)
                    .fold(1.0, f64::max),
                series,
            }
        })
        .collect()
}

/// The report's section on the BBOB aggregates: what was reached, per dimension.
fn bbob_markdown(ecdfs: &[BbobEcdf]) -> String {
    if ecdfs.is_empty() {
        return String::new();
    }
    let mut s = String::from(
        "## BBOB: runtime ECDFs over functions\n\nAs cocopp aggregates them: per dimension, every run of every BBOB function against COCO's 51 targets 10^2..10^-8 of f − f_opt (each run's own instance); the share of (function, instance, target) triples reached within the budget (figures `ecdf-dDD_bbob`, x = evaluations / dimension). The runs are in COCO's format under `coco/`, for `cocopp`.\n\n",
    );
    let mut rows = Vec::new();
    for e in ecdfs {
        for (opt, v) in &e.series {
            rows.push(vec![
                e.dim.to_string(),
                opt.clone(),
                e.functions.to_string(),
                (v.len() / coco::targets().len()).to_string(),
                format!("{:.0}", e.budget_per_dim),
                format!("{:.3}", e.reached(v)),
            ]);
        }
    }
    s += &markdown(
        &[
            "dim",
            "optimizer",
            "functions",
            "runs",
            "budget / dim",
            "triples reached",
        ],
        &rows,
        &[true, false, true, true, true, true],
    );
    s.push('\n');
    s
}

fn write_bbob_ecdfs(dir: &Path, ecdfs: &[BbobEcdf]) -> Result<()> {
    for e in ecdfs {
        render::ecdf_of(
            &dir.join(format!("ecdf-d{:02}_{BBOB_GROUP}", e.dim)),
            &format!(
                "bbob {}-D: {} functions, {} runs, 51 targets 1e2..1e-8",
                e.dim, e.functions, e.runs
            ),
            &e.series,
            (
                "function evaluations / dimension",
                "fraction of (function, instance, target) triples",
            ),
            (1.0 / e.dim as f64, e.budget_per_dim),
        )?;
    }
    Ok(())
}

/// Compares two results folders of the same suite, cell by cell: medians, a two-sided
/// Mann-Whitney U test of the final errors (Holm over the cells) and A12 = P(B > A).
pub fn compare(a_dir: &Path, b_dir: &Path) -> Result<String> {
    let a = StoredRun::load(a_dir)?;
    let b = StoredRun::load(b_dir)?;
    if a.suite.name != b.suite.name {
        return Err(Error::Input(format!(
            "{} is suite `{}` but {} is suite `{}`: compare results of the same suite",
            a_dir.display(),
            a.suite.name,
            b_dir.display(),
            b.suite.name
        )));
    }
    let (aa, ab) = (a.analyse(), b.analyse());
    let mut rows = Vec::new();
    let mut pvals = Vec::new();
    let mut missing = Vec::new();
    for oa in &aa.objectives {
        for ca in &oa.cells {
            let cb = ab
                .objectives
                .iter()
                .find(|o| o.id == oa.id)
                .and_then(|o| o.cells.iter().find(|c| c.optimizer == ca.optimizer));
            let Some(cb) = cb else {
                missing.push(format!("{} x {} only in A", oa.id, ca.optimizer));
                continue;
            };
            let identical = ca.errors == cb.errors;
            let p = mann_whitney(&ca.errors, &cb.errors).p_value;
            pvals.push(p);
            rows.push((
                oa.id.clone(),
                ca.optimizer.clone(),
                ca.stats.median,
                cb.stats.median,
                p,
                a12(&cb.errors, &ca.errors),
                identical,
            ));
        }
    }
    for ob in &ab.objectives {
        for cb in &ob.cells {
            let in_a = aa
                .objectives
                .iter()
                .any(|o| o.id == ob.id && o.cells.iter().any(|c| c.optimizer == cb.optimizer));
            if !in_a {
                missing.push(format!("{} x {} only in B", ob.id, cb.optimizer));
            }
        }
    }
    let adjusted = holm(&pvals);
    let table: Vec<Vec<String>> = rows
        .iter()
        .zip(&adjusted)
        .map(|((obj, opt, ma, mb, p, a12, same), h)| {
            vec![
                obj.to_string(),
                opt.clone(),
                sig(*ma, 3),
                sig(*mb, 3),
                if *same {
                    "identical".into()
                } else {
                    sig(*p, 3)
                },
                if *same { "-".into() } else { sig(*h, 3) },
                format!("{a12:.2}"),
                if !*same && *h < analysis::ALPHA {
                    if mb < ma {
                        "B better".into()
                    } else {
                        "B worse".into()
                    }
                } else {
                    String::new()
                },
            ]
        })
        .collect();
    let mut s = format!(
        "A: {} (seed {}, {} trials)\nB: {} (seed {}, {} trials)\n\n",
        a_dir.display(),
        a.provenance.seed,
        a.provenance.trials,
        b_dir.display(),
        b.provenance.seed,
        b.provenance.trials
    );
    s += &markdown(
        &[
            "objective",
            "optimizer",
            "median A",
            "median B",
            "p",
            "p (Holm)",
            "A12 (B>A)",
            "change",
        ],
        &table,
        &[false, false, true, true, true, true, true, false],
    );
    if !missing.is_empty() {
        // A blank line first: a line right under a table would render as one more row.
        s.push('\n');
        for m in missing {
            s += &format!("- {m}\n");
        }
    }
    Ok(s)
}
