//! `optbench.Experiment`: a Python optimizer's run of a suite, through the crate's
//! `ExternalRun`. Every trial's problem evaluates through the trial's own harness
//! evaluator, so the folder it writes is what `optbench run` writes for a built-in
//! optimizer (same seeds, budgets, traces, progress log, provenance and report).

use crate::problem::{Counter, Problem, Slot, lock};
use crate::value_error;
use optbench::Error;
use optbench::base::limits::MAX_TRIALS;
use optbench::objective::Bounds;
use optbench::pipeline::external::{ExternalOptions, ExternalRun, ExternalTrialInfo};
use optbench::pipeline::run::Overrides;
use pyo3::exceptions::PyOSError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyType};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard};

/// The crate's error as Python's: bad input is a ValueError, a failed read or write an
/// OSError; both carry the crate's message.
fn py_error(e: Error) -> PyErr {
    match e {
        Error::Input(m) => value_error(m),
        e @ Error::Io { .. } => PyOSError::new_err(e.to_string()),
    }
}

struct State {
    /// None once closed.
    run: Option<ExternalRun>,
    /// Plan positions still to hand out, in plan order.
    pending: Vec<usize>,
    next: usize,
    /// The trial handed out last, until it is finished.
    current: Option<(usize, Slot)>,
}

/// A Python optimizer's run of a suite: iterate it for the trials (each a `Trial` with its
/// `problem`, `seed` and `budget`); a trial is recorded when `trial.finish()` is called or
/// the loop moves on; `close()` (or leaving a `with` block) writes the results folder, which
/// `optbench report` and `optbench merge` read.
#[pyclass(module = "optbench", frozen)]
pub struct Experiment {
    state: Mutex<State>,
    out: PathBuf,
    planned: usize,
    optimizer: String,
}

impl Experiment {
    fn state(&self) -> MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl State {
    fn run(&mut self) -> PyResult<&mut ExternalRun> {
        self.run.as_mut().ok_or_else(|| {
            value_error("the experiment is closed; open it again with resume=True to continue")
        })
    }

    /// Records the trial of plan position `index` whose problem counts in `slot`.
    fn finish(&mut self, index: usize, slot: &Slot) -> PyResult<()> {
        let mut counter = lock(slot);
        let Counter::Trial(t) = &*counter else {
            return Err(value_error(format!("trial {index} is finished already")));
        };
        if t.evaluations() == 0 {
            let info = t.info();
            return Err(value_error(format!(
                "trial {index} (objective `{}`, trial {}) has no evaluation: evaluate at least one point of its problem before finishing it",
                info.objective, info.trial
            )));
        }
        let finished = Counter::Finished {
            evaluations: t.evaluations(),
            budget: t.info().budget,
            best: counter.best(),
        };
        let Counter::Trial(t) = std::mem::replace(&mut *counter, finished) else {
            unreachable!("matched above");
        };
        drop(counter);
        self.run()?.finish(*t).map_err(py_error)?;
        if self.current.as_ref().is_some_and(|(i, _)| *i == index) {
            self.current = None;
        }
        Ok(())
    }

    /// Records the trial handed out last if it is still running.
    fn finish_current(&mut self) -> PyResult<()> {
        match self.current.take() {
            Some((i, slot)) if matches!(&*lock(&slot), Counter::Trial(_)) => {
                self.current = Some((i, Arc::clone(&slot)));
                self.finish(i, &slot)
            }
            _ => Ok(()),
        }
    }
}

#[pymethods]
impl Experiment {
    /// Opens the results folder of optimizer `optimizer` (an id: letters, digits, `-`, `_`,
    /// `.`) on every objective of the suite at `suite` (default folder
    /// `results/<suite>-<optimizer>`). `trials`, `seed`, `budget` override the suite's as
    /// `optbench run` does: give the built-in run's, so the two can be merged. `resume`
    /// continues an interrupted run (its finished trials are kept); `overwrite` writes into
    /// a folder that holds other results.
    #[new]
    #[pyo3(signature = (suite, optimizer, out = None, description = None, *, trials = None, seed = None, budget = None, resume = false, overwrite = false, report = true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        suite: PathBuf,
        optimizer: &str,
        out: Option<PathBuf>,
        description: Option<String>,
        trials: Option<usize>,
        seed: Option<u64>,
        budget: Option<u64>,
        resume: bool,
        overwrite: bool,
        report: bool,
    ) -> PyResult<Self> {
        // The ranges of `optbench run --trials/--budget`.
        if let Some(t) = trials
            && !(1..=MAX_TRIALS).contains(&t)
        {
            return Err(value_error(format!(
                "trials = {t}: expected 1 to {MAX_TRIALS} (the number of trials per objective)"
            )));
        }
        if budget == Some(0) {
            return Err(value_error(
                "budget = 0: expected a positive number of evaluations per trial",
            ));
        }
        let sys = py.import("sys")?;
        let mut extra = BTreeMap::new();
        extra.insert(
            "python".to_string(),
            sys.getattr("version")?.extract::<String>()?,
        );
        extra.insert(
            "numpy".to_string(),
            py.import("numpy")?
                .getattr("__version__")?
                .extract::<String>()?,
        );
        extra.insert(
            "optbench-python".to_string(),
            env!("CARGO_PKG_VERSION").to_string(),
        );
        let command: Vec<String> = sys.getattr("argv")?.extract()?;
        let options = ExternalOptions {
            overrides: Overrides {
                trials,
                seed,
                budget,
            },
            resume,
            force_resume: false,
            overwrite,
            description,
            extra,
            command: Some(command),
            report: report.then_some(optbench::report::generate as optbench::pipeline::run::Report),
        };
        let run = py
            .detach(|| ExternalRun::open(&suite, optimizer, out.as_deref(), options))
            .map_err(py_error)?;
        let pending = run.pending();
        Ok(Experiment {
            out: run.out_dir().to_path_buf(),
            planned: run.trials().len(),
            optimizer: optimizer.to_string(),
            state: Mutex::new(State {
                run: Some(run),
                pending,
                next: 0,
                current: None,
            }),
        })
    }

