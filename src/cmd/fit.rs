//! `optbench fit`: one model fitted to one recording (or several) with one optimizer.

use crate::base::error::Result;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct FitArgs {
    /// Training recording: a CSV file, twin:SIGNAL or eq318:SIGNAL (see `optbench list`).
    /// Repeatable: several records fitted together (parameters shared, costs summed; with
    /// `--model-param d0=true` an offset per record; bouc-wen also fits each record's initial
    /// hysteretic state, `--model-param h0=false` starts them from rest).
    #[arg(long, required = true, alias = "recording")]
    pub train: Vec<String>,
    /// Held-out recording (same forms); the model is never fitted to it. Repeatable. With
    /// several records (training or validation), bouc-wen refits each validation record's
    /// own offset (with d0) and initial state on it, the actuator's parameters held fixed
    /// (`--model-param refit_validation=never` keeps the dissertation's protocol).
    #[arg(long)]
    pub validate: Vec<String>,
    /// Model to fit (a fitting objective of `optbench list`).
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(crate::registry::fitting_kind_names()))]
    pub model: String,
    /// Optimizer (`optbench list` gives each one's parameters).
    #[arg(long, default_value = "msga", value_parser = clap::builder::PossibleValuesParser::new(crate::registry::optimizer_names()))]
    pub optimizer: String,
    /// Time, input and output column names of CSV recordings.
    #[arg(long, default_value = "t,u,y")]
    pub columns: String,
    /// CSV recordings with gaps or irregular time stamps are linearly interpolated onto a
    /// uniform grid (jitter within 1 % of the step is accepted without it).
    #[arg(long)]
    pub resample: bool,
    /// Column separator of CSV recordings: ',', ';', tab or whitespace (default: detected;
    /// decimal commas are detected).
    #[arg(long)]
    pub delimiter: Option<crate::data::recording::Delimiter>,
    /// Seconds left out at the start of every CSV recording (training and validation): for
    /// records that start in motion (`diagnose` reports such a start-up).
    #[arg(long, allow_negative_numbers = true)]
    pub trim_start: Option<f64>,
    /// Function evaluations (default: the dissertation's 200 individuals x 150 iterations).
    #[arg(long, default_value_t = 30_000, value_parser = clap::value_parser!(u64).range(1..))]
    pub budget: u64,
    /// Seed of the optimizer's random stream.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Model parameter, repeatable: --model-param mode=free-run --model-param hidden=9.
    #[arg(long = "model-param", alias = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Optimizer parameter, repeatable: --optimizer-param population=100.
    #[arg(long = "optimizer-param", alias = "opt", value_name = "KEY=VALUE")]
    pub opt: Vec<String>,
    /// Worker threads for the optimizer's batched evaluations (default: one per core).
    /// Results do not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=crate::base::limits::MAX_THREADS as i64))]
    pub threads: Option<u32>,
    /// Output folder (default: results/fit-MODEL-OPTIMIZER).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress bar (it shows only when stderr is a terminal anyway).
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(a: FitArgs) -> Result<()> {
    let out = a.out.clone().unwrap_or_else(|| {
        PathBuf::from("results").join(format!("fit-{}-{}", a.model, a.optimizer))
    });
    let threads = a.threads;
    let text = super::with_threads(threads, move || {
        crate::pipeline::single_fit::run_fit(&crate::pipeline::single_fit::FitRequest {
            model: a.model,
            optimizer: a.optimizer,
            recording: a.train.join(" | "),
            validate: (!a.validate.is_empty()).then(|| a.validate.join(" | ")),
            columns: a.columns,
            resample: a.resample,
            delimiter: a.delimiter,
            trim_start: a.trim_start,
            budget: a.budget,
            seed: a.seed,
            model_params: a.params,
            optimizer_params: a.opt,
            out,
            progress: !a.quiet,
        })
    })?;
    print!("{text}");
    Ok(())
}
