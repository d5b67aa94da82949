//! Rank-based comparisons of optimizers: Mann-Whitney U for one objective, Vargha-Delaney
//! A12 as its effect size, Holm's correction across objectives, and Friedman's test across
//! all objectives at once (its permutation p-value in [`super::friedman`]).
//!
//! Rank tests are used because final values of stochastic optimizers are rarely normal
//! (heavy tails, many runs ending exactly at the optimum). The tests and the correction
//! reproduce scipy and statsmodels to rounding; the unit tests pin reference values computed
//! with them.
//!
//! `statrs::stats_tests::mannwhitneyu` (0.19.1) is not used for the p-value, for reasons
//! found while checking it against scipy 1.17.1 (see `statrs_mannwhitneyu_disagrees`):
//! its exact path returns the complement of the p-value whenever `a.len() <= b.len()`
//! (e.g. p = 1 instead of 0.0317 for 4 vs 5 separated values), and its normal path computes
//! the upper tail as `1 - cdf(z)`, which loses relative precision for small p (about
//! 1e-16 / p). Even `Normal::sf` is only good to ~1e-10 relative in 0.19.1 (its `erfc`
//! carries 10-digit constants, fixed upstream in statrs-dev/statrs#412, unreleased): the
//! normal tail is therefore taken from `ChiSquared(1)::sf` (regularised incomplete gamma,
//! ~1e-14 relative), using 2 P(Z > z) = P(chi2_1 > z^2) for z >= 0.

use super::friedman::{FriedmanMethod, permutation_p};
use super::rank::{average_ranks, tie_term};
use serde::{Deserialize, Serialize};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Result of a two-sided Mann-Whitney U test.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MannWhitney {
    /// U of the first sample `a`, as scipy reports it: the number of pairs (a_i, b_j) with
    /// a_i > b_j, ties counting one half. It ranges over 0..=n_a n_b; a small U means `a`
    /// tends to be smaller (better, for minimisation). `u / (n_a n_b)` is [`a12`].
    pub u: f64,
    /// Two-sided p-value.
    pub p_value: f64,
    /// Whether the p-value is from the exact null distribution (else normal approximation).
    pub exact: bool,
}

/// Two-sided Mann-Whitney U test (Wilcoxon rank-sum) of `a` against `b`, as
/// `scipy.stats.mannwhitneyu(a, b, method='auto', use_continuity=True)`.
///
/// The method follows scipy's `auto` rule: the exact distribution of U when there are no ties
/// and either sample has at most 8 values (where the normal approximation is poor), otherwise
/// the normal approximation with tie-corrected variance and continuity correction.
///
/// Panics if a sample is empty or contains NaN (scipy raises too).
pub fn mann_whitney(a: &[f64], b: &[f64]) -> MannWhitney {
    assert!(
        !a.is_empty() && !b.is_empty(),
        "Mann-Whitney U needs two non-empty samples"
    );
    let (n1, n2) = (a.len(), b.len());
    let (u1, ties) = u_statistic(a, b);
    let mn = (n1 * n2) as f64;
    // The two-sided p-value doubles the upper tail beyond the larger of U1 and U2 = mn - U1.
    let u = u1.max(mn - u1);
    let exact = !(n1 > 8 && n2 > 8) && ties.iter().all(|&t| t == 1);
    let p_value = if exact {
        // No ties, so U is an integer; P(U >= u) = P(U <= mn - u) by symmetry.
        (2.0 * exact_cdf((mn - u) as usize, n1, n2)).min(1.0)
    } else {
        let n = (n1 + n2) as f64;
        let tie_term = tie_term(&ties);
        let var = mn / 12.0 * ((n + 1.0) - tie_term / (n * (n - 1.0)));
        // scipy: z = (u - mn/2 - 0.5) / sqrt(var) (continuity correction), p = 2 sf(z),
        // clipped to 1. For z > 0, 2 sf(z) = P(chi2_1 > z^2), which statrs computes
        // accurately; for z <= 0 (u = mn/2, including every value tied, var = 0) p is 1.
        let excess = u - mn / 2.0 - 0.5;
        if excess > 0.0 {
            chi2_sf(1.0, excess * excess / var)
        } else {
            1.0
        }
    };
    MannWhitney {
        u: u1,
        p_value,
        exact,
    }
}

/// Upper tail of the chi-square distribution with `df` degrees of freedom at `x`.
fn chi2_sf(df: f64, x: f64) -> f64 {
    ChiSquared::new(df)
        .expect("positive degrees of freedom")
        .sf(x)
}

/// U of `a` and the sizes of the groups of tied values in the pooled sample.
fn u_statistic(a: &[f64], b: &[f64]) -> (f64, Vec<usize>) {
    let pooled: Vec<f64> = a.iter().chain(b).copied().collect();
    let (ranks, ties) = average_ranks(&pooled);
    let n1 = a.len();
    let r1: f64 = ranks[..n1].iter().sum();
    (r1 - (n1 * (n1 + 1)) as f64 / 2.0, ties)
}

