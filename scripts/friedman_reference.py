#!/usr/bin/env python3
"""Reference p-values of Friedman's test from its permutation distribution, for the unit
test `friedman_permutation_p_matches_scipy` in src/stats/hypothesis.rs.

    python3 scripts/friedman_reference.py      # numpy and scipy (tested with scipy 1.17.1)

For each case (rows = blocks/objectives, columns = treatments/optimizers) it prints scipy's
statistic and chi-square p-value, then the permutation p-value computed independently of
optbench:
  - exact: scipy.stats.permutation_test with permutation_type='samples' (each block's values
    arranged among the treatments every way, (k!)^n arrangements, n_resamples=inf) and the
    tie-corrected Friedman statistic, alternative='greater';
  - for the 6-block case, brute force in numpy over every arrangement of blocks 2..6 (block 1
    held: relabelling the treatments does not change the statistic), 24^5 = 8 million;
  - for the 8-treatment case, (k!)^n is 6.5e13: Monte Carlo with 10^6 resamples from numpy's
    default_rng(2024), with its standard error.
"""

import itertools

import numpy as np
from scipy import stats

CASES = {
    # The tied blocks of friedman_matches_scipy (its first four rows; then all six).
    "ties4": [
        [0.0, 0.0, 1.5, 2.0],
        [3.2, 1.1, 1.1, 4.0],
        [0.5, 0.7, 0.6, 0.9],
        [2.0, 2.0, 2.0, 1.0],
    ],
    "ties6": [
        [0.0, 0.0, 1.5, 2.0],
        [3.2, 1.1, 1.1, 4.0],
        [0.5, 0.7, 0.6, 0.9],
        [2.0, 2.0, 2.0, 1.0],
        [1e-8, 3e-3, 2e-1, 2e-1],
        [7.0, 5.0, 6.0, 8.0],
    ],
    # The untied blocks of friedman_matches_scipy.
    "plain5": [
        [1.0, 2.0, 3.0],
        [1.0, 3.0, 2.0],
        [2.0, 1.0, 3.0],
        [1.0, 2.0, 3.0],
        [1.0, 2.0, 3.0],
    ],
    # suites/functions.toml, seed 2013: median errors of GA, PSO, MSGA, RS (docs chapter 4).
    "functions4": [
        [0.010427039514165293, 5.9396931817445875e-15, 0.006697469531842526, 0.11600807050965112],
        [1.8321644450577423, 0.0, 0.0, 1.0583818344894667],
        [12.166615937713335, 1.0656346520344786, 1.372526965137185, 351.3806124257218],
        [6288.2698758943025, 3553.26965013067, 1123.7156135250852, 8210.704183082407],
    ],
    # The same with DE, SHADE, CMA-ES, MSGA-LBFGS: eight treatments.
    "functions8": [
        [0.010427039514165293, 5.9396931817445875e-15, 0.006697469531842526,
         0.11600807050965112, 0.0, 0.0, 3.3306690738754696e-16, 0.007396040334115339],
        [1.8321644450577423, 0.0, 0.0, 1.0583818344894667, 0.0, 0.0, 0.0, 0.0],
        [12.166615937713335, 1.0656346520344786, 1.372526965137185, 351.3806124257218,
         0.7149982196160245, 2.3582802377575263e-12, 4.884981308350689e-15,
         1.6653345369377348e-16],
        [6288.2698758943025, 3553.26965013067, 1123.7156135250852, 8210.704183082407,
         7395.636283133532, 2102.1242393674765, 1476.417690674044, 473.7533384577855],
    ],
}


def chi2_stat(ranks):
    """Tie-corrected Friedman statistic of ranks shaped (..., n blocks, k treatments)."""
    n, k = ranks.shape[-2], ranks.shape[-1]
    ssbn = (ranks.sum(axis=-2) ** 2).sum(axis=-1)
    return (12.0 / (k * n * (k + 1)) * ssbn - 3.0 * n * (k + 1))


def tie_correction(arr):
    n, k = arr.shape
    ties = 0.0
    for row in arr:
        _, counts = np.unique(row, return_counts=True)
        ties += (counts * (counts**2 - 1)).sum()
    return 1.0 - ties / (k * (k * k - 1) * n)


def scipy_exact(arr):
    c = tie_correction(arr)

    def statistic(*samples, axis):
        x = np.stack(samples, axis=-1)  # (..., n, k)
        x = np.moveaxis(x, axis, -2) if axis != -1 else x
        ranks = stats.rankdata(x, axis=-1)
        return chi2_stat(ranks) / c

    res = stats.permutation_test(
        tuple(arr.T), statistic, permutation_type="samples", vectorized=True,
        n_resamples=np.inf, alternative="greater",
    )
    return res.pvalue


def brute_force(arr):
    ranks = stats.rankdata(arr, axis=1)
    n, k = ranks.shape
    perms = np.array(list(itertools.permutations(range(k))))
    blocks = [ranks[b][perms] for b in range(1, n)]  # each (k!, k)
    sums = ranks[0].copy()[None, :]
    for blk in blocks:
        sums = (sums[:, None, :] + blk[None, :, :]).reshape(-1, k)
    observed = (ranks.sum(axis=0) ** 2).sum()
    ss = (sums**2).sum(axis=1)
    return np.mean(ss >= observed - 1e-9)


def monte_carlo(arr, resamples=10**6):
    rng = np.random.default_rng(2024)
    ranks = stats.rankdata(arr, axis=1)
    n, k = ranks.shape
    observed = (ranks.sum(axis=0) ** 2).sum()
    hits = 0
    done = 0
    while done < resamples:
        m = min(100_000, resamples - done)
        sums = np.tile(ranks[0], (m, 1))
        for b in range(1, n):
            idx = np.argsort(rng.random((m, k)), axis=1)
            sums += ranks[b][idx]
        hits += int(((sums**2).sum(axis=1) >= observed - 1e-9).sum())
        done += m
    p = (1 + hits) / (1 + resamples)
    return p, np.sqrt(p * (1 - p) / resamples)


def main():
    for name, rows in CASES.items():
        arr = np.array(rows)
        r = stats.friedmanchisquare(*arr.T)
        print(f"{name}: statistic {float(r.statistic)!r}, chi-square p {float(r.pvalue)!r}")
        if name == "functions8":
            p, se = monte_carlo(arr)
            print(f"  Monte Carlo (10^6) p {p!r} +- {se!r}")
        elif name == "ties6":
            print(f"  brute force p {float(brute_force(arr))!r}")
        else:
            print(f"  exact p (scipy permutation_test) {float(scipy_exact(arr))!r}")
            print(f"  brute force p {float(brute_force(arr))!r}")


if __name__ == "__main__":
    main()
