//! Suites: a TOML file naming objectives, optimizers, seed, trials and budget. Loading a
//! suite validates everything (kinds, parameters, ranges) before any trial runs, with
//! errors that name the file, the line and the key.
//!
//! ```toml
//! name = "functions"      # results go to results/<name>/
//! seed = 2013             # every random stream derives from it
//! trials = 30             # seeded repeats of every objective x optimizer
//! budget = 40000          # function evaluations per trial (or budget_per_dim = k: k x dim)
//! targets = [1e-2, 1e-4]  # optional: error-to-optimum levels for fixed-target views
//! stop_at = 1e-8          # optional: end a trial once its error reaches this
//!
//! [[objective]]
//! kind = "griewank"       # see `optbench list`
//! id = "griewank-2d"      # optional name in results (default: kind-<dim>d)
//! dim = 2
//! budget = 40000          # optional per-objective override (also targets, stop_at)
//! optimizers = ["MSGA"]   # optional: only these optimizer ids run on this objective
//! # instances = "1-15"    # kinds with an `instance` key: trial t runs instances[t mod n]
//!
//! [bbob]                  # optional: COCO's BBOB functions x dimensions (see [`bbob`])
//! dimensions = [2, 5]
//!
//! [[optimizer]]
//! kind = "msga"
//! id = "MSGA"             # optional name in results (default: the kind)
//! polish = 0.1            # optional: Nelder-Mead polish of the best point, last 10 % of the budget
//! polish_with = "lbfgs"   # optional: the polish's method, "nelder-mead" (default) or "lbfgs"
//! objects = 40
//! ```
//!
//! Errors are measured to the objective's known optimum, or to 0 where none is known (cost
//! functions), so `targets` and `stop_at` mean the same thing for both.

use crate::base::error::Result;
use crate::base::limits;
use crate::base::name::RESERVED_TABLE_IDS;
use crate::base::params::Params;
use crate::base::{SafeName, TrialSeed};
use crate::harness::OptimizerConfig;
use crate::objective::Objective;
use crate::pipeline::external::{EXTERNAL_KIND, EXTERNAL_PARAMS, ExternalConfig};
use crate::registry::{RECORDING_KEYS, anchor_recordings, objective_kinds, optimizer_kinds};
use serde::Deserialize;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use text::{Fields as RawEntry, Header, SuiteText};
use toml::Spanned;

pub mod bbob;
pub mod instances;
pub mod paper;
pub mod text;

pub use paper::{CellRef, FIT_TIME, PaperRow, PaperTable};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSuite {
    name: Spanned<String>,
    #[serde(default)]
    description: Option<String>,
    seed: Spanned<i64>,
    trials: Spanned<i64>,
    #[serde(default)]
    budget: Option<Spanned<i64>>,
    #[serde(default)]
    budget_per_dim: Option<Spanned<i64>>,
    #[serde(default)]
    targets: Option<Spanned<Vec<f64>>>,
    #[serde(default)]
    stop_at: Option<Spanned<f64>>,
    #[serde(rename = "objective", default)]
    objectives: Vec<Spanned<RawEntry>>,
    #[serde(rename = "optimizer", default)]
    optimizers: Vec<Spanned<RawEntry>>,
    #[serde(rename = "table", default)]
    tables: Vec<Spanned<PaperTable>>,
    #[serde(default)]
    bbob: Option<Spanned<RawEntry>>,
}

/// One objective of a suite, built and validated.
pub struct ObjectiveEntry {
    /// Name in results (and in plot and IOHprofiler file names).
    pub id: SafeName,
    pub kind: &'static str,
    pub objective: Arc<dyn Objective>,
    /// Evaluations per trial.
    pub budget: u64,
    /// Error levels for fixed-target statistics.
    pub targets: Vec<f64>,
    /// Error at which a trial ends early.
    pub stop_at: Option<f64>,
    /// Indices of the optimizers that run on this objective (default: all).
    pub optimizers: Vec<usize>,
    /// The parameters as given (with an `instances` list: those of its first instance).
    pub params: Params,
    /// With an `instances` list: each instance's number and objective, in list order
    /// (`objective` is the first's); empty otherwise.
    pub instances: Vec<(usize, Arc<dyn Objective>)>,
}

impl ObjectiveEntry {
    /// The objective trial `trial` runs: instance `instances[trial mod n]` where the entry
    /// has a list (COCO's one run per instance), else the one objective. Its dimension,
    /// bounds and kind are those of every other instance; its optimum is its own.
    pub fn objective_of(&self, trial: usize) -> &Arc<dyn Objective> {
        match self.instances.len() {
            0 => &self.objective,
            n => &self.instances[trial % n].1,
        }
    }

