//! Runs of an optimizer that lives outside optbench (a Python user's, through the `optbench`
//! package in `python/`): it runs a suite's plan against the crate's own [`Evaluator`], so
//! its results folder is what `optbench run` would have written for a built-in optimizer —
//! the same trial seeds, budgets counted in the one place that counts them, the same
//! records (improvements, checkpoints), progress log, provenance and summary — and
//! `optbench report` analyses it and `optbench merge` sets it beside a built-in run.
//!
//! ```text
//! let mut run = ExternalRun::open(suite, "mypso", None, ExternalOptions::default())?;
//! for i in run.pending() {
//!     let mut t = run.start(i)?;        // seed, bounds, budget in t.info()
//!     while let Ok(v) = t.evaluate(&x) { ... }   // Err(EvalError::Exhausted) ends it
//!     run.finish(t)?;                   // appended to progress.jsonl at once
//! }
//! run.close(false)?;                    // traces, summary, provenance, report
//! ```
//!
//! The run's suite is the given suite's objectives with one optimizer, of kind `external`
//! (its id and description), named `<suite>-<optimizer>` (default folder
//! `results/<suite>-<optimizer>/`); that text is what the folder's `suite.toml` holds and
//! what `optbench report` re-reads. `optbench run` refuses a suite with an `external`
//! optimizer ([`refuse_external`]): it cannot drive it.
//!
//! Every finished trial is in `progress.jsonl` the moment [`ExternalRun::finish`] returns,
//! so a crashed or interrupted run reopened with `resume` skips them; a trial started and
//! never finished simply runs again (from the same seed).

use crate::base::error::{Error, Result};
use crate::base::params::{Default as D, Kind, Spec};
use crate::base::{SafeName, atomic_write};
use crate::harness::{Evaluator, Optimizer, OptimizerConfig, TrialRecord};
use crate::objective::Bounds;
use crate::pipeline::run::{Overrides, Prepared, Report, finish, open_log};
use crate::pipeline::runner::{TrialIdentity, trial_spec};
use crate::pipeline::store::Provenance;
use crate::pipeline::store::progress::ProgressLog;
use crate::pipeline::suite::Suite;
use rand::RngExt;
use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime};

/// The optimizer kind of a suite entry that runs outside optbench.
pub const EXTERNAL_KIND: &str = "external";

/// Parameters of an `external` optimizer entry (besides its required `id`).
pub const EXTERNAL_PARAMS: &[Spec] = &[Spec {
    name: "description",
    kind: Kind::Text,
    default: D::Derived("none"),
    help: "what the optimizer is (name, version, settings), kept in the suite as run",
}];

/// The configuration of an `external` optimizer: only what describes it. Its `Debug` text
/// enters every trial's key, so a changed description is a different optimizer to resume.
#[derive(Debug)]
pub struct ExternalConfig {
    pub description: Option<String>,
}

impl OptimizerConfig for ExternalConfig {
    fn batch_size(&self) -> usize {
        1
    }

    /// Never reached through `optbench run` ([`refuse_external`] stops it first); a caller
    /// driving the trial loop anyway gets a trial that ends at once, with no evaluation.
    fn start(&self, _: &Bounds, _: u64, _: &crate::base::TrialSeed) -> Box<dyn Optimizer> {
        Box::new(Elsewhere)
    }
}

/// The stand-in of an optimizer that runs elsewhere: it ends the trial.
struct Elsewhere;

impl Optimizer for Elsewhere {
    fn step(&mut self, ev: &mut Evaluator) {
        ev.converged();
    }
}

/// Refuses a suite with an `external` optimizer, saying how such an optimizer runs.
pub fn refuse_external(suite: &Suite) -> Result<()> {
    match suite.optimizers.iter().find(|o| o.kind == EXTERNAL_KIND) {
        None => Ok(()),
        Some(o) => Err(o.params.entry_error(format!(
            "is of kind `external`: it runs outside optbench, which cannot drive it. Run it \
             from Python (package `optbench`: `optbench.Experiment(SUITE, \"{}\")`) or the \
             Rust API `optbench::pipeline::external::ExternalRun` into a folder of its own, \
             run the built-in optimizers from a suite without it, and combine the two \
             folders with `optbench merge DIR DIR --out DIR` (docs/03-suites-and-results.md)",
            o.id
        ))),
    }
}

