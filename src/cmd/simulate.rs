//! `optbench simulate`: piezo-twin recordings written as CSV files, or (`--model`) a saved
//! model run on a recording or a signal.

use crate::base::error::{Error, Result};
use crate::base::limits;
use crate::data::recording::{Columns, Delimiter, ReadOptions};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Drive signal, e.g. "sine:freq=10,amp=2.3,offset=2.35" (default: the dissertation's five
    /// sinusoids and its validation chirp, one CSV each).
    #[arg(long, conflicts_with = "model")]
    pub signal: Option<String>,
    /// Seconds of --signal, or of a signal given as --input (chirps carry their own).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Twin overrides, e.g. "mode=off,creep=on,noise=0.001".
    #[arg(long, default_value = "", conflicts_with = "model")]
    pub twin: String,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sampling interval [s] (default: 0.001; with --model and a signal, the model's).
    #[arg(long)]
    pub dt: Option<f64>,
    /// Column names written, default t,u,y (with --model also read from --input: time,
    /// input and, if the file has it, the measured output; default the model's own).
    #[arg(long)]
    pub columns: Option<String>,
    /// Output folder (default: results/twin, or results/predicted with --model).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// A model.json written by `optbench fit` or `diagnose`: run it on --input and write
    /// INPUT_predicted.csv (time, input, measured and predicted output, residual).
    #[arg(long, requires = "input")]
    pub model: Option<PathBuf>,
    /// With --model: a CSV recording, or a signal spec as --signal takes.
    #[arg(long, requires = "model")]
    pub input: Option<String>,
    /// With --model: start from this fitted record's own initial state and offset (its
    /// label in model.json's records, e.g. validate) instead of from rest.
    #[arg(long, requires = "model")]
    pub record: Option<String>,
    /// Column separator of a CSV --input: ',', ';', tab or whitespace (default: detected).
    #[arg(long, default_value = "auto")]
    pub delimiter: Delimiter,
    /// A CSV --input with gaps or irregular time stamps is linearly interpolated onto a
    /// uniform grid.
    #[arg(long)]
    pub resample: bool,
    /// Print nothing but errors.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(a: SimulateArgs) -> Result<()> {
    let columns = a.columns.as_deref().map(Columns::parse).transpose()?;
    let text = if let (Some(model), Some(input)) = (a.model, a.input) {
        crate::pipeline::simulate::run_model(&crate::pipeline::simulate::ModelRequest {
            model,
            input,
            record: a.record,
            columns,
            read: ReadOptions {
                resample: a.resample,
                delimiter: a.delimiter,
            },
            dt: a.dt,
            duration: a.duration,
            out: a.out.unwrap_or_else(|| PathBuf::from("results/predicted")),
        })?
    } else {
        let dt = a.dt.unwrap_or(1e-3);
        // The samples asked for (chirps carry their own duration, checked with their spec).
        let longest = a.duration.unwrap_or_else(|| {
            crate::data::signal::seed_experiments()
                .iter()
                .map(|e| e.2)
                .fold(0.0, f64::max)
        });
        limits::samples(longest, dt)
            .map_err(|e| Error::Input(format!("--duration {longest:?} with --dt {dt:?}: {e}")))?;
        crate::pipeline::simulate::run(&crate::pipeline::simulate::SimulateRequest {
            signal: a.signal.map(|s| (s, a.duration)),
            twin: a.twin,
            seed: a.seed,
            dt,
            columns: columns.unwrap_or_default(),
            out: a.out.unwrap_or_else(|| PathBuf::from("results/twin")),
        })?
    };
    if !a.quiet {
        print!("{text}");
    }
    Ok(())
}
