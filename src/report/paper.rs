//! Tables for papers, rendered from an [`Analysis`]: Markdown (also printed), LaTeX
//! (booktabs) and CSV.

use super::analysis::{ALPHA, Analysis, ObjectiveStats};
use crate::render::latex::{
    booktabs, latex_bold, latex_escape, latex_label, latex_num, latex_sup, sentence,
};
use crate::render::table::{markdown, sig};
use std::fmt::Write;

/// Marker and text for cell `i` against the best of its objective.
fn versus_best(o: &ObjectiveStats, i: usize) -> (bool, String) {
    match o.versus_best(i) {
        None => (false, "best".into()),
        Some(p) => {
            // A12 oriented as "this optimizer vs the best": > 0.5 means worse.
            let a12 = if p.a == o.cells[i].optimizer {
                p.a12
            } else {
                1.0 - p.a12
            };
            (
                p.p_holm < ALPHA,
                format!("p={} A12={:.2}", sig(p.p_holm, 2), a12),
            )
        }
    }
}

/// Significant digits of every median the tables print (Markdown and LaTeX alike).
const DIGITS: usize = 3;

/// How the tables define the best, said in the report and in the LaTeX caption.
pub const TIE_RULE: &str = "lowest median per objective, and every median that prints equal \
                            to it (ties as printed, to 3 significant digits)";

/// Which cells of `o` the tables mark as best: the lowest median and every cell whose
/// median prints the same (to [`DIGITS`] significant digits). Ties are decided as printed,
/// not as stored, so a reader never sees two equal numbers with only one marked.
pub fn best_cells(o: &ObjectiveStats) -> Vec<bool> {
    let best = sig(o.cells[o.best].stats.median, DIGITS);
    o.cells
        .iter()
        .map(|c| sig(c.stats.median, DIGITS) == best)
        .collect()
}

/// The main table: one row per objective x optimizer.
pub fn summary_markdown(a: &Analysis) -> String {
    let header = [
        "objective",
        "optimizer",
        "median [95% CI]",
        "q1",
        "q3",
        "mean",
        "std",
        "min",
        "max",
        "vs best (Holm)",
    ];
    let mut rows = Vec::new();
    for o in &a.objectives {
        let bold = best_cells(o);
        for (i, c) in o.cells.iter().enumerate() {
            let (significant, text) = versus_best(o, i);
            let med = format!(
                "{} [{}, {}]",
                sig(c.stats.median, DIGITS),
                sig(c.median_ci.0, DIGITS),
                sig(c.median_ci.1, DIGITS)
            );
            rows.push(vec![
                o.id.to_string(),
                c.optimizer.clone(),
                if bold[i] { format!("**{med}**") } else { med },
                sig(c.stats.q1, 3),
                sig(c.stats.q3, 3),
                sig(c.stats.mean, 3),
                sig(c.stats.std, 2),
                sig(c.stats.min, 3),
                sig(c.stats.max, 3),
                if significant {
                    format!("{text} *")
                } else {
                    text
                },
            ]);
        }
    }
    let right: Vec<bool> = (0..header.len()).map(|i| (2..9).contains(&i)).collect();
    markdown(&header, &rows, &right)
}

/// Success rate and ERT per target.
pub fn ert_markdown(a: &Analysis) -> String {
    let mut out = String::new();
    for o in a.objectives.iter().filter(|o| !o.targets.is_empty()) {
        let mut header = vec!["optimizer".to_string()];
        header.extend(
            o.targets
                .iter()
                .map(|t| format!("{} <= {}", short(o), sig(*t, 2))),
        );
        let rows: Vec<Vec<String>> = o
            .cells
            .iter()
            .map(|c| {
                let mut r = vec![c.optimizer.clone()];
                r.extend(c.targets.iter().map(|e| match e.ert {
                    Some(v) => format!("{}/{} {}", e.successes, e.trials, sig(v, 3)),
                    None => format!("0/{} -", e.trials),
                }));
                r
            })
            .collect();
        let h: Vec<&str> = header.iter().map(String::as_str).collect();
        let right: Vec<bool> = (0..h.len()).map(|i| i > 0).collect();
        writeln!(
            out,
            "**{}** (successes/trials and ERT in evaluations)\n",
            o.id
        )
        .unwrap();
        out += &markdown(&h, &rows, &right);
        out.push('\n');
    }
    out
}

