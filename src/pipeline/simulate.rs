//! `optbench simulate`: recordings of the piezo twin, by default the dissertation's experiments
//! (sinusoids at 1, 4, 10, 20 and 28 Hz and the validation signal of Fig. 3.27(b)); or, with
//! `--model`, a model saved by `fit` or `diagnose` run on a recording or a signal.

use crate::base::error::{Error, Result};
use crate::base::limits;
use crate::data::recording::{Columns, ReadOptions, header_names};
use crate::data::signal::{Signal, seed_experiments};
use crate::objective::source::{SimOptions, Source, read_noting};
use crate::physics::model_file::{self, Input, ModelFile};
use crate::render::table::sig;
use std::path::{Path, PathBuf};

/// What to simulate.
#[derive(Debug, Clone)]
pub struct SimulateRequest {
    /// One signal (with its duration), or None for the dissertation's experiments.
    pub signal: Option<(String, Option<f64>)>,
    pub twin: String,
    pub seed: u64,
    pub dt: f64,
    pub columns: Columns,
    pub out: PathBuf,
}

/// Writes the recordings and returns one line per file.
pub fn run(req: &SimulateRequest) -> Result<String> {
    let opts = |duration: Option<f64>| SimOptions {
        duration,
        dt: req.dt,
        twin: req.twin.clone(),
        seed: req.seed,
    };
    let jobs: Vec<(String, Source)> = match &req.signal {
        Some((spec, duration)) => vec![(
            "twin".into(),
            Source::parse(
                &format!("twin:{spec}"),
                Path::new("."),
                "t,u,y",
                opts(*duration),
            )?,
        )],
        None => seed_experiments()
            .into_iter()
            .map(|(name, signal, duration)| {
                let src = Source::Twin {
                    signal,
                    opts: opts(Some(duration)),
                };
                (name, src)
            })
            .collect(),
    };
    std::fs::create_dir_all(&req.out)
        .map_err(|e| Error::io(format!("creating {}", req.out.display()), e))?;
    let mut text = String::new();
    for (name, src) in jobs {
        let rec = src.load()?;
        let path = req.out.join(format!("{name}.csv"));
        rec.write_csv(&path, &req.columns)?;
        let (lo, hi) = rec
            .y
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        text += &format!(
            "{}: {} samples, {:.3} s, y in [{lo:.4}, {hi:.4}] {}\n",
            path.display(),
            rec.len(),
            rec.dt() * (rec.len() - 1) as f64,
            rec.units[2]
        );
    }
    Ok(text)
}

/// What to run a saved model on (`optbench simulate --model`).
#[derive(Debug, Clone)]
pub struct ModelRequest {
    pub model: PathBuf,
    /// A CSV recording, or a signal spec ("sine:freq=10,amp=2.3,offset=2.35").
    pub input: String,
    /// A fitted record whose own initial state and offset to start from.
    pub record: Option<String>,
    /// Column names read from a CSV input (a missing output column is no measurement) and
    /// written (`None`: the model's own, else t,u,y).
    pub columns: Option<Columns>,
    pub read: ReadOptions,
    /// Sampling interval of a signal spec (default: the model's).
    pub dt: Option<f64>,
    /// Seconds of a signal spec (chirps carry their own).
    pub duration: Option<f64>,
    pub out: PathBuf,
}

/// The input of a model run: time, input, measured output if any, and a name for the file.
struct ModelInput {
    t: Vec<f64>,
    u: Vec<f64>,
    y: Option<Vec<f64>>,
    dt: f64,
    stem: String,
}

fn model_input(req: &ModelRequest, columns: &Columns, model_dt: f64) -> Result<ModelInput> {
    let path = Path::new(&req.input);
    if path.is_file() {
        let names = header_names(path, &req.read)?;
        let measured = names.contains(&columns.output);
        // Without the output column the input is read in its place (and not used).
        let cols = Columns {
            output: if measured {
                columns.output.clone()
            } else {
                columns.input.clone()
            },
            ..columns.clone()
        };
        let rec = read_noting(path, &cols, &req.read)?;
        let stem = path
            .file_stem()
            .map_or("input".into(), |s| s.to_string_lossy().to_string());
        return Ok(ModelInput {
            dt: rec.dt(),
            y: measured.then(|| rec.y.clone()),
            t: rec.t,
            u: rec.u,
            stem,
        });
    }
    let signal = Signal::parse(&req.input).map_err(|e| {
        Error::Input(format!(
            "--input {}: neither a file nor a signal spec ({e})",
            req.input
        ))
    })?;
    let dt = req.dt.unwrap_or(model_dt);
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(Error::Input(format!(
            "--dt {dt}: expected a positive interval in seconds"
        )));
    }
    let duration = match (req.duration, &signal) {
        (Some(d), _) if d > 0.0 && d.is_finite() => d,
        (Some(d), _) => {
            return Err(Error::Input(format!(
                "--duration {d}: expected seconds > 0"
            )));
        }
        (None, Signal::Chirp { duration, .. }) => *duration,
        (None, _) => {
            return Err(Error::Input(format!(
                "--input {}: give --duration (seconds) for this signal",
                req.input
            )));
        }
    };
    limits::samples(duration, dt)
        .map_err(|e| Error::Input(format!("--input {}: {e}", req.input)))?;
    let u = signal.sample(dt, duration);
    if u.len() < 2 {
        return Err(Error::Input(format!(
            "--input {}: {duration} s at {dt} s is {} samples; at least 2 needed",
            req.input,
            u.len()
        )));
    }
    Ok(ModelInput {
        t: (0..u.len()).map(|k| k as f64 * dt).collect(),
        u,
        y: None,
        dt,
        stem: "signal".into(),
    })
}

/// Runs the saved model on the input, writes `OUT/<input>_predicted.csv` and returns what
/// to print (the RMSE against a measured output, when the input has one).
pub fn run_model(req: &ModelRequest) -> Result<String> {
    let model = ModelFile::read(&req.model)?;
    let columns = match (&req.columns, model.column_names()) {
        (Some(c), _) => c.clone(),
        (None, Some([t, u, y])) => Columns::parse(&format!("{t},{u},{y}"))?,
        (None, None) => Columns::default(),
    };
    let input = model_input(req, &columns, model.sampling_interval_s)?;
    let pred = model.run(
        &req.model,
        &Input {
            u: &input.u,
            y: input.y.as_deref(),
            dt: input.dt,
        },
        req.record.as_deref(),
    )?;
    std::fs::create_dir_all(&req.out)
        .map_err(|e| Error::io(format!("creating {}", req.out.display()), e))?;
    let path = req.out.join(format!("{}_predicted.csv", input.stem));
    let c = &columns;
    model_file::write_prediction(
        &path,
        [&c.time, &c.input, &c.output],
        &input.t,
        &input.u,
        input.y.as_deref(),
        &pred,
    )?;
    let (lo, hi) = pred
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let unit = &model.units.output;
    let mut text = format!(
        "{}: {} model, {} samples every {} s, predicted {} in [{}, {}] {unit}\n",
        path.display(),
        model.kind,
        pred.len(),
        input.dt,
        c.output,
        sig(lo, 6),
        sig(hi, 6)
    );
    if let Some(y) = &input.y {
        text += &format!(
            "RMSE against the measured {}: {} {unit}\n",
            c.output,
            sig(model.rmse(y, &pred), 6)
        );
    }
    Ok(text)
}
