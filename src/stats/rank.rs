//! Average ranks with tie groups: the common first step of the rank-based tests.

/// 1-based ranks of `values` in input order, tied values sharing the mean of the ranks they
/// span (scipy's `rankdata(method='average')`), and the size of every group of equal values
/// (what the tie corrections need). Panics on NaN: it has no rank, and silently placing it
/// would change every p-value.
pub(crate) fn average_ranks(values: &[f64]) -> (Vec<f64>, Vec<usize>) {
    assert!(
        values.iter().all(|v| !v.is_nan()),
        "rank-based statistics are undefined for NaN"
    );
    let mut order: Vec<usize> = (0..values.len()).collect();
    // total_cmp puts -0.0 just before 0.0; grouping below uses ==, so they still tie.
    order.sort_by(|&i, &j| values[i].total_cmp(&values[j]));
    let mut ranks = vec![0.0; values.len()];
    let mut groups = Vec::new();
    let mut start = 0;
    while start < order.len() {
        let mut end = start + 1;
        while end < order.len() && values[order[end]] == values[order[start]] {
            end += 1;
        }
        // Ranks start+1 ..= end, whose mean is (start + 1 + end) / 2.
        let rank = (start + 1 + end) as f64 / 2.0;
        for &i in &order[start..end] {
            ranks[i] = rank;
        }
        groups.push(end - start);
        start = end;
    }
    (ranks, groups)
}

/// `Σ (t³ - t)` over the tie groups of [`average_ranks`]: the tie correction of every
/// rank test's variance (0 without ties).
pub(crate) fn tie_term(groups: &[usize]) -> f64 {
    groups
        .iter()
        .map(|&t| {
            let t = t as f64;
            t * t * t - t
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ties_share_the_mean_rank() {
        // scipy.stats.rankdata([4, 2, 2, 1, -0.0, 0.0]) = [6, 4.5, 4.5, 3, 1.5, 1.5]
        let (r, g) = average_ranks(&[4.0, 2.0, 2.0, 1.0, -0.0, 0.0]);
        assert_eq!(r, vec![6.0, 4.5, 4.5, 3.0, 1.5, 1.5]);
        assert_eq!(g, vec![2, 1, 2, 1]);
        let (r, g) = average_ranks(&[f64::INFINITY, 1.0, f64::INFINITY]);
        assert_eq!(r, vec![2.5, 1.0, 2.5]);
        assert_eq!(g, vec![1, 2]);
        assert_eq!(average_ranks(&[]), (vec![], vec![]));
    }

    #[test]
    #[should_panic(expected = "NaN")]
    fn nan_is_refused() {
        average_ranks(&[1.0, f64::NAN]);
    }
}
