//! `optbench bench`: evaluation speed on this machine (see [`crate::speed`]).

use crate::base::error::{Error, Result};
use crate::base::limits::MAX_THREADS;
use crate::speed::{BenchConfig, STAGES, run_with_progress};
use std::io::IsTerminal;

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// A few seconds instead of about a minute (smaller records and populations).
    #[arg(long)]
    pub quick: bool,
    /// Threads for the all-thread figures (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_THREADS as i64))]
    pub threads: Option<u32>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// Also write the figures as JSON to this file (read by scripts/compare-peers).
    #[arg(long)]
    pub json: Option<std::path::PathBuf>,
}

pub fn run(a: BenchArgs) -> Result<()> {
    let cfg = if a.quick {
        BenchConfig::quick()
    } else {
        BenchConfig::full()
    };
    // As `run`: no bar when the report goes to a pipe or file either.
    let show = !a.quiet && std::io::stdout().is_terminal();
    let bar = crate::pipeline::runner::progress_bar(STAGES as u64, "measurements", show);
    let report = super::with_threads(a.threads, || {
        Ok(run_with_progress(&cfg, &mut |stage| {
            bar.inc(1);
            bar.set_message(stage.to_string());
        }))
    })?;
    bar.finish_and_clear();
    print!("{}", report.render());
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&report.to_json())
            .map_err(|e| Error::Input(format!("bench JSON: {e}")))?;
        std::fs::write(path, text).map_err(|source| Error::Io {
            context: path.display().to_string(),
            source,
        })?;
    }
    Ok(())
}
