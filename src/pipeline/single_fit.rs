//! `optbench fit`: one fit of a model to a recording with one optimizer, with the numbers
//! and figures a reader checks first (dissertation Fig. 3.5/3.6): RMSE and max error on training and
//! validation data in the recording's units, the fitted parameters, measured against model
//! over time with the error below, the input-output loops and the convergence curve.
//!
//! Flags become the same parameter tables as suites use (`optbench list`), so checks and
//! messages are the same.

use crate::base::error::{Error, Result};
use crate::base::params::{Origin, Params};
use crate::base::{TrialSeed, atomic_write};
use crate::harness::TrialRecord;
use crate::objective::Objective;
use crate::physics::model_file::{self, Input, ModelFile};
use crate::pipeline::runner::{TrialSpec, progress_bar, run_trial_observed};
use crate::registry::{objective_kinds, optimizer_kinds};
use crate::render::{self, table::sig};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What to fit, as given on the command line.
#[derive(Debug, Clone)]
pub struct FitRequest {
    pub model: String,
    pub optimizer: String,
    pub recording: String,
    pub validate: Option<String>,
    pub columns: String,
    /// Interpolate CSV recordings with gaps or irregular time onto a uniform grid.
    pub resample: bool,
    /// Column separator of CSV recordings (`None`: detected).
    pub delimiter: Option<crate::data::recording::Delimiter>,
    /// Seconds left out at the start of every recording.
    pub trim_start: Option<f64>,
    pub budget: u64,
    pub seed: u64,
    /// Extra model parameters (`key=value`, values in TOML syntax).
    pub model_params: Vec<String>,
    /// Extra optimizer parameters.
    pub optimizer_params: Vec<String>,
    pub out: PathBuf,
    /// Show a progress bar (on a terminal).
    pub progress: bool,
}