/// P(U <= k) under the null hypothesis, without ties, for samples of sizes n1 and n2.
///
/// The number of arrangements giving U = u is the coefficient of q^u in the Gaussian binomial
/// [n1 + n2 choose m]_q = prod_{i=1..m} (1 - q^(n+i)) / (1 - q^i), m = min, n = max of the
/// sizes. Coefficients up to degree k only depend on lower ones, so the polynomial is
/// truncated at k <= n1 n2 / 2: O(m k) work, m <= 8 under the `auto` rule. The small tail
/// counts are exact integers in f64, as in scipy's own recurrence.
fn exact_cdf(k: usize, n1: usize, n2: usize) -> f64 {
    let (m, n) = (n1.min(n2), n1.max(n2));
    let mut c = vec![0.0f64; k + 1];
    c[0] = 1.0;
    for i in 1..=m {
        // Multiply by (1 - q^(n+i)): downwards, so c[u - s] is still the old coefficient.
        let s = n + i;
        for u in (s..=k).rev() {
            c[u] -= c[u - s];
        }
        // Divide by (1 - q^i), i.e. multiply by 1 + q^i + q^2i + ...: a strided prefix sum.
        for u in i..=k {
            c[u] += c[u - i];
        }
    }
    // C(n1 + n2, m), built so every intermediate value is itself a binomial coefficient.
    let total = (1..=m).fold(1.0f64, |t, i| t * (n + i) as f64 / i as f64);
    c.iter().sum::<f64>() / total
}

/// Holm-Bonferroni adjusted p-values, in the order of `p`: the k-th smallest p-value of m is
/// multiplied by m - k + 1, the results made non-decreasing in that order and capped at 1.
///
/// Use it when one report tests many objectives: it controls the family-wise error rate
/// without assuming independence, and rejects at least as much as plain Bonferroni. Equal to
/// `statsmodels.stats.multitest.multipletests(p, method='holm')[1]`. Panics on a value
/// outside [0, 1] (including NaN).
pub fn holm(p: &[f64]) -> Vec<f64> {
    assert!(
        p.iter().all(|v| (0.0..=1.0).contains(v)),
        "p-values must lie in [0, 1]"
    );
    let m = p.len();
    let mut order: Vec<usize> = (0..m).collect();
    // Ties may come in any order: the running maximum gives them the same adjusted value.
    order.sort_by(|&i, &j| p[i].total_cmp(&p[j]));
    let mut adjusted = vec![0.0; m];
    let mut running = 0.0f64;
    for (k, &i) in order.iter().enumerate() {
        running = running.max(p[i] * (m - k) as f64);
        adjusted[i] = running.min(1.0);
    }
    adjusted
}

/// Vargha-Delaney A12 = P(X_a > X_b) + 0.5 P(X_a = X_b) over all pairs of a value of `a` and
/// one of `b`: the probability that a run of `a` ends higher than a run of `b`.
///
/// For minimisation, A12 < 0.5 means `a` tends to be better (smaller); 0.5 is no difference,
/// 0 means every run of `a` beat every run of `b`. It is the effect size that goes with
/// [`mann_whitney`] (A12 = U / (n_a n_b)): a p-value says whether there is a difference, A12
/// how large it is. Vargha and Delaney's thresholds on |A12 - 0.5| are 0.06 (small),
/// 0.14 (medium) and 0.21 (large). Panics on empty samples or NaN.
pub fn a12(a: &[f64], b: &[f64]) -> f64 {
    assert!(
        !a.is_empty() && !b.is_empty(),
        "A12 needs two non-empty samples"
    );
    u_statistic(a, b).0 / (a.len() * b.len()) as f64
}

/// Result of Friedman's test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Friedman {
    /// Tie-corrected chi-square statistic.
    pub statistic: f64,
    /// Degrees of freedom: number of treatments minus one.
    pub df: usize,
    /// P(statistic >= observed) over the arrangements of every block's ranks: exact, or
    /// by seeded resampling where the distribution is too large ([`Friedman::method`]).
    pub p_value: f64,
    pub method: FriedmanMethod,
    /// The chi-square approximation (upper tail with `df` degrees of freedom), scipy's
    /// p-value: rough for the few blocks of a benchmark suite.
    pub p_chi2: f64,
    /// Mean rank of every treatment over the blocks (1 = best), in column order: the usual
    /// summary next to the test, and the input of critical-difference diagrams.
    pub mean_ranks: Vec<f64>,
}

