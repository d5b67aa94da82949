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
//! kind = "imc-rbf"           # or "pid", "ff-pi", "ff-bw", "ff-pi+pid", "ff-bw+pid"; every
//!                            # other key is a parameter (optbench control --help)
//! learning_rate = 0.1
//!
//! [[plant]]
//! id = "twin"                # the default twin; several [[plant]]s give mismatch studies
//! twin = ""                  # twin overrides of the plant in the loop
//! model_twin = "mode=off"    # optional: the twin the IMC's and feedforwards' models are identified on
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
use super::reference::Reference;
use super::run::{ControllerSpec, DEFAULT_TRANSIENT_S, RunSpec};
use crate::base::SafeName;
use crate::base::error::Result;
use crate::base::name::RESERVED_TABLE_IDS;
use crate::pipeline::suite::PaperTable;
use crate::pipeline::suite::text::{self, Fields, Header, SuiteText, value_text};
use serde::Deserialize;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use toml::Spanned;

mod report;
mod run;
mod tables;

pub use run::{ControlResults, ModelRecord, RunOverrides, RunRecord, run_file, run_suite};
pub use tables::{CellStats, MetricStats, comparison_markdown, table_latex, table_markdown};

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
    controllers: Vec<Spanned<Fields>>,
    #[serde(rename = "plant", default)]
    plants: Vec<Spanned<RawPlant>>,
    #[serde(rename = "table", default)]
    tables: Vec<Spanned<PaperTable>>,
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

/// A named controller of a suite.
#[derive(Debug, Clone)]
pub struct ControllerEntry {
    /// Names figure and signal files.
    pub id: SafeName,
    pub spec: ControllerSpec,
}

