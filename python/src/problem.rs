//! A problem as Python sees it: an objective behind the crate's own evaluator, which
//! counts every point (alone or in a batch), enforces the budget and keeps the best.

use crate::{BudgetExhausted, TargetReached, value_error};
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use optbench::harness::Evaluator;
use optbench::objective::Bounds;
use optbench::pipeline::external::ExternalTrial;
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use std::sync::{Arc, Mutex, MutexGuard};

/// Where a problem's evaluations are counted: its own evaluator (a standalone problem), an
/// Experiment's running trial, or what a finished trial spent and found (the Experiment
/// took the trial back to record it).
pub enum Counter {
    Standalone(Box<Evaluator>),
    // Both boxed: an evaluator and a trial are large beside a finished trial.
    Trial(Box<ExternalTrial>),
    Finished {
        evaluations: u64,
        budget: u64,
        best: Option<(f64, Vec<f64>)>,
    },
}

impl Counter {
    fn used(&self) -> u64 {
        match self {
            Counter::Standalone(ev) => ev.used(),
            Counter::Trial(t) => t.evaluations(),
            Counter::Finished { evaluations, .. } => *evaluations,
        }
    }

    /// The budget; `u64::MAX` is unlimited.
    fn budget(&self) -> u64 {
        match self {
            Counter::Standalone(ev) => ev.budget(),
            Counter::Trial(t) => t.info().budget,
            Counter::Finished { budget, .. } => *budget,
        }
    }

    fn remaining(&self) -> u64 {
        match self {
            Counter::Standalone(ev) => ev.remaining(),
            Counter::Trial(t) => t.remaining(),
            Counter::Finished { .. } => 0,
        }
    }

    /// (best value, its point), None before the first evaluation.
    pub fn best(&self) -> Option<(f64, Vec<f64>)> {
        let (f, x) = match self {
            Counter::Standalone(ev) => (ev.best(), ev.best_x()),
            Counter::Trial(t) => (t.best(), t.best_x()),
            Counter::Finished { best, .. } => return best.clone(),
        };
        (!x.is_empty()).then(|| (f, x.to_vec()))
    }

    /// Evaluates row-major `points` into `out` in order as far as the trial allows; how
    /// many were evaluated, or None once the trial is finished.
    fn evaluate_batch(&mut self, points: &[f64], out: &mut [f64]) -> Option<usize> {
        match self {
            Counter::Standalone(ev) => Some(ev.evaluate_batch(points, out)),
            // The only error left after the shape check: the trial was over already.
            Counter::Trial(t) => Some(t.evaluate_batch(points, out).unwrap_or(0)),
            Counter::Finished { .. } => None,
        }
    }
}

/// Shared between a problem and the Experiment trial that records it.
pub type Slot = Arc<Mutex<Counter>>;

/// Locks a slot; a panic inside an objective (reported to Python as PanicException) must not
/// make the problem unusable for reading its counts.
pub fn lock(slot: &Slot) -> MutexGuard<'_, Counter> {
    slot.lock().unwrap_or_else(|e| e.into_inner())
}

/// An optimization problem: call it on a point (1-D array) for its value, or on a batch
/// (2-D array, one point per row) for an array of values.
#[pyclass(module = "optbench", frozen)]
pub struct Problem {
    bounds: Bounds,
    optimum: Option<f64>,
    name: String,
    id: String,
    slot: Slot,
}

impl Problem {
    pub fn new(bounds: Bounds, optimum: Option<f64>, name: String, id: String, slot: Slot) -> Self {
        Problem {
            bounds,
            optimum,
            name,
            id,
            slot,
        }
    }

    /// (best value, its point) so far, live or of the finished trial.
    fn best(&self) -> Option<(f64, Vec<f64>)> {
        lock(&self.slot).best()
    }
}

/// `x` as a C-contiguous float64 array: numbers of any real dtype (float, int, bool) are
/// converted, anything else is refused (complex values would lose their imaginary part).
fn as_f64_array<'py>(py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    let np = py.import("numpy")?;
    let a = np.call_method1("asarray", (x,))?;
    let kind: String = a.getattr("dtype")?.getattr("kind")?.extract()?;
    if !matches!(kind.as_str(), "f" | "i" | "u" | "b") {
        let dtype = a.getattr("dtype")?.str()?.to_string();
        return Err(value_error(format!(
            "expected real numbers (an array of float64), got dtype {dtype}"
        )));
    }
    // asarray keeps a 0-D array 0-D (ascontiguousarray would make it 1-D), so a scalar is
    // refused by shape rather than taken for a point of dimension 1.
    let kwargs = pyo3::types::PyDict::new(py);
    kwargs.set_item("dtype", "float64")?;
    kwargs.set_item("order", "C")?;
    np.call_method("asarray", (a,), Some(&kwargs))
}

