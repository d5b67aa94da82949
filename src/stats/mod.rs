//! Descriptive statistics of trial outcomes.
//!
//! Quantiles use linear interpolation between order statistics (Hyndman-Fan type 7, the
//! default of numpy and R), so medians and quartiles match what most readers recompute.

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
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// Summary of `values` (at least one).
pub fn describe(values: &[f64]) -> Describe {
    let mut s = values.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    let mean = s.iter().sum::<f64>() / n as f64;
    let std = if n > 1 {
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
    fn single_value_has_zero_spread() {
        let d = describe(&[5.0]);
        assert_eq!((d.median, d.std, d.q1, d.q3), (5.0, 0.0, 5.0, 5.0));
    }
}
