//! The command layer: one file per subcommand, each parsing its arguments and calling the
//! library; nothing below imports it.
//!
//! Arguments are the user's values: no unwrap or index on them here (a bad value is an
//! error with exit 2, never a panic), which clippy holds this layer to.
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

pub mod bench;
pub mod control;
pub mod diagnose;
pub mod fit;
pub mod invert;
pub mod list;
pub mod merge;
pub mod report;
pub mod run;
pub mod shell;
pub mod simulate;

use crate::base::error::Result;
use clap::{Parser, Subcommand};

/// The version with the commit it was built from (`git describe --dirty`, set by build.rs),
/// so a result can be traced to its source.
pub const VERSION: &str = env!("OPTBENCH_VERSION");

/// Reproducible benchmarks of optimizers on test functions and hysteresis fitting.
#[derive(Parser, Debug)]
#[command(name = "optbench", version = VERSION, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run every trial of a suite, write results/NAME/ (NAME from the suite) and its report.
    Run(run::RunArgs),
    /// Regenerate the report (tables, plots, IOHprofiler export) of a results folder from
    /// its stored traces; with two folders of the same suite, compare them.
    Report(report::ReportArgs),
    /// Combine the results folders of `run --shard K/N` (or of resumable runs of the same
    /// suite) into one, identical to a single run's.
    Merge(merge::MergeArgs),
    /// Fit one model to one recording with one optimizer; numbers and figures in --out.
    Fit(fit::FitArgs),
    /// Feedforward by an inverted Prandtl-Ishlinskii model: fit it to a recording, compute
    /// the command for a desired trajectory, compare with a recorded command.
    Invert(invert::InvertArgs),
    /// Write piezo-twin recordings: the dissertation's experiments, or one --signal.
    Simulate(simulate::SimulateArgs),
    /// Locate where a hysteresis model misses a recording, name the missing physics and
    /// fit the better model (or, with --proof, run the concealed-effect proof).
    Diagnose(diagnose::DiagnoseArgs),
    /// List objectives and optimizers with their parameters and defaults.
    List(list::ListArgs),
    /// Measure evaluation speed on this machine: scalar, batched and all-thread paths of
    /// every objective kind, harness overhead, MSGA threads.
    Bench(bench::BenchArgs),
    /// Closed-loop hysteresis compensation on the twin: IMC with two RBF networks or
    /// incremental PID tracking a reference; signals, numbers and figures in --out.
    Control(control::ControlArgs),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell) to stdout.
    Completions(shell::CompletionsArgs),
    /// Write the man pages (optbench.1 and one per subcommand) into a folder.
    Man(shell::ManArgs),
}

/// Entry point: returns the process exit code.
pub fn main() -> i32 {
    let cli = Cli::parse();
    match dispatch(cli) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}

fn dispatch(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Run(a) => run::run(a),
        Command::Report(a) => report::run(a),
        Command::Merge(a) => merge::run(a),
        Command::Fit(a) => fit::run(a),
        Command::Invert(a) => invert::run(a),
        Command::Simulate(a) => simulate::run(a),
        Command::Diagnose(a) => diagnose::run(a),
        Command::List(a) => list::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Control(a) => control::run(a),
        Command::Completions(a) => shell::completions(a),
        Command::Man(a) => shell::man(a),
    }
}

/// Runs `f` on a pool of `threads` workers (rayon's global pool, one per core, when None).
/// Results never depend on it: every random stream is seeded per task, not per thread.
fn with_threads<T: Send>(threads: Option<u32>, f: impl FnOnce() -> Result<T> + Send) -> Result<T> {
    match threads {
        None => f(),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build()
            .map_err(|e| crate::base::error::Error::Input(format!("--threads {n}: {e}")))?
            .install(f),
    }
}