#[pymethods]
impl Problem {
    /// f(x) of one point (a float), or the values of a batch of points (n x dimension) as
    /// a 1-D array, each point counted as one evaluation. Raises BudgetExhausted (or
    /// TargetReached) for points the trial may no longer evaluate: a batch that crosses
    /// the budget evaluates the points within it, in order, and the exception carries
    /// their values (`values`, `evaluated`).
    fn __call__<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<Py<PyAny>> {
        let a = as_f64_array(py, x)?;
        let a = a.cast_into::<numpy::PyArrayDyn<f64>>()?;
        let d = self.bounds.dim();
        let shape = a.shape().to_vec();
        let single = match shape.as_slice() {
            [n] if *n == d => true,
            [_, n] if *n == d => false,
            [n] => {
                return Err(value_error(format!(
                    "{}: a point has {d} coordinates, got {n}",
                    self.id
                )));
            }
            [r, n] => {
                return Err(value_error(format!(
                    "{}: a batch has shape (n, {d}), got ({r}, {n})",
                    self.id
                )));
            }
            s => {
                return Err(value_error(format!(
                    "{}: expected a point (1-D, {d} values) or a batch (2-D, n x {d}), got a {}-D array",
                    self.id,
                    s.len()
                )));
            }
        };
        let points = a.readonly().as_slice()?.to_vec();
        let n = self
            .bounds
            .check_points(&points)
            .map_err(|e| value_error(format!("{}: {e}", self.id)))?;
        let slot = Arc::clone(&self.slot);
        let outcome: Result<_, ()> = py.detach(move || {
            let mut counter = lock(&slot);
            let mut out = vec![0.0; n];
            let k = counter.evaluate_batch(&points, &mut out).ok_or(())?;
            out.truncate(k);
            let budget = counter.budget();
            Ok((out, k, counter.used() >= budget, budget))
        });
        let (values, k, budget_spent, budget) = match outcome {
            Ok(o) => o,
            Err(_) => {
                return Err(value_error(format!(
                    "{}: its trial is finished; evaluate the problem of a running trial",
                    self.id
                )));
            }
        };
        if k < n {
            let (err, why) = if budget_spent {
                (
                    BudgetExhausted::new_err(()),
                    format!("the budget of {budget} evaluations is spent"),
                )
            } else {
                (
                    TargetReached::new_err(()),
                    "the trial reached its stop value".to_string(),
                )
            };
            let msg = format!("{}: {why}; {k} of the {n} points were evaluated", self.id);
            let e = err.value(py);
            e.setattr("args", PyTuple::new(py, [msg])?)?;
            e.setattr("values", PyArray1::from_vec(py, values))?;
            e.setattr("evaluated", k)?;
            return Err(err);
        }
        if single {
            Ok(values[0].into_pyobject(py)?.into_any().unbind())
        } else {
            Ok(PyArray1::from_vec(py, values).into_any().unbind())
        }
    }

    /// Lower bounds of the search domain.
    #[getter]
    fn lower_bounds<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.bounds.lower())
    }

    /// Upper bounds of the search domain.
    #[getter]
    fn upper_bounds<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, self.bounds.upper())
    }

    #[getter]
    fn dimension(&self) -> usize {
        self.bounds.dim()
    }

    /// The known optimal value f* (BBOB: the instance's f_opt), or None.
    #[getter]
    fn optimum(&self) -> Option<f64> {
        self.optimum
    }

    /// Evaluations counted so far by the crate's evaluator (every point of a batch).
    #[getter]
    fn evaluations(&self) -> u64 {
        lock(&self.slot).used()
    }

    /// The evaluation budget, or None when unlimited.
    #[getter]
    fn budget(&self) -> Option<u64> {
        let b = lock(&self.slot).budget();
        (b < u64::MAX).then_some(b)
    }

    /// Evaluations that may still be made (None when unlimited).
    #[getter]
    fn remaining(&self) -> Option<u64> {
        let c = lock(&self.slot);
        (c.budget() < u64::MAX).then(|| c.remaining())
    }

    /// The best value evaluated so far (None before the first evaluation). As the
    /// harness records it: a NaN or infinite value counts as the finite penalty.
    #[getter]
    fn best_value(&self) -> Option<f64> {
        self.best().map(|(f, _)| f)
    }

    /// Where [`Problem::best_value`] was found (None before the first evaluation).
    #[getter]
    fn best_x<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        self.best().map(|(_, x)| PyArray1::from_vec(py, x))
    }

    /// The objective's family, e.g. `griewank`, `bbob`, `bouc-wen`.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// The problem's identity: a suite's objective id, `KIND-Dd`, or COCO's
    /// `bbob_f001_i01_d02` for BBOB problems.
    #[getter]
    fn id(&self) -> &str {
        &self.id
    }

    fn __repr__(&self) -> String {
        let used = self.evaluations();
        match self.budget() {
            Some(b) => format!(
                "<optbench.Problem {} (dimension {}): {used} of {b} evaluations>",
                self.id,
                self.bounds.dim()
            ),
            None => format!(
                "<optbench.Problem {} (dimension {}): {used} evaluations>",
                self.id,
                self.bounds.dim()
            ),
        }
    }
}
