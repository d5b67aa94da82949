//! The control suite's `report.md`: the plants, the tables, every cell, the comparisons,
//! the internal models and the figures.

use super::ControlSuite;
use super::run::{ControlResults, ModelRecord};
use super::tables::{cell_text, comparison_markdown, table_markdown};
use crate::control::run::Identification;
use crate::render::table::{markdown, sig};
use crate::stats::describe;
use std::collections::BTreeMap;

/// The report: tables, the models, the comparisons, and the figures.
pub(super) fn report_markdown(
    suite: &ControlSuite,
    res: &ControlResults,
    figures: &[String],
) -> String {
    let mut s = format!("# {}\n\n", suite.name);
    if let Some(d) = &suite.description {
        s += &format!("{d}\n\n");
    }
    s += &format!(
        "Seed {}, {} trials per cell (each trial: its own sensor-noise realisation and its own PSO fit of the internal model); loop at 1 ms; transient = first {} s. Failed runs (the divergence guard tripped: |u| > {} V, |y| > {} mm or NaN) count as +inf.\n\n",
        suite.seed, suite.trials, suite.transient, suite.guard.u_limit, suite.guard.y_limit
    );
    s += "## Plants\n\n";
    for p in &suite.plants {
        s += &format!(
            "- `{}`: twin `{}`, internal model identified on twin `{}`{}\n",
            p.id,
            if p.twin.is_empty() {
                "default"
            } else {
                &p.twin
            },
            p.model_twin.as_deref().unwrap_or(if p.twin.is_empty() {
                "default"
            } else {
                &p.twin
            }),
            p.description
                .as_ref()
                .map(|d| format!(": {d}"))
                .unwrap_or_default()
        );
    }
    s += "\n## Tables\n\n";
    for t in &suite.tables {
        s += &table_markdown(t, suite, res);
        s.push('\n');
    }
    s += "## Every cell\n\n";
    let rows: Vec<Vec<String>> = res
        .cells
        .iter()
        .map(|c| {
            vec![
                c.plant.clone(),
                c.controller.clone(),
                c.reference.clone(),
                cell_text(c, false),
                cell_text(c, true),
            ]
        })
        .collect();
    s += &markdown(
        &[
            "plant",
            "controller",
            "reference",
            "RMSE [mm] whole run",
            "RMSE [mm] after transient",
        ],
        &rows,
        &[false, false, false, true, true],
    );
    s += "\n";
    s += &comparison_markdown(suite, res);
    if !res.models.is_empty() {
        s += "\n## Identified models\n\n";
        let mut by: BTreeMap<usize, Vec<&ModelRecord>> = BTreeMap::new();
        for m in &res.models {
            by.entry(m.setting).or_default().push(m);
        }
        for (setting, ms) in by {
            let free: Vec<f64> = ms.iter().map(|m| m.free_run_rmse_mm).collect();
            let df = describe(&free);
            let rmse = format!(
                "RMSE on the identification record over {} fits: free run median {} [q1 {}, q3 {}] mm",
                ms.len(),
                sig(df.median, 3),
                sig(df.q1, 3),
                sig(df.q3, 3),
            );
            let twin = |t: &str| {
                if t.is_empty() {
                    "default".to_string()
                } else {
                    t.to_string()
                }
            };
            s += &match &ms[0].config {
                Identification::Rbf(c) => {
                    let one: Vec<f64> = ms.iter().filter_map(|m| m.one_step_rmse_mm).collect();
                    format!(
                        "- setting {setting}: {}-{}-1 RBF NARX ({} input, {} output lags), PSO {} x {} evaluations, {} cost, identified on twin `{}` with `{}` for {} s; {rmse}, one-step {} mm\n",
                        c.input_lags + c.output_lags,
                        c.hidden,
                        c.input_lags,
                        c.output_lags,
                        c.swarm,
                        c.budget,
                        c.mode,
                        twin(&c.twin),
                        c.signal,
                        c.duration,
                        sig(describe(&one).median, 3)
                    )
                }
                Identification::Inverse(c) => format!(
                    "- setting {setting}: inverted model {}, identified on twin `{}` with `{}` for {} s; {rmse}\n",
                    c.model.describe(),
                    twin(&c.twin),
                    c.signal,
                    c.duration,
                ),
            };
        }
    }
    if !figures.is_empty() {
        s += "\n## Figures (trial 0 of each cell)\n\n";
        for f in figures {
            s += &format!("- [{f}](figures/{f}.png)\n");
        }
    }
    s += "\n## Files\n\n`runs.jsonl` (one line per run: seeds, metrics, failure), `models.jsonl` (every fitted internal model with its parameters), `summary.json` (cell statistics), `tables/` (Markdown, LaTeX, `cells.csv`), `signals/` (trial 0 of each cell as CSV), `figures/` (SVG and PNG), `provenance.json`.\n";
    s
}

/// What the statistics of the report mean (Markdown, for `report.html`).
pub(super) fn statistics_markdown(suite: &ControlSuite) -> String {
    format!(
        "Every cell (plant x controller x reference) runs {trials} trials; a trial has its own \
         sensor-noise realisation and, for IMC, its own PSO fit of the internal model, so the \
         spread over trials is the spread a rerun of the experiment would show. A run whose \
         divergence guard trips counts as +inf: a cell's median is finite only while fewer \
         than half its runs failed.

- **RMSE [mm]**: root mean square of reference minus output over the whole run; \
  **after transient**: from {transient} s on.
- **Median [lo, hi]**: the middle RMSE over the trials and a 95 % percentile-bootstrap \
  interval of it ({resamples} resamples, seeded); an upper end of ∞ means failed runs reach into \
  the interval.
- **Ratio**: median RMSE of the second controller / median of the first.
- **p (Wilcoxon)**: two-sided Wilcoxon signed-rank test over paired trials (both controllers \
  of a trial see the same noise realisation), the test to read. **p (MW)**: the unpaired \
  Mann-Whitney U test, for comparison; pairing removes the noise both share, so it is \
  the weaker of the two here.
- **A12**: the probability that the first controller's RMSE is larger than the second's \
  in a random pair of trials (0.5: no difference); **first wins**: paired trials where the \
  first is lower.
- **(dissertation x)**: the dissertation's single run, beside our median over trials.",
        trials = suite.trials,
        transient = suite.transient,
        resamples = super::tables::RESAMPLES
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::suite::SMALL;
    use std::path::Path;

    #[test]
    fn the_report_names_plants_tables_cells_and_figures() {
        let suite = ControlSuite::parse(SMALL, Path::new("c.toml")).unwrap();
        let res = ControlResults {
            runs: Vec::new(),
            models: Vec::new(),
            cells: Vec::new(),
        };
        let md = report_markdown(&suite, &res, &["rmse_twin_sine5".to_string()]);
        for part in [
            "# small\n",
            "Seed 5, 3 trials per cell",
            "- `twin`: twin `default`, internal model identified on twin `default`\n",
            "- `creep`: twin `creep=on`, internal model identified on twin `creep=on`\n",
            "**Table 1**",
            "## Every cell",
            "- [rmse_twin_sine5](figures/rmse_twin_sine5.png)",
        ] {
            assert!(md.contains(part), "{part:?} missing in\n{md}");
        }
        assert!(
            !md.contains("## Identified models"),
            "no model-based controller, no models section"
        );
        // The paper tables (one per [[table]]) and every cell render as GFM tables.
        let tables = crate::render::table::check_gfm_tables(&md);
        assert_eq!(tables, Ok(suite.tables.len() + 2), "{md}");
    }
}
