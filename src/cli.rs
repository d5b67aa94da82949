//! Command-line interface. Parsing and dispatch only; the work lives in the library.

use crate::base::error::Result;
use crate::registry::{objective_kinds, optimizer_kinds};
use crate::report::table::markdown;
use clap::{Parser, Subcommand};
use std::io::IsTerminal;
use std::path::PathBuf;

/// Reproducible benchmarks of optimizers on test functions and hysteresis fitting.
#[derive(Parser, Debug)]
#[command(name = "optbench", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Run every trial of a suite, write results/NAME/ (NAME from the suite) and its report.
    Run(RunArgs),
    /// Regenerate the report (tables, plots, IOHprofiler export) of a results folder from
    /// its stored traces; with two folders of the same suite, compare them.
    Report(ReportArgs),
    /// Combine the results folders of `run --shard K/N` (or of resumable runs of the same
    /// suite) into one, identical to a single run's.
    Merge(MergeArgs),
    /// Fit one model to one recording with one optimizer; numbers and figures in --out.
    Fit(FitArgs),
    /// Write piezo-twin recordings: the seed's experiments, or one --signal.
    Simulate(SimulateArgs),
    /// Locate where a hysteresis model misses a recording, name the missing physics and
    /// fit the better model (or, with --proof, run the concealed-effect proof).
    Diagnose(crate::diagnose::cli::DiagnoseArgs),
    /// List objectives and optimizers with their parameters and defaults.
    List,
    /// Measure evaluation speed on this machine: scalar, batched and all-thread paths of
    /// every objective kind, harness overhead, MSGA threads.
    Bench(BenchArgs),
    /// Closed-loop hysteresis compensation on the twin: IMC with two RBF networks or
    /// incremental PID tracking a reference; signals, numbers and figures in --out.
    Control(ControlArgs),
}

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// A few seconds instead of about a minute (smaller records and populations).
    #[arg(long)]
    pub quick: bool,
    /// Threads for the all-thread figures (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub threads: Option<u32>,
    /// Also write the figures as JSON to this file (read by scripts/compare-peers).
    #[arg(long)]
    pub json: Option<std::path::PathBuf>,
}

