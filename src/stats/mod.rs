//! Statistics of trial outcomes: descriptive summaries (here), hypothesis tests and effect
//! sizes ([`hypothesis`]), bootstrap confidence intervals ([`bootstrap`]) and expected
//! running time to a target ([`ert`](mod@ert)). All are pure functions of their inputs (the
//! bootstrap also of its rng), checked against scipy/statsmodels reference values in tests.
//!
//! Quantiles use linear interpolation between order statistics (Hyndman-Fan type 7, the
//! default of numpy and R), so medians and quartiles match what most readers recompute.
//! Do not swap in `statrs`' `quantile`/`percentile` (`statrs::statistics::OrderStatistics`):
//! they are Hyndman-Fan type 8 (median-unbiased), which gives different quartiles on the small
//! samples of a benchmark; the report uses type 7 via [`quantile_sorted`] throughout.

pub mod bootstrap;
pub mod ert;
pub mod friedman;
pub mod hypothesis;
mod rank;

pub use bootstrap::bootstrap_median_ci;
pub use ert::{Ert, RunToTarget, ert, first_hit};
pub use friedman::FriedmanMethod;
pub use hypothesis::{
    Friedman, MannWhitney, PairedMethod, Wilcoxon, a12, friedman, holm, mann_whitney, wilcoxon,
};

use serde::{Deserialize, Serialize};

/// Five-number summary plus mean and sample standard deviation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Describe {
    pub n: usize,
    pub median: f64,
    pub q1: f64,
    pub q3: f64,
    pub mean: f64,
    /// Sample standard deviation (n - 1 in the denominator); 0 for a single value.
    pub std: f64,
    pub min: f64,
    pub max: f64,
}

/// Quantile `p` in [0, 1] of already sorted values (type 7).
pub fn quantile_sorted(sorted: &[f64], p: f64) -> f64 {
    assert!(!sorted.is_empty(), "quantile of no values");
    let h = (sorted.len() - 1) as f64 * p.clamp(0.0, 1.0);
    let lo = h.floor() as usize;
    let hi = h.ceil() as usize;
    if sorted[lo] == sorted[hi] {
        // Also keeps infinite order statistics from turning into NaN (inf - inf).
        return sorted[lo];
    }
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// Summary of `values` (at least one).
pub fn describe(values: &[f64]) -> Describe {
    let mut s = values.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    let mean = s.iter().sum::<f64>() / n as f64;
    let std = if !mean.is_finite() {
        // An infinite value (a trial that never saw a finite value) has no finite spread.
        f64::INFINITY
    } else if n > 1 {
        (s.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
    } else {
        0.0
    };
    Describe {
        n,
        median: quantile_sorted(&s, 0.5),
        q1: quantile_sorted(&s, 0.25),
        q3: quantile_sorted(&s, 0.75),
        mean,
        std,
        min: s[0],
        max: s[n - 1],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_numpy_type7() {
        // numpy: np.percentile([1, 2, 4, 7, 11], [25, 50, 75]) = [2., 4., 7.];
        // np.percentile([3, 1, 2, 10], [25, 50, 75]) = [1.75, 2.5, 4.75];
        // np.std([3, 1, 2, 10], ddof=1) = 4.0824829046386...
        let d = describe(&[1.0, 2.0, 4.0, 7.0, 11.0]);
        assert_eq!((d.q1, d.median, d.q3), (2.0, 4.0, 7.0));
        let d = describe(&[3.0, 1.0, 2.0, 10.0]);
        assert_eq!((d.q1, d.median, d.q3), (1.75, 2.5, 4.75));
        assert!((d.std - 4.082_482_904_638_63).abs() < 1e-12);
        assert_eq!((d.min, d.max, d.mean, d.n), (1.0, 10.0, 4.0, 4));
    }

    #[test]
    fn statrs_quantile_is_not_type7() {
        // Why quantile_sorted exists: statrs' quantile is type 8, h = (n + 1/3) p + 1/3.
        // For [1, 2, 4, 7, 11] and p = 0.25: h = 5/3, so 1 + (2/3)(2 - 1) = 5/3, not 2.
        use statrs::statistics::{Data, OrderStatistics};
        let mut data = Data::new(vec![1.0, 2.0, 4.0, 7.0, 11.0]);
        assert!((data.quantile(0.25) - 5.0 / 3.0).abs() < 1e-12);
        assert_eq!(quantile_sorted(&[1.0, 2.0, 4.0, 7.0, 11.0], 0.25), 2.0);
    }

    #[test]
    fn infinite_values_never_make_nan() {
        let s = [1.0, f64::INFINITY, f64::INFINITY, f64::INFINITY];
        assert_eq!(quantile_sorted(&s, 0.5), f64::INFINITY);
        assert_eq!(quantile_sorted(&s, 0.0), 1.0);
        assert_eq!(quantile_sorted(&s, 0.2), f64::INFINITY);
        let d = describe(&s);
        assert!(!d.std.is_nan() && !d.mean.is_nan() && !d.median.is_nan());
    }

    #[test]
    fn single_value_has_zero_spread() {
        let d = describe(&[5.0]);
        assert_eq!((d.median, d.std, d.q1, d.q3), (5.0, 0.0, 5.0, 5.0));
    }
}
