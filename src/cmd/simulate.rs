//! `optbench simulate`: piezo-twin recordings written as CSV files.

use crate::base::error::{Error, Result};
use crate::base::limits;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Drive signal, e.g. "sine:freq=10,amp=2.3,offset=2.35" (default: the dissertation's five
    /// sinusoids and its validation chirp, one CSV each).
    #[arg(long)]
    pub signal: Option<String>,
    /// Seconds of --signal (chirps carry their own).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Twin overrides, e.g. "mode=off,creep=on,noise=0.001".
    #[arg(long, default_value = "")]
    pub twin: String,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Sampling interval [s].
    #[arg(long, default_value_t = 1e-3)]
    pub dt: f64,
    /// Column names written.
    #[arg(long, default_value = "t,u,y")]
    pub columns: String,
    /// Output folder.
    #[arg(long, default_value = "results/twin")]
    pub out: PathBuf,
}

pub fn run(a: SimulateArgs) -> Result<()> {
    // The samples asked for (chirps carry their own duration, checked with their spec).
    let longest = a.duration.unwrap_or_else(|| {
        crate::data::signal::seed_experiments()
            .iter()
            .map(|e| e.2)
            .fold(0.0, f64::max)
    });
    limits::samples(longest, a.dt)
        .map_err(|e| Error::Input(format!("--duration {longest:?} with --dt {:?}: {e}", a.dt)))?;
    let req = crate::pipeline::simulate::SimulateRequest {
        signal: a.signal.map(|s| (s, a.duration)),
        twin: a.twin,
        seed: a.seed,
        dt: a.dt,
        columns: crate::data::recording::Columns::parse(&a.columns)?,
        out: a.out,
    };
    print!("{}", crate::pipeline::simulate::run(&req)?);
    Ok(())
}
