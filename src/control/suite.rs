//! Control suites: every controller x reference x plant over seeded noise realisations,
//! run by `optbench run` when the suite file has a `[control]` section.
//!
//! ```toml
//! name = "control"
//! seed = 2013
//! trials = 30
//!
//! [control]
//! references = ["sweep-1-2hz", "sweep-1-10hz", { id = "sine5", spec = "sine:freq=5,amp=0.2,offset=0.3", duration = 3.0 }]
//! transient = 1.0            # s, optional (default 1)
//! figures = true             # optional: draw trial 0 of every cell (default true)
//!
//! [[controller]]
//! id = "IMC-RBF"
//! kind = "imc-rbf"           # or "pid"; every other key is a parameter (optbench control --help)
//! learning_rate = 0.1
//!
//! [[plant]]
//! id = "twin"                # the default twin; several [[plant]]s give mismatch studies
//! twin = ""                  # twin overrides of the plant in the loop
//! model_twin = "mode=off"    # optional: the twin the internal model is identified on
//! references = ["sweep-1-2hz"]   # optional subsets
//! controllers = ["IMC-RBF"]
//!
//! [[table]]                  # optional paper-layout tables, cells "CONTROLLER/PLANT/REFERENCE"
//! id = "table4.1"
//! title = "Table 4.1: RMS error at different frequencies [mm]"
//! value = "rmse"             # or "rmse_steady" (after the transient)
//! columns = ["1-3 Hz", "1-4 Hz", "1-10 Hz"]
//! rows = [{ label = "IMC-RBF", cells = ["IMC-RBF/twin/sweep-1-3hz", ...], seed = [0.0028, 0.0031, 0.0067] }]
//! ```
//!
//! Seeds: the internal model of trial `t` is fitted once per identification setting from
//! [`model_seed`] and shared by every reference (identify once, then run experiments); the
//! sensor noise of (reference, plant, trial) comes from [`noise_seed`] and is the same for
//! every controller, so controllers are compared on the same realisations. Runs execute in
//! parallel and are stored in plan order: the same seed gives the same bytes on any number
//! of threads.