    /// The instance number trial `trial` runs, where the entry has an `instances` list.
    pub fn instance_of(&self, trial: usize) -> Option<usize> {
        (!self.instances.is_empty()).then(|| self.instances[trial % self.instances.len()].0)
    }

    /// The value at which trial `trial` stops, from `stop_at` (in presented units where the
    /// objective has a presentation, else as an error to its instance's known optimum).
    pub fn stop_value(&self, trial: usize) -> Option<f64> {
        let s = self.stop_at?;
        let o = self.objective_of(trial);
        Some(match o.presentation() {
            Some(p) => p.invert(s),
            None => o.optimum().unwrap_or(0.0) + s,
        })
    }
}

/// One optimizer of a suite, validated.
pub struct OptimizerEntry {
    /// Name in results (and the IOHprofiler export's folder).
    pub id: SafeName,
    pub kind: &'static str,
    pub config: Arc<dyn OptimizerConfig>,
    pub params: Params,
}

/// A validated suite.
pub struct Suite {
    pub path: PathBuf,
    /// The file as read with its recordings' relative paths made absolute: what a results
    /// folder stores, so its copy finds the same files wherever it lies (`report`,
    /// `--resume`, `merge` read it), and what the run's fingerprint hashes.
    pub text: String,
    /// Names the results folder.
    pub name: SafeName,
    pub description: Option<String>,
    pub seed: u64,
    pub trials: usize,
    pub objectives: Vec<ObjectiveEntry>,
    pub optimizers: Vec<OptimizerEntry>,
    /// Paper-layout tables for the report.
    pub tables: Vec<PaperTable>,
}

/// One (objective, optimizer, trial) cell of the plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlannedTrial {
    pub objective: usize,
    pub optimizer: usize,
    pub trial: usize,
}

impl Suite {
    /// Reads and validates the suite at `path`.
    pub fn load(path: &Path) -> Result<Suite> {
        Self::parse(&text::read(path)?, path)
    }