#[derive(clap::Args, Debug)]
pub struct ControlArgs {
    /// Controller: imc-rbf (the seed's IMC with two RBF networks) or pid (eq. 4.9).
    #[arg(long)]
    pub controller: String,
    /// Reference in mm: sweep-1-2hz, sweep-1-3hz, sweep-1-4hz, sweep-1-10hz (the seed's),
    /// or a signal spec such as "sine:freq=5,amp=0.2,offset=0.3" (with --duration).
    #[arg(long)]
    pub reference: String,
    /// Seconds of the reference (default: its own, 5 s for the sweeps).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Twin overrides of the plant, e.g. "creep=on,mode.zeta=0.02".
    #[arg(long, default_value = "")]
    pub plant: String,
    /// Twin overrides the internal model is identified on (default: the plant's); e.g.
    /// --model-twin "mode=off" --plant "creep=on" for a model/plant mismatch.
    #[arg(long)]
    pub model_twin: Option<String>,
    /// Controller parameter, repeatable: --param ki=0.4 --param learning_rate=0.05
    /// (pid: kp, ki, kd; imc-rbf: learning_rate, momentum, error_scale, sensitivity,
    /// model_mode, model_budget, ...; a wrong key lists the valid ones).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Seconds at the start counted as the transient (figures and the steady RMSE).
    #[arg(long, default_value_t = 1.0)]
    pub transient: f64,
    /// Seed of the model fit and the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder (default: results/control-CONTROLLER).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
pub struct RunArgs {
    /// Suite file (TOML), e.g. suites/functions.toml.
    pub suite: PathBuf,
    /// Results folder (default: results/NAME, NAME from the suite).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Override the suite's number of trials.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub trials: Option<u32>,
    /// Worker threads for trials (default: one per core). Results do not depend on it.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
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
    /// Run only share K of N of the trials (round robin over the plan), e.g. 3/8; default
    /// --out results/NAME-shard-K-of-N. Combine the shards with `optbench merge`.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<crate::scale::Shard>,
}

#[derive(clap::Args, Debug)]
pub struct MergeArgs {
    /// Results folders of the shards.
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Where the merged results go.
    #[arg(long)]
    pub out: PathBuf,
    /// No table.
    #[arg(long, short)]
    pub quiet: bool,
}

#[derive(clap::Args, Debug)]
pub struct ReportArgs {
    /// Results folder written by `optbench run`.
    pub results: PathBuf,
    /// A second results folder of the same suite: print the differences instead.
    pub other: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
pub struct FitArgs {
    /// Training recording: a CSV file, twin:SIGNAL or eq318:SIGNAL (see `optbench list`).
    /// Repeatable: several records fitted together (parameters shared, costs summed; with
    /// `--param d0=true` an offset per record; bouc-wen also fits each record's initial
    /// hysteretic state, `--param h0=false` starts them from rest).
    #[arg(long, required = true)]
    pub recording: Vec<String>,
    /// Held-out recording (same forms); the model is never fitted to it. Repeatable. With
    /// several records (training or validation), bouc-wen refits each validation record's
    /// own offset (with d0) and initial state on it, the actuator's parameters held fixed
    /// (`--param refit_validation=never` keeps the seed's protocol).
    #[arg(long)]
    pub validate: Vec<String>,
    /// Model to fit (a fitting objective of `optbench list`, e.g. bouc-wen or rbf).
    #[arg(long)]
    pub model: String,
    /// Optimizer (ga, pso, msga, bp, random).
    #[arg(long, default_value = "msga")]
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
    pub delimiter: Option<crate::recording::Delimiter>,
    /// Seconds left out at the start of every CSV recording (training and validation): for
    /// records that start in motion (`diagnose` reports such a start-up).
    #[arg(long, allow_negative_numbers = true)]
    pub trim_start: Option<f64>,
    /// Function evaluations (default: the seed's 200 individuals x 150 iterations).
    #[arg(long, default_value_t = 30_000)]
    pub budget: u64,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Model parameter, repeatable: --param mode=free-run --param hidden=9.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Optimizer parameter, repeatable: --opt population=100.
    #[arg(long = "opt", value_name = "KEY=VALUE")]
    pub opt: Vec<String>,
    /// Output folder (default: results/fit-MODEL-OPTIMIZER).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Drive signal, e.g. "sine:freq=10,amp=2.3,offset=2.35" (default: the seed's five
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
        Command::Run(args) => run(args),
        Command::Merge(a) => {
            print!("{}", crate::scale::merge(&a.dirs, &a.out, a.quiet)?);
            Ok(())
        }
        Command::Report(args) => {
            match args.other {
                Some(other) => print!("{}", crate::report::compare(&args.results, &other)?),
                None => {
                    let table = crate::report::generate(&args.results)?;
                    print!("{table}");
                    println!("\nreport: {}", args.results.join("report.md").display());
                }
            }
            Ok(())
        }
        Command::Fit(a) => {
            let out = a.out.clone().unwrap_or_else(|| {
                PathBuf::from("results").join(format!("fit-{}-{}", a.model, a.optimizer))
            });
            print!(
                "{}",
                crate::fitting::run_fit(&crate::fitting::FitRequest {
                    model: a.model,
                    optimizer: a.optimizer,
                    recording: a.recording.join(" | "),
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
                })?
            );
            Ok(())
        }
        Command::Simulate(a) => {
            let req = crate::simulate::SimulateRequest {
                signal: a.signal.map(|s| (s, a.duration)),
                twin: a.twin,
                seed: a.seed,
                dt: a.dt,
                columns: crate::recording::Columns::parse(&a.columns)?,
                out: a.out,
            };
            print!("{}", crate::simulate::run(&req)?);
            Ok(())
        }
        Command::Control(a) => {
            let out = a.out.clone().unwrap_or_else(|| {
                PathBuf::from("results").join(format!("control-{}", a.controller))
            });
            print!(
                "{}",
                crate::control::command::run(&crate::control::command::ControlRequest {
                    controller: a.controller,
                    params: a.params,
                    reference: a.reference,
                    duration: a.duration,
                    plant: a.plant,
                    model_twin: a.model_twin,
                    transient: a.transient,
                    seed: a.seed,
                    out,
                })?
            );
            Ok(())
        }
        Command::Diagnose(a) => {
            print!("{}", crate::diagnose::cli::run(a)?);
            Ok(())
        }
        Command::List => {
            print!("{}", list());
            Ok(())
        }
        Command::Bench(a) => {
            let cfg = if a.quick {
                crate::speed::BenchConfig::quick()
            } else {
                crate::speed::BenchConfig::full()
            };
            let report = match a.threads {
                Some(t) => rayon::ThreadPoolBuilder::new()
                    .num_threads(t as usize)
                    .build()
                    .map_err(|e| crate::Error::Input(format!("thread pool: {e}")))?
                    .install(|| crate::speed::run(&cfg)),
                None => crate::speed::run(&cfg),
            };
            print!("{}", report.render());
            if let Some(path) = &a.json {
                let text = serde_json::to_string_pretty(&report.to_json())
                    .map_err(|e| crate::Error::Input(format!("bench JSON: {e}")))?;
                std::fs::write(path, text).map_err(|source| crate::Error::Io {
                    context: path.display().to_string(),
                    source,
                })?;
            }
            Ok(())
        }
    }
}

fn run(args: RunArgs) -> Result<()> {
    if std::fs::read_to_string(&args.suite)
        .is_ok_and(|t| crate::control::suite::is_control_suite(&t))
    {
        return crate::control::suite::run_cli(
            &args.suite,
            &crate::control::suite::RunOverrides {
                out: args.out,
                trials: args.trials.map(|t| t as usize),
                threads: args.threads.map(|t| t as usize),
                seed: args.seed,
                budget: args.budget,
                quiet: args.quiet,
            },
        );
    }
    let req = crate::scale::RunRequest {
        suite: args.suite,
        out: args.out,
        overrides: crate::scale::Overrides {
            trials: args.trials.map(|t| t as usize),
            seed: args.seed,
            budget: args.budget,
        },
        threads: args.threads.map(|t| t as usize),
        progress: !args.quiet && std::io::stdout().is_terminal() && std::io::stderr().is_terminal(),
        quiet: args.quiet,
        resume: args.resume,
        force_resume: args.force_resume,
        shard: args.shard,
    };
    print!("{}", crate::scale::run(&req)?);
    Ok(())
}

/// The text of `optbench list`.
pub fn list() -> String {
    let mut s = String::new();
    let section = |s: &mut String,
                   title: &str,
                   name: &str,
                   help: &str,
                   params: &[crate::base::params::Spec]| {
        s.push_str(&format!("{title} `{name}`: {help}\n"));
        let rows: Vec<Vec<String>> = params
            .iter()
            .map(|p| {
                vec![
                    p.name.to_string(),
                    p.kind.to_string(),
                    p.default.to_string(),
                    p.help.to_string(),
                ]
            })
            .collect();
        if rows.is_empty() {
            s.push_str("  (no parameters)\n\n");
        } else {
            for line in markdown(&["parameter", "type", "default", "meaning"], &rows, &[]).lines() {
                s.push_str("  ");
                s.push_str(line);
                s.push('\n');
            }
            s.push('\n');
        }
    };
    s.push_str(
        "OBJECTIVES ([[objective]] kind = ...; also id, budget, targets, stop_at, optimizers)\n\n",
    );
    for k in objective_kinds() {
        section(&mut s, "objective", k.name, k.help, k.params);
    }
    s.push_str("OPTIMIZERS ([[optimizer]] kind = ...; also id, polish, polish_with)\n\n");
    for k in optimizer_kinds() {
        section(&mut s, "optimizer", k.name, k.help, k.params);
    }
    s
}