use super::closed_loop::Guard;
use super::figures::write_run_figures;
use super::model::{FittedModel, ModelFitConfig};
use super::reference::Reference;
use super::run::{ControllerSpec, DEFAULT_TRANSIENT_S, Metrics, RunSpec};
use super::single::{model_seed, noise_seed, run_csv};
use crate::base::error::{Error, Result};
use crate::base::{TrialSeed, atomic_write};
use crate::render::latex::{booktabs, latex_escape};
use crate::render::table::{markdown, sig};
use crate::stats::{a12, bootstrap_median_ci, describe, mann_whitney};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// Whether suite text is a control suite (has a `[control]` table).
pub fn is_control_suite(text: &str) -> bool {
    toml::from_str::<toml::Table>(text)
        .map(|t| t.get("control").is_some_and(|v| v.is_table()))
        .unwrap_or(false)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSuite {
    name: Spanned<String>,
    #[serde(default)]
    description: Option<String>,
    seed: Spanned<i64>,
    trials: Spanned<i64>,
    control: Spanned<RawControl>,
    #[serde(rename = "controller", default)]
    controllers: Vec<Spanned<BTreeMap<String, Spanned<toml::Value>>>>,
    #[serde(rename = "plant", default)]
    plants: Vec<Spanned<RawPlant>>,
    #[serde(rename = "table", default)]
    tables: Vec<Spanned<ControlTable>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawControl {
    references: Vec<Spanned<RawReference>>,
    #[serde(default)]
    transient: Option<f64>,
    #[serde(default)]
    figures: Option<bool>,
    #[serde(default)]
    u_limit: Option<f64>,
    #[serde(default)]
    y_limit: Option<f64>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum RawReference {
    Name(String),
    Table {
        id: Option<String>,
        spec: String,
        duration: Option<f64>,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlant {
    id: String,
    #[serde(default)]
    twin: String,
    #[serde(default)]
    model_twin: Option<String>,
    #[serde(default)]
    references: Option<Vec<String>>,
    #[serde(default)]
    controllers: Option<Vec<String>>,
    #[serde(default)]
    description: Option<String>,
}

/// A paper-layout table of a control suite: cells `CONTROLLER/PLANT/REFERENCE`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ControlTable {
    pub id: String,
    pub title: String,
    /// `rmse` (whole run, default) or `rmse_steady` (after the transient).
    #[serde(default)]
    pub value: Option<String>,
    #[serde(default)]
    pub note: Option<String>,
    pub columns: Vec<String>,
    pub rows: Vec<ControlRow>,
}

/// One row of a [`ControlTable`].
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ControlRow {
    pub label: String,
    pub cells: Vec<String>,
    /// The seed's numbers, one per column (nan or missing: none).
    #[serde(default)]
    pub seed: Vec<f64>,
}

/// A named controller of a suite.
#[derive(Debug, Clone)]
pub struct ControllerEntry {
    pub id: String,
    pub spec: ControllerSpec,
}

/// A plant of a suite (twin overrides, and the twin its internal models are identified on).
#[derive(Debug, Clone)]
pub struct PlantEntry {
    pub id: String,
    pub twin: String,
    pub model_twin: Option<String>,
    pub description: Option<String>,
    /// Indices into the suite's references and controllers.
    pub references: Vec<usize>,
    pub controllers: Vec<usize>,
}

/// A validated control suite.
#[derive(Debug, Clone)]
pub struct ControlSuite {
    pub path: PathBuf,
    pub text: String,
    pub name: String,
    pub description: Option<String>,
    pub seed: u64,
    pub trials: usize,
    pub transient: f64,
    pub figures: bool,
    pub guard: Guard,
    pub references: Vec<Reference>,
    pub controllers: Vec<ControllerEntry>,
    pub plants: Vec<PlantEntry>,
    pub tables: Vec<ControlTable>,
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

fn valid_id(s: &str) -> bool {
    !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
}

fn value_text(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// One planned run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlannedRun {
    pub plant: usize,
    pub controller: usize,
    pub reference: usize,
    pub trial: usize,
}

impl ControlSuite {
    /// Reads and validates a control suite.
    pub fn load(path: &Path) -> Result<ControlSuite> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Error::Input(format!("{}: cannot read suite: {e}", path.display())))?;
        Self::parse(&text, path)
    }

    /// Validates suite text; errors name the file, line and key.
    pub fn parse(text: &str, path: &Path) -> Result<ControlSuite> {
        let at = |offset: usize, msg: String| Error::at(path, line_of(text, offset), msg);
        let raw: RawSuite = toml::from_str(text).map_err(|e| {
            let line = e.span().map(|s| line_of(text, s.start)).unwrap_or(1);
            Error::at(path, line, e.message().trim_end())
        })?;
        let name = raw.name.get_ref().clone();
        if !valid_id(&name) || name.starts_with('.') {
            return Err(at(
                raw.name.span().start,
                format!("`name` = {name:?}: use letters, digits, '-', '_' or '.'"),
            ));
        }
        let seed = u64::try_from(*raw.seed.get_ref())
            .map_err(|_| at(raw.seed.span().start, "`seed` must be >= 0".into()))?;
        let trials = *raw.trials.get_ref();
        if trials < 1 {
            return Err(at(
                raw.trials.span().start,
                format!("`trials` = {trials}: expected an integer >= 1"),
            ));
        }
        let control_at = raw.control.span().start;
        let control = raw.control.into_inner();
        let transient = control.transient.unwrap_or(DEFAULT_TRANSIENT_S);
        let mut guard = Guard::default();
        if let Some(u) = control.u_limit {
            guard.u_limit = u;
        }
        if let Some(y) = control.y_limit {
            guard.y_limit = y;
        }
        if !(guard.u_limit > 0.0 && guard.y_limit > 0.0) {
            return Err(at(
                control_at,
                "[control] `u_limit` and `y_limit` must be > 0".into(),
            ));
        }

        let mut references: Vec<Reference> = Vec::new();
        for r in &control.references {
            let line_at = r.span().start;
            let reference = match r.get_ref() {
                RawReference::Name(n) => Reference::parse(n, None),
                RawReference::Table { id, spec, duration } => Reference::parse(spec, *duration)
                    .map(|mut r| {
                        if let Some(id) = id {
                            r.name = id.clone();
                        }
                        r
                    }),
            }
            .map_err(|e| at(line_at, format!("[control] references: {e}")))?;
            if !valid_id(&reference.name) {
                return Err(at(
                    line_at,
                    format!(
                        "reference `{}`: give it an `id` (letters, digits, '-', '_', '.'): {{ id = \"...\", spec = \"...\" }}",
                        reference.name
                    ),
                ));
            }
            if references.iter().any(|x| x.name == reference.name) {
                return Err(at(
                    line_at,
                    format!("reference `{}` is listed twice", reference.name),
                ));
            }
            if !(transient >= 0.0 && transient < reference.duration) {
                return Err(at(
                    control_at,
                    format!(
                        "[control] `transient` = {transient}: must be in [0, {}) (reference `{}`)",
                        reference.duration, reference.name
                    ),
                ));
            }
            references.push(reference);
        }
        if references.is_empty() {
            return Err(at(control_at, "[control] `references` is empty".into()));
        }

        if raw.controllers.is_empty() {
            return Err(Error::at(path, 1, "the suite has no [[controller]]"));
        }
        let mut controllers: Vec<ControllerEntry> = Vec::new();
        for c in &raw.controllers {
            let line = line_of(text, c.span().start);
            let mut fields = c.get_ref().clone();
            let take = |fields: &mut BTreeMap<String, Spanned<toml::Value>>, key: &str| {
                fields.remove(key).map(|v| {
                    let l = line_of(text, v.span().start);
                    (v.into_inner(), l)
                })
            };
            let (kind, kline) = take(&mut fields, "kind").ok_or_else(|| {
                Error::at(path, line, "[[controller]] without `kind` (imc-rbf or pid)")
            })?;
            let kind = kind.as_str().map(String::from).ok_or_else(|| {
                Error::at(path, kline, "`kind`: expected a string (imc-rbf or pid)")
            })?;
            if !super::run::CONTROLLER_KINDS.contains(&kind.as_str()) {
                return Err(Error::at(
                    path,
                    kline,
                    format!(
                        "unknown controller kind `{kind}`; valid: {}",
                        super::run::CONTROLLER_KINDS.join(", ")
                    ),
                ));
            }
            let id = match take(&mut fields, "id") {
                Some((toml::Value::String(s), _)) => s,
                Some((_, l)) => return Err(Error::at(path, l, "`id`: expected a string")),
                None => kind.clone(),
            };
            if !valid_id(&id) {
                return Err(Error::at(
                    path,
                    line,
                    format!("controller id {id:?}: use letters, digits, '-', '_' or '.'"),
                ));
            }
            if controllers.iter().any(|x| x.id == id) {
                return Err(Error::at(
                    path,
                    line,
                    format!("controller id `{id}` is used twice"),
                ));
            }
            let params: Vec<(String, String)> = fields
                .iter()
                .map(|(k, v)| (k.clone(), value_text(v.get_ref())))
                .collect();
            let spec = ControllerSpec::parse(&kind, &params).map_err(|e| {
                // Point at the offending key when the message names one.
                let l = fields
                    .iter()
                    .find(|(k, _)| e.to_string().contains(&format!("`{k}`")))
                    .map(|(_, v)| line_of(text, v.span().start))
                    .unwrap_or(line);
                Error::at(path, l, format!("controller `{id}`: {e}"))
            })?;
            controllers.push(ControllerEntry { id, spec });
        }

        let raw_plants: Vec<Spanned<RawPlant>> = if raw.plants.is_empty() {
            vec![Spanned::new(
                0..0,
                RawPlant {
                    id: "twin".into(),
                    twin: String::new(),
                    model_twin: None,
                    references: None,
                    controllers: None,
                    description: None,
                },
            )]
        } else {
            raw.plants
        };
        let mut plants: Vec<PlantEntry> = Vec::new();
        for p in &raw_plants {
            let line = line_of(text, p.span().start);
            let rp = p.get_ref();
            let err = |m: String| Error::at(path, line, format!("plant `{}`: {m}", rp.id));
            if !valid_id(&rp.id) {
                return Err(err("use letters, digits, '-', '_' or '.' in `id`".into()));
            }
            if plants.iter().any(|x| x.id == rp.id) {
                return Err(err("the id is used twice".into()));
            }
            let select =
                |names: &Option<Vec<String>>, all: Vec<&str>, what: &str| -> Result<Vec<usize>> {
                    match names {
                        None => Ok((0..all.len()).collect()),
                        Some(ns) => ns
                            .iter()
                            .map(|n| {
                                all.iter().position(|x| x == n).ok_or_else(|| {
                                    err(format!(
                                        "`{what}` names `{n}`, not one of this suite's: {}",
                                        all.join(", ")
                                    ))
                                })
                            })
                            .collect(),
                    }
                };
            let refs = select(
                &rp.references,
                references.iter().map(|r| r.name.as_str()).collect(),
                "references",
            )?;
            let ctrls = select(
                &rp.controllers,
                controllers.iter().map(|c| c.id.as_str()).collect(),
                "controllers",
            )?;
            let entry = PlantEntry {
                id: rp.id.clone(),
                twin: rp.twin.clone(),
                model_twin: rp.model_twin.clone(),
                description: rp.description.clone(),
                references: refs,
                controllers: ctrls,
            };
            // Validate the twin overrides through a run spec.
            RunSpec {
                controller: controllers[0].spec.clone(),
                reference: references[0].clone(),
                plant: entry.twin.clone(),
                model_twin: entry.model_twin.clone(),
                guard,
                transient: 0.0,
            }
            .validate()
            .map_err(|e| err(e.to_string()))?;
            plants.push(entry);
        }

        let mut tables = Vec::new();
        for t in &raw.tables {
            let line = line_of(text, t.span().start);
            let tb = t.get_ref();
            check_table(tb, &controllers, &plants, &references)
                .map_err(|m| Error::at(path, line, format!("table `{}`: {m}", tb.id)))?;
            tables.push(tb.clone());
        }

        Ok(ControlSuite {
            path: path.to_path_buf(),
            text: text.to_string(),
            name,
            description: raw.description,
            seed,
            trials: trials as usize,
            transient,
            figures: control.figures.unwrap_or(true),
            guard,
            references,
            controllers,
            plants,
            tables,
        })
    }

    /// Every run, plant-major, then controller, reference, trial.
    pub fn plan(&self) -> Vec<PlannedRun> {
        let mut v = Vec::new();
        for (pi, p) in self.plants.iter().enumerate() {
            for &c in &p.controllers {
                for &r in &p.references {
                    for trial in 0..self.trials {
                        v.push(PlannedRun {
                            plant: pi,
                            controller: c,
                            reference: r,
                            trial,
                        });
                    }
                }
            }
        }
        v
    }

    /// The full specification of a planned run.
    pub fn run_spec(&self, r: &PlannedRun) -> RunSpec {
        let p = &self.plants[r.plant];
        RunSpec {
            controller: self.controllers[r.controller].spec.clone(),
            reference: self.references[r.reference].clone(),
            plant: p.twin.clone(),
            model_twin: p.model_twin.clone(),
            guard: self.guard,
            transient: self.transient,
        }
    }

    /// Sets the PSO budget of every internal-model fit (`optbench run --budget`).
    pub fn set_model_budget(&mut self, budget: u64) {
        for c in &mut self.controllers {
            if let ControllerSpec::ImcRbf(s) = &mut c.spec {
                s.model.budget = budget;
            }
        }
    }
}

/// Checks a table's shape and that each cell names a run of the suite.
fn check_table(
    t: &ControlTable,
    controllers: &[ControllerEntry],
    plants: &[PlantEntry],
    references: &[Reference],
) -> std::result::Result<(), String> {
    if let Some(v) = &t.value
        && !matches!(v.as_str(), "rmse" | "rmse_steady")
    {
        return Err(format!("`value` = `{v}`: expected rmse or rmse_steady"));
    }
    for row in &t.rows {
        if row.cells.len() != t.columns.len() {
            return Err(format!(
                "row `{}` has {} cells for {} columns",
                row.label,
                row.cells.len(),
                t.columns.len()
            ));
        }
        if !row.seed.is_empty() && row.seed.len() != t.columns.len() {
            return Err(format!(
                "row `{}` has {} seed values for {} columns",
                row.label,
                row.seed.len(),
                t.columns.len()
            ));
        }
        for c in &row.cells {
            cell_index(c, controllers, plants, references)?;
        }
    }
    Ok(())
}

/// (plant, controller, reference) indices of a cell `CONTROLLER/PLANT/REFERENCE` that runs.
fn cell_index(
    c: &str,
    controllers: &[ControllerEntry],
    plants: &[PlantEntry],
    references: &[Reference],
) -> std::result::Result<(usize, usize, usize), String> {
    let parts: Vec<&str> = c.split('/').map(str::trim).collect();
    let [ci, pi, ri] = parts[..] else {
        return Err(format!("cell `{c}`: expected CONTROLLER/PLANT/REFERENCE"));
    };
    let ctrl = controllers
        .iter()
        .position(|x| x.id == ci)
        .ok_or_else(|| format!("cell `{c}`: no controller `{ci}`"))?;
    let plant = plants
        .iter()
        .position(|x| x.id == pi)
        .ok_or_else(|| format!("cell `{c}`: no plant `{pi}`"))?;
    let reference = references
        .iter()
        .position(|x| x.name == ri)
        .ok_or_else(|| format!("cell `{c}`: no reference `{ri}`"))?;
    let p = &plants[plant];
    if !p.controllers.contains(&ctrl) || !p.references.contains(&reference) {
        return Err(format!("cell `{c}`: that combination does not run"));
    }
    Ok((plant, ctrl, reference))
}

/// One stored run: a line of `runs.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    pub controller: String,
    pub plant: String,
    pub reference: String,
    pub trial: usize,
    pub noise_seed: u64,
    /// Key of the internal model's fit (hex), for IMC runs.
    pub model_seed: Option<String>,
    pub metrics: Metrics,
}

/// One fitted internal model: a line of `models.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelRecord {
    /// Index of the identification setting (order of first use in the plan).
    pub setting: usize,
    pub trial: usize,
    pub seed: String,
    pub config: ModelFitConfig,
    pub evaluations: u64,
    pub free_run_rmse_mm: f64,
    pub one_step_rmse_mm: f64,
    pub params: Vec<f64>,
    pub u_scale: f64,
    pub y_scale: f64,
}

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
const RESAMPLES: usize = 2000;

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
fn finite_or_inf(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::INFINITY)
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
    let mut settings: Vec<(String, ModelFitConfig)> = Vec::new();
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

    let fitted: Vec<FittedModel> = pool.install(|| {
        fits.par_iter()
            .map(|&(s, trial)| {
                let (key, cfg) = &settings[s];
                cfg.fit(&model_seed(suite.seed, key, trial as u64))
            })
            .collect::<Result<Vec<_>>>()
    })?;
    let model_of = |s: usize, trial: usize| -> &FittedModel {
        let i = fits
            .binary_search(&(s, trial))
            .expect("every fit of the plan was run");
        &fitted[i]
    };

    let outcomes: Vec<(RunRecord, Option<super::run::Outcome>)> = pool.install(|| {
        plan.par_iter()
            .zip(&run_setting)
            .map(|(r, s)| {
                let spec = suite.run_spec(r);
                let plant = &suite.plants[r.plant];
                let nseed = noise_seed(suite.seed, &spec.reference.name, &plant.id, r.trial as u64);
                let model = s.map(|s| model_of(s, r.trial));
                let o = spec.execute(model, nseed)?;
                let record = RunRecord {
                    controller: suite.controllers[r.controller].id.clone(),
                    plant: plant.id.clone(),
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
        .map(|(&(s, trial), f)| ModelRecord {
            setting: s,
            trial,
            seed: model_seed(suite.seed, &settings[s].0, trial as u64).hex(),
            config: settings[s].1.clone(),
            evaluations: f.record.evaluations,
            free_run_rmse_mm: f.free_run_rmse,
            one_step_rmse_mm: f.one_step_rmse,
            params: f.model.params.clone(),
            u_scale: f.model.u_scale,
            y_scale: f.model.y_scale,
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
    let mkdir = |d: &Path| {
        std::fs::create_dir_all(d).map_err(|e| Error::io(format!("creating {}", d.display()), e))
    };
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
                        (id.clone(), v)
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

/// Statistics of every (plant, controller, reference) cell, in plan order.
fn cell_stats(suite: &ControlSuite, runs: &[RunRecord]) -> Vec<CellStats> {
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
                    controller: c.clone(),
                    plant: p.id.clone(),
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
fn cell_text(s: &CellStats, steady: bool) -> String {
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

fn table_cell(
    t: &ControlTable,
    suite: &ControlSuite,
    res: &ControlResults,
    c: &str,
) -> Option<String> {
    let (p, ci, ri) = cell_index(c, &suite.controllers, &suite.plants, &suite.references).ok()?;
    let s = find_cell(
        res,
        &suite.controllers[ci].id,
        &suite.plants[p].id,
        &suite.references[ri].name,
    )?;
    Some(cell_text(s, t.value.as_deref() == Some("rmse_steady")))
}

/// A paper-layout table: our median [95 % CI] over trials, the seed's number beside it.
pub fn table_markdown(t: &ControlTable, suite: &ControlSuite, res: &ControlResults) -> String {
    let mut header = vec![String::new()];
    header.extend(t.columns.iter().cloned());
    let rows: Vec<Vec<String>> = t
        .rows
        .iter()
        .map(|row| {
            let mut r = vec![row.label.clone()];
            for (i, c) in row.cells.iter().enumerate() {
                let ours = table_cell(t, suite, res, c).unwrap_or_else(|| "not run".into());
                r.push(match row.seed.get(i).copied().filter(|v| v.is_finite()) {
                    Some(v) => format!("{ours} (seed {})", sig(v, 3)),
                    None => ours,
                });
            }
            r
        })
        .collect();
    let h: Vec<&str> = header.iter().map(String::as_str).collect();
    let right: Vec<bool> = (0..h.len()).map(|i| i > 0).collect();
    let what = if t.value.as_deref() == Some("rmse_steady") {
        format!("RMSE [mm] after the first {} s", suite.transient)
    } else {
        "RMSE [mm] over the whole run".to_string()
    };
    let mut s = format!(
        "**{}** ({what}; ours: median [95% CI] over {} noise realisations and model fits, failed runs counted as +inf; the seed's single run in brackets)\n\n",
        t.title, suite.trials
    );
    s += &markdown(&h, &rows, &right);
    if let Some(n) = &t.note {
        s += &format!("\n{n}\n");
    }
    s
}

/// The same table in LaTeX (booktabs): ours, and the seed's number in parentheses.
pub fn table_latex(t: &ControlTable, suite: &ControlSuite, res: &ControlResults) -> String {
    let caption = format!(
        "{} Ours: median over {} trials [95\\% CI]; the seed's single run in parentheses.",
        latex_escape(&t.title),
        suite.trials
    );
    let mut body = String::new();
    for row in &t.rows {
        let cells: Vec<String> = row
            .cells
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let ours = table_cell(t, suite, res, c).unwrap_or_else(|| "--".into());
                match row.seed.get(i).copied().filter(|v| v.is_finite()) {
                    Some(v) => format!("{} ({})", latex_escape(&ours), sig(v, 3)),
                    None => latex_escape(&ours),
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

fn cells_csv(cells: &[CellStats]) -> String {
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

/// The first controller of each plant against every other, on each reference: ratio of median RMSEs,
/// two-sided Mann-Whitney p and A12 (probability that the first has the larger RMSE), and
/// in how many paired trials (same noise realisation) the first is better.
pub fn comparison_markdown(suite: &ControlSuite, res: &ControlResults) -> String {
    let mut rows = Vec::new();
    for p in &suite.plants {
        for &ri in &p.references {
            let r = &suite.references[ri].name;
            // The plant's first controller against each of the others.
            if let Some((&a, others)) = p.controllers.split_first() {
                for &b in others {
                    let (ca, cb) = (&suite.controllers[a].id, &suite.controllers[b].id);
                    let get = |c: &str| -> Vec<f64> {
                        let mut v: Vec<&RunRecord> = res
                            .runs
                            .iter()
                            .filter(|x| x.controller == c && x.plant == p.id && &x.reference == r)
                            .collect();
                        v.sort_by_key(|x| x.trial);
                        v.iter().map(|x| finite_or_inf(x.metrics.rmse_mm)).collect()
                    };
                    let (va, vb) = (get(ca), get(cb));
                    if va.is_empty() || vb.is_empty() {
                        continue;
                    }
                    let (ma, mb) = (describe(&va).median, describe(&vb).median);
                    let ratio = if ma.is_finite() && mb.is_finite() && ma > 0.0 {
                        sig(mb / ma, 3)
                    } else {
                        "—".into()
                    };
                    let mw = mann_whitney(&va, &vb);
                    let wins = va.iter().zip(&vb).filter(|(x, y)| x < y).count();
                    rows.push(vec![
                        p.id.clone(),
                        r.clone(),
                        format!("{ca} vs {cb}"),
                        ratio,
                        sig(mw.p_value, 2),
                        format!("{:.2}", a12(&va, &vb)),
                        format!("{wins}/{}", va.len().min(vb.len())),
                    ]);
                }
            }
        }
    }
    let mut s = String::from(
        "**Pairwise comparisons** (RMSE over the whole run; ratio = median of the second / median of the first; A12 = P(first's RMSE > second's); wins = paired trials, same noise, where the first is lower)\n\n",
    );
    s += &markdown(
        &[
            "plant",
            "reference",
            "pair",
            "ratio",
            "p (MW)",
            "A12",
            "first wins",
        ],
        &rows,
        &[false, false, false, true, true, true, true],
    );
    s
}

/// The report: tables, the models, the comparisons, and the figures.
fn report_markdown(suite: &ControlSuite, res: &ControlResults, figures: &[String]) -> String {
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
        s += "\n## Internal models\n\n";
        let mut by: BTreeMap<usize, Vec<&ModelRecord>> = BTreeMap::new();
        for m in &res.models {
            by.entry(m.setting).or_default().push(m);
        }
        for (setting, ms) in by {
            let free: Vec<f64> = ms.iter().map(|m| m.free_run_rmse_mm).collect();
            let one: Vec<f64> = ms.iter().map(|m| m.one_step_rmse_mm).collect();
            let (df, d1) = (describe(&free), describe(&one));
            let c = &ms[0].config;
            s += &format!(
                "- setting {setting}: {}-{}-1 RBF NARX ({} input, {} output lags), PSO {} x {} evaluations, {} cost, identified on twin `{}` with `{}` for {} s; RMSE on the identification record over {} fits: free run median {} [q1 {}, q3 {}] mm, one-step {} mm\n",
                c.input_lags + c.output_lags,
                c.hidden,
                c.input_lags,
                c.output_lags,
                c.swarm,
                c.budget,
                c.mode,
                if c.twin.is_empty() {
                    "default"
                } else {
                    &c.twin
                },
                c.signal,
                c.duration,
                ms.len(),
                sig(df.median, 3),
                sig(df.q1, 3),
                sig(df.q3, 3),
                sig(d1.median, 3)
            );
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

/// `optbench run` options as they apply to a control suite.
#[derive(Debug, Clone, Default)]
pub struct RunOverrides {
    pub out: Option<PathBuf>,
    pub trials: Option<usize>,
    pub threads: Option<usize>,
    pub seed: Option<u64>,
    /// PSO evaluations of every internal-model fit.
    pub budget: Option<u64>,
    pub quiet: bool,
}

/// `optbench run` on a control suite: load, apply the overrides, run, write, print.
pub fn run_cli(path: &Path, o: &RunOverrides) -> Result<()> {
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
    let text = run_suite(&suite, o.threads, &out)?;
    if !o.quiet {
        print!("{text}");
        println!("\nresults and report: {}", out.display());
    }
    Ok(())
}
