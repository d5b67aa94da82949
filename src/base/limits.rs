//! Upper limits on every size a user can set (suite keys and command-line flags), so that a
//! mistyped or hostile value is refused with a message (exit 2) instead of a panic
//! ("capacity overflow") or an allocation the machine cannot serve.
//!
//! One rule derives them: the largest allocation a size implies, with every other size at
//! its own limit, stays under [`BUDGET_BYTES`]. Each limit's comment gives its arithmetic
//! (8 B per `f64`). The parameter tables (`optbench list`) carry the same numbers as
//! ranges, so a suite key is refused at its file:line and a flag by its name.

/// Memory one user-set size may claim: 1 GiB, an eighth of a modest 8 GiB machine, so a
/// run with a trial on each of a few cores still fits.
pub const BUDGET_BYTES: u64 = 1 << 30;

/// `f64` values within [`BUDGET_BYTES`]: 2^27 (134 million).
pub const BUDGET_F64: u64 = BUDGET_BYTES / 8;

/// Variables of an objective. CMA-ES holds up to seven dim x dim matrices while it
/// decomposes its covariance (C, B, C^-1/2 and temporaries): 7 x 4,000² x 8 B = 0.9 GB.
pub const MAX_DIM: usize = 4_000;

/// Points per generation (population, lambda, batch; MSGA's five membranes together;
/// SHADE's archive counts as one more): parents and offspring of [`MAX_DIM`] variables,
/// 2 x 10,000 x 4,000 x 8 B = 0.64 GB.
pub const MAX_POPULATION: usize = 10_000;

/// Samples of one recording (CSV rows, simulated `duration / dt`, `samples`): a fit keeps
/// about ten columns of each record (time, input, output, scaled copies, model output and
/// residual): 10 x 10^7 x 8 B = 0.8 GB. At 1 ms sampling that is 2.8 hours.
pub const MAX_SAMPLES: usize = 10_000_000;

/// Bytes of one recording file, checked before it is read whole: [`MAX_SAMPLES`] rows of up
/// to a hundred bytes (a few numbers printed with full precision), the one allocation of
/// the memory budget.
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// Trials of one objective x optimizer pair (`trials`, `--trials`, `--seeds`): each keeps
/// its record (best point, trace) until the report, at most 2 KiB + 8 B x [`MAX_DIM`] =
/// 34 KB: 10,000 of them are 0.34 GB. The whole plan is checked by [`trial_memory`].
pub const MAX_TRIALS: usize = 10_000;

/// Bootstrap refits of `diagnose`: each keeps 16 B, so memory is not what binds (1.6 MB);
/// each is a whole refit, and past 10^5 the p-value's resolution 1/(B+1) gains nothing a
/// test at 5 % or 1 % can use.
pub const MAX_BOOTSTRAP: usize = 100_000;

/// Worker threads (`--threads`): each reserves a 2 MiB stack, 512 x 2 MiB = 1 GiB.
pub const MAX_THREADS: usize = 512;

/// Nesting levels of a signal spec (each `(` and each `k*` adds one). A level costs the
/// recursive parser and evaluation three stack frames of well under 1 KiB: 64 levels stay
/// under a tenth of the 2 MiB stack of the smallest thread they run on.
pub const MAX_NESTING: usize = 64;

/// Largest magnitude of a bound or a recorded value. Squares summed over [`MAX_SAMPLES`]
/// (4 x 10^60 x 10^7) and Rosenbrock's 100 x^4 over [`MAX_DIM`] variables (5 x 10^125)
/// stay below [`NONFINITE_COST`], so no legitimate cost ranks at or above the penalty.
pub const MAX_MAGNITUDE: f64 = 1e30;

/// The finite cost a non-finite value counts as (penalised, never the best): above every
/// cost [`MAX_MAGNITUDE`] allows, and its square summed over [`MAX_TRIALS`] (10^304) keeps
/// means and variances of results finite.
pub const NONFINITE_COST: f64 = 1e150;

/// Bytes the records of `trials` trials of an objective with `dim` variables keep until
/// the report (see [`MAX_TRIALS`]); a whole plan's sum must stay under [`BUDGET_BYTES`].
pub fn trial_memory(trials: u64, dim: usize) -> u64 {
    trials.saturating_mul(2048 + 8 * dim as u64)
}

/// Samples of `duration` seconds at `dt`, refused above [`MAX_SAMPLES`] (also when the
/// ratio overflows).
pub fn samples(duration: f64, dt: f64) -> Result<usize, String> {
    let n = (duration / dt).round();
    if !(n.is_finite() && n <= MAX_SAMPLES as f64) {
        return Err(format!(
            "{duration:?} s at dt {dt:?} s is {n:e} samples, above the limit of {MAX_SAMPLES} \
             (a recording's memory budget)"
        ));
    }
    Ok(n as usize)
}

/// `value` of `what` refused above `max`, with the limit in the message.
pub fn at_most(what: &str, value: u64, max: usize) -> Result<usize, String> {
    match usize::try_from(value) {
        Ok(v) if v <= max => Ok(v),
        _ => Err(format!(
            "{what} {value}: at most {max} (a limit derived from memory)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_follow_their_derivations() {
        let mb = |x: u64| x as f64 / 1e6;
        let d = MAX_DIM as u64;
        assert!(7 * d * d * 8 < BUDGET_BYTES, "{}", mb(7 * d * d * 8));
        assert!(2 * MAX_POPULATION as u64 * d * 8 < BUDGET_BYTES);
        assert!(10 * MAX_SAMPLES as u64 * 8 < BUDGET_BYTES);
        assert!(trial_memory(MAX_TRIALS as u64, MAX_DIM) < BUDGET_BYTES);
        assert!((MAX_THREADS as u64) << 21 <= BUDGET_BYTES);
        let m = MAX_MAGNITUDE;
        assert!(4.0 * m * m * MAX_SAMPLES as f64 <= NONFINITE_COST);
        assert!(100.0 * m.powi(4) * MAX_DIM as f64 <= NONFINITE_COST);
        assert!((NONFINITE_COST * NONFINITE_COST * MAX_TRIALS as f64).is_finite());
    }

    #[test]
    fn samples_and_sizes_are_refused_above_their_limits() {
        assert_eq!(samples(1.0, 1e-3), Ok(1000));
        let e = samples(1e6, 1e-3).unwrap_err();
        assert!(e.contains("10000000"), "{e}");
        assert!(samples(1.0, 1e-300).is_err());
        assert!(samples(f64::INFINITY, 1.0).is_err());
        assert_eq!(at_most("--x", 5, 10), Ok(5));
        let e = at_most("--bootstrap", u64::MAX, MAX_BOOTSTRAP).unwrap_err();
        assert!(e.contains("--bootstrap") && e.contains("100000"), "{e}");
    }
}