fn short(o: &ObjectiveStats) -> &'static str {
    if o.optimum.is_some() { "err" } else { "f" }
}

/// Median error at 1 %, 10 % and 100 % of the budget: one table per objective, one column
/// per evaluation count (objectives differ in budget, so they share no columns).
pub fn fixed_budget_markdown(a: &Analysis) -> String {
    let mut out = String::new();
    for o in &a.objectives {
        let mut header = vec!["optimizer".to_string()];
        header.extend(o.fixed_budgets.iter().map(|&b| {
            let pct = 100.0 * b as f64 / o.budget.max(1) as f64;
            let pct = if pct.fract() == 0.0 {
                format!("{pct:.0}")
            } else {
                sig(pct, 2)
            };
            format!("{b} ({pct}% of budget)")
        }));
        let rows: Vec<Vec<String>> = o
            .cells
            .iter()
            .zip(&o.fixed_budget_medians)
            .map(|(c, meds)| {
                let mut r = vec![c.optimizer.clone()];
                r.extend(meds.iter().map(|m| sig(*m, 3)));
                r
            })
            .collect();
        let what = match (&o.label, o.optimum) {
            (_, Some(_)) => "median error to the optimum".to_string(),
            (Some(l), None) => format!("median {l}"),
            (None, None) => "median value".to_string(),
        };
        writeln!(
            out,
            "**{}** ({what} after the evaluations in each column)\n",
            o.id
        )
        .unwrap();
        let h: Vec<&str> = header.iter().map(String::as_str).collect();
        let right: Vec<bool> = (0..h.len()).map(|i| i > 0).collect();
        out += &markdown(&h, &rows, &right);
        out.push('\n');
    }
    out
}

/// Metrics at the trials' final points (e.g. free-run and validation RMSE of a fitted
/// model): per objective, optimizers x metrics, median [95 % CI].
pub fn metrics_markdown(a: &Analysis) -> String {
    let mut out = String::new();
    for o in a
        .objectives
        .iter()
        .filter(|o| o.cells.iter().any(|c| !c.metrics.is_empty()))
    {
        let names: Vec<&str> = o.cells[0].metrics.iter().map(|m| m.name.as_str()).collect();
        let mut header = vec!["optimizer"];
        header.extend(&names);
        let rows: Vec<Vec<String>> = o
            .cells
            .iter()
            .map(|c| {
                let mut r = vec![c.optimizer.clone()];
                r.extend(c.metrics.iter().map(|m| {
                    format!(
                        "{} [{}, {}]",
                        sig(m.stats.median, 3),
                        sig(m.median_ci.0, 3),
                        sig(m.median_ci.1, 3)
                    )
                }));
                r
            })
            .collect();
        let right: Vec<bool> = (0..header.len()).map(|i| i > 0).collect();
        writeln!(out, "**{}** (median [95% CI] over trials)\n", o.id).unwrap();
        out += &markdown(&header, &rows, &right);
        out.push('\n');
    }
    out
}

/// Every pairwise test.
pub fn pairwise_markdown(a: &Analysis) -> String {
    let mut rows = Vec::new();
    for o in &a.objectives {
        for p in &o.pairs {
            rows.push(vec![
                o.id.to_string(),
                format!("{} vs {}", p.a, p.b),
                sig(p.p_value, 3),
                sig(p.p_holm, 3),
                format!("{:.3}", p.a12),
            ]);
        }
    }
    markdown(
        &[
            "objective",
            "pair (A vs B)",
            "p (Mann-Whitney)",
            "p (Holm)",
            "A12",
        ],
        &rows,
        &[false, false, true, true, true],
    )
}