/// Friedman's rank test that k treatments (optimizers, the columns) perform alike over n
/// blocks (objectives, the rows of `blocks`).
///
/// It answers "does any optimizer differ across the whole suite" from within-objective ranks
/// only, so objectives of incomparable scales weigh the same. In each row the lowest value
/// gets rank 1, ties get their average rank. The statistic and its tie correction are
/// computed as `scipy.stats.friedmanchisquare(*columns)` does. The p-value is the statistic's
/// permutation distribution (every block's ranks arranged every way, ties kept; see
/// `stats/friedman.rs`): exact where that is cheap (four blocks of up to six treatments),
/// else from 10^5 resamples of a fixed seed. The chi-square approximation with k - 1 degrees
/// of freedom is kept beside it; it is rough for few blocks (scipy's documentation asks for
/// n > 10), and a benchmark's objectives are few.
///
/// Differences from scipy: k = 2 is accepted (the statistic is well defined; without ties it
/// is the squared z of the sign test), where scipy demands 3 columns; when every row is tied,
/// scipy returns NaN (0 / 0) while this returns statistic 0 and p-value 1, as the data
/// show no difference. Panics on no rows, fewer than 2 columns, rows of unequal length or NaN.
pub fn friedman(blocks: &[Vec<f64>]) -> Friedman {
    assert!(
        !blocks.is_empty(),
        "Friedman's test needs at least one block"
    );
    let k = blocks[0].len();
    assert!(k >= 2, "Friedman's test needs at least two treatments");
    assert!(
        blocks.iter().all(|row| row.len() == k),
        "every block must have one value per treatment"
    );
    let mut rank_sums = vec![0.0; k];
    let mut ties = 0.0;
    let mut all_ranks = Vec::with_capacity(blocks.len());
    for row in blocks {
        let (ranks, groups) = average_ranks(row);
        for (s, r) in rank_sums.iter_mut().zip(&ranks) {
            *s += r;
        }
        all_ranks.push(ranks);
        ties += tie_term(&groups);
    }
    let (n, kf) = (blocks.len() as f64, k as f64);
    let c = 1.0 - ties / (kf * (kf * kf - 1.0) * n);
    let ssbn: f64 = rank_sums.iter().map(|r| r * r).sum();
    let (statistic, p_chi2, (p_value, method)) = if c > 0.0 {
        let statistic = (12.0 / (kf * n * (kf + 1.0)) * ssbn - 3.0 * n * (kf + 1.0)) / c;
        (
            statistic,
            chi2_sf(kf - 1.0, statistic),
            permutation_p(&all_ranks),
        )
    } else {
        (0.0, 1.0, (1.0, FriedmanMethod::Exact))
    };
    Friedman {
        statistic,
        df: k - 1,
        p_value,
        method,
        p_chi2,
        mean_ranks: rank_sums.iter().map(|s| s / n).collect(),
    }
}

/// Result of a two-sided Wilcoxon signed-rank test of paired samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Wilcoxon {
    /// min(W+, W-): the smaller signed-rank sum, as scipy reports it for two sides.
    pub statistic: f64,
    pub p_value: f64,
    /// Pairs that differ (zero differences are left out, Wilcoxon's rule).
    pub n: usize,
    /// How the p-value was computed.
    pub method: PairedMethod,
}

/// The null distribution a [`Wilcoxon`] p-value comes from, chosen as scipy's `auto` does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum PairedMethod {
    /// The exact distribution of W+ (no ties, no zero differences, at most 50 pairs).
    Exact,
    /// Every one of the 2^n sign flips (ties or zeros, at most 13 pairs).
    Permutation,
    /// The normal approximation with the tie correction (no continuity correction).
    Normal,
}

