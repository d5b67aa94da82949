//! `optbench control`: one closed-loop run on the twin, its signals as CSV, its numbers as
//! JSON and the dissertation's figures.

use super::closed_loop::Guard;
use super::figures::write_run_figures;
use super::reference::Reference;
use super::run::{ControllerSpec, DT, Identified, Outcome, RunSpec, key_values};
use crate::base::error::{Error, Result};
use crate::base::{TrialSeed, atomic_write};
use crate::render::table::sig;
use rand::RngExt;
use serde::Serialize;
use std::path::PathBuf;

/// What `optbench control` was asked.
#[derive(Debug, Clone)]
pub struct ControlRequest {
    /// A kind of [`super::run::CONTROLLER_KINDS`].
    pub controller: String,
    /// `key=value` controller settings.
    pub params: Vec<String>,
    pub reference: String,
    pub duration: Option<f64>,
    /// Twin overrides of the plant.
    pub plant: String,
    /// Twin overrides for identifying the internal model (None: the plant's).
    pub model_twin: Option<String>,
    pub transient: f64,
    pub seed: u64,
    pub out: PathBuf,
}

/// The key of the internal model fitted for trial `trial` of a run seeded `base`: one model
/// per (identification setting `model_id`, trial), shared by every reference, as a model is
/// identified once on a rig and then used for all experiments.
pub fn model_seed(base: u64, model_id: &str, trial: u64) -> TrialSeed {
    TrialSeed::derive(base, "internal-model", model_id, trial)
}

/// The sensor-noise seed of trial `trial`: shared by every controller on the same reference
/// and plant, so controllers are compared on the same noise realisation (paired).
pub fn noise_seed(base: u64, reference: &str, plant_id: &str, trial: u64) -> u64 {
    TrialSeed::derive(base, reference, plant_id, trial)
        .rng(0)
        .random()
}

#[derive(Serialize)]
struct Summary<'a> {
    controller: &'a ControllerSpec,
    reference: &'a str,
    duration_s: f64,
    plant: &'a str,
    model_twin: Option<&'a str>,
    seed: u64,
    noise_seed: u64,
    model_seed: Option<String>,
    metrics: &'a super::run::Metrics,
    model_fit_evaluations: Option<u64>,
    figures: Vec<String>,
}

/// The signals of a run as CSV text.
pub fn run_csv(o: &Outcome) -> String {
    let r = &o.run;
    let mut s = String::from("t_s,reference_mm,output_mm,error_mm,command_V,feedback_mm\n");
    for k in 0..r.len() {
        s += &format!(
            "{},{},{},{},{},{}\n",
            k as f64 * r.dt,
            r.reference[k],
            r.output[k],
            r.reference[k] - r.output[k],
            r.command[k],
            r.feedback[k]
        );
    }
    s
}

fn fmt_mm(v: Option<f64>) -> String {
    v.map(|x| format!("{} mm", sig(x, 3)))
        .unwrap_or_else(|| "— (failed)".into())
}

/// Runs the request, writes `run.csv`, `summary.json` and the figures into `out`, and
/// returns a short report.
pub fn run(req: &ControlRequest) -> Result<String> {
    let controller = ControllerSpec::parse(&req.controller, &key_values(&req.params)?)?;
    let reference = Reference::parse(&req.reference, req.duration)?;
    let spec = RunSpec {
        controller,
        reference,
        plant: req.plant.clone(),
        model_twin: req.model_twin.clone(),
        guard: Guard::default(),
        transient: req.transient,
    };
    spec.validate()?;
    if req.out.is_file() {
        return Err(Error::Input(format!(
            "--out {}: is a file, expected a folder",
            req.out.display()
        )));
    }
    let mseed = model_seed(req.seed, "cli", 0);
    let nseed = noise_seed(req.seed, &spec.reference.name, "cli", 0);
    let fitted = match spec.model_config() {
        Some(m) => Some(m.fit(&mseed)?),
        None => None,
    };
    let outcome = spec.execute(fitted.as_ref(), nseed)?;
    std::fs::create_dir_all(&req.out)
        .map_err(|e| Error::io(format!("creating {}", req.out.display()), e))?;
    let title = format!("{} on {}", spec.controller.kind(), spec.reference.name);
    let figures = write_run_figures(&req.out, "", &title, &outcome.run, spec.transient)?;
    atomic_write(&req.out.join("run.csv"), run_csv(&outcome).as_bytes())?;
    let summary = Summary {
        controller: &spec.controller,
        reference: &spec.reference.name,
        duration_s: spec.reference.duration,
        plant: &spec.plant,
        model_twin: spec.model_twin.as_deref(),
        seed: req.seed,
        noise_seed: nseed,
        model_seed: fitted.as_ref().map(|_| mseed.hex()),
        metrics: &outcome.metrics,
        model_fit_evaluations: fitted.as_ref().map(Identified::evaluations),
        figures: figures.clone(),
    };
    let json = serde_json::to_string_pretty(&summary)
        .map_err(|e| Error::Input(format!("summary: {e}")))?;
    atomic_write(&req.out.join("summary.json"), json.as_bytes())?;

    let m = &outcome.metrics;
    let mut text = format!(
        "{title}: {} samples at {} ms, plant `{}`\n",
        outcome.run.len(),
        DT * 1e3,
        if spec.plant.is_empty() {
            "default twin"
        } else {
            &spec.plant
        }
    );
    match &fitted {
        Some(Identified::Rbf(f)) => {
            text += &format!(
                "internal model: 3-7-1 RBF NARX by PSO ({} evaluations), free-run RMSE {} on its record\n",
                f.record.evaluations,
                fmt_mm(Some(f.free_run_rmse))
            )
        }
        Some(Identified::Inverse(f)) => {
            text += &format!(
                "inverted model: {}, free-run RMSE {} on its record\n",
                f.model.describe(f.evaluations),
                fmt_mm(Some(f.free_run_rmse))
            )
        }
        None => {}
    }
    if let Some(f) = &m.failure {
        text += &format!(
            "FAILED at {:.3} s (sample {}): {}\n",
            f.time_s, f.sample, f.reason
        );
    }
    text += &format!(
        "RMS error {} (whole run), {} after {} s; max |e| after it {}",
        fmt_mm(m.rmse_mm),
        fmt_mm(m.rmse_steady_mm),
        spec.transient,
        fmt_mm(m.max_error_steady_mm),
    );
    // The IMC feedback (plant minus model) exists only with an internal model.
    if let Some(Identified::Rbf(_)) = fitted {
        text += &format!("; IMC feedback RMS {}", fmt_mm(Some(m.feedback_rms_mm)));
    }
    text += "\n";
    text += &format!("output folder: {}\n", req.out.display());
    Ok(text)
}