/// Average ranks and Friedman's test.
pub fn ranks_markdown(a: &Analysis) -> String {
    let Some(f) = &a.friedman else {
        return "Ranks need at least two objectives and two optimizers.\n".into();
    };
    let mut order: Vec<usize> = (0..a.optimizers.len()).collect();
    order.sort_by(|&x, &y| f.mean_ranks[x].total_cmp(&f.mean_ranks[y]));
    let rows: Vec<Vec<String>> = order
        .iter()
        .map(|&i| vec![a.optimizers[i].clone(), format!("{:.2}", f.mean_ranks[i])])
        .collect();
    let mut s = markdown(
        &["optimizer", "average rank (1 = best)"],
        &rows,
        &[false, true],
    );
    writeln!(
        s,
        "\nFriedman test over {} objectives: chi2 = {:.3}, df = {}, p = {} ({}; the \
         chi-square approximation, rough for few objectives, gives {})",
        a.objectives.len(),
        f.statistic,
        f.df,
        sig(f.p_value, 3),
        f.method.label(),
        sig(f.p_chi2, 3)
    )
    .unwrap();
    s
}

/// The whole Markdown report.
pub fn report_markdown(a: &Analysis) -> String {
    let mut s = String::new();
    writeln!(s, "# optbench report: {} (seed {})\n", a.suite, a.seed).unwrap();
    writeln!(
        s,
        "Each trial counts with its final best: the error to the optimum where the optimum is \
         known, else the value as labelled below. Median with a 95 % percentile-bootstrap \
         interval ({} resamples, seeded); quartiles are type 7. Bold: {TIE_RULE}. \
         'vs best': two-sided Mann-Whitney U against the best (the lowest median; ties \
         broken by the lower mean), Holm-corrected over all pairs of the objective, and \
         A12 = P(this > best); * marks p < {ALPHA}.\n",
        super::analysis::RESAMPLES
    )
    .unwrap();
    let labelled: Vec<String> = a
        .objectives
        .iter()
        .filter_map(|o| o.label.as_ref().map(|l| format!("- `{}`: {l}", o.id)))
        .collect();
    if !labelled.is_empty() {
        s += "Values shown, where not an error to a known optimum:\n\n";
        s += &labelled.join("\n");
        s += "\n\n";
    }
    s += &summary_markdown(a);
    let metrics = metrics_markdown(a);
    if !metrics.is_empty() {
        s += "\n## Model metrics at the final points\n\n\
              One-step-ahead predictions use the measured past outputs and flatter a model; \
              free-run simulations use the model's own. The model is never fitted to validation \
              data; with several records, a validation record's own offset and initial state \
              are refitted on it with the model held fixed (`refit_validation`).\n\n";
        s += &metrics;
    }
    s += "\n## Average ranks\n\n";
    s += &ranks_markdown(a);
    s += "\n## Fixed budget\n\n";
    s += &fixed_budget_markdown(a);
    let ert = ert_markdown(a);
    if !ert.is_empty() {
        s += "\n## Fixed target: success rate and ERT\n\n\
              ERT = evaluations summed over all trials (failures count their whole budget) \
              divided by the successes.\n\n";
        s += &ert;
    }
    s += "\n## Pairwise tests\n\n";
    s += &pairwise_markdown(a);
    s
}

