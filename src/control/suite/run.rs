//! Running a control suite: the internal models fitted once per identification setting and
//! trial, every run in parallel, and everything written into the results folder.

use super::ControlSuite;
use super::report::report_markdown;
use super::tables::{
    CellStats, cell_stats, cells_csv, comparison_markdown, finite_or_inf, table_latex,
    table_markdown,
};
use crate::base::atomic_write;
use crate::base::error::{Error, Result};
use crate::control::figures::write_run_figures;
use crate::control::run::{Identification, Identified, Metrics};
use crate::control::single::{model_seed, noise_seed, run_csv};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// One stored run: a line of `runs.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    pub controller: String,
    pub plant: String,
    pub reference: String,
    pub trial: usize,
    pub noise_seed: u64,
    /// Key of the model's fit (hex), for model-based runs.
    pub model_seed: Option<String>,
    pub metrics: Metrics,
}

/// One fitted model (an IMC's internal model or a feedforward's inverted one): a line of
/// `models.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelRecord {
    /// Index of the identification setting (order of first use in the plan).
    pub setting: usize,
    pub trial: usize,
    pub seed: String,
    pub config: Identification,
    pub evaluations: u64,
    pub free_run_rmse_mm: f64,
    /// RBF NARX models only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub one_step_rmse_mm: Option<f64>,
    /// RBF NARX: the network's vector in normalised units (see `u_scale`, `y_scale`); inverted
    /// models: the values of `param_names`.
    pub params: Vec<f64>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub param_names: Vec<String>,
    pub u_scale: f64,
    pub y_scale: f64,
}

impl ModelRecord {
    fn new(
        setting: usize,
        trial: usize,
        seed: String,
        config: Identification,
        f: &Identified,
    ) -> Self {
        let (one_step, params, param_names, u_scale, y_scale) = match f {
            Identified::Rbf(m) => (
                Some(m.one_step_rmse),
                m.model.params.clone(),
                Vec::new(),
                m.model.u_scale,
                m.model.y_scale,
            ),
            Identified::Inverse(m) => (
                None,
                m.params.iter().map(|p| p.1).collect(),
                m.params.iter().map(|p| p.0.clone()).collect(),
                1.0,
                1.0,
            ),
        };
        ModelRecord {
            setting,
            trial,
            seed,
            config,
            evaluations: f.evaluations(),
            free_run_rmse_mm: f.free_run_rmse(),
            one_step_rmse_mm: one_step,
            params,
            param_names,
            u_scale,
            y_scale,
        }
    }
}

/// Everything a control suite produced.
#[derive(Debug, Clone)]
pub struct ControlResults {
    pub runs: Vec<RunRecord>,
    pub models: Vec<ModelRecord>,
    pub cells: Vec<CellStats>,
}

