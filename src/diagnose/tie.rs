//! Ties: when another effect explains the residual about as well as the one a round names,
//! the records cannot tell them apart, and the report must say so instead of letting a
//! small margin pass for evidence. Two candidates that both pass the gate are tied when, on
//! the training record, the other's BIC gain is within [`TIE_SHARE`] of the named one's
//! (either way) and, on the validation record, its fall of the mean square is within
//! [`TIE_SHARE`] too or the paired block bootstrap cannot tell the two falls apart. Why they tie is measured, not
//! assumed: how closely their corrections to the parent's output agree.

use super::evaluate::{Data, Evaluated, gain_band, validation_residual};
use super::residual::correlation;
use crate::render::table::sig;
use serde::Serialize;

/// Share of the named candidate's gain (training ΔBIC, validation fall of the mean square)
/// within which another candidate is as good.
pub const TIE_SHARE: f64 = 0.15;

/// Another candidate the records cannot tell from the named one.
#[derive(Clone, Debug, Serialize)]
pub struct Tie {
    /// The other candidate's effects and form, as in `candidates`.
    pub name: String,
    pub form: String,
    /// Its training ΔBIC over the named one's (1 = as good).
    pub train_share: f64,
    /// Its fall of the validation mean square over the named one's.
    pub validate_share: f64,
    /// Paired block-bootstrap 95 % band of its validation mean square minus the named one's.
    pub validate_difference: [f64; 2],
    /// Correlation of the two corrections to the parent's output on the validation record:
    /// near 1, they explain the same residual.
    pub correlation: f64,
    /// One sentence for the report.
    pub why: String,
    /// The excitation that would separate them (`--suggest`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub next_experiment: Option<super::suggest::NextExperiment>,
}

/// Whether `other` (training ΔBIC `delta_other`) ties with `named` (`delta_named`), both
/// extending `parent`; the tie if so.
pub(super) fn tie(
    parent: &Evaluated,
    named: (&Evaluated, f64),
    other: (&Evaluated, f64),
    label: (String, String),
    d: &Data,
    seed: u64,
) -> Option<Tie> {
    let ((n, dn), (o, dof)) = (named, other);
    if dn >= 0.0 || dof >= 0.0 {
        return None;
    }
    let train_share = dof / dn;
    let ms = |e: &Evaluated| e.validate_rmse * e.validate_rmse;
    let fall_named = ms(parent) - ms(n);
    let fall_other = ms(parent) - ms(o);
    if fall_named <= 0.0 || fall_other <= 0.0 {
        return None;
    }
    let validate_share = fall_other / fall_named;
    // Mean square of the other minus the named: positive when the other is worse.
    let band = gain_band(validation_residual(o), validation_residual(n), seed);
    // Within the share either way: a candidate explaining far more, or far less, is no
    // alternative reading of the same evidence.
    let close = |share: f64| (1.0 - TIE_SHARE..=1.0 / (1.0 - TIE_SHARE)).contains(&share);
    let train_tied = close(train_share);
    let validate_tied = close(validate_share) || (band[0] <= 0.0 && band[1] >= 0.0);
    if !(train_tied && validate_tied) {
        return None;
    }
    let correction = |e: &Evaluated| -> Vec<f64> {
        let full: Vec<f64> = e
            .out_v
            .iter()
            .zip(&parent.out_v)
            .map(|(a, b)| a - b)
            .collect();
        d.scored(&full)
    };
    let r = correlation(&correction(n), &correction(o));
    let (name, form) = label;
    let why = format!(
        "{name} [{form}] explains {} % of the training gain and {} % of the validation fall (difference of the mean squares 95 % [{}, {}]); their corrections to the parent correlate {} on validation{}",
        sig(100.0 * train_share, 3),
        sig(100.0 * validate_share, 3),
        sig(band[0], 3),
        sig(band[1], 3),
        sig(r, 3),
        if r >= 0.9 {
            ": they explain the same residual"
        } else {
            ""
        }
    );
    Some(Tie {
        name,
        form,
        train_share,
        validate_share,
        validate_difference: band,
        correlation: r,
        why,
        next_experiment: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn correlation_of_proportional_and_unrelated_series() {
        let a: Vec<f64> = (0..100).map(|i| (i as f64 * 0.3).sin()).collect();
        let b: Vec<f64> = a.iter().map(|v| 2.0 * v + 1.0).collect();
        let c: Vec<f64> = (0..100).map(|i| (i as f64 * 0.3).cos()).collect();
        assert!((correlation(&a, &b) - 1.0).abs() < 1e-12);
        assert!((correlation(&a, &a.iter().map(|v| -v).collect::<Vec<_>>()) + 1.0).abs() < 1e-12);
        assert!(correlation(&a, &c).abs() < 0.1);
        assert_eq!(correlation(&a, &[1.0; 100]), 0.0);
    }
}
