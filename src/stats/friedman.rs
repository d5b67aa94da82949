//! The p-value of Friedman's statistic from its permutation distribution, for the few
//! blocks (objectives) a benchmark has, where the chi-square approximation is rough.
//!
//! Under the null hypothesis the k values of a block are exchangeable, so every arrangement
//! of the block's ranks (its actual ranks, ties included) is equally likely, independently
//! across blocks. The tie correction depends only on the ranks present, not on their
//! arrangement, so the statistic orders arrangements as the sum of squared rank sums does;
//! the p-value is the chance of a sum at least as large as observed. Ranks are multiples of
//! one half: they are doubled into integers, so every comparison is exact.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// How a Friedman p-value was computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FriedmanMethod {
    /// The exact permutation distribution, every arrangement of every block counted.
    Exact,
    /// `resamples` random arrangements of the blocks from a fixed seed, p = (1 + #{at
    /// least as large}) / (1 + resamples).
    Permutation { resamples: u64 },
}

impl FriedmanMethod {
    /// Short label for reports: `exact` or `permutation, 10^5`.
    pub fn label(&self) -> String {
        match self {
            FriedmanMethod::Exact => "exact".into(),
            FriedmanMethod::Permutation { resamples } => {
                let e = (*resamples as f64).log10();
                if (e - e.round()).abs() < 1e-9 {
                    format!("permutation, 10^{}", e.round())
                } else {
                    format!("permutation, {resamples}")
                }
            }
        }
    }
}

/// Largest (states x arrangements) the exact distribution may take: a few seconds at most.
/// Four blocks of up to six treatments stay exact; eight treatments go to resampling.
const EXACT_WORK: f64 = 4e6;

/// Resamples of the Monte-Carlo p-value: its standard error at p = 0.01 is 3e-4.
const RESAMPLES: u64 = 100_000;

/// Seed of the resampling stream: fixed, so a report's p-value is reproducible.
const SEED: u64 = 0x4672_6965_646d_616e; // "Friedman"

/// P(sum of squared rank sums >= observed) for the within-block `ranks` (one row per
/// block, average ranks), exactly when the distribution is small enough, else by
/// resampling; and which of the two it is.
pub(crate) fn permutation_p(ranks: &[Vec<f64>]) -> (f64, FriedmanMethod) {
    let doubled: Vec<Vec<i64>> = ranks
        .iter()
        .map(|row| row.iter().map(|r| (2.0 * r).round() as i64).collect())
        .collect();
    let k = doubled[0].len();
    let mut sums = vec![0i64; k];
    for row in &doubled {
        for (s, r) in sums.iter_mut().zip(row) {
            *s += r;
        }
    }
    let observed = squares(&sums);
    match exact(&doubled, observed) {
        Some(p) => (p, FriedmanMethod::Exact),
        None => (
            resampled(&doubled, observed, RESAMPLES),
            FriedmanMethod::Permutation {
                resamples: RESAMPLES,
            },
        ),
    }
}

fn squares(v: &[i64]) -> i64 {
    v.iter().map(|s| s * s).sum()
}

/// Number of distinct arrangements of `row` (k! over the tie groups' factorials).
fn arrangement_count(row: &[i64]) -> f64 {
    let mut sorted = row.to_vec();
    sorted.sort_unstable();
    let fact = |n: usize| (1..=n).map(|i| i as f64).product::<f64>();
    let mut count = fact(sorted.len());
    for group in sorted.chunk_by(|a, b| a == b) {
        count /= fact(group.len());
    }
    count
}

/// Every distinct arrangement of `row` (lexicographic next-permutation of the sorted row).
fn arrangements(row: &[i64]) -> Vec<Vec<i64>> {
    let mut a = row.to_vec();
    a.sort_unstable();
    let mut out = vec![a.clone()];
    loop {
        let Some(i) = (1..a.len()).rev().find(|&i| a[i - 1] < a[i]) else {
            return out;
        };
        let j = (i..a.len())
            .rev()
            .find(|&j| a[j] > a[i - 1])
            .expect("a larger element");
        a.swap(i - 1, j);
        a[i..].reverse();
        out.push(a.clone());
    }
}

