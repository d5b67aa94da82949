//! `optbench run SUITE`: every trial of a benchmark suite (or a control suite), its results
//! and report.

use crate::base::error::Result;
use crate::base::limits::{MAX_THREADS, MAX_TRIALS};
use std::io::IsTerminal;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Suite file (TOML), e.g. suites/functions.toml.
    pub suite: PathBuf,
    /// Results folder (default: results/NAME, NAME from the suite).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Override the suite's number of trials.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_TRIALS as i64))]
    pub trials: Option<u32>,
    /// Worker threads for trials (default: one per core). Results do not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_THREADS as i64))]
    pub threads: Option<u32>,
    /// Override the suite's seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Override every objective's budget (evaluations per trial), e.g. for a quick check.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub budget: Option<u64>,
    /// No progress bar and no table.
    #[arg(long, short)]
    pub quiet: bool,
    /// Continue an interrupted run in --out: finished trials (in progress.jsonl) are kept,
    /// the rest run. Starts fresh if there is nothing to resume.
    #[arg(long)]
    pub resume: bool,
    /// Resume even if the suite, overrides, build or shard changed: keep only the stored
    /// trials whose configuration is unchanged.
    #[arg(long)]
    pub force_resume: bool,
    /// Run into --out even if it holds another suite's results or other files: optbench's
    /// own files there (results, report, tables, plots, ioh) are removed first; other files
    /// are left alone. Without it such a folder is refused.
    #[arg(long, conflicts_with_all = ["resume", "force_resume"])]
    pub overwrite: bool,
    /// Run only share K of N of the trials (round robin over the plan), e.g. 3/8; default
    /// --out results/NAME-shard-K-of-N. Combine the shards with `optbench merge`.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<crate::pipeline::run::Shard>,
}

pub fn run(args: RunArgs) -> Result<()> {
    if std::fs::read_to_string(&args.suite)
        .is_ok_and(|t| crate::control::suite::is_control_suite(&t))
    {
        print!(
            "{}",
            crate::control::suite::run_file(
                &args.suite,
                &crate::control::suite::RunOverrides {
                    out: args.out,
                    trials: args.trials.map(|t| t as usize),
                    threads: args.threads.map(|t| t as usize),
                    seed: args.seed,
                    budget: args.budget,
                    quiet: args.quiet,
                    overwrite: args.overwrite,
                },
            )?
        );
        return Ok(());
    }
    let req = crate::pipeline::run::RunRequest {
        suite: args.suite,
        out: args.out,
        overrides: crate::pipeline::run::Overrides {
            trials: args.trials.map(|t| t as usize),
            seed: args.seed,
            budget: args.budget,
        },
        threads: args.threads.map(|t| t as usize),
        progress: !args.quiet && std::io::stdout().is_terminal() && std::io::stderr().is_terminal(),
        quiet: args.quiet,
        resume: args.resume,
        force_resume: args.force_resume,
        overwrite: args.overwrite,
        shard: args.shard,
        report: Some(crate::report::generate),
    };
    #[cfg(feature = "mpi")]
    if crate::pipeline::scale::mpi::launched_by_mpirun() {
        print!("{}", crate::pipeline::scale::mpi::run(&req)?);
        return Ok(());
    }
    print!("{}", crate::pipeline::run::run(&req)?);
    Ok(())
}