/// A `key=value` flag value as a TOML value (numbers and booleans typed, else a string).
fn toml_value(v: &str) -> toml::Value {
    toml::from_str::<toml::Table>(&format!("v = {v}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(v.to_string()))
}

fn pairs(
    flag: &str,
    items: &[String],
    into: &mut BTreeMap<String, (toml::Value, usize)>,
) -> Result<()> {
    for item in items {
        let (k, v) = item
            .split_once('=')
            .ok_or_else(|| Error::Input(format!("{flag} {item}: expected key=value")))?;
        into.insert(k.trim().to_string(), (toml_value(v.trim()), 0));
    }
    Ok(())
}

fn origin(what: String) -> Origin {
    Origin {
        file: PathBuf::from("command line"),
        line: 0,
        what,
    }
}

/// The fit's stored summary (`fit.json`).
#[derive(Debug, Serialize)]
struct FitSummary<'a> {
    model: &'a str,
    optimizer: &'a str,
    recording: String,
    validate: Vec<String>,
    seed: u64,
    budget: u64,
    evaluations: u64,
    cost: f64,
    params: Vec<(String, f64)>,
    metrics: Vec<crate::objective::Metric>,
    wall_s: f64,
}

/// Runs the fit, writes its folder, and returns the text to print.
pub fn run_fit(req: &FitRequest) -> Result<String> {
    if req.budget == 0 {
        return Err(Error::Input(
            "--budget 0: expected at least 1 evaluation".into(),
        ));
    }
    let kinds = objective_kinds();
    let fit_kinds = crate::registry::fitting_kind_names();
    let kind = kinds
        .iter()
        .find(|k| k.name == req.model && fit_kinds.contains(&k.name))
        .ok_or_else(|| {
            Error::Input(format!(
                "--model {}: not a fitting model; valid: {}",
                req.model,
                fit_kinds.join(", ")
            ))
        })?;
    let mut given = BTreeMap::new();
    given.insert(
        "recording".into(),
        (toml::Value::String(req.recording.clone()), 0),
    );
    if let Some(v) = &req.validate {
        given.insert("validate".into(), (toml::Value::String(v.clone()), 0));
    }
    given.insert(
        "columns".into(),
        (toml::Value::String(req.columns.clone()), 0),
    );
    if req.resample {
        given.insert("resample".into(), (toml::Value::Boolean(true), 0));
    }
    if let Some(d) = req.delimiter {
        given.insert("delimiter".into(), (toml::Value::String(d.to_string()), 0));
    }
    if let Some(s) = req.trim_start {
        given.insert("trim_start".into(), (toml::Value::Float(s), 0));
    }
    pairs("--model-param", &req.model_params, &mut given)?;
    let params = Params::validate(
        kind.params,
        &given,
        origin(format!("--model {}", kind.name)),
    )?;
    let objective: Arc<dyn Objective> = (kind.build)(&params)?;
    let view = objective
        .as_fit()
        .ok_or_else(|| Error::Input(format!("--model {}: not a fitting model", req.model)))?;

    let okinds = optimizer_kinds();
    let okind = okinds
        .iter()
        .find(|k| k.name == req.optimizer)
        .ok_or_else(|| {
            Error::Input(format!(
                "--optimizer {}: unknown; valid: {}",
                req.optimizer,
                okinds.iter().map(|k| k.name).collect::<Vec<_>>().join(", ")
            ))
        })?;
    let mut ogiven = BTreeMap::new();
    pairs("--optimizer-param", &req.optimizer_params, &mut ogiven)?;
    let oparams = Params::validate(
        okind.params,
        &ogiven,
        origin(format!("--optimizer {}", okind.name)),
    )?;
    let optimizer = (okind.build)(&oparams)?;
    if optimizer.needs_gradient() && !objective.has_gradient() {
        return Err(Error::Input(format!(
            "--optimizer {} needs a gradient, which --model {} does not have here",
            okind.name, kind.name
        )));
    }

    let bar = progress_bar(req.budget, "evaluations", req.progress);
    let record = run_trial_observed(
        TrialSpec {
            objective_id: &req.model,
            optimizer_id: &req.optimizer,
            trial: 0,
            objective: Arc::clone(&objective),
            optimizer: optimizer.as_ref(),
            budget: req.budget,
            stop_value: None,
            stall: None,
            seed: TrialSeed::derive(req.seed, &req.model, &req.optimizer, 0),
        },
        &|used| bar.set_position(used),
    );
    bar.finish_and_clear();

    std::fs::create_dir_all(&req.out)
        .map_err(|e| Error::io(format!("creating {}", req.out.display()), e))?;
    // A result is a number: a metric the best point makes non-finite (a model that
    // diverges on a validation record) is named, never written as null.
    let (metrics, diverged): (Vec<_>, Vec<_>) = objective
        .metrics(&record.best_x)
        .into_iter()
        .partition(|m| m.value.is_finite());
    for m in &diverged {
        eprintln!(
            "note: {} is {} at the fitted parameters (the model diverges); left out of fit.json",
            m.name, m.value
        );
    }
    let named = view.named_params(&record.best_x);
    let recs = view.recordings();
    let (trains, held): (Vec<_>, Vec<_>) = recs.iter().partition(|(l, _)| l.starts_with("train"));
    let train_names = trains
        .iter()
        .map(|(_, r)| r.name.as_str())
        .collect::<Vec<_>>()
        .join(" + ");
    let summary = FitSummary {
        model: &req.model,
        optimizer: &req.optimizer,
        recording: train_names.clone(),
        validate: held.iter().map(|(_, r)| r.name.clone()).collect(),
        seed: req.seed,
        budget: req.budget,
        evaluations: record.evaluations,
        cost: record.best,
        params: named.clone(),
        metrics: metrics.clone(),
        wall_s: record.wall_s,
    };
    let mut json = serde_json::to_vec_pretty(&summary).expect("serialisable");
    json.push(b'\n');
    atomic_write(&req.out.join("fit.json"), &json)?;
    let mut line = serde_json::to_vec(&record).expect("serialisable");
    line.push(b'\n');
    atomic_write(&req.out.join("trace.jsonl"), &line)?;
    write_figures(&req.out, objective.as_ref(), &record)?;
    let mut model = view.model(&record.best_x);
    model.fitted = model_file::Fitted {
        command: "fit".into(),
        optimizer: req.optimizer.clone(),
        budget: req.budget,
        evaluations: record.evaluations,
        seed: req.seed,
        train: trains.iter().map(|(_, r)| r.name.clone()).collect(),
        validate: held.iter().map(|(_, r)| r.name.clone()).collect(),
    };
    let columns = crate::data::recording::Columns::parse(&req.columns)?;
    model.columns = Some(model_file::Units {
        time: columns.time.clone(),
        input: columns.input.clone(),
        output: columns.output.clone(),
    });
    let model_path = req.out.join("model.json");
    model.write(&model_path)?;
    let predicted = write_predictions(&model, &model_path, &recs, &columns, &req.out)?;

    let mut text = format!(
        "{} fitted by {} to {} ({} evaluations, {:.1} s)\n\n",
        req.model, req.optimizer, train_names, record.evaluations, record.wall_s
    );
    for m in &metrics {
        text += &format!("  {:<34} {}\n", m.name, sig(m.value, 4));
    }
    if named.len() <= 16 {
        text += "\nparameters:\n";
        let w = named
            .iter()
            .map(|(k, _)| k.chars().count())
            .max()
            .unwrap_or(0);
        for (k, v) in &named {
            text += &format!("  {k:<w$} {}\n", sig(*v, 6));
        }
    }
    text += &bound_notes(&model);
    text += &format!(
        "\nmodel (runs again with `optbench simulate --model`): {}\npredicted outputs: {}\nfit folder: {}\n",
        model_path.display(),
        predicted.join(", "),
        req.out.display()
    );
    Ok(text)
}

/// One line per parameter the search left at a bound (the optimum may lie beyond it).
pub fn bound_notes(model: &ModelFile) -> String {
    let at = model.at_bounds();
    if at.is_empty() {
        return String::new();
    }
    let mut text = String::from("\n");
    for (name, side) in at {
        text += &format!("{name} at its {side} bound: widen the range or check the model\n");
    }
    text
}

/// Runs `model` on every record of the fit (each from its own fitted state) and writes
/// `LABEL_predicted.csv` beside the measured output; returns the files written. A record
/// the model diverges on is named and left out.
pub fn write_predictions(
    model: &ModelFile,
    model_path: &Path,
    recs: &[(&str, &crate::data::recording::Recording)],
    columns: &crate::data::recording::Columns,
    dir: &Path,
) -> Result<Vec<String>> {
    let names = [
        columns.time.as_str(),
        columns.input.as_str(),
        columns.output.as_str(),
    ];
    let mut written = Vec::new();
    for (label, rec) in recs {
        let input = Input {
            u: &rec.u,
            y: Some(&rec.y),
            dt: rec.dt(),
        };
        let own = model.records.iter().any(|r| r.label == *label);
        match model.run(model_path, &input, own.then_some(*label)) {
            Ok(pred) => {
                let file = format!("{label}_predicted.csv");
                model_file::write_prediction(
                    &dir.join(&file),
                    names,
                    &rec.t,
                    &rec.u,
                    Some(&rec.y),
                    &pred,
                )?;
                written.push(file);
            }
            Err(e) => eprintln!("note: no {label}_predicted.csv: {e}"),
        }
    }
    Ok(written)
}

fn write_figures(dir: &Path, objective: &dyn Objective, record: &TrialRecord) -> Result<()> {
    let Some(view) = objective.as_fit() else {
        return Ok(());
    };
    let label = objective
        .presentation()
        .map(|p| p.label)
        .unwrap_or_else(|| "cost".into());
    let shown = match objective.presentation() {
        Some(p) => record.presented(&p),
        None => TrialRecord {
            optimum: None,
            ..record.clone()
        },
    };
    render::convergence(
        &dir.join("convergence"),
        &format!("{} by {}: convergence", record.objective, record.optimizer),
        &[render::convergence_series(&record.optimizer, &[&shown])],
        &format!("best-so-far {label}"),
        true,
    )?;
    for (i, (set, rec)) in view.recordings().into_iter().enumerate() {
        let models = view.outputs(&record.best_x, i);
        let unit = |i: usize| {
            if rec.units[i].is_empty() {
                String::new()
            } else {
                format!(" [{}]", rec.units[i])
            }
        };
        render::timeseries_with_error(
            &dir.join(format!("{set}_time")),
            &format!("{set}: measured and model ({})", record.optimizer),
            &rec.t,
            (render::MEASURED, &rec.y),
            &models,
            &format!("time{}", unit(0)),
            &format!("output{}", unit(2)),
        )?;
        render::loops(
            &dir.join(format!("{set}_loops")),
            &format!("{set}: input-output loops ({})", record.optimizer),
            &rec.u,
            (render::MEASURED, &rec.y),
            &models,
            &format!("input{}", unit(1)),
            &format!("output{}", unit(2)),
        )?;
    }
    Ok(())
}