/// How to open an external run.
#[derive(Debug, Clone, Default)]
pub struct ExternalOptions {
    /// `--trials`, `--seed`, `--budget` as `optbench run` takes them: give the same ones as
    /// the built-in run it is to be merged with.
    pub overrides: Overrides,
    /// Continue an interrupted run in the folder: its finished trials are kept (as
    /// `run --resume`).
    pub resume: bool,
    /// Resume even if the suite, overrides or build changed, keeping only the trials whose
    /// configuration is unchanged (as `run --force-resume`).
    pub force_resume: bool,
    /// Write into a folder holding other results: optbench's files there are removed first
    /// (as `run --overwrite`).
    pub overwrite: bool,
    /// What the optimizer is (stored in the suite as run); default: the description of an
    /// `external` entry of the same id in the suite, if any.
    pub description: Option<String>,
    /// Added to `provenance.json` as `extra` (e.g. `python` = its version, `numpy` = ...).
    pub extra: BTreeMap<String, String>,
    /// The command recorded in `provenance.json` (e.g. Python's `sys.argv`); default: this
    /// process's command line.
    pub command: Option<Vec<String>>,
    /// Writes the report at [`ExternalRun::close`]: pass `Some(optbench::report::generate)`
    /// (the pipeline sits below the report); None writes the results without it.
    pub report: Option<Report>,
}

/// One planned trial, as the external optimizer needs it.
#[derive(Debug, Clone, PartialEq)]
pub struct ExternalTrialInfo {
    /// Position in the plan ([`ExternalRun::start`] takes it).
    pub index: usize,
    pub objective: String,
    pub objective_kind: String,
    /// The objective's validated parameters (`dim`, `function`, `instance`, ...) as text.
    pub params: Vec<(String, String)>,
    /// Trial number within its objective (0-based).
    pub trial: usize,
    /// A seed for the optimizer's own generator (e.g. `numpy.random.default_rng(seed)`):
    /// the first 64-bit draw of the trial's ChaCha stream, so it is fixed by the suite seed,
    /// objective id, optimizer id and trial number, as a built-in optimizer's streams are.
    pub seed: u64,
    /// The trial's random key as stored in its record (`seed` in `traces.jsonl`).
    pub seed_key: String,
    /// Evaluations the trial may spend.
    pub budget: u64,
    pub dim: usize,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    /// Known optimum of the objective (f*), if any.
    pub optimum: Option<f64>,
    /// The trial ends once a value <= this is seen (the suite's `stop_at`).
    pub stop_value: Option<f64>,
    /// Whether the trial is finished (in the progress log).
    pub finished: bool,
}

/// Why an evaluation was not made.
#[derive(Debug, Clone, PartialEq)]
pub enum EvalError {
    /// The trial is over: its budget is spent, or the stop value was reached.
    Exhausted {
        evaluations: u64,
        budget: u64,
        reached_target: bool,
    },
    /// The points do not have the objective's dimension.
    Shape(String),
    /// A coordinate is NaN or infinite (nothing is evaluated or counted).
    NotFinite(String),
}

impl fmt::Display for EvalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EvalError::Exhausted {
                evaluations,
                reached_target: true,
                ..
            } => write!(
                f,
                "the trial reached its stop value after {evaluations} evaluations; finish it"
            ),
            EvalError::Exhausted { budget, .. } => {
                write!(
                    f,
                    "the trial's budget of {budget} evaluations is spent; finish it"
                )
            }
            EvalError::Shape(m) | EvalError::NotFinite(m) => f.write_str(m),
        }
    }
}

impl std::error::Error for EvalError {}

/// One trial in progress: owns the evaluator that counts and records its evaluations.
pub struct ExternalTrial {
    info: ExternalTrialInfo,
    key: String,
    identity: TrialIdentity,
    evaluator: Evaluator,
    started: Instant,
}

impl ExternalTrial {
    pub fn info(&self) -> &ExternalTrialInfo {
        &self.info
    }

    pub fn index(&self) -> usize {
        self.info.index
    }

    pub fn dim(&self) -> usize {
        self.info.dim
    }

    /// Evaluations spent so far.
    pub fn evaluations(&self) -> u64 {
        self.evaluator.used()
    }

    /// Evaluations that may still be spent (0 once the stop value is reached).
    pub fn remaining(&self) -> u64 {
        self.evaluator.remaining()
    }

    /// Whether the trial is over (budget spent or stop value reached).
    pub fn done(&self) -> bool {
        self.evaluator.done()
    }

    /// Best value so far (+inf before the first evaluation).
    pub fn best(&self) -> f64 {
        self.evaluator.best()
    }

    /// Where the best value was found (empty before the first evaluation).
    pub fn best_x(&self) -> &[f64] {
        self.evaluator.best_x()
    }

