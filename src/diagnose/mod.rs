//! `optbench diagnose`: where a hysteresis model misses a recording, which physics it left
//! out, and the better model, with evidence.
//!
//! 1. **Baseline.** The plain Bouc-Wen model ([`Structure`](crate::physics::structure::Structure) without extensions) is fitted to
//!    the training recording: PSO over the loop shape, then a Levenberg-Marquardt polish
//!    from the best points it found, through the harness (evaluations counted by the
//!    evaluator), linear coefficients by least squares.
//! 2. **Noise floor** from the data alone ([`residual::noise_floor`]).
//! 3. **Locate** the validation residual in time, in the loop plane and in frequency
//!    ([`residual::locate`]).
//! 4. **Test** the validation residual (Ljung-Box, prewhitened input cross-correlation,
//!    Billings' higher-order correlations; [`residual::battery`]). The battery's score is
//!    calibrated by a parametric bootstrap of the fitted baseline (simulated output plus
//!    Gaussian noise at the noise floor, refitted): its p-value is the share of bootstrap
//!    scores at least as large, so the false-alarm rate of "structure left" is known.
//! 5. **Name** by nested refits: each extension not yet in the model is added at its
//!    neutral value (the parent model exactly) and refitted (PSO over its own parameters,
//!    then Levenberg-Marquardt over all). A candidate is accepted only if BIC on the training data
//!    improves by more than [`Options::bic_margin`], its validation RMSE falls below the
//!    parent's 95 % band (moving-block bootstrap of the parent's validation residual), and
//!    the residual battery's score falls. The best such candidate (training ΔBIC plus its
//!    criterion on validation) is added and the round repeats from the new model until
//!    nothing more is accepted. Effects that mimic each other (delay, input-lag, dynamics;
//!    creep, offset-drift) compete in the same round, so the nested comparison, not the
//!    screen, decides; where the data cannot tell them apart, the simpler reading wins: a
//!    mode with no resonant peak, or creep pinned at its fastest time constant, yields to
//!    input timing; creep to a record's own drift. A named effect's other forms compete in
//!    later rounds, and after every acceptance an effect the model no longer needs is
//!    dropped (backward step) and the search goes on.

pub mod core_choice;
pub mod coupling;
pub mod forecast;
pub mod plausible;
pub mod proof;
pub mod recordings;
pub mod refit;
pub mod report;
pub mod residual;
pub mod saved;
pub mod steps;
pub mod suggest;
pub mod tie;
pub mod unexplained;

mod evaluate;
mod judge;
mod options;
mod propose;
mod search;
#[cfg(test)]
mod tests;

pub use options::{
    Candidate, Diagnosis, FreeRun, HoldTrial, ModelSummary, Options, Series, StepsReport, TestSet,
};

use crate::base::error::Result;
use crate::data::recording::Recording;
use search::{Records, Search};

/// Diagnoses `train` against `validate` (each at its own sampling interval).
pub fn diagnose(train: &Recording, validate: &Recording, opts: &Options) -> Result<Diagnosis> {
    diagnose_with_tests(
        std::slice::from_ref(train),
        std::slice::from_ref(validate),
        &[],
        opts,
    )
}

/// [`diagnose`] on one or several training and validation records (actuator parameters
/// shared, each record's own initial state, timing, offset, drift and creep states fitted
/// on it), then the baseline and the final model in free run on each of `tests`.
pub fn diagnose_with_tests(
    train: &[Recording],
    validate: &[Recording],
    tests: &[TestSet],
    opts: &Options,
) -> Result<Diagnosis> {
    let started = std::time::Instant::now();
    let spin = crate::pipeline::runner::spinner(opts.progress);
    spin.set_message("fitting the plain model");
    let searched = |opts: &Options| -> Result<Search> {
        let records = Records::new(train, validate, opts)?;
        Ok(Search::baseline(records, started, spin.clone()).run())
    };
    let first = searched(opts)?;
    if !opts.chooses_core() {
        return Ok(first.diagnosis(tests));
    }
    let (kept, choice, spent) = core_choice::choose(first, opts, |model| {
        searched(&Options {
            model: model.into(),
            ..opts.clone()
        })
    })?;
    let mut d = kept.diagnosis(tests);
    d.model = format!("auto: {}", choice.chosen);
    d.evaluations += spent;
    d.core_choice = Some(choice);
    Ok(d)
}