/// Runs a control suite on `threads` threads (None: one per core), writes `out`, and returns
/// the printed text (the paper tables).
pub fn run_suite(suite: &ControlSuite, threads: Option<usize>, out: &Path) -> Result<String> {
    let started = std::time::SystemTime::now();
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        builder = builder.num_threads(n);
    }
    let pool = builder
        .build()
        .map_err(|e| Error::Input(format!("cannot start {threads:?} threads: {e}")))?;
    let plan = suite.plan();

    // Identification settings in order of first use, and the (setting, trial) fits.
    let mut settings: Vec<(String, Identification)> = Vec::new();
    let mut run_setting: Vec<Option<usize>> = Vec::with_capacity(plan.len());
    for r in &plan {
        let idx = suite.run_spec(r).model_config().map(|m| {
            let key = serde_json::to_string(&m).expect("serialisable");
            match settings.iter().position(|(k, _)| *k == key) {
                Some(i) => i,
                None => {
                    settings.push((key, m));
                    settings.len() - 1
                }
            }
        });
        run_setting.push(idx);
    }
    let mut fits: Vec<(usize, usize)> = plan
        .iter()
        .zip(&run_setting)
        .filter_map(|(r, s)| s.map(|s| (s, r.trial)))
        .collect();
    fits.sort_unstable();
    fits.dedup();

    let fitted: Vec<Identified> = pool.install(|| {
        fits.par_iter()
            .map(|&(s, trial)| {
                let (key, cfg) = &settings[s];
                cfg.fit(&model_seed(suite.seed, key, trial as u64))
            })
            .collect::<Result<Vec<_>>>()
    })?;
    let model_of = |s: usize, trial: usize| -> &Identified {
        let i = fits
            .binary_search(&(s, trial))
            .expect("every fit of the plan was run");
        &fitted[i]
    };

    let outcomes: Vec<(RunRecord, Option<crate::control::run::Outcome>)> = pool.install(|| {
        plan.par_iter()
            .zip(&run_setting)
            .map(|(r, s)| {
                let spec = suite.run_spec(r);
                let plant = &suite.plants[r.plant];
                let nseed = noise_seed(suite.seed, &spec.reference.name, &plant.id, r.trial as u64);
                let model = s.map(|s| model_of(s, r.trial));
                let o = spec.execute(model, nseed)?;
                let record = RunRecord {
                    controller: suite.controllers[r.controller].id.to_string(),
                    plant: plant.id.to_string(),
                    reference: spec.reference.name.clone(),
                    trial: r.trial,
                    noise_seed: nseed,
                    model_seed: s
                        .map(|s| model_seed(suite.seed, &settings[s].0, r.trial as u64).hex()),
                    metrics: o.metrics.clone(),
                };
                // Keep the signals of trial 0 for the figures.
                let keep = suite.figures && r.trial == 0;
                Ok((record, keep.then_some(o)))
            })
            .collect::<Result<Vec<_>>>()
    })?;

    let models: Vec<ModelRecord> = fits
        .iter()
        .zip(&fitted)
        .map(|(&(s, trial), f)| {
            let seed = model_seed(suite.seed, &settings[s].0, trial as u64).hex();
            ModelRecord::new(s, trial, seed, settings[s].1.clone(), f)
        })
        .collect();
    let runs: Vec<RunRecord> = outcomes.iter().map(|(r, _)| r.clone()).collect();
    let cells = cell_stats(suite, &runs);
    let results = ControlResults {
        runs,
        models,
        cells,
    };

    // Write: everything into the folder, each file atomically.
    let mkdir = |d: &Path| crate::base::create_dir_within(out, d);
    mkdir(out)?;
    let mut figures = Vec::new();
    if suite.figures {
        let fig_dir = out.join("figures");
        mkdir(&fig_dir)?;
        let sig_dir = out.join("signals");
        mkdir(&sig_dir)?;
        let drawn: Vec<Result<Vec<String>>> = pool.install(|| {
            outcomes
                .par_iter()
                .filter_map(|(r, o)| o.as_ref().map(|o| (r, o)))
                .map(|(r, o)| {
                    let prefix = format!("{}_{}_{}_", r.controller, r.plant, r.reference);
                    atomic_write(
                        &sig_dir.join(format!("{prefix}trial0.csv")),
                        run_csv(o).as_bytes(),
                    )?;
                    let title = format!("{} on {} ({})", r.controller, r.reference, r.plant);
                    write_run_figures(&fig_dir, &prefix, &title, &o.run, suite.transient)
                })
                .collect()
        });
        for d in drawn {
            figures.extend(d?);
        }
        for p in &suite.plants {
            for &ri in &p.references {
                let reference = &suite.references[ri].name;
                let groups: Vec<(String, Vec<f64>)> = p
                    .controllers
                    .iter()
                    .map(|&ci| {
                        let id = &suite.controllers[ci].id;
                        let v = results
                            .runs
                            .iter()
                            .filter(|r| {
                                &r.controller == id && r.plant == p.id && &r.reference == reference
                            })
                            .map(|r| finite_or_inf(r.metrics.rmse_mm))
                            .collect();
                        (id.to_string(), v)
                    })
                    .collect();
                let stem = format!("rmse_{}_{}", p.id, reference);
                crate::render::boxplot(
                    &fig_dir.join(&stem),
                    &format!(
                        "RMS tracking error, {reference} ({}), {} trials",
                        p.id, suite.trials
                    ),
                    &groups,
                    "RMSE [mm]",
                    true,
                )?;
                figures.push(stem);
            }
        }
    }
    let report = report_markdown(suite, &results, &figures);
    atomic_write(&out.join("suite.toml"), suite.text.as_bytes())?;
    let lines = |v: &[String]| v.iter().map(|l| format!("{l}\n")).collect::<String>();
    let run_lines: Vec<String> = results
        .runs
        .iter()
        .map(|r| serde_json::to_string(r).expect("serialisable"))
        .collect();
    atomic_write(&out.join("runs.jsonl"), lines(&run_lines).as_bytes())?;
    let model_lines: Vec<String> = results
        .models
        .iter()
        .map(|m| serde_json::to_string(m).expect("serialisable"))
        .collect();
    atomic_write(&out.join("models.jsonl"), lines(&model_lines).as_bytes())?;
    let summary = serde_json::to_string_pretty(&results.cells).expect("serialisable");
    atomic_write(&out.join("summary.json"), summary.as_bytes())?;
    let tables_dir = out.join("tables");
    mkdir(&tables_dir)?;
    for t in &suite.tables {
        atomic_write(
            &tables_dir.join(format!("{}.md", t.id)),
            table_markdown(t, suite, &results).as_bytes(),
        )?;
        atomic_write(
            &tables_dir.join(format!("{}.tex", t.id)),
            table_latex(t, suite, &results).as_bytes(),
        )?;
    }
    atomic_write(
        &tables_dir.join("cells.csv"),
        cells_csv(&results.cells).as_bytes(),
    )?;
    atomic_write(&out.join("report.md"), report.as_bytes())?;
    let prov = crate::pipeline::store::Provenance::of_run(
        &suite.name,
        &suite.path,
        suite.seed,
        suite.trials,
        pool.current_num_threads(),
        started,
    );
    atomic_write(
        &out.join("provenance.json"),
        serde_json::to_string_pretty(&prov)
            .expect("serialisable")
            .as_bytes(),
    )?;
    crate::report::html::write(
        out,
        &crate::report::html::Page {
            title: &format!(
                "optbench control suite: {} (seed {})",
                suite.name, suite.seed
            ),
            markdown: &report,
            statistics: &super::report::statistics_markdown(suite),
            figures: &out.join("figures"),
            figures_link: "figures/",
            figure_groups: &[],
            provenance: &out.join("provenance.json"),
        },
    )?;

    let mut text = format!(
        "control suite {} (seed {}, {} trials, {} threads, {:.1} s)\n\n",
        suite.name,
        suite.seed,
        suite.trials,
        pool.current_num_threads(),
        prov.wall_s
    );
    for t in &suite.tables {
        text += &table_markdown(t, suite, &results);
        text.push('\n');
    }
    text += &comparison_markdown(suite, &results);
    Ok(text)
}