    fn exhausted(&self) -> EvalError {
        let best = self.evaluator.best();
        EvalError::Exhausted {
            evaluations: self.evaluator.used(),
            budget: self.info.budget,
            reached_target: self.info.stop_value.is_some_and(|s| best <= s),
        }
    }

    /// The value at `x` (a NaN or -inf value comes back as +inf, as every optimizer sees
    /// it), counted as one evaluation; an error once the trial is over.
    pub fn evaluate(&mut self, x: &[f64]) -> Result<f64, EvalError> {
        if x.len() != self.info.dim {
            return Err(EvalError::Shape(format!(
                "a point of objective `{}` has {} coordinates, got {}",
                self.info.objective,
                self.info.dim,
                x.len()
            )));
        }
        self.check_finite(x)?;
        self.evaluator.evaluate(x).ok_or_else(|| self.exhausted())
    }

    /// Refuses points with a coordinate that is not a number: no objective is defined there.
    /// Points outside the box are evaluated (every objective is defined there, as in COCO);
    /// an optimizer that leaves the box gets what it finds.
    fn check_finite(&self, points: &[f64]) -> Result<(), EvalError> {
        let d = self.info.dim.max(1);
        match points.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(i) => Err(EvalError::NotFinite(format!(
                "coordinate {} of point {} is {}: expected finite numbers (objective `{}`)",
                i % d,
                i / d,
                points[i],
                self.info.objective
            ))),
        }
    }

    /// Evaluates the row-major `points` (`out.len()` points of [`Self::dim`] coordinates)
    /// into `out`, each counted as one evaluation, in order until the budget is spent or the
    /// stop value reached: returns how many were evaluated; the rest of `out` is +inf. An
    /// error if the trial was over before the batch.
    pub fn evaluate_batch(&mut self, points: &[f64], out: &mut [f64]) -> Result<usize, EvalError> {
        if points.len() != out.len() * self.info.dim {
            return Err(EvalError::Shape(format!(
                "{} points of objective `{}` need {} numbers ({} coordinates each), got {}",
                out.len(),
                self.info.objective,
                out.len() * self.info.dim,
                self.info.dim,
                points.len()
            )));
        }
        self.check_finite(points)?;
        if out.is_empty() {
            return Ok(0);
        }
        if self.evaluator.done() {
            return Err(self.exhausted());
        }
        Ok(self.evaluator.evaluate_batch(points, out))
    }

    /// [`Self::evaluate_batch`] on a list of points (plain types, for bindings): the values
    /// of the points evaluated, in order — fewer than given when the budget ran out or the
    /// stop value was reached inside the batch.
    pub fn evaluate_many(&mut self, points: &[Vec<f64>]) -> Result<Vec<f64>, EvalError> {
        let d = self.info.dim;
        if let Some((i, p)) = points.iter().enumerate().find(|(_, p)| p.len() != d) {
            return Err(EvalError::Shape(format!(
                "point {i} of the batch has {} coordinates, objective `{}` has {d}",
                p.len(),
                self.info.objective
            )));
        }
        let flat: Vec<f64> = points.concat();
        let mut out = vec![0.0; points.len()];
        let n = self.evaluate_batch(&flat, &mut out)?;
        out.truncate(n);
        Ok(out)
    }
}

/// What [`ExternalRun::close`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct ExternalClosed {
    /// The results folder.
    pub dir: PathBuf,
    pub finished: usize,
    pub planned: usize,
    /// What `optbench run` prints at its end (the report's main table when there is one).
    pub text: String,
}

/// An external optimizer's run of a suite's plan, writing a results folder as
/// `optbench run` does. Holds the folder's lock until closed or dropped.
pub struct ExternalRun {
    p: Prepared,
    log: Option<ProgressLog>,
    /// Finished records by trial key (resumed and new).
    done: HashMap<String, TrialRecord>,
    reused: usize,
    started: SystemTime,
    extra: BTreeMap<String, String>,
    command: Option<Vec<String>>,
    report: Option<Report>,
}

