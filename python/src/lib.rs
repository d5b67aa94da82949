//! `optbench._optbench`: the crate's objectives and results logger for optimizers written
//! in Python. Every evaluation goes through the crate's `Evaluator` (the one place that
//! counts), so a Python optimizer is measured exactly as the built-in ones are.

mod experiment;
mod problem;

use optbench::base::params::Origin;
use optbench::harness::Evaluator;
use optbench::objective::Objective;
use problem::{Counter, Problem};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

create_exception!(
    optbench,
    BudgetExhausted,
    PyException,
    "The problem's evaluation budget is spent: stop the optimizer and finish the trial."
);
create_exception!(
    optbench,
    TargetReached,
    BudgetExhausted,
    "The trial reached its stop value: nothing more is evaluated (a BudgetExhausted, so one \
     `except` ends an optimizer either way)."
);

/// A ValueError carrying the crate's message.
pub fn value_error(msg: impl Into<String>) -> PyErr {
    PyValueError::new_err(msg.into())
}

/// `budget` as the evaluator's limit: None is unlimited; zero and negative budgets are
/// refused rather than read as "nothing may be evaluated" by mistake.
fn budget_limit(budget: Option<i64>, what: &str) -> PyResult<u64> {
    match budget {
        None => Ok(u64::MAX),
        Some(b) if b >= 1 => Ok(b as u64),
        Some(b) => Err(value_error(format!(
            "{what}: budget = {b}; expected a positive number of evaluations, or None for unlimited"
        ))),
    }
}

/// A Python value as the suite file's TOML value of a key (bool before int: Python's
/// bools are ints).
fn toml_value(key: &str, v: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return v.extract::<i64>().map(toml::Value::Integer).map_err(|_| {
            value_error(format!(
                "`{key}` = {v}: expected an integer that fits in 64 bits"
            ))
        });
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    // numpy scalars (np.int64, np.float64) and other numbers that say what they are.
    let np = v.py().import("numpy")?;
    if v.is_instance(&np.getattr("integer")?)? {
        return Ok(toml::Value::Integer(v.call_method0("__int__")?.extract()?));
    }
    if v.is_instance(&np.getattr("floating")?)? {
        return Ok(toml::Value::Float(v.call_method0("__float__")?.extract()?));
    }
    Err(value_error(format!(
        "`{key}`: got a {}; expected a number, a bool or a string",
        v.get_type().name()?
    )))
}

/// A problem with its own evaluator (no trial: a standalone problem).
fn standalone(objective: Arc<dyn Objective>, budget: u64, id: String) -> Problem {
    let (bounds, optimum) = (objective.bounds().clone(), objective.optimum());
    let name = objective.name().to_string();
    let ev = Evaluator::new(objective, budget, None);
    Problem::new(
        bounds,
        optimum,
        name,
        id,
        Arc::new(Mutex::new(Counter::Standalone(Box::new(ev)))),
    )
}

/// Builds an objective of registry kind `kind` from keyword parameters, with the suite's
/// validation and messages (origin: the calling function, `optbench.bbob` or `optbench.problem`).
fn build(
    caller: &str,
    kind: &str,
    given: BTreeMap<String, (toml::Value, usize)>,
) -> PyResult<Arc<dyn Objective>> {
    let origin = Origin {
        file: caller.into(),
        line: 0,
        what: format!("objective kind `{kind}`"),
    };
    optbench::registry::build_objective(kind, &given, origin)
        .map_err(|e| value_error(e.to_string()))
}

/// The BBOB problem f`function` (1-24) of `dimension` and `instance`, with the values of
/// COCO's bbob suite (f_opt included); `budget` in evaluations, or None for unlimited.
#[pyfunction]
#[pyo3(signature = (function, dimension, instance = 1, *, budget = None))]
fn bbob(function: i64, dimension: i64, instance: i64, budget: Option<i64>) -> PyResult<Problem> {
    let id = format!("bbob_f{function:03}_i{instance:02}_d{dimension:02}");
    let limit = budget_limit(budget, &id)?;
    let given = [
        ("function", function),
        ("dim", dimension),
        ("instance", instance),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), (toml::Value::Integer(v), 0)))
    .collect();
    let objective = build("optbench.bbob", "bbob", given)?;
    Ok(standalone(objective, limit, id))
}

/// The problem of any objective kind of `optbench list` (test functions, hysteresis fits on
/// recordings or twin signals), its keys as in a suite's `[[objective]]` table; `budget` in
/// evaluations, or None for unlimited.
#[pyfunction(name = "problem")]
#[pyo3(signature = (kind, *, budget = None, **params))]
fn make_problem(
    kind: &str,
    budget: Option<i64>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<Problem> {
    let mut given = BTreeMap::new();
    if let Some(params) = params {
        for (k, v) in params.iter() {
            let key: String = k.extract()?;
            let value = toml_value(&key, &v)?;
            given.insert(key, (value, 0));
        }
    }
    let objective = build("optbench.problem", kind, given)?;
    let id = format!("{}-d{}", objective.name(), objective.dim());
    let limit = budget_limit(budget, &id)?;
    Ok(standalone(objective, limit, id))
}

/// The objective kinds `problem` accepts.
#[pyfunction]
fn kinds() -> Vec<&'static str> {
    optbench::registry::objective_kinds()
        .iter()
        .map(|k| k.name)
        .collect()
}

#[pymodule]
fn _optbench(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Problem>()?;
    m.add_class::<experiment::Experiment>()?;
    m.add_class::<experiment::Trial>()?;
    m.add_function(wrap_pyfunction!(bbob, m)?)?;
    m.add_function(wrap_pyfunction!(make_problem, m)?)?;
    m.add_function(wrap_pyfunction!(kinds, m)?)?;
    m.add("BudgetExhausted", m.py().get_type::<BudgetExhausted>())?;
    m.add("TargetReached", m.py().get_type::<TargetReached>())?;
    Ok(())
}