/// The summary as a booktabs table: objectives x optimizers, median errors, the best (and
/// its ties as printed, [`best_cells`]) in bold math, a dagger where the difference to the
/// best is significant after Holm, `--` where an optimizer did not run on an objective.
pub fn summary_latex(a: &Analysis) -> String {
    let mut s = String::new();
    writeln!(s, "% optbench report: {} (seed {})", a.suite, a.seed).unwrap();
    writeln!(s, "% requires \\usepackage{{booktabs}}").unwrap();
    writeln!(
        s,
        "% bold: {TIE_RULE}; written with \\boldmath, so math digits are bold too"
    )
    .unwrap();
    writeln!(s, "\\begin{{table}}[t]\n\\centering").unwrap();
    writeln!(
        s,
        "\\caption{{Median over trials of the final error to the optimum (of the final value \
         where the optimum is unknown, e.g.\\ a fit's RMSE). Bold: {}; \
         $^\\dagger$: different from the best (two-sided Mann--Whitney U, Holm-corrected, \
         $p<{ALPHA}$).}}",
        TIE_RULE
    )
    .unwrap();
    writeln!(s, "\\label{{tab:{}}}", latex_label(&a.suite)).unwrap();
    writeln!(
        s,
        "\\begin{{tabular}}{{l{}}}",
        "r".repeat(a.optimizers.len())
    )
    .unwrap();
    writeln!(s, "\\toprule").unwrap();
    let head: Vec<String> = a.optimizers.iter().map(|o| latex_escape(o)).collect();
    writeln!(s, "Objective & {} \\\\", head.join(" & ")).unwrap();
    writeln!(s, "\\midrule").unwrap();
    for o in &a.objectives {
        let bold = best_cells(o);
        // One column per optimizer of the suite: an objective may run only some of them.
        let cells: Vec<String> = a
            .optimizers
            .iter()
            .map(
                |name| match o.cells.iter().position(|c| &c.optimizer == name) {
                    None => "--".to_string(),
                    Some(i) => {
                        let n = latex_num(o.cells[i].stats.median);
                        let n = if bold[i] { latex_bold(&n) } else { n };
                        if versus_best(o, i).0 {
                            latex_sup(&n, "\\dagger")
                        } else {
                            n
                        }
                    }
                },
            )
            .collect();
        writeln!(s, "{} & {} \\\\", latex_escape(&o.id), cells.join(" & ")).unwrap();
    }
    writeln!(s, "\\bottomrule\n\\end{{tabular}}\n\\end{{table}}").unwrap();
    s
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:e}")
    } else {
        String::new()
    }
}

/// Machine-readable tables: (file name, CSV text).
pub fn csv_tables(a: &Analysis) -> Vec<(&'static str, String)> {
    let mut summary = String::from(
        "objective,optimizer,trials,median,median_ci_low,median_ci_high,q1,q3,mean,std,min,max,best,p_holm_vs_best,a12_vs_best,evaluations,wall_s\n",
    );
    let mut pairs = String::from("objective,a,b,p_value,p_holm,a12\n");
    let mut ert = String::from("objective,optimizer,target,successes,trials,success_rate,ert\n");
    let mut fixed = String::from("objective,optimizer,evaluations,median_error\n");
    for o in &a.objectives {
        let id = csv_field(&o.id);
        for (i, c) in o.cells.iter().enumerate() {
            let (p, a12) = match o.versus_best(i) {
                None => (String::new(), String::new()),
                Some(p) => {
                    let a12 = if p.a == c.optimizer {
                        p.a12
                    } else {
                        1.0 - p.a12
                    };
                    (num(p.p_holm), format!("{a12}"))
                }
            };
            let d = &c.stats;
            writeln!(
                summary,
                "{id},{},{},{},{},{},{},{},{},{},{},{},{},{p},{a12},{},{}",
                csv_field(&c.optimizer),
                d.n,
                num(d.median),
                num(c.median_ci.0),
                num(c.median_ci.1),
                num(d.q1),
                num(d.q3),
                num(d.mean),
                num(d.std),
                num(d.min),
                num(d.max),
                i == o.best,
                c.evaluations,
                c.wall_s
            )
            .unwrap();
            for (t, e) in o.targets.iter().zip(&c.targets) {
                writeln!(
                    ert,
                    "{id},{},{},{},{},{},{}",
                    csv_field(&c.optimizer),
                    num(*t),
                    e.successes,
                    e.trials,
                    e.success_rate,
                    e.ert.map(num).unwrap_or_default()
                )
                .unwrap();
            }
            for (b, m) in o.fixed_budgets.iter().zip(&o.fixed_budget_medians[i]) {
                writeln!(fixed, "{id},{},{b},{}", csv_field(&c.optimizer), num(*m)).unwrap();
            }
        }
        for p in &o.pairs {
            writeln!(
                pairs,
                "{id},{},{},{},{},{}",
                csv_field(&p.a),
                csv_field(&p.b),
                num(p.p_value),
                num(p.p_holm),
                p.a12
            )
            .unwrap();
        }
    }
    let mut metrics = String::from(
        "objective,optimizer,metric,median,median_ci_low,median_ci_high,q1,q3,min,max\n",
    );
    for o in &a.objectives {
        for c in &o.cells {
            for m in &c.metrics {
                writeln!(
                    metrics,
                    "{},{},{},{},{},{},{},{},{},{}",
                    csv_field(&o.id),
                    csv_field(&c.optimizer),
                    csv_field(&m.name),
                    num(m.stats.median),
                    num(m.median_ci.0),
                    num(m.median_ci.1),
                    num(m.stats.q1),
                    num(m.stats.q3),
                    num(m.stats.min),
                    num(m.stats.max)
                )
                .unwrap();
            }
        }
    }
    vec![
        ("metrics.csv", metrics),
        ("summary.csv", summary),
        ("pairwise.csv", pairs),
        ("ert.csv", ert),
        ("fixed_budget.csv", fixed),
    ]
}