impl ExternalRun {
    /// Loads the suite at `suite`, makes the plan of optimizer `optimizer` (an id: letters,
    /// digits, '-', '_', '.') on every objective for the suite's trials, and opens (or, with
    /// `resume`, continues) its results folder `out` (default `results/<suite>-<optimizer>`).
    pub fn open(
        suite: &Path,
        optimizer: &str,
        out: Option<&Path>,
        options: ExternalOptions,
    ) -> Result<ExternalRun> {
        let started = SystemTime::now();
        let id = SafeName::new(optimizer).map_err(|why| {
            Error::Input(format!(
                "optimizer id {optimizer:?} {why} (it names the optimizer in results)"
            ))
        })?;
        let original = Suite::load(suite)?;
        let description = options.description.clone().or_else(|| {
            original
                .optimizers
                .iter()
                .find(|o| o.kind == EXTERNAL_KIND && o.id == id)
                .and_then(|o| o.params.opt_str("description").map(String::from))
        });
        let text = external_suite_text(&original, &id, description.as_deref())?;
        let mut own = Suite::parse(&text, suite)?;
        options.overrides.apply(&mut own)?;
        let out = out
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("results").join(own.name.as_str()));
        let p = Prepared::new(
            own,
            suite,
            out,
            options.overrides.budget,
            None,
            options.overwrite,
        )?;
        let (log, done) = open_log(&p, options.resume, options.force_resume)?;
        // The suite as run, at once: the folder names what it holds before any trial ends.
        atomic_write(&p.out.join("suite.toml"), p.suite.text.as_bytes())?;
        Ok(ExternalRun {
            reused: done.len(),
            p,
            log: Some(log),
            done,
            started,
            extra: options.extra,
            command: options.command,
            report: options.report,
        })
    }

    /// The results folder.
    pub fn out_dir(&self) -> &Path {
        &self.p.out
    }

    /// The suite as run (its objectives and the one external optimizer).
    pub fn suite(&self) -> &Suite {
        &self.p.suite
    }

    /// Trials already finished when the run was opened (resumed from the log).
    pub fn resumed(&self) -> usize {
        self.reused
    }

    /// Every planned trial in plan order (objective-major, then trial number).
    pub fn trials(&self) -> Vec<ExternalTrialInfo> {
        (0..self.p.plan.len()).map(|i| self.info(i)).collect()
    }

    /// Plan positions of the trials not finished yet, in plan order.
    pub fn pending(&self) -> Vec<usize> {
        (0..self.p.plan.len())
            .filter(|&i| !self.done.contains_key(&self.p.keys[i]))
            .collect()
    }

    fn info(&self, index: usize) -> ExternalTrialInfo {
        let t = &self.p.plan[index];
        let spec = trial_spec(&self.p.suite, t);
        let entry = &self.p.suite.objectives[t.objective];
        let bounds = spec.objective.bounds();
        ExternalTrialInfo {
            index,
            objective: entry.id.to_string(),
            objective_kind: entry.kind.to_string(),
            params: entry
                .params
                .values()
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect(),
            trial: t.trial,
            seed: spec.seed.rng(0).random(),
            seed_key: spec.seed.hex(),
            budget: spec.budget,
            dim: spec.objective.dim(),
            lower: bounds.lower().to_vec(),
            upper: bounds.upper().to_vec(),
            optimum: spec.objective.optimum(),
            stop_value: spec.stop_value,
            finished: self.done.contains_key(&self.p.keys[index]),
        }
    }

    fn open_log(&self) -> Result<&ProgressLog> {
        self.log.as_ref().ok_or_else(|| {
            Error::Input(format!(
                "{}: the run is closed; open it again with resume to continue",
                self.p.out.display()
            ))
        })
    }

    /// Starts trial `index` of the plan: a fresh evaluator with the trial's budget and stop
    /// value. Starting a trial again (its optimizer failed) starts it afresh.
    pub fn start(&self, index: usize) -> Result<ExternalTrial> {
        self.open_log()?;
        let Some(t) = self.p.plan.get(index) else {
            return Err(Error::Input(format!(
                "trial index {index}: the plan has {} trials (0 to {})",
                self.p.plan.len(),
                self.p.plan.len().saturating_sub(1)
            )));
        };
        let info = self.info(index);
        if info.finished {
            return Err(Error::Input(format!(
                "trial {index} (objective `{}`, trial {}) is finished already; run the pending ones",
                info.objective, info.trial
            )));
        }
        let spec = trial_spec(&self.p.suite, t);
        let evaluator = Evaluator::new(
            std::sync::Arc::clone(&spec.objective),
            spec.budget,
            spec.stop_value,
        )
        .with_stall(spec.stall);
        Ok(ExternalTrial {
            key: self.p.keys[index].clone(),
            identity: TrialIdentity::of(&spec),
            info,
            evaluator,
            started: Instant::now(),
        })
    }

    /// Ends `trial`: its record (as `optbench run` builds it) is appended to the progress
    /// log at once. A trial may end before its budget is spent (its optimizer stopped); it
    /// must have spent at least one evaluation.
    pub fn finish(&mut self, trial: ExternalTrial) -> Result<()> {
        let log = self.open_log()?;
        let i = trial.info.index;
        if self.p.keys.get(i) != Some(&trial.key) {
            return Err(Error::Input(format!(
                "trial {i} was started by another run; finish it with the run that started it"
            )));
        }
        if self.done.contains_key(&trial.key) {
            return Err(Error::Input(format!(
                "trial {i} (objective `{}`, trial {}) is finished already",
                trial.info.objective, trial.info.trial
            )));
        }
        if trial.evaluator.used() == 0 {
            return Err(Error::Input(format!(
                "trial {i} (objective `{}`, trial {}) has no evaluation: evaluate at least one point before finishing it",
                trial.info.objective, trial.info.trial
            )));
        }
        let wall_s = trial.started.elapsed().as_secs_f64();
        let record = trial.identity.record(trial.evaluator.finish(), wall_s);
        log.append(&trial.key, &record)?;
        self.done.insert(trial.key, record);
        Ok(())
    }

    /// Writes `traces.jsonl`, `summary.json`, `provenance.json` and the report (with
    /// [`ExternalOptions::report`]) as `optbench run` does at its end, and releases the
    /// folder. Refused while trials are unfinished unless `partial`: then the results of the
    /// finished trials are written (provenance `extra.partial` says how many), and the run
    /// can be completed later by opening it again with `resume`.
    pub fn close(&mut self, partial: bool) -> Result<ExternalClosed> {
        self.open_log()?;
        let pending = self.pending();
        if let Some(&first) = pending.first()
            && !partial
        {
            let info = self.info(first);
            return Err(Error::Input(format!(
                "{}: {} of {} trials are unfinished (e.g. trial {first}: objective `{}`, trial {}); finish them, or close with partial to write the results of the finished ones (and resume later)",
                self.p.out.display(),
                pending.len(),
                self.p.plan.len(),
                info.objective,
                info.trial
            )));
        }
        let records: Vec<TrialRecord> = self
            .p
            .keys
            .iter()
            .filter_map(|k| self.done.get(k).cloned())
            .collect();
        let mut provenance = Provenance::new(&self.p.suite, 1, self.started);
        if let Some(c) = &self.command {
            provenance.command = c.clone();
        }
        provenance.extra = self.extra.clone();
        if !pending.is_empty() {
            provenance.extra.insert(
                "partial".into(),
                format!("{} of {} trials finished", records.len(), self.p.plan.len()),
            );
        }
        let text = finish(
            &self.p,
            &records,
            provenance,
            self.reused,
            false,
            self.report,
        )?;
        self.log = None;
        Ok(ExternalClosed {
            dir: self.p.out.clone(),
            finished: records.len(),
            planned: self.p.plan.len(),
            text,
        })
    }
}

