//! How a record judges a model it was not fitted to: by prediction alone.
//!
//! A validation record has parts of its own that no other record can tell: its initial
//! hysteretic state, its sub-sample timing at another sampling rate, its sensor offset, its
//! drift, its creep states at the first sample. They must be fitted on the record, and a
//! sample they were fitted on cannot judge them: a spline drift refitted on the whole
//! validation record fitted it and so won over creep that only predicted it (issue 50).
//! So each validation record is split at forecast origins ([`origins`]: the lead, a fifth
//! of the record or longer until the drive has moved, then four equal blocks): the record's
//! own parts are fitted on the samples before an origin and the samples from there to the
//! next origin are predicted; the lead is fitted only and never scored. The nonlinear state (initial state, timing) is fitted on
//! the lead alone. Every scored sample is thus predicted from parameters fitted on other
//! samples: the actuator's on the training record, the record's own on the samples before
//! it (a prequential forecast, Dawid 1984). A drift then counts for what it forecasts over
//! a fifth of the record, which a real sensor drift does and a drift standing in for creep
//! after the drive's steps does not. Nothing is charged as free parameters on the scored
//! samples because none is fitted there.

use super::refit::{Fitted, record_state_for};
use serde::Serialize;
use std::ops::Range;

/// The rule in one sentence, for `diagnosis.json` and the report.
pub const JUDGING_RULE: &str = "by prediction alone: the actuator's parameters are fitted on the training record; each validation record's own parts (initial state, timing, offset, drift, creep states) are fitted on its samples before each forecast origin (the lead, a fifth of the record or longer until the drive has covered half its range, then four equal blocks) and the samples from the first origin on are predicted and judge; no parameter is fitted on a sample that judges it";

/// Least share of a record before its first forecast origin (fitted, not scored).
pub const LEAD_SHARE: f64 = 0.2;

/// Forecast origins of a record driven by `u`: the lead ends at a fifth of the record, or
/// later where the drive has not yet covered half its range by then (capped at half the
/// record): on a hold the initial hysteretic state and the offset are one, so a lead that
/// never moves cannot fit the state the forecast starts from. The rest is split in four.
pub fn origins(u: &[f64]) -> Vec<usize> {
    let n = u.len();
    if n < 2 {
        return vec![n.max(1)];
    }
    let span = |v: &[f64]| {
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        hi - lo
    };
    let half = 0.5 * span(u);
    let first = ((LEAD_SHARE * n as f64).round() as usize).clamp(1, n - 1);
    let cap = (n / 2).max(first);
    let (mut lo, mut hi) = u[..first]
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let mut lead = first;
    while lead < cap && hi - lo < half {
        lo = lo.min(u[lead]);
        hi = hi.max(u[lead]);
        lead += 1;
    }
    (0..4)
        .map(|i| (lead + (i * (n - lead)) / 4).min(n - 1))
        .collect()
}

/// The samples of a record driven by `u` that judge: from the first origin on (of a
/// periodic record, the same share of the period).
pub fn scored(u: &[f64]) -> Range<usize> {
    origins(u)[0].min(u.len())..u.len()
}

/// A periodic record's period `v` twice: simulated over two periods, the second is the
/// steady state.
pub fn two_periods(v: &[f64]) -> Vec<f64> {
    v.iter().chain(v).copied().collect()
}

/// One record predicted: the output on its samples, the coefficients of the last fit, the
/// evaluations of the state search, and how many parameters were fitted on its own
/// samples (before the origins).
pub struct RecordForecast {
    pub out: Vec<f64>,
    pub coef: Vec<f64>,
    pub used: u64,
    pub fitted: usize,
}

/// `f` (at the record's sampling interval, one record) predicting the record `(u, y)`:
/// its initial state (and, when `timing`, its sub-sample timing) searched on the lead, its
/// own coefficients on the samples before each origin ([`origins`]). A `periodic` record
/// is one period of a steady state: it is simulated over two periods, its own parts fitted
/// on the first period's lead, and the second period returned (no start-up transient
/// scored; the samples of the lead, fitted, are left out of the score by [`scored`]).
pub fn forecast_record(
    f: &Fitted,
    u: &[f64],
    y: &[f64],
    seed: u64,
    timing: bool,
    periodic: bool,
) -> RecordForecast {
    let n = u.len().min(y.len());
    let lead = origins(&u[..n])[0];
    let (u2, y2, at): (Vec<f64>, Vec<f64>, Vec<usize>) = if periodic {
        (two_periods(&u[..n]), two_periods(&y[..n]), vec![lead])
    } else {
        (u[..n].to_vec(), y[..n].to_vec(), origins(&u[..n]))
    };
    let (theta, used) = record_state_for(f, &u2[..lead], &y2[..lead], 60, seed, timing);
    let fc = f
        .structure
        .forecast_on(&theta, &f.linear.coef, &u2, &y2, &at);
    RecordForecast {
        out: fc.out[fc.out.len() - n..].to_vec(),
        coef: fc.coef,
        used,
        fitted: fitted_on_record(f, timing),
    }
}

/// Parameters of `f` (one record) fitted on a record's own samples: its own coefficients
/// (offset, drift, creep states), its initial state and, when `timing`, its timing.
pub fn fitted_on_record(f: &Fitted, timing: bool) -> usize {
    f.structure.record_coefs().len()
        + f.structure
            .specs()
            .iter()
            .filter(|s| s.name == "g0_frac" || (timing && s.name == "timing_samples"))
            .count()
}

/// How a validation record judged (`diagnosis.json`): its samples, how many of them were
/// scored, and how many parameters were fitted on its own samples (all before the first
/// scored sample of their forecast).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Judging {
    pub samples: usize,
    pub scored: usize,
    pub fitted_on_record: usize,
    /// Parameters fitted on the scored samples: always 0, stated so a reader need not
    /// take it on trust.
    pub fitted_on_scored: usize,
}