/// Two-sided Wilcoxon signed-rank test of `a[i]` against `b[i]`, for trials that are paired
/// by design (the same noise realisation, the same seed): it tests the differences within
/// pairs, which the unpaired Mann-Whitney test ignores. Equal to
/// `scipy.stats.wilcoxon(a, b)` (scipy 1.17: `zero_method='wilcox'`, no continuity
/// correction, `method='auto'`). A pair in which both values are +inf (both runs failed) is a
/// zero difference; one failed run makes an infinite difference, ranked largest.
///
/// Panics if the samples differ in length or hold NaN.
pub fn wilcoxon(a: &[f64], b: &[f64]) -> Wilcoxon {
    assert_eq!(
        a.len(),
        b.len(),
        "the Wilcoxon signed-rank test needs pairs"
    );
    let d: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| if x == y { 0.0 } else { x - y })
        .collect();
    assert!(d.iter().all(|x| !x.is_nan()), "NaN in a paired sample");
    let zeros = d.iter().filter(|&&x| x == 0.0).count();
    let nonzero: Vec<f64> = d.iter().copied().filter(|&x| x != 0.0).collect();
    let n = nonzero.len();
    if n == 0 {
        return Wilcoxon {
            statistic: 0.0,
            p_value: 1.0,
            n,
            method: PairedMethod::Exact,
        };
    }
    let magnitudes: Vec<f64> = nonzero.iter().map(|x| x.abs()).collect();
    let (ranks, ties) = average_ranks(&magnitudes);
    let r_plus: f64 = nonzero
        .iter()
        .zip(&ranks)
        .filter(|(x, _)| **x > 0.0)
        .map(|(_, r)| r)
        .sum::<f64>()
        + 0.0; // an empty sum is -0.0
    let total = (n * (n + 1)) as f64 / 2.0;
    let statistic = r_plus.min(total - r_plus);
    let tied = ties.iter().any(|&t| t > 1);
    let (p_value, method) = if !tied && zeros == 0 && d.len() <= 50 {
        (exact_signed_rank_p(r_plus as usize, n), PairedMethod::Exact)
    } else if d.len() <= 13 {
        (sign_flip_p(&ranks, r_plus), PairedMethod::Permutation)
    } else {
        let nf = n as f64;
        let tie_term = tie_term(&ties);
        let se = ((nf * (nf + 1.0) * (2.0 * nf + 1.0) - tie_term / 2.0) / 24.0).sqrt();
        let z = (r_plus - total / 2.0) / se;
        // 2 sf(|z|) = P(chi2_1 > z^2), accurate in the far tail.
        let p = if z.is_finite() && z != 0.0 {
            chi2_sf(1.0, z * z)
        } else {
            1.0
        };
        (p, PairedMethod::Normal)
    };
    Wilcoxon {
        statistic,
        p_value: p_value.min(1.0),
        n,
        method,
    }
}

/// Two-sided exact p-value of W+ = `w` with `n` untied nonzero differences: 2 min(P(W+ <=
/// w), P(W+ >= w)). The counts of subsets of {1..n} by their sum are exact integers in f64
/// up to n = 50 (2^50 < 2^53).
fn exact_signed_rank_p(w: usize, n: usize) -> f64 {
    let max = n * (n + 1) / 2;
    let mut count = vec![0.0f64; max + 1];
    count[0] = 1.0;
    for r in 1..=n {
        for s in (r..=max).rev() {
            count[s] += count[s - r];
        }
    }
    let all = 2f64.powi(n as i32);
    let below: f64 = count[..=w].iter().sum();
    let above: f64 = count[w..].iter().sum();
    2.0 * below.min(above) / all
}