/// The median and 95 % interval a paper-table cell shows, if the run has it.
fn paper_cell(
    a: &Analysis,
    cell: &str,
    default_metric: Option<&String>,
) -> Option<(f64, (f64, f64))> {
    let r = crate::pipeline::suite::CellRef::parse(cell)?;
    let o = a.objectives.iter().find(|o| o.id == r.objective)?;
    let c = o.cells.iter().find(|c| c.optimizer == r.optimizer)?;
    match r.metric.as_ref().or(default_metric) {
        Some(m) => {
            let ms = match m.as_str() {
                super::analysis::FIT_TIME => &c.fit_time,
                _ => c.metrics.iter().find(|x| &x.name == m)?,
            };
            Some((ms.stats.median, ms.median_ci))
        }
        None => Some((c.stats.median, c.median_ci)),
    }
}

/// A paper-layout table in Markdown: `heading`, then each cell as `ours` gives it ("not
/// run" where it gives none) with the published number beside it, then the table's note.
/// Benchmark and control suites share it, so their tables read alike.
pub fn layout_markdown(
    t: &crate::pipeline::suite::PaperTable,
    heading: &str,
    ours: impl Fn(&str) -> Option<String>,
) -> String {
    let reference = t.reference.as_deref().unwrap_or("dissertation");
    let mut header = vec![String::new()];
    header.extend(t.columns.iter().cloned());
    let rows: Vec<Vec<String>> = t
        .rows
        .iter()
        .map(|row| {
            let mut r = vec![row.label.clone()];
            for (i, cell) in row.cells.iter().enumerate() {
                let ours = ours(cell).unwrap_or_else(|| "not run".into());
                r.push(match row.seed.get(i).copied().filter(|v| v.is_finite()) {
                    Some(v) => format!("{ours} ({reference} {})", sig(v, 3)),
                    None => ours,
                });
            }
            r
        })
        .collect();
    let h: Vec<&str> = header.iter().map(String::as_str).collect();
    let right: Vec<bool> = (0..h.len()).map(|i| i > 0).collect();
    let mut s = format!("{heading}\n\n");
    s += &markdown(&h, &rows, &right);
    if let Some(n) = &t.note {
        s += &format!("\n{n}\n");
    }
    s
}