    /// Validates suite text; `path` is used in messages and provenance.
    pub fn parse(text: &str, path: &Path) -> Result<Suite> {
        let st = SuiteText::new(path, text);
        let raw: RawSuite = st.parse()?;
        let Header { name, seed, trials } = st.header(&raw.name, &raw.seed, &raw.trials)?;
        let spanned_int =
            |v: &Option<Spanned<i64>>| v.as_ref().map(|v| (*v.get_ref(), st.line(v.span().start)));
        let suite_budget = (spanned_int(&raw.budget), spanned_int(&raw.budget_per_dim));
        if suite_budget.0.is_some() || suite_budget.1.is_some() {
            instances::budget((None, None), suite_budget, 1).map_err(|(l, m)| st.on(l, m))?;
        }
        let targets = match &raw.targets {
            Some(t) => check_targets(t.get_ref()).map_err(|m| st.at(t.span().start, m))?,
            None => Vec::new(),
        };
        let stop_at = match &raw.stop_at {
            Some(s) => {
                Some(check_level(*s.get_ref(), "stop_at").map_err(|m| st.at(s.span().start, m))?)
            }
            None => None,
        };
        let mut entries = match &raw.bbob {
            Some(section) => bbob::expand(&st, section)?,
            None => Vec::new(),
        };
        entries.extend(raw.objectives.iter().cloned());
        if entries.is_empty() {
            return Err(st.on(1, "the suite has no [[objective]] (nor a [bbob] section)"));
        }
        if raw.optimizers.is_empty() {
            return Err(st.on(1, "the suite has no [[optimizer]]"));
        }

        let kinds = objective_kinds();
        let mut objectives = Vec::new();
        let mut selections = Vec::new();
        let mut ids = BTreeSet::new();
        let base = path.parent().unwrap_or(Path::new(""));
        let mut anchored = Vec::new();
        for entry in &entries {
            let (line, mut fields) = (st.line(entry.span().start), entry.get_ref().clone());
            let kind = st.take_kind(&kinds, |k| k.name, &mut fields, line, "objective")?;
            for key in RECORDING_KEYS {
                if let Some(v) = fields.get_mut(key)
                    && kind.params.iter().any(|s| s.name == key)
                    && let toml::Value::String(spec) = v.get_ref()
                    && let Some(a) = anchor_recordings(spec, base)
                {
                    anchored.push((v.span(), a.clone()));
                    *v.get_mut() = toml::Value::String(a);
                }
            }
            let id = st.take_str(&mut fields, "id")?;
            let own_budget = (
                st.take_int(&mut fields, "budget")?,
                st.take_int(&mut fields, "budget_per_dim")?,
            );
            let numbers = instance_list(&st, &mut fields, kind, line)?;
            let own_targets = st.take_floats(&mut fields, "targets")?;
            let own_stop = st.take_float(&mut fields, "stop_at")?;
            let only = st.take_array(&mut fields, "optimizers", "strings", |x| {
                x.as_str().map(String::from)
            })?;
            let what = format!("objective `{}`", id.as_deref().unwrap_or(kind.name));
            let given = st.given(fields);
            let mut instances = Vec::new();
            let mut first = None;
            // A refused instance is reported at the `instances` line.
            for (n, at) in numbers
                .iter()
                .flat_map(|(ns, at)| ns.iter().map(move |&n| (n, *at)))
            {
                let mut given = given.clone();
                given.insert("instance".into(), (toml::Value::Integer(n as i64), at));
                let what = format!("{what}, instance {n}");
                let params = Params::validate(kind.params, &given, st.origin(line, what))?;
                instances.push((n, (kind.build)(&params)?));
                first.get_or_insert(params);
            }
            let params = match first {
                Some(p) => p,
                None => Params::validate(kind.params, &given, st.origin(line, what))?,
            };
            let objective = match instances.first() {
                Some((_, o)) => Arc::clone(o),
                None => (kind.build)(&params)?,
            };
            // A benchmark-suite member is named by its problem (`bbob-f03-i02-d05`), or by
            // function and dimension over an `instances` list (`bbob-f03-d05`), so several of
            // one kind and dimension need no ids of their own.
            let id = id.unwrap_or_else(|| match objective.suite_id() {
                Some(s) if !instances.is_empty() => bbob::objective_id(s.function, objective.dim()),
                Some(_) => objective.name().to_string(),
                None => format!("{}-{}d", kind.name, objective.dim()),
            });
            let id = st.check_id(&id, &mut ids, line, "objective", &[])?;
            let budget = instances::budget(own_budget, suite_budget, objective.dim()).map_err(
                |(l, m)| {
                    st.on(
                        if l == 0 { line } else { l },
                        format!("objective `{id}`: {m}"),
                    )
                },
            )?;
            let targets = match own_targets {
                Some((t, l)) => check_targets(&t).map_err(|m| st.on(l, m))?,
                None => targets.clone(),
            };
            let stop_at = match own_stop {
                Some((s, l)) => Some(check_level(s, "stop_at").map_err(|m| st.on(l, m))?),
                None => stop_at,
            };
            objectives.push(ObjectiveEntry {
                id,
                kind: kind.name,
                objective,
                budget,
                targets,
                stop_at,
                optimizers: Vec::new(),
                params,
                instances,
            });
            selections.push(only);
        }

        let kinds = optimizer_kinds();
        let mut optimizers = Vec::new();
        let mut ids = BTreeSet::new();
        for entry in &raw.optimizers {
            let (line, mut fields) = (st.line(entry.span().start), entry.get_ref().clone());
            if fields.get("kind").and_then(|k| k.get_ref().as_str()) == Some(EXTERNAL_KIND) {
                optimizers.push(external_entry(&st, fields, line, &mut ids)?);
                continue;
            }
            let kind = st.take_kind(&kinds, |k| k.name, &mut fields, line, "optimizer")?;
            let id = st
                .take_str(&mut fields, "id")?
                .unwrap_or_else(|| kind.name.into());
            let polish = st.take_float(&mut fields, "polish")?;
            let polish_line = fields.get("polish_with").map(|v| st.line(v.span().start));
            let polish_with = st.take_str(&mut fields, "polish_with")?;
            let id = st.check_id(&id, &mut ids, line, "optimizer", &[])?;
            let params = Params::validate(
                kind.params,
                &st.given(fields),
                st.origin(line, format!("optimizer `{id}`")),
            )?;
            let mut config = (kind.build)(&params)?;
            if let Some((share, line)) = polish {
                if !(share > 0.0 && share < 1.0) {
                    return Err(st.on(
                        line,
                        format!(
                            "optimizer `{id}`: `polish` = {share}: expected a budget share in (0, 1)"
                        ),
                    ));
                }
                let local =
                    crate::optimizer::polish_method(polish_with.as_deref()).map_err(|m| {
                        st.on(
                            polish_line.unwrap_or(line),
                            format!("optimizer `{id}`: {m}"),
                        )
                    })?;
                config = Arc::new(crate::optimizer::nelder_mead::PolishedConfig {
                    global: config,
                    share,
                    local,
                });
            } else if let Some(l) = polish_line {
                return Err(st.on(
                    l,
                    format!(
                        "optimizer `{id}`: `polish_with` needs `polish` = a budget share in (0, 1)"
                    ),
                ));
            }
            optimizers.push(OptimizerEntry {
                id,
                kind: kind.name,
                config,
                params,
            });
        }

        for (obj, only) in objectives.iter_mut().zip(selections) {
            obj.optimizers = match only {
                None => (0..optimizers.len()).collect(),
                Some((names, line)) => names
                    .iter()
                    .map(|n| {
                        optimizers.iter().position(|o| &o.id == n).ok_or_else(|| {
                            st.on(
                                line,
                                format!(
                                    "objective `{}`: `optimizers` names `{n}`, which is not an optimizer id of this suite ({})",
                                    obj.id,
                                    optimizers.iter().map(|o| o.id.as_str()).collect::<Vec<_>>().join(", ")
                                ),
                            )
                        })
                    })
                    .collect::<Result<Vec<_>>>()?,
            };
        }
        for (i, opt) in optimizers
            .iter()
            .enumerate()
            .filter(|(_, o)| o.config.needs_gradient())
        {
            if let Some(obj) = objectives
                .iter()
                .find(|o| o.optimizers.contains(&i) && !o.objective.has_gradient())
            {
                return Err(opt.params.entry_error(format!(
                    "needs the objective's gradient, but objective `{}` is a black box; \
                     leave it out of that objective's `optimizers` list",
                    obj.id
                )));
            }
        }

        let mut tables = Vec::new();
        // Metric names come from evaluating an objective's metrics (a simulation of each of
        // its recordings), so each objective is asked once for all tables.
        let mut metric_names = BTreeMap::new();
        let mut ids = BTreeSet::new();
        for t in &raw.tables {
            let line = st.line(t.span().start);
            st.check_id(&t.get_ref().id, &mut ids, line, "table", RESERVED_TABLE_IDS)?;
            check_table(t.get_ref(), &objectives, &optimizers, &mut metric_names)
                .map_err(|m| st.on(line, format!("table `{}`: {m}", t.get_ref().id)))?;
            tables.push(t.get_ref().clone());
        }

        // Replaced back to front, so the spans ahead stay valid.
        anchored.sort_by_key(|(span, _)| span.start);
        let mut text = text.to_string();
        for (span, a) in anchored.into_iter().rev() {
            text.replace_range(span, &toml::Value::String(a).to_string());
        }
        let suite = Suite {
            tables,
            path: path.to_path_buf(),
            text,
            name,
            description: raw.description,
            seed,
            trials,
            objectives,
            optimizers,
        };
        if let Some(o) = suite.objectives.iter().find(|o| o.instances.len() > trials) {
            return Err(st.at(
                raw.trials.span().start,
                format!(
                    "`trials` = {trials}, but objective `{}` lists {} instances, so some would never run (trial t runs instance t mod n); set `trials` to at least {} (a multiple runs each equally often)",
                    o.id,
                    o.instances.len(),
                    o.instances.len()
                ),
            ));
        }
        if let Some(m) = suite.plan_too_large() {
            return Err(st.at(raw.trials.span().start, format!("`trials` = {trials}: {m}")));
        }
        Ok(suite)
    }