/// `optbench run` options as they apply to a control suite.
#[derive(Debug, Clone, Default)]
pub struct RunOverrides {
    pub out: Option<PathBuf>,
    pub trials: Option<usize>,
    pub threads: Option<usize>,
    pub seed: Option<u64>,
    /// Evaluations of every iterative model fit (the IMC's PSO, the Bouc-Wen CMA-ES).
    pub budget: Option<u64>,
    pub quiet: bool,
    /// See `pipeline::run::RunRequest::overwrite`.
    pub overwrite: bool,
}

/// `optbench run` on a control suite: load, apply the overrides, run and write; returns the
/// text to print.
pub fn run_file(path: &Path, o: &RunOverrides) -> Result<String> {
    let mut suite = ControlSuite::load(path)?;
    if let Some(t) = o.trials {
        suite.trials = t;
    }
    if let Some(s) = o.seed {
        suite.seed = s;
    }
    if let Some(b) = o.budget {
        suite.set_model_budget(b);
    }
    let out = o
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results").join(&suite.name));
    if out.is_file() {
        return Err(Error::Input(format!(
            "--out {}: is a file, expected a folder",
            out.display()
        )));
    }
    let _lock = crate::pipeline::store::lock_and_claim(&out, &suite.name, o.overwrite)?;
    // Every file is written anew (no resume): none of an earlier run may stay beside them.
    crate::pipeline::store::output::clear_written(&out)?;
    let text = run_suite(&suite, o.threads, &out)?;
    Ok(if o.quiet {
        String::new()
    } else {
        format!("{text}\nresults and report: {}\n", out.display())
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::suite::SMALL;

    fn small() -> ControlSuite {
        ControlSuite::parse(SMALL, Path::new("c.toml")).unwrap()
    }

    #[test]
    fn a_run_writes_every_file_and_the_same_bytes_on_any_number_of_threads() {
        let tmp = tempfile::tempdir().unwrap();
        let (one, two) = (tmp.path().join("one"), tmp.path().join("two"));
        let text = run_suite(&small(), Some(1), &one).unwrap();
        run_suite(&small(), Some(2), &two).unwrap();
        assert!(
            text.contains("Table 1") && text.contains("Pairwise comparisons"),
            "{text}"
        );
        for f in [
            "runs.jsonl",
            "models.jsonl",
            "summary.json",
            "tables/t1.md",
            "tables/t1.tex",
            "tables/cells.csv",
            "report.md",
        ] {
            let a = std::fs::read(one.join(f)).unwrap();
            assert_eq!(a, std::fs::read(two.join(f)).unwrap(), "{f}");
        }
        let runs: Vec<RunRecord> = std::fs::read_to_string(one.join("runs.jsonl"))
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(runs.len(), small().plan().len());
        // PID needs no internal model.
        assert!(
            std::fs::read_to_string(one.join("models.jsonl"))
                .unwrap()
                .is_empty()
        );
        // Controllers on one plant and reference share each trial's noise realisation.
        let noise = |c: &str, t: usize| {
            runs.iter()
                .find(|r| r.controller == c && r.plant == "twin" && r.trial == t)
                .unwrap()
                .noise_seed
        };
        assert_eq!(noise("P", 1), noise("PI", 1));
        assert_ne!(noise("P", 1), noise("P", 2));
        assert!(!one.join("figures").exists());
    }

    #[test]
    fn overrides_apply_and_quiet_prints_nothing() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("c.toml");
        std::fs::write(&path, SMALL).unwrap();
        let out = tmp.path().join("r");
        let o = RunOverrides {
            out: Some(out.clone()),
            trials: Some(1),
            seed: Some(9),
            quiet: true,
            ..RunOverrides::default()
        };
        assert_eq!(run_file(&path, &o).unwrap(), "");
        let lines = std::fs::read_to_string(out.join("runs.jsonl")).unwrap();
        assert_eq!(lines.lines().count(), 3);
        let file = tmp.path().join("file");
        std::fs::write(&file, "").unwrap();
        let o = RunOverrides {
            out: Some(file),
            ..RunOverrides::default()
        };
        assert!(
            run_file(&path, &o)
                .unwrap_err()
                .to_string()
                .contains("is a file")
        );
    }
}