    /// The results folder.
    #[getter]
    fn out(&self) -> String {
        self.out.display().to_string()
    }

    /// The optimizer's id in the results.
    #[getter]
    fn optimizer(&self) -> &str {
        &self.optimizer
    }

    /// Trials in the plan (objectives x trials), finished or not.
    #[getter]
    fn planned(&self) -> usize {
        self.planned
    }

    /// Trials still to run, the one in progress included.
    fn __len__(&self) -> usize {
        let st = self.state();
        st.pending.len() - st.next + usize::from(st.current.is_some())
    }

    fn __iter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    /// The next trial; the one before it is recorded first if it is still running.
    fn __next__(slf: Bound<'_, Self>) -> PyResult<Option<Trial>> {
        let me = slf.get();
        let mut st = me.state();
        st.finish_current()?;
        let Some(&index) = st.pending.get(st.next) else {
            return Ok(None);
        };
        let trial = st.run()?.start(index).map_err(py_error)?;
        let info = trial.info().clone();
        let bounds = Bounds::new(info.lower.clone(), info.upper.clone()).map_err(value_error)?;
        let slot: Slot = Arc::new(Mutex::new(Counter::Trial(Box::new(trial))));
        let problem = Problem::new(
            bounds,
            info.optimum,
            info.objective_kind.clone(),
            info.objective.clone(),
            Arc::clone(&slot),
        );
        st.next += 1;
        st.current = Some((index, Arc::clone(&slot)));
        drop(st);
        Ok(Some(Trial {
            problem: Py::new(slf.py(), problem)?,
            info,
            slot,
            experiment: slf.unbind(),
        }))
    }

    /// Records the running trial, writes the results folder (traces, summary, provenance,
    /// report) and releases it; returns the folder. With `partial=True` unfinished trials
    /// are allowed: the finished ones are written, and `resume=True` completes the run later.
    #[pyo3(signature = (partial = false))]
    fn close(&self, py: Python<'_>, partial: bool) -> PyResult<String> {
        let mut st = self.state();
        if !partial {
            st.finish_current()?;
        }
        let run = st.run()?;
        let closed = py.detach(|| run.close(partial)).map_err(py_error)?;
        st.run = None;
        Ok(closed.dir.display().to_string())
    }

    /// Whether the results folder is written (the experiment is closed).
    #[getter]
    fn closed(&self) -> bool {
        self.state().run.is_none()
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    /// Closes the experiment: fully after the block ran through; after an exception,
    /// writing only the finished trials (the one that failed runs again on resume), and the
    /// exception goes on.
    fn __exit__(
        &self,
        py: Python<'_>,
        exc_type: Option<Bound<'_, PyType>>,
        _exc: Option<Bound<'_, PyAny>>,
        _tb: Option<Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        if self.closed() {
            return Ok(false);
        }
        self.close(py, exc_type.is_some())?;
        Ok(false)
    }

    fn __repr__(&self) -> String {
        format!(
            "<optbench.Experiment {} of {}: {} of {} trials to run>",
            self.optimizer,
            self.out.display(),
            self.__len__(),
            self.planned
        )
    }
}

/// One trial of an Experiment: its `problem` (counted by the trial's harness evaluator),
/// the `seed` for the optimizer's own generator and the `budget`.
#[pyclass(module = "optbench", frozen)]
pub struct Trial {
    problem: Py<Problem>,
    info: ExternalTrialInfo,
    slot: Slot,
    experiment: Py<Experiment>,
}

#[pymethods]
impl Trial {
    /// The problem to optimize; it raises BudgetExhausted once the budget is spent.
    #[getter]
    fn problem(&self, py: Python<'_>) -> Py<Problem> {
        self.problem.clone_ref(py)
    }

    /// A seed for the optimizer's generator (e.g. `numpy.random.default_rng(seed)`), fixed
    /// by the suite's seed, the objective, the optimizer id and the trial number.
    #[getter]
    fn seed(&self) -> u64 {
        self.info.seed
    }

    /// Evaluations the trial may spend.
    #[getter]
    fn budget(&self) -> u64 {
        self.info.budget
    }

    /// The objective's id in the suite.
    #[getter]
    fn objective(&self) -> &str {
        &self.info.objective
    }

    /// The objective's validated parameters, as text (`dim`, `function`, ...).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in &self.info.params {
            d.set_item(k, v)?;
        }
        Ok(d)
    }

    /// Trial number within its objective (0-based).
    #[getter]
    fn number(&self) -> usize {
        self.info.trial
    }

    /// Position in the suite's plan.
    #[getter]
    fn index(&self) -> usize {
        self.info.index
    }

    /// The trial ends once a value at or below this is seen (the suite's `stop_at`), or None.
    #[getter]
    fn stop_value(&self) -> Option<f64> {
        self.info.stop_value
    }

    /// Whether the trial is recorded.
    #[getter]
    fn finished(&self) -> bool {
        matches!(&*lock(&self.slot), Counter::Finished { .. })
    }

    /// Records the trial (it must have at least one evaluation); its problem evaluates no
    /// more.
    fn finish(&self) -> PyResult<()> {
        self.experiment
            .get()
            .state()
            .finish(self.info.index, &self.slot)
    }

    fn __repr__(&self) -> String {
        format!(
            "<optbench.Trial {} #{} (budget {}, seed {})>",
            self.info.objective, self.info.trial, self.info.budget, self.info.seed
        )
    }
}