    /// Why the plan's trial records would not fit in memory (see
    /// [`limits::trial_memory`]), if they would not.
    pub fn plan_too_large(&self) -> Option<String> {
        let bytes = self
            .objectives
            .iter()
            .map(|o| {
                let n = (o.optimizers.len() as u64).saturating_mul(self.trials as u64);
                limits::trial_memory(n, o.objective.dim())
            })
            .fold(0u64, u64::saturating_add);
        (bytes > limits::BUDGET_BYTES).then(|| {
            format!(
                "the plan's trial records would take {bytes} B, above the budget of {} B (fewer trials, objectives or optimizers)",
                limits::BUDGET_BYTES
            )
        })
    }

    /// Every trial, objective-major, in a fixed order.
    pub fn plan(&self) -> Vec<PlannedTrial> {
        let mut plan = Vec::new();
        for (objective, entry) in self.objectives.iter().enumerate() {
            for &optimizer in &entry.optimizers {
                for trial in 0..self.trials {
                    plan.push(PlannedTrial {
                        objective,
                        optimizer,
                        trial,
                    });
                }
            }
        }
        plan
    }

    /// The random key of a planned trial.
    pub fn seed_of(&self, t: &PlannedTrial) -> TrialSeed {
        TrialSeed::derive(
            self.seed,
            &self.objectives[t.objective].id,
            &self.optimizers[t.optimizer].id,
            t.trial as u64,
        )
    }
}

