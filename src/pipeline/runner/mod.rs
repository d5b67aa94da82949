//! Runs a suite's plan: every trial in parallel on a rayon pool, results in plan order, so
//! the output does not depend on the number of threads.

pub mod trial;

pub use trial::{TrialIdentity, TrialSpec, run_trial, run_trial_observed};

use crate::base::error::{Error, Result};
use crate::harness::TrialRecord;
use crate::pipeline::suite::{PlannedTrial, Suite};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::sync::Arc;

/// How to run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Worker threads for trials (None: one per core).
    pub threads: Option<usize>,
    /// Show a progress bar.
    pub progress: bool,
}

/// Runs every trial of `suite`; returns the records in plan order and the thread count.
pub fn run_suite(suite: &Suite, opts: &RunOptions) -> Result<(Vec<TrialRecord>, usize)> {
    run_trials(suite, &suite.plan(), opts, &|_, _| {})
}

/// Runs the trials of `plan` (all or part of `suite.plan()`), calling `done(i, record)` on
/// the worker thread the moment trial `plan[i]` ends (to store it at once); returns the
/// records in the order of `plan` and the thread count.
pub fn run_trials(
    suite: &Suite,
    plan: &[PlannedTrial],
    opts: &RunOptions,
    done: &(dyn Fn(usize, &TrialRecord) + Sync),
) -> Result<(Vec<TrialRecord>, usize)> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = opts.threads {
        builder = builder.num_threads(n);
    }
    let pool = builder
        .build()
        .map_err(|e| Error::Input(format!("cannot start {:?} threads: {e}", opts.threads)))?;
    let bar = progress_bar(plan.len() as u64, "trials", opts.progress);
    let records = pool.install(|| {
        plan.par_iter()
            .enumerate()
            .map(|(i, t)| {
                let record = run_planned(suite, t);
                done(i, &record);
                bar.inc(1);
                record
            })
            .collect::<Vec<_>>()
    });
    bar.finish_and_clear();
    Ok((records, pool.current_num_threads()))
}

/// A progress bar of `len` steps counted in `unit` on stderr, or a hidden one when `show`
/// is false or stderr is not a terminal (a log file gets no bar lines).
pub fn progress_bar(len: u64, unit: &str, show: bool) -> ProgressBar {
    use std::io::IsTerminal;
    if !show || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {unit} ({{eta}} left) {{msg}}"
        ))
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar
}

/// A spinner with a message (the stage of a job of unknown length), hidden as
/// [`progress_bar`] is.
pub fn spinner(show: bool) -> ProgressBar {
    use std::io::IsTerminal;
    if !show || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} {spinner} {msg}").expect("valid template"),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(200));
    bar
}

/// Runs one planned trial of `suite` (on the calling thread).
pub fn run_planned(suite: &Suite, t: &PlannedTrial) -> TrialRecord {
    run_trial(trial_spec(suite, t))
}

/// What a planned trial of `suite` runs: its objective, optimizer, budget, stop value and
/// seed (also what an external optimizer's trial is given, [`crate::pipeline::external`]).
pub fn trial_spec<'a>(suite: &'a Suite, t: &PlannedTrial) -> TrialSpec<'a> {
    let obj = &suite.objectives[t.objective];
    let opt = &suite.optimizers[t.optimizer];
    TrialSpec {
        objective_id: &obj.id,
        optimizer_id: &opt.id,
        trial: t.trial,
        objective: Arc::clone(&obj.objective),
        optimizer: opt.config.as_ref(),
        budget: obj.budget,
        stop_value: obj.stop_value(),
        stall: None,
        seed: suite.seed_of(t),
    }
}