/// A suite's paper-layout table: our median [95 % CI] with the paper's number beside it.
pub fn paper_table_markdown(t: &crate::pipeline::suite::PaperTable, a: &Analysis) -> String {
    let what = match &t.value {
        Some(v) => format!("{v}; "),
        None => String::new(),
    };
    let heading = format!(
        "**{}** ({what}ours: median [95% CI] over trials; {} in brackets)",
        t.title,
        t.reference
            .as_deref()
            .map_or("the dissertation's single run".to_string(), |r| format!(
                "the {r} value"
            ))
    );
    layout_markdown(t, &heading, |cell| {
        paper_cell(a, cell, t.value.as_ref())
            .map(|(m, (lo, hi))| format!("{} [{}, {}]", sig(m, 3), sig(lo, 3), sig(hi, 3)))
    })
}

/// The same table in LaTeX (booktabs): ours above, the dissertation's number below in grey-free
/// parentheses, so it prints in black and white.
pub fn paper_table_latex(t: &crate::pipeline::suite::PaperTable, a: &Analysis) -> String {
    let caption = format!(
        "{} Ours: median over trials; {} in parentheses.",
        latex_escape(&sentence(&t.title)),
        latex_escape(
            t.reference
                .as_deref()
                .unwrap_or("the dissertation's single run")
        )
    );
    let mut body = String::new();
    for row in &t.rows {
        let ours: Vec<String> = row
            .cells
            .iter()
            .map(|c| match paper_cell(a, c, t.value.as_ref()) {
                Some((m, _)) => latex_num(m),
                None => "--".into(),
            })
            .collect();
        writeln!(
            body,
            "{} & {} \\\\",
            latex_escape(&row.label),
            ours.join(" & ")
        )
        .unwrap();
        if !row.seed.is_empty() {
            let seed: Vec<String> = row
                .seed
                .iter()
                .map(|v| {
                    if v.is_finite() {
                        format!("({})", latex_num(*v))
                    } else {
                        String::new()
                    }
                })
                .collect();
            writeln!(body, " & {} \\\\", seed.join(" & ")).unwrap();
        }
    }
    booktabs(
        &format!("{} ({})", t.id, a.suite),
        &caption,
        &t.columns,
        &body,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::TrialRecord;
    use crate::report::analysis::{ObjectiveInfo, analyse};

    fn rec(opt: &str, trial: usize, best: f64) -> TrialRecord {
        TrialRecord {
            objective: "f_1".into(),
            optimizer: opt.into(),
            trial,
            seed: String::new(),
            budget: 100,
            evaluations: 100,
            best,
            best_x: vec![0.0],
            optimum: Some(0.0),
            stopped_at_target: false,
            nonfinite: 0,
            penalised: 0,
            wall_s: 0.0,
            improvements: vec![(1, 10.0), (50, best)],
            checkpoints: vec![],
        }
    }

    /// "good" and "same" overlap; "bad" is far worse in every trial.
    fn analysis() -> Analysis {
        let mut r = Vec::new();
        for t in 0..12 {
            r.push(rec("good", t, 0.01 * (1.0 + t as f64)));
            r.push(rec("same", t, 0.01 * (1.5 + t as f64)));
            r.push(rec("bad", t, 5.0 + t as f64));
        }
        let info = [ObjectiveInfo {
            id: crate::base::SafeName::new("f_1").unwrap(),
            dim: 1,
            targets: vec![1.0, 0.05],
            label: None,
        }];
        analyse("s", 1, &info, &r, &Default::default())
    }

    #[test]
    fn latex_bolds_the_best_and_marks_significant_differences() {
        let a = analysis();
        let tex = summary_latex(&a);
        assert!(tex.contains("\\toprule") && tex.contains("\\bottomrule"));
        assert!(tex.contains("Objective & good & same & bad \\\\"), "{tex}");
        let row = tex.lines().find(|l| l.starts_with("f\\_1 &")).unwrap();
        let cells: Vec<&str> = row.trim_end_matches(" \\\\").split(" & ").collect();
        // Bold math: \textbf{$..$} would leave the digits regular.
        assert_eq!(cells[1], "{\\bfseries\\boldmath $0.0650$}");
        assert!(!tex.contains("\\textbf"), "{tex}");
        assert!(
            !cells[2].contains("dagger"),
            "overlapping runs are not different: {row}"
        );
        assert!(cells[3].ends_with("^{\\dagger}$"), "{row}");
    }

    #[test]
    fn ties_as_printed_are_all_bold_and_missing_cells_keep_their_column() {
        let mut r = Vec::new();
        for t in 0..6 {
            // "a" and "b" differ only past the third digit: they print alike.
            r.push(rec("a", t, 0.5 + 1e-9 * t as f64));
            r.push(rec("b", t, 0.5 + 2e-9 * t as f64));
            r.push(rec("c", t, 0.7));
        }
        let mut other = rec("c", 0, 0.1);
        other.objective = "g".into();
        r.push(other);
        let info = ["f_1", "g"].map(|id| ObjectiveInfo {
            id: crate::base::SafeName::new(id).unwrap(),
            dim: 1,
            targets: vec![],
            label: None,
        });
        let a = analyse("s", 1, &info, &r, &Default::default());
        assert_eq!(best_cells(&a.objectives[0]), [true, true, false]);
        let tex = summary_latex(&a);
        let row = |id: &str| -> Vec<String> {
            let l = tex.lines().find(|l| l.starts_with(id)).unwrap();
            l.trim_end_matches(" \\\\")
                .split(" & ")
                .map(String::from)
                .collect()
        };
        let f = row("f\\_1 &");
        assert!(
            f[1].contains("boldmath") && f[2].contains("boldmath"),
            "{tex}"
        );
        assert!(!f[3].contains("boldmath"), "{tex}");
        // `g` ran only "c": its number sits in c's column, the others say so.
        assert_eq!(
            row("g &")[1..],
            ["--", "--", "{\\bfseries\\boldmath $0.100$}"]
        );
        let md = summary_markdown(&a);
        assert_eq!(md.matches("**0.500 [").count(), 2, "{md}");
    }

    #[test]
    fn every_markdown_table_of_the_report_renders() {
        let a = analysis();
        let md = report_markdown(&a);
        // summary, ranks note (no table: one objective), fixed budget, ERT, pairwise.
        assert_eq!(crate::render::table::check_gfm_tables(&md), Ok(4), "{md}");
        let fixed = fixed_budget_markdown(&a);
        assert!(
            fixed.contains(
                "| optimizer | 1 (1% of budget) | 10 (10% of budget) | 100 (100% of budget) |"
            ),
            "{fixed}"
        );
    }

    #[test]
    fn markdown_and_csv_agree_with_the_analysis() {
        let a = analysis();
        let md = summary_markdown(&a);
        assert!(md.contains("**0.0650 ["), "{md}");
        let bad = md.lines().find(|l| l.contains("| bad")).unwrap();
        assert!(bad.trim_end().ends_with("* |"), "{bad}");
        let csv = csv_tables(&a);
        let table = |name: &str| csv.iter().find(|(n, _)| *n == name).unwrap().1.clone();
        let summary = table("summary.csv");
        assert_eq!(summary.lines().count(), 4);
        assert!(
            summary
                .lines()
                .nth(1)
                .unwrap()
                .starts_with("f_1,good,12,6.5e-2,")
        );
        let ert = table("ert.csv");
        // Every run reaches error 1.0 at evaluation 50 except "bad" (never).
        assert!(ert.contains("f_1,good,1e0,12,12,1,5e1"), "{ert}");
        assert!(ert.contains("f_1,bad,1e0,0,12,0,\n"), "{ert}");
    }
}