/// The exact p-value, or `None` if its distribution is too large to build.
///
/// Block 0 is held as observed (relabelling the treatments maps any of its arrangements to
/// any other without changing the statistic), and the distribution is built block by block
/// over the vector of rank sums, kept sorted: adding a uniformly arranged block to a vector
/// or to any permutation of it gives the same sorted sums, so sorted vectors suffice.
/// Weights are counts of equally likely arrangements; a `BTreeMap` keeps the summation order
/// fixed.
fn exact(rows: &[Vec<i64>], observed: i64) -> Option<f64> {
    let mut first = rows[0].clone();
    first.sort_unstable();
    let mut states: BTreeMap<Vec<i64>, f64> = BTreeMap::from([(first, 1.0)]);
    let Some((last, middle)) = rows[1..].split_last() else {
        return Some(1.0);
    };
    let mut work = 0.0;
    for row in middle {
        work += states.len() as f64 * arrangement_count(row);
        if work > EXACT_WORK {
            return None;
        }
        let mut next = BTreeMap::new();
        for a in arrangements(row) {
            for (s, w) in &states {
                let mut v: Vec<i64> = s.iter().zip(&a).map(|(x, y)| x + y).collect();
                v.sort_unstable();
                *next.entry(v).or_insert(0.0) += w;
            }
        }
        states = next;
    }
    work += states.len() as f64 * arrangement_count(last);
    if work > EXACT_WORK {
        return None;
    }
    let (mut hit, mut total) = (0.0, 0.0);
    let last = arrangements(last);
    for (s, w) in &states {
        for a in &last {
            let ss: i64 = s.iter().zip(a).map(|(x, y)| (x + y) * (x + y)).sum();
            total += w;
            if ss >= observed {
                hit += w;
            }
        }
    }
    Some(hit / total)
}

/// The Monte-Carlo p-value over `resamples` random arrangements of blocks 1.. (block 0
/// held, as in [`exact`]), shuffled by Fisher-Yates from the fixed [`SEED`].
fn resampled(rows: &[Vec<i64>], observed: i64, resamples: u64) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let k = rows[0].len();
    let mut row = vec![0i64; k];
    let mut sums = vec![0i64; k];
    let mut hits = 0u64;
    for _ in 0..resamples {
        sums.copy_from_slice(&rows[0]);
        for r in &rows[1..] {
            row.copy_from_slice(r);
            for i in (1..k).rev() {
                row.swap(i, rng.random_range(0..=i));
            }
            for (s, v) in sums.iter_mut().zip(&row) {
                *s += v;
            }
        }
        hits += u64::from(squares(&sums) >= observed);
    }
    (1 + hits) as f64 / (1 + resamples) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrangements_of_a_multiset_are_distinct_and_all_there() {
        let a = arrangements(&[3, 1, 3, 2]);
        assert_eq!(a.len(), 12);
        assert_eq!(arrangement_count(&[3, 1, 3, 2]), 12.0);
        let mut d = a.clone();
        d.dedup();
        assert_eq!(d, a, "sorted and distinct");
        assert_eq!(arrangements(&[1, 2, 3]).len(), 6);
        assert_eq!(arrangements(&[2, 2]), vec![vec![2, 2]]);
    }

    /// The sorted-state distribution against brute force over every arrangement of every
    /// block, on a case with ties.
    #[test]
    fn the_exact_distribution_is_the_brute_force_one() {
        let rows: Vec<Vec<i64>> = vec![
            vec![2, 4, 6, 8],
            vec![2, 5, 5, 8],
            vec![4, 2, 8, 6],
            vec![3, 3, 6, 8],
        ];
        let observed = squares(&[11, 14, 25, 30]);
        let all: Vec<Vec<Vec<i64>>> = rows[1..].iter().map(|r| arrangements(r)).collect();
        let (mut hit, mut total) = (0u64, 0u64);
        for a in &all[0] {
            for b in &all[1] {
                for c in &all[2] {
                    let sums: Vec<i64> = (0..4).map(|j| rows[0][j] + a[j] + b[j] + c[j]).collect();
                    total += 1;
                    hit += u64::from(squares(&sums) >= observed);
                }
            }
        }
        let p = exact(&rows, observed).unwrap();
        assert_eq!(p, hit as f64 / total as f64);
        // And resampling agrees within five standard errors.
        let r = resampled(&rows, observed, 20_000);
        assert!(
            (r - p).abs() < 5.0 * (p * (1.0 - p) / 20_000.0).sqrt(),
            "{r} vs {p}"
        );
    }

    #[test]
    fn labels_name_the_method() {
        assert_eq!(FriedmanMethod::Exact.label(), "exact");
        let p = FriedmanMethod::Permutation { resamples: 100_000 };
        assert_eq!(p.label(), "permutation, 10^5");
    }
}
