//! What optbench shows people, regenerated from a results folder's stored traces alone:
//! `report.md` and `tables/` (Markdown, LaTeX, CSV), `plots/` (SVG and PNG), `ioh/` (an
//! IOHprofiler export) and `analysis.json`. The same folder always gives the same bytes.

pub mod analysis;
pub mod html;
pub mod ioh;
pub mod paper;

use crate::base::error::{Error, Result};
use crate::base::{SafeName, atomic_write, create_dir_within};
use crate::harness::TrialRecord;
use crate::pipeline::store::{Provenance, read_traces};
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

    let tables = dir.join("tables");
    create_dir_within(dir, &tables)?;
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

    create_dir_within(dir, &dir.join("plots"))?;
    write_plots(&dir.join("plots"), &run, &a)?;

    let objectives: Vec<ioh::IohObjective<'_>> = a
        .objectives
        .iter()
        .map(|o| ioh::IohObjective {
            id: &o.id,
            dim: o.dim,
        })
        .collect();
    let optimizers: Vec<&SafeName> = run.suite.optimizers.iter().map(|o| &o.id).collect();
    create_dir_within(dir, &dir.join("ioh"))?;
    ioh::export(
        &dir.join("ioh"),
        &run.suite.name,
        &objectives,
        &optimizers,
        &run.records,
    )?;
    // Last: the page embeds the figures just drawn.
    let groups: Vec<String> = a.objectives.iter().map(|o| o.id.to_string()).collect();
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

fn write_plots(dir: &Path, run: &StoredRun, a: &Analysis) -> Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::io(format!("creating {}", dir.display()), e))?;
    for o in &a.objectives {
        let of_obj: Vec<&TrialRecord> =
            run.records.iter().filter(|r| r.objective == o.id).collect();
        let by_opt = |opt: &str| -> Vec<&TrialRecord> {
            of_obj
                .iter()
                .copied()
                .filter(|r| r.optimizer == opt)
                .collect()
        };
        let what = match (&o.label, o.optimum) {
            (Some(l), _) => format!("best-so-far {l}"),
            (None, Some(_)) => "best-so-far error to optimum".into(),
            (None, None) => "best-so-far value".into(),
        };
        let series: Vec<render::ConvergenceSeries> = o
            .cells
            .iter()
            .map(|c| render::convergence_series(&c.optimizer, &by_opt(&c.optimizer)))
            .collect();
        let all_positive = o.cells.iter().all(|c| c.stats.min > 0.0) || o.optimum.is_some();
        let n = o.cells.first().map(|c| c.stats.n).unwrap_or(0);
        render::convergence(
            &dir.join(format!("convergence_{}", o.id)),
            &format!("{}: median and IQR over {n} trials", o.id),
            &series,
            &what,
            all_positive,
        )?;
        let groups: Vec<(String, Vec<f64>)> = o
            .cells
            .iter()
            .map(|c| (c.optimizer.clone(), c.errors.clone()))
            .collect();
        render::boxplot(
            &dir.join(format!("box_{}", o.id)),
            &format!(
                "{}: final {} ({n} trials)",
                o.id,
                if o.optimum.is_some() {
                    "error"
                } else {
                    "value"
                }
            ),
            &groups,
            if o.optimum.is_some() {
                "final error to optimum"
            } else {
                "final value"
            },
            all_positive,
        )?;
        // Runtime ECDF over (trial x target) pairs.
        let targets = if o.targets.is_empty() {
            let first: Vec<f64> = of_obj
                .iter()
                .map(|r| {
                    error_of(
                        r.improvements.first().map(|i| i.1).unwrap_or(f64::INFINITY),
                        o.optimum,
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
        let ecdf: Vec<(String, Vec<f64>)> = o
            .cells
            .iter()
            .map(|c| {
                let mut v = Vec::new();
                for r in by_opt(&c.optimizer) {
                    for &t in &targets {
                        let threshold = o.optimum.unwrap_or(0.0) + t;
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
        render::ecdf(
            &dir.join(format!("ecdf_{}", o.id)),
            &format!(
                "{}: runtime ECDF, {} targets {}..{}",
                o.id,
                targets.len(),
                sig(targets[0], 2),
                sig(*targets.last().unwrap(), 2)
            ),
            &ecdf,
            "function evaluations",
            (1.0, o.budget as f64),
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