/// The text of `suite` run by one external optimizer `id`: its objectives (without their
/// `optimizers` selections, so every objective runs), no paper tables (they name the
/// suite's own optimizers), and one `[[optimizer]]` of kind `external`; named
/// `<suite>-<id>` so it never claims the built-in run's folder.
fn external_suite_text(suite: &Suite, id: &SafeName, description: Option<&str>) -> Result<String> {
    let mut table: toml::Table = suite
        .text
        .parse()
        .map_err(|e| Error::Input(format!("{}: {e}", suite.path.display())))?;
    let name = format!("{}-{id}", suite.name);
    SafeName::new(&name).map_err(|why| {
        Error::Input(format!(
            "the external run's suite name `{name}` (suite name and optimizer id) {why}; choose a shorter optimizer id"
        ))
    })?;
    table.insert("name".into(), toml::Value::String(name));
    table.remove("table");
    if let Some(toml::Value::Array(objectives)) = table.get_mut("objective") {
        for o in objectives.iter_mut() {
            if let toml::Value::Table(t) = o {
                t.remove("optimizers");
            }
        }
    }
    let mut entry = toml::Table::new();
    entry.insert("kind".into(), toml::Value::String(EXTERNAL_KIND.into()));
    entry.insert("id".into(), toml::Value::String(id.to_string()));
    if let Some(d) = description {
        entry.insert("description".into(), toml::Value::String(d.into()));
    }
    table.insert(
        "optimizer".into(),
        toml::Value::Array(vec![toml::Value::Table(entry)]),
    );
    Ok(format!(
        "# {EXTERNAL_KIND} run of `{}` by optimizer `{id}`, written by optbench\n{}",
        suite.name,
        toml::to_string(&table).expect("a TOML table serialises")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_and_trials_can_move_to_another_thread() {
        fn send<T: Send>() {}
        send::<ExternalRun>();
        send::<ExternalTrial>();
    }
}
