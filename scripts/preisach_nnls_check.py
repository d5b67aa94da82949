#!/usr/bin/env python3
"""The least-squares optimum of a discretised Preisach model on a recording, computed
independently of optbench: every relay switched here in Python, the weights by
`scipy.optimize.nnls`. optbench's `Preisach::fit` (its staircase interface, merged relay
states and its own Lawson-Hanson NNLS) must reach the same optimum; tests/operator_models.rs
compares the two.

Model (src/physics/preisach.rs): N cells over [min u, max u], thresholds at the cell
centres t_k = min u + (k + 1/2) (max u - min u) / N; relay (i, j), j <= i, is 1 once
u >= t_i, 0 once u < t_j, and keeps its value in between; it starts on iff
t_i + t_j <= 2 u(0) (demagnetised at the first sample). y = d0 + sum mu_ij R_ij,
mu_ij >= 0, d0 free (split into d0+ - d0-, both >= 0, for scipy's nnls, which has no free
variables). Weights are listed row by row: (0,0), (1,0), (1,1), (2,0), ...

The optimal fitted output is unique even where the weights are not (a record that visits
fewer relay states than there are relays): `rank` says which case it is.

Usage: python3 scripts/preisach_nnls_check.py CSV --columns t,u,y --levels N --out JSON
Exit 0 on success, 2 on bad input, 3 when numpy or scipy is missing.
"""

import argparse
import csv
import json
import sys


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("csv")
    ap.add_argument("--columns", default="t,u,y")
    ap.add_argument("--levels", type=int, default=8)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    try:
        import numpy as np
        from scipy.optimize import nnls
        import scipy
    except ImportError as e:
        print(f"preisach_nnls_check: {e} (pip install numpy scipy)", file=sys.stderr)
        sys.exit(3)
    if a.levels < 1:
        print(f"preisach_nnls_check: --levels {a.levels}; expected at least 1", file=sys.stderr)
        sys.exit(2)
    _, ucol, ycol = a.columns.split(",")
    try:
        with open(a.csv, newline="") as f:
            rows = list(csv.DictReader(f))
        header = list(rows[0]) if rows else []
        missing = [c for c in (ucol, ycol) if c not in header]
        if missing:
            print(f"preisach_nnls_check: {a.csv}: no column {', '.join(missing)} "
                  f"(the header has {', '.join(header) or 'nothing'}); set --columns t,u,y",
                  file=sys.stderr)
            sys.exit(2)
        u = [float(r[ucol]) for r in rows]
        y = np.array([float(r[ycol]) for r in rows])
    except (OSError, ValueError) as e:
        print(f"preisach_nnls_check: {a.csv}: {e}", file=sys.stderr)
        sys.exit(2)
    n = a.levels
    lo, hi = min(u), max(u)
    if not hi > lo:
        print(f"preisach_nnls_check: {a.csv}: the input is constant", file=sys.stderr)
        sys.exit(2)
    cell = (hi - lo) / n
    t = [lo + (k + 0.5) * cell for k in range(n)]
    relays = [(i, j) for i in range(n) for j in range(i + 1)]
    on = [t[i] + t[j] <= 2.0 * u[0] for i, j in relays]
    A = np.empty((len(u), len(relays)))
    for k, x in enumerate(u):
        for r, (i, j) in enumerate(relays):
            if x >= t[i]:
                on[r] = True
            elif x < t[j]:
                on[r] = False
        A[k] = on
    one = np.ones(len(u))
    M = np.column_stack([A, one, -one])
    x, rnorm = nnls(M, y, maxiter=50 * M.shape[1])
    m = len(relays)
    out = {
        "source": a.csv.split("/")[-1],
        "solver": f"scipy.optimize.nnls {scipy.__version__}",
        "levels": n,
        "thresholds": t,
        "rank": int(np.linalg.matrix_rank(np.column_stack([A, one]))),
        "weights": list(x[:m]),
        "offset": x[m] - x[m + 1],
        "rmse": rnorm / len(u) ** 0.5,
    }
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