/// A plant of a suite (twin overrides, and the twin its internal models are identified on).
#[derive(Debug, Clone)]
pub struct PlantEntry {
    /// Names figure and signal files.
    pub id: SafeName,
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
    /// Names the results folder.
    pub name: SafeName,
    pub description: Option<String>,
    pub seed: u64,
    pub trials: usize,
    pub transient: f64,
    pub figures: bool,
    pub guard: Guard,
    pub references: Vec<Reference>,
    pub controllers: Vec<ControllerEntry>,
    pub plants: Vec<PlantEntry>,
    pub tables: Vec<PaperTable>,
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
        Self::parse(&text::read(path)?, path)
    }

    /// Validates suite text; errors name the file, line and key.
    pub fn parse(text: &str, path: &Path) -> Result<ControlSuite> {
        let st = SuiteText::new(path, text);
        let raw: RawSuite = st.parse()?;
        let Header { name, seed, trials } = st.header(&raw.name, &raw.seed, &raw.trials)?;
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
            return Err(st.at(control_at, "[control] `u_limit` and `y_limit` must be > 0"));
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
            .map_err(|e| st.at(line_at, format!("[control] references: {e}")))?;
            if let Err(why) = SafeName::new(&reference.name) {
                return Err(st.at(
                    line_at,
                    format!(
                        "reference `{}` {why}; give it an `id`: {{ id = \"...\", spec = \"...\" }}",
                        reference.name
                    ),
                ));
            }
            if references.iter().any(|x| x.name == reference.name) {
                return Err(st.at(
                    line_at,
                    format!("reference `{}` is listed twice", reference.name),
                ));
            }
            if !(transient >= 0.0 && transient < reference.duration) {
                return Err(st.at(
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
            return Err(st.at(control_at, "[control] `references` is empty"));
        }

        if raw.controllers.is_empty() {
            return Err(st.on(1, "the suite has no [[controller]]"));
        }
        let mut controllers: Vec<ControllerEntry> = Vec::new();
        let mut ids = BTreeSet::new();
        for c in &raw.controllers {
            let (line, mut fields) = (st.line(c.span().start), c.get_ref().clone());
            let kind = *st.take_kind(
                &super::run::CONTROLLER_KINDS,
                |k| *k,
                &mut fields,
                line,
                "controller",
            )?;
            // An id names files, which take no '+': `ff-pi+pid` defaults to `ff-pi-pid`.
            let id = st
                .take_str(&mut fields, "id")?
                .unwrap_or_else(|| kind.replace('+', "-"));
            let id = st.check_id(&id, &mut ids, line, "controller", &[])?;
            let params: Vec<(String, String)> = fields
                .iter()
                .map(|(k, v)| (k.clone(), value_text(v.get_ref())))
                .collect();
            let spec = ControllerSpec::parse(kind, &params).map_err(|e| {
                // Point at the offending key when the message names one.
                let l = fields
                    .iter()
                    .find(|(k, _)| e.to_string().contains(&format!("`{k}`")))
                    .map(|(_, v)| st.line(v.span().start))
                    .unwrap_or(line);
                st.on(l, format!("controller `{id}`: {e}"))
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
        let mut plant_ids = BTreeSet::new();
        let mut stems_seen = BTreeSet::new();
        for p in &raw_plants {
            let line = st.line(p.span().start);
            let rp = p.get_ref();
            let err = |m: String| st.on(line, format!("plant `{}`: {m}", rp.id));
            let id = st.check_id(&rp.id, &mut plant_ids, line, "plant", &[])?;
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
                id,
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
            // Figure and signal files join ids with '_', which ids may contain too.
            let mut stems: Vec<String> = Vec::new();
            for &r in &entry.references {
                let reference = &references[r].name;
                stems.push(format!("rmse_{}_{reference}", entry.id));
                for &c in &entry.controllers {
                    stems.push(format!("{}_{}_{reference}_", controllers[c].id, entry.id));
                }
            }
            for stem in stems {
                if !stems_seen.insert(stem.to_ascii_lowercase()) {
                    return Err(err(format!(
                        "its figure files `{stem}...` would overwrite another run's (ids are joined with '_'); rename a controller, plant or reference"
                    )));
                }
            }
            plants.push(entry);
        }

        let mut tables = Vec::new();
        let mut ids = BTreeSet::new();
        for t in &raw.tables {
            let line = st.line(t.span().start);
            let tb = t.get_ref();
            st.check_id(&tb.id, &mut ids, line, "table", RESERVED_TABLE_IDS)?;
            check_table(tb, &controllers, &plants, &references)
                .map_err(|m| st.on(line, format!("table `{}`: {m}", tb.id)))?;
            tables.push(tb.clone());
        }

        Ok(ControlSuite {
            path: path.to_path_buf(),
            text: text.to_string(),
            name,
            description: raw.description,
            seed,
            trials,
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

    /// Sets the budget of every iterative model fit (`optbench run --budget`): the IMC's PSO
    /// and the Bouc-Wen feedforward's CMA-ES (a PI fit is closed-form).
    pub fn set_model_budget(&mut self, budget: u64) {
        for c in &mut self.controllers {
            match &mut c.spec {
                ControllerSpec::ImcRbf(s) => s.model.budget = budget,
                ControllerSpec::Feedforward(f) => f.fit.model.set_budget(budget),
                ControllerSpec::Pid(_) => {}
            }
        }
    }
}

/// Checks a table's shape and that each cell names a run of the suite.
fn check_table(
    t: &PaperTable,
    controllers: &[ControllerEntry],
    plants: &[PlantEntry],
    references: &[Reference],
) -> std::result::Result<(), String> {
    if let Some(v) = &t.value
        && !matches!(v.as_str(), "rmse" | "rmse_steady")
    {
        return Err(format!("`value` = `{v}`: expected rmse or rmse_steady"));
    }
    t.check_shape()?;
    for row in &t.rows {
        for c in &row.cells {
            cell_index(c, controllers, plants, references)?;
        }
    }
    Ok(())
}

/// (plant, controller, reference) indices of a cell `CONTROLLER/PLANT/REFERENCE` that runs.
pub(super) fn cell_index(
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

/// A small control suite for the tests of this module and its parts: two PID tunings on a
/// short sine, two plants, one paper table.
#[cfg(test)]
pub(super) const SMALL: &str = r#"name = "small"
seed = 5
trials = 3

[control]
references = [{ id = "sine5", spec = "sine:freq=5,amp=0.2,offset=0.3", duration = 0.6 }]
transient = 0.2
figures = false

[[controller]]
id = "P"
kind = "pid"
ki = 0.2

[[controller]]
id = "PI"
kind = "pid"
ki = 0.4

[[plant]]
id = "twin"

[[plant]]
id = "creep"
twin = "creep=on"
controllers = ["PI"]

[[table]]
id = "t1"
title = "Table 1"
columns = ["twin", "creep"]
rows = [{ label = "PI", cells = ["PI/twin/sine5", "PI/creep/sine5"], seed = [0.01, nan] }]
"#;

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<ControlSuite> {
        ControlSuite::parse(text, Path::new("c.toml"))
    }

    fn error(text: &str) -> String {
        match parse(text) {
            Ok(_) => panic!("expected an error"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn a_suite_plans_plant_major_with_each_plants_selection() {
        let s = parse(SMALL).unwrap();
        assert!(is_control_suite(SMALL));
        assert_eq!((s.name.as_str(), s.seed, s.trials), ("small", 5, 3));
        let plan = s.plan();
        // twin: both controllers; creep: PI only; one reference; three trials each.
        assert_eq!(plan.len(), (2 + 1) * 3);
        assert_eq!(
            plan.iter()
                .map(|r| (r.plant, r.controller))
                .collect::<Vec<_>>()[..4],
            [(0, 0), (0, 0), (0, 0), (0, 1)]
        );
        assert!(plan[6..].iter().all(|r| (r.plant, r.controller) == (1, 1)));
        let spec = s.run_spec(&plan[6]);
        assert_eq!((spec.plant.as_str(), spec.transient), ("creep=on", 0.2));
        assert_eq!(s.tables[0].rows[0].cells.len(), 2);
    }

    #[test]
    fn errors_name_the_line_and_what_is_valid() {
        let bad_kind = SMALL.replace("kind = \"pid\"\nki = 0.2", "kind = \"lqr\"\nki = 0.2");
        let m = error(&bad_kind);
        assert!(
            m.contains("c.toml:12") && m.contains("lqr") && m.contains("imc-rbf, pid"),
            "{m}"
        );
        let twice = SMALL.replace("id = \"PI\"", "id = \"P\"");
        let m = error(&twice);
        assert!(m.contains("c.toml:15") && m.contains("used twice"), "{m}");
        let bad_plant = SMALL.replace("controllers = [\"PI\"]", "controllers = [\"PID\"]");
        let m = error(&bad_plant);
        assert!(m.contains("plant `creep`") && m.contains("`PID`"), "{m}");
        let bad_cell = SMALL.replace("PI/creep/sine5", "PI/creep/sine9");
        let m = error(&bad_cell);
        assert!(
            m.contains("c.toml:28") && m.contains("no reference `sine9`"),
            "{m}"
        );
        let not_run = SMALL.replace(
            "\"PI/twin/sine5\", \"PI/creep/sine5\"",
            "\"PI/twin/sine5\", \"P/creep/sine5\"",
        );
        let m = error(&not_run);
        assert!(m.contains("does not run"), "{m}");
        let short_row = SMALL.replace("seed = [0.01, nan]", "seed = [0.01]");
        let m = error(&short_row);
        assert!(m.contains("1 seed values for 2 columns"), "{m}");
        let escape = SMALL.replace("id = \"P\"\n", "id = \"../P\"\n");
        let m = error(&escape);
        assert!(m.contains("c.toml:10") && m.contains("use letters"), "{m}");
        // `P_x` on `twin` and `P` on `x_twin` would draw into the same files.
        let joined = SMALL
            .replace("id = \"PI\"", "id = \"P_x\"")
            .replace("id = \"creep\"", "id = \"x_twin\"")
            .replace("controllers = [\"PI\"]", "controllers = [\"P\"]");
        let m = error(&joined);
        assert!(
            m.contains("c.toml:23") && m.contains("P_x_twin_sine5_"),
            "{m}"
        );
        let late = SMALL.replace("transient = 0.2", "transient = 0.6");
        assert!(error(&late).contains("`transient` = 0.6"));
    }

    #[test]
    fn the_model_budget_override_reaches_every_imc_fit() {
        let imc = SMALL.replace("kind = \"pid\"\nki = 0.4", "kind = \"imc-rbf\"");
        let mut s = parse(&imc).unwrap();
        s.set_model_budget(123);
        let budgets: Vec<u64> = s
            .controllers
            .iter()
            .filter_map(|c| match &c.spec {
                ControllerSpec::ImcRbf(x) => Some(x.model.budget),
                _ => None,
            })
            .collect();
        assert_eq!(budgets, [123]);
    }
}