/// Two-sided p-value of W+ over every sign flip of the ranked differences (as scipy's
/// permutation test with all 2^n flips: both tails counted with a relative tolerance).
fn sign_flip_p(ranks: &[f64], r_plus: f64) -> f64 {
    let n = ranks.len();
    let tol = r_plus.abs() * 1e-14 + 1e-14;
    let (mut below, mut above) = (0u64, 0u64);
    for mask in 0u64..(1 << n) {
        let w: f64 = (0..n)
            .filter(|i| mask >> i & 1 == 1)
            .map(|i| ranks[i])
            .sum();
        below += u64::from(w <= r_plus + tol);
        above += u64::from(w >= r_plus - tol);
    }
    let all = (1u64 << n) as f64;
    2.0 * (below.min(above) as f64) / all
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative difference within `tol` (absolute near zero).
    #[track_caller]
    fn assert_close(actual: f64, expected: f64, tol: f64) {
        let scale = expected.abs().max(f64::MIN_POSITIVE);
        assert!(
            (actual - expected).abs() <= tol * scale,
            "{actual:e} != {expected:e} (relative tolerance {tol:e})"
        );
    }

    // Samples for the larger cases, generated once with
    // numpy.random.default_rng(20240601) and rounded to the decimals shown:
    // A30 = round(lognormal(-3, 1, 30), 6), B30 = round(lognormal(0, 1, 30), 6),
    // C30 = round(exponential(1.0, 30), 1) with the first 7 set to 0.0,
    // D30 = round(exponential(1.5, 30), 1) with the first 3 set to 0.0 (C30 and D30 pooled:
    // 60 values, 26 distinct),
    // E12 = round(normal(0, 1, 12), 3), F10 = round(normal(0.5, 1, 10), 3),
    // G3 = round(normal(0, 1, 3), 3), H40 = round(normal(1.0, 1, 40), 3).
    // Only these literals matter: the references below were computed from them.
    const A30: [f64; 30] = [
        0.09517, 0.079605, 0.026173, 0.015325, 0.04308, 0.165872, 0.188923, 0.123477, 0.070409,
        0.246606, 0.170817, 0.039942, 0.017215, 0.034577, 0.032712, 0.099014, 0.007453, 0.041116,
        0.264801, 0.019835, 0.02332, 0.045764, 0.01206, 0.043735, 0.049014, 0.049556, 0.018527,
        0.034533, 0.095734, 0.024366,
    ];
    const B30: [f64; 30] = [
        1.728402, 1.926129, 0.240028, 0.524502, 1.925744, 1.638031, 1.19647, 0.705663, 1.11467,
        6.51934, 0.801352, 1.785413, 0.659187, 0.820102, 1.911765, 0.394948, 0.784729, 0.543184,
        0.423709, 1.192144, 3.455002, 1.247831, 0.682654, 0.234308, 2.268133, 1.234245, 0.531893,
        2.366556, 4.827017, 0.195606,
    ];
    const C30: [f64; 30] = [
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.7, 0.6, 2.1, 0.7, 2.1, 0.2, 0.1, 0.2, 0.7, 0.3, 1.9,
        4.1, 0.3, 1.5, 0.0, 0.8, 2.8, 0.6, 1.4, 1.1, 0.2, 2.3, 4.3,
    ];
    const D30: [f64; 30] = [
        0.0, 0.0, 0.0, 0.3, 0.3, 0.5, 3.9, 1.0, 0.7, 0.7, 0.9, 1.7, 0.5, 0.0, 4.9, 1.2, 2.9, 4.4,
        0.8, 1.8, 1.2, 0.2, 0.5, 1.5, 0.0, 1.4, 1.0, 0.0, 0.8, 1.1,
    ];
    const E12: [f64; 12] = [
        -0.61, -2.623, -0.37, -1.74, 1.017, 0.105, 0.585, 1.173, -0.033, -0.017, 0.447, 2.389,
    ];
    const F10: [f64; 10] = [
        0.291, 0.083, 0.628, 1.255, 0.278, 0.22, 1.334, 2.549, 1.858, -1.21,
    ];
    const G3: [f64; 3] = [-0.063, 1.36, -1.019];
    const H40: [f64; 40] = [
        1.24, 1.743, -0.081, -0.354, 0.212, 2.343, 0.864, 1.249, 0.352, 0.97, -0.976, 0.562, 1.343,
        -0.594, 0.998, 0.845, 1.822, -1.604, 0.859, 1.328, 0.893, 1.333, -0.233, 2.831, 2.019,
        1.372, 2.229, 0.64, 2.026, -0.059, 2.601, 2.006, 0.11, 0.134, 1.63, 1.021, 2.135, 0.99,
        1.214, 0.968,
    ];

    /// (a, b, scipy U, scipy p, exact).
    type Case = (Vec<f64>, Vec<f64>, f64, f64, bool);

    /// References: scipy 1.17.1, `r = scipy.stats.mannwhitneyu(a, b, method='auto',
    /// use_continuity=True, alternative='two-sided')`, printed as `repr(float(r.statistic))`,
    /// `repr(float(r.pvalue))`; `exact` is scipy's `auto` choice (no ties and a size <= 8).
    fn scipy_cases() -> Vec<Case> {
        vec![
            // Exact, n_a < n_b (where statrs 0.19.1 is wrong), no ties.
            (
                vec![1.2, 3.4, 0.5, 2.2],
                vec![4.1, 2.9, 5.5, 3.8, 6.0],
                1.0,
                0.031746031746031744,
                true,
            ),
            // Exact, scipy's documentation example (n_a > n_b).
            (
                vec![19.0, 22.0, 16.0, 29.0, 24.0],
                vec![20.0, 11.0, 17.0, 12.0],
                17.0,
                0.1111111111111111,
                true,
            ),
            // Exact, U at the centre: doubled tail exceeds 1 and is clipped.
            (vec![1.0, 4.0], vec![2.0, 3.0], 2.0, 1.0, true),
            // Exact at the boundary of the auto rule: 8 and 8.
            (
                vec![3.1, 0.4, 2.2, 5.0, 1.9, 4.4, 0.8, 2.7],
                vec![3.5, 6.1, 2.0, 5.6, 4.9, 7.2, 3.9, 6.6],
                10.0,
                0.020668220668220667,
                true,
            ),
            // Exact, 3 against 40: the small side decides.
            (G3.to_vec(), H40.to_vec(), 35.0, 0.2562191070415687, true),
            // Normal just past the boundary: 9 and 9, no ties.
            (
                vec![3.1, 0.4, 2.2, 5.0, 1.9, 4.4, 0.8, 2.7, 1.1],
                vec![3.5, 6.1, 2.0, 5.6, 4.9, 7.2, 3.9, 6.6, 5.2],
                10.0,
                0.008071487425268009,
                false,
            ),
            // Normal because of ties although small (3 tied values).
            (
                vec![1.0, 2.0, 2.0, 3.0, 5.0],
                vec![2.0, 4.0, 4.0, 6.0, 7.0, 8.0],
                5.0,
                0.07934368319771502,
                false,
            ),
            // Everything tied: zero variance, p = 1.
            (vec![1.0, 1.0], vec![1.0, 1.0, 1.0], 3.0, 1.0, false),
            // Normal, 12 against 10, no ties.
            (E12.to_vec(), F10.to_vec(), 37.0, 0.13791345941250951, false),
            // Trial-sized groups (30 and 30), no ties, far tail.
            (
                A30.to_vec(),
                B30.to_vec(),
                6.0,
                5.494052450965186e-11,
                false,
            ),
            (
                B30.to_vec(),
                A30.to_vec(),
                894.0,
                5.494052450965186e-11,
                false,
            ),
            // Trial-sized groups with many ties (runs ending at the optimum 0.0).
            (C30.to_vec(), D30.to_vec(), 395.0, 0.4170662076607704, false),
        ]
    }

    #[test]
    fn mann_whitney_matches_scipy() {
        for (a, b, u, p, exact) in scipy_cases() {
            let r = mann_whitney(&a, &b);
            assert_eq!(r.u, u, "U for {a:?} vs {b:?}");
            assert_eq!(r.exact, exact, "method for {a:?} vs {b:?}");
            // Same algorithm as scipy in both branches: agreement to rounding.
            assert_close(r.p_value, p, 1e-13);
        }
    }

    #[test]
    fn mann_whitney_is_symmetric_in_p() {
        for (a, b, ..) in scipy_cases() {
            let (ab, ba) = (mann_whitney(&a, &b), mann_whitney(&b, &a));
            assert_eq!(ab.p_value, ba.p_value);
            assert_eq!(ab.u + ba.u, (a.len() * b.len()) as f64);
        }
    }

    #[test]
    fn exact_distribution_of_u() {
        // Sizes 2 and 3: the 10 arrangements give U = 0,1,2,2,3,3,4,4,5,6.
        let cdf: Vec<f64> = (0..=6).map(|k| exact_cdf(k, 2, 3)).collect();
        let counts = [1.0, 2.0, 4.0, 6.0, 8.0, 9.0, 10.0];
        for (c, n) in cdf.iter().zip(counts) {
            assert_close(*c, n / 10.0, 1e-15);
        }
        assert_eq!(exact_cdf(3, 3, 2), exact_cdf(3, 2, 3));
        // P(U = 0) = 1 / C(n1 + n2, n1): 1 / C(16, 8) = 1 / 12870.
        assert_close(exact_cdf(0, 8, 8), 1.0 / 12870.0, 1e-15);
    }

    #[test]
    #[should_panic(expected = "non-empty")]
    fn mann_whitney_refuses_empty() {
        mann_whitney(&[], &[1.0]);
    }

    /// Why the p-value is computed here rather than by statrs (see the module doc). If this
    /// fails after a statrs upgrade, statrs has fixed its exact path and could be delegated to.
    #[test]
    fn statrs_mannwhitneyu_disagrees() {
        use statrs::distribution::Normal;
        use statrs::stats_tests::Alternative;
        use statrs::stats_tests::mannwhitneyu::{MannWhitneyUMethod, mannwhitneyu};
        let run = |a: &[f64], b: &[f64]| {
            mannwhitneyu(a, b, MannWhitneyUMethod::Automatic, Alternative::TwoSided).unwrap()
        };
        // Agrees where n_a > n_b (exact) and in the body of the normal approximation.
        let (u, p) = run(&[19.0, 22.0, 16.0, 29.0, 24.0], &[20.0, 11.0, 17.0, 12.0]);
        assert_eq!(u, 17.0);
        assert_close(p, 0.1111111111111111, 1e-12);
        let (u, p) = run(&E12, &F10);
        assert_eq!(u, 37.0);
        assert_close(p, 0.13791345941250951, 1e-9); // to its erfc's accuracy, see below
        // Exact with n_a <= n_b: scipy (and mann_whitney) give 0.031746031746031744.
        let (u, p) = run(&[1.2, 3.4, 0.5, 2.2], &[4.1, 2.9, 5.5, 3.8, 6.0]);
        assert_eq!(u, 1.0);
        assert_eq!(p, 1.0, "statrs now matches scipy's exact p-value");
        // Far tail: 1 - cdf instead of sf, 2.8e-6 relative error here.
        let (_, p) = run(&A30, &B30);
        assert!((p / 5.494052450965186e-11 - 1.0).abs() > 1e-9);
        // Normal::sf itself: 1 - Phi(1) = 0.15865525393145705 (mpmath.ncdf(-1) at 40 digits),
        // statrs 0.19.1 gives 0.15865525394505725 (8.6e-11 relative).
        let sf1 = Normal::standard().sf(1.0);
        assert!(
            (sf1 / 0.15865525393145705 - 1.0).abs() > 1e-11,
            "statrs erfc was fixed"
        );
    }

    #[test]
    fn holm_matches_statsmodels() {
        // statsmodels 0.15.0: multipletests(p, method='holm')[1], printed with repr.
        let cases: [(&[f64], &[f64]); 6] = [
            // Ties (0.04 twice) and monotonisation (0.04 * 4 = 0.16 raised to 0.2; 0.5 * 1
            // raised to 0.6).
            (
                &[0.01, 0.04, 0.03, 0.005, 0.04, 0.5, 0.3, 0.2],
                &[
                    0.07,
                    0.2,
                    0.18,
                    0.04,
                    0.2,
                    0.6000000000000001,
                    0.6000000000000001,
                    0.6000000000000001,
                ],
            ),
            // Capped: 0.6 * 2 = 1.2 and the running maximum 1.2 for 0.7.
            (&[0.7, 0.6, 0.001], &[1.0, 1.0, 0.003]),
            // Monotonised: 0.012 * 2 = 0.024 raised to 0.01 * 3 = 0.03.
            (&[0.4, 0.01, 0.012], &[0.4, 0.03, 0.03]),
            (&[0.02, 0.02, 0.02], &[0.06, 0.06, 0.06]),
            (&[0.03], &[0.03]),
            (&[], &[]),
        ];
        for (p, expected) in cases {
            // Same arithmetic as statsmodels (p * (m - k), running max, cap): exact equality.
            assert_eq!(holm(p), expected, "holm({p:?})");
        }
    }

    #[test]
    #[should_panic(expected = "[0, 1]")]
    fn holm_refuses_nan() {
        holm(&[0.1, f64::NAN]);
    }

    #[test]
    fn a12_by_hand() {
        // a = [1, 2, 3], b = [2, 3, 4]: 9 pairs, a > b once (3 > 2), equal twice (2 = 2,
        // 3 = 3): (1 + 0.5 * 2) / 9 = 2 / 9.
        assert_close(a12(&[1.0, 2.0, 3.0], &[2.0, 3.0, 4.0]), 2.0 / 9.0, 1e-15);
        assert_close(a12(&[2.0, 3.0, 4.0], &[1.0, 2.0, 3.0]), 7.0 / 9.0, 1e-15);
        // Every a below every b: a always better for minimisation.
        assert_eq!(a12(&[0.1, 0.2], &[1.0, 2.0, 3.0]), 0.0);
        assert_eq!(a12(&[5.0], &[1.0, 2.0, 3.0]), 1.0);
        assert_eq!(a12(&[0.0, 0.0], &[0.0]), 0.5);
        // [1, 5] vs [2, 3, 4]: 5 beats three, 1 beats none: 3 / 6.
        assert_eq!(a12(&[1.0, 5.0], &[2.0, 3.0, 4.0]), 0.5);
        // Equals scipy's U / (n_a n_b) with ties: 395 / 900 for C30 vs D30 (see scipy_cases).
        assert_close(a12(&C30, &D30), 395.0 / 900.0, 1e-15);
        assert_close(a12(&A30, &B30), 6.0 / 900.0, 1e-15);
    }

    #[test]
    fn friedman_matches_scipy() {
        // scipy 1.17.1: with arr = numpy.array(blocks), r = friedmanchisquare(*arr.T);
        // repr(float(r.statistic)), repr(float(r.pvalue)); mean ranks from
        // scipy.stats.rankdata(arr, axis=1).mean(axis=0).
        // Ties within rows 1, 2, 4 (three-way) and 5.
        let blocks = vec![
            vec![0.0, 0.0, 1.5, 2.0],
            vec![3.2, 1.1, 1.1, 4.0],
            vec![0.5, 0.7, 0.6, 0.9],
            vec![2.0, 2.0, 2.0, 1.0],
            vec![1e-8, 3e-3, 2e-1, 2e-1],
            vec![7.0, 5.0, 6.0, 8.0],
        ];
        let f = friedman(&blocks);
        assert_eq!(f.df, 3);
        assert_close(f.statistic, 5.150943396226428, 1e-12);
        assert_close(f.p_chi2, 0.16107217239919921, 1e-13);
        let ranks = [2.0833333333333335, 2.0, 2.5, 3.4166666666666665];
        for (r, e) in f.mean_ranks.iter().zip(ranks) {
            assert_close(*r, e, 1e-15);
        }
        // Without ties: statistic 6.400000000000006, p 0.04076220397836611, ranks
        // [1.2, 2.0, 2.8].
        let blocks = vec![
            vec![1.0, 2.0, 3.0],
            vec![1.0, 3.0, 2.0],
            vec![2.0, 1.0, 3.0],
            vec![1.0, 2.0, 3.0],
            vec![1.0, 2.0, 3.0],
        ];
        let f = friedman(&blocks);
        assert_eq!(f.df, 2);
        assert_close(f.statistic, 6.400000000000006, 1e-12);
        assert_close(f.p_chi2, 0.04076220397836611, 1e-13);
        // exp(-6.4 / 2) is the exact chi-square(2) tail: checks statrs' sf independently.
        assert_close(f.p_chi2, (-f.statistic / 2.0).exp(), 1e-12);
        assert_eq!(f.mean_ranks.len(), 3);
        for (r, e) in f.mean_ranks.iter().zip([1.2, 2.0, 2.8]) {
            assert_close(*r, e, 1e-15);
        }
    }

    #[test]
    fn friedman_all_tied_is_no_evidence() {
        let f = friedman(&[vec![0.0, 0.0, 0.0], vec![1.0, 1.0, 1.0]]);
        assert_eq!((f.statistic, f.p_value), (0.0, 1.0));
        assert_eq!(f.mean_ranks, vec![2.0, 2.0, 2.0]);
    }

    #[test]
    #[should_panic(expected = "one value per treatment")]
    fn friedman_refuses_ragged_rows() {
        friedman(&[vec![1.0, 2.0, 3.0], vec![1.0, 2.0]]);
    }

    /// References: scipy 1.17.1, `r = scipy.stats.wilcoxon(a, b)`, `repr(float(r.statistic))`,
    /// `repr(float(r.pvalue))`.
    #[test]
    fn wilcoxon_matches_scipy() {
        let n60_a: Vec<f64> = (1..=60).map(f64::from).collect();
        let n60_b: Vec<f64> = (1..=60)
            .map(|x| {
                let s = if x % 2 == 0 { 1.0 } else { -1.0 };
                f64::from(x) + s * 0.5 * f64::from(x) / 10.0
            })
            .collect();
        type PairedCase = (Vec<f64>, Vec<f64>, f64, f64, PairedMethod);
        let cases: Vec<PairedCase> = vec![
            (
                vec![1.2, 3.4, 2.2, 5.0, 4.1, 0.3, 2.9],
                vec![1.0, 3.9, 2.0, 4.0, 4.5, 0.1, 2.0],
                9.0,
                0.46875,
                PairedMethod::Exact,
            ),
            (
                vec![0.83, 0.95, 0.71, 0.88, 0.92, 0.79, 0.90, 0.85, 0.77, 0.93],
                vec![0.80, 0.91, 0.75, 0.83, 0.88, 0.70, 0.86, 0.84, 0.70, 0.90],
                6.0,
                0.02734375,
                PairedMethod::Permutation,
            ),
            (
                vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
                vec![1.0, 3.0, 2.0, 4.0, 7.0, 5.0],
                4.0,
                1.0,
                PairedMethod::Permutation,
            ),
            (
                n60_a,
                n60_b,
                900.0,
                0.9120730845618369,
                PairedMethod::Normal,
            ),
            (
                vec![3.0, 1.0, 4.0, 1.5, 5.0, 9.0, 2.6, 5.3, 5.8, 9.7, 9.3, 2.3],
                vec![2.0, 7.0, 1.0, 8.0, 2.8, 1.8, 2.8, 4.5, 9.0, 4.5, 2.3, 5.3],
                32.5,
                0.63525390625,
                PairedMethod::Permutation,
            ),
        ];
        for (a, b, stat, p, method) in cases {
            let w = wilcoxon(&a, &b);
            assert_eq!((w.statistic, w.method), (stat, method), "{a:?}");
            assert!((w.p_value - p).abs() <= 1e-12 * p, "{} vs {p}", w.p_value);
            // Swapping the samples mirrors the signs, not the test.
            let s = wilcoxon(&b, &a);
            assert_eq!(s.statistic, w.statistic);
            assert!((s.p_value - w.p_value).abs() < 1e-15);
        }
    }

    #[test]
    fn wilcoxon_sees_pairing_that_mann_whitney_cannot() {
        // Each pair differs by a small constant shift under a large spread between pairs:
        // rank sums of the two samples barely differ, the signs within pairs all agree.
        let a: Vec<f64> = (0..20).map(|k| f64::from(k * k)).collect();
        let b: Vec<f64> = a
            .iter()
            .enumerate()
            .map(|(k, x)| x + 0.5 + 0.01 * k as f64)
            .collect();
        assert!(mann_whitney(&a, &b).p_value > 0.5);
        let w = wilcoxon(&a, &b);
        assert_eq!((w.statistic, w.n, w.method), (0.0, 20, PairedMethod::Exact));
        assert!((w.p_value - 2.0 / 2f64.powi(20)).abs() < 1e-18);
        // Failed runs: both +inf is no difference, one +inf the largest.
        let inf = f64::INFINITY;
        let w = wilcoxon(&[inf, inf, 1.0, 2.0], &[inf, 1.0, 2.0, 4.0]);
        assert_eq!((w.n, w.method), (3, PairedMethod::Permutation));
        assert_eq!(wilcoxon(&[1.0, 2.0], &[1.0, 2.0]).p_value, 1.0);
    }
}