/// An `[[optimizer]]` of kind `external`: one that runs outside optbench
/// ([`crate::pipeline::external`]); `id` is required (it is the optimizer's only name), and
/// `description` says what it is.
fn external_entry(
    st: &SuiteText<'_>,
    mut fields: RawEntry,
    line: usize,
    ids: &mut BTreeSet<String>,
) -> Result<OptimizerEntry> {
    fields.remove("kind");
    let id = st.take_str(&mut fields, "id")?.ok_or_else(|| {
        st.on(
            line,
            "optimizer of kind `external` without `id`: give it the name its results carry",
        )
    })?;
    let id = st.check_id(&id, ids, line, "optimizer", &[])?;
    let params = Params::validate(
        EXTERNAL_PARAMS,
        &st.given(fields),
        st.origin(line, format!("optimizer `{id}`")),
    )?;
    Ok(OptimizerEntry {
        id,
        kind: EXTERNAL_KIND,
        config: Arc::new(ExternalConfig {
            description: params.opt_str("description").map(String::from),
        }),
        params,
    })
}

/// Checks a paper table's shape and that every cell names an objective x optimizer that
/// runs (and, for `@metric`, a metric the objective reports).
fn check_table(
    t: &PaperTable,
    objectives: &[ObjectiveEntry],
    optimizers: &[OptimizerEntry],
    names: &mut BTreeMap<String, Vec<String>>,
) -> std::result::Result<(), String> {
    t.check_shape()?;
    for row in &t.rows {
        for c in &row.cells {
            let r = CellRef::parse(c)
                .ok_or_else(|| format!("cell `{c}`: expected objective:optimizer[@metric]"))?;
            let obj = objectives
                .iter()
                .find(|o| o.id == r.objective)
                .ok_or_else(|| format!("cell `{c}`: no objective `{}`", r.objective))?;
            let opt = optimizers
                .iter()
                .position(|o| o.id == r.optimizer)
                .ok_or_else(|| format!("cell `{c}`: no optimizer `{}`", r.optimizer))?;
            if !obj.optimizers.contains(&opt) {
                return Err(format!(
                    "cell `{c}`: `{}` does not run on `{}`",
                    r.optimizer, r.objective
                ));
            }
            if let Some(m) = r.metric.as_ref().or(t.value.as_ref()) {
                let names = names.entry(obj.id.to_string()).or_insert_with(|| {
                    let b = obj.objective.bounds();
                    let mid: Vec<f64> = b
                        .lower()
                        .iter()
                        .zip(b.upper())
                        .map(|(l, u)| 0.5 * (l + u))
                        .collect();
                    obj.objective
                        .metrics(&mid)
                        .into_iter()
                        .map(|m| m.name)
                        .collect()
                });
                if m != FIT_TIME && !names.contains(m) {
                    return Err(format!(
                        "cell `{c}`: objective `{}` reports no metric `{m}`; it reports: {}",
                        r.objective,
                        names.join(", ")
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The entry's `instances` list and its line, refused where its kind takes no `instance` or the entry
/// also sets one.
fn instance_list(
    st: &SuiteText<'_>,
    fields: &mut RawEntry,
    kind: &crate::registry::ObjectiveKind,
    line: usize,
) -> Result<Option<(Vec<usize>, usize)>> {
    let Some(v) = fields.remove("instances") else {
        return Ok(None);
    };
    let at = st.line(v.span().start);
    if !kind.params.iter().any(|s| s.name == "instance") {
        return Err(st.on(
            at,
            format!(
                "objective kind `{}` takes no `instance`, so no `instances` list; kinds with instances take an `instance` key (see `optbench list`)",
                kind.name
            ),
        ));
    }
    if let Some(i) = fields.get("instance") {
        return Err(st.on(
            st.line(i.span().start).max(line),
            "both `instance` and `instances` are set; give one of them",
        ));
    }
    instances::parse_list(v.get_ref(), "instances")
        .map(|n| Some((n, at)))
        .map_err(|m| st.on(at, m))
}

fn check_level(x: f64, key: &str) -> std::result::Result<f64, String> {
    if x.is_finite() && x >= 0.0 {
        Ok(x)
    } else {
        Err(format!("`{key}` = {x}: expected an error level >= 0"))
    }
}

fn check_targets(t: &[f64]) -> std::result::Result<Vec<f64>, String> {
    let mut v = t
        .iter()
        .map(|&x| check_level(x, "targets"))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    v.sort_by(|a, b| b.total_cmp(a));
    v.dedup();
    Ok(v)
}
