#!/usr/bin/env python3
"""Reference p-values of Friedman's test from its permutation distribution, written into
tests/fixtures/friedman_reference.json, which tests/friedman.rs checks optbench against.

    python3 scripts/friedman_reference.py            # print the references
    python3 scripts/friedman_reference.py --write    # and store them in the fixture

Needs numpy and scipy (written with scipy 1.17.1, numpy 2.4.6). The fixture holds the
cases (rows = blocks/objectives, columns = treatments/optimizers); for each this script adds
scipy's statistic and chi-square p-value and the permutation p-value, computed
independently of optbench:
  - exact: scipy.stats.permutation_test with permutation_type='samples' (each block's values
    arranged among the treatments every way, (k!)^n arrangements, n_resamples=inf) on the
    tie-corrected Friedman statistic, alternative='greater', where (k!)^n <= 10^6; checked
    against a brute force in numpy over every arrangement of blocks 2..n (block 1 held:
    relabelling the treatments does not change the statistic), which alone serves up to
    24^5 = 8 million arrangements;
  - beyond that (eight treatments: (8!)^3 = 6.5e13): Monte Carlo with 10^6 resamples from
    numpy's default_rng(2024), with its standard error.
"""

import argparse
import itertools
import json
import math
import re
from pathlib import Path

import numpy as np
from scipy import stats

FIXTURE = Path(__file__).resolve().parent.parent / "tests/fixtures/friedman_reference.json"


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
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="store the references in the fixture")
    args = ap.parse_args()
    fixture = json.loads(FIXTURE.read_text())
    for case in fixture["cases"]:
        arr = np.array(case["blocks"])
        n, k = arr.shape
        r = stats.friedmanchisquare(*arr.T)
        case["statistic"] = float(r.statistic)
        case["p_chi2"] = float(r.pvalue)
        arrangements = math.factorial(k) ** (n - 1)
        if arrangements <= 8 * 10**6:
            p = float(brute_force(arr))
            if math.factorial(k) ** n <= 10**6:
                exact = float(scipy_exact(arr))
                assert abs(exact - p) <= 1e-12 * p, (case["name"], exact, p)
                p = exact
            case.update(method="exact", p=p)
            case.pop("standard_error", None)
        else:
            p, se = monte_carlo(arr)
            case.update(method="monte-carlo, 10^6", p=float(p), standard_error=float(se))
        print(f"{case['name']}: statistic {case['statistic']!r}, chi-square p "
              f"{case['p_chi2']!r}, {case['method']} p {case['p']!r}"
              + (f" +- {case['standard_error']!r}" if "standard_error" in case else ""))
    if args.write:
        text = json.dumps(fixture, indent=1)
        # Rows of numbers on one line each.
        text = re.sub(r"\[\s+([^\[\]{}]*?)\s+\]",
                      lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",")) + "]",
                      text)
        FIXTURE.write_text(text + "\n")
        print(f"wrote {FIXTURE}")


if __name__ == "__main__":
    main()
