#!/usr/bin/env python3
"""The least-squares optimum of a plain Prandtl-Ishlinskii model on a recording, computed
independently of optbench: the play operators written out here in Python, the weights by
`scipy.optimize.nnls`. optbench's `PiModel::fit` (its own Lawson-Hanson NNLS over its own
plays) must give the same weights; tests/operator_models.rs compares the two.

Model: y = d0 + sum_i w_i z_i, z_i(k) = max(u(k) - r_i, min(u(k) + r_i, z_i(k-1))),
z_i(-1) = 0, r_i = i/n (max u - min u)/2, w_i >= 0, d0 free (split into d0+ - d0-, both >= 0,
so that scipy's nnls, which has no free variables, solves the same problem).

Usage: python3 scripts/pi_nnls_check.py CSV --columns t,u,y --operators N --out JSON
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
    ap.add_argument("--operators", type=int, default=10)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    try:
        import numpy as np
        from scipy.optimize import nnls
        import scipy
    except ImportError as e:
        print(f"pi_nnls_check: {e} (pip install numpy scipy)", file=sys.stderr)
        sys.exit(3)
    _, ucol, ycol = a.columns.split(",")
    try:
        with open(a.csv, newline="") as f:
            rows = list(csv.DictReader(f))
        u = np.array([float(r[ucol]) for r in rows])
        y = np.array([float(r[ycol]) for r in rows])
    except (OSError, KeyError, ValueError) as e:
        print(f"pi_nnls_check: {a.csv}: {e}", file=sys.stderr)
        sys.exit(2)
    n = a.operators
    r = [(u.max() - u.min()) / 2 * i / n for i in range(n)]
    cols = []
    for ri in r:
        z = 0.0
        col = np.empty(len(u))
        for k, x in enumerate(u):
            z = max(x - ri, min(x + ri, z))
            col[k] = z
        cols.append(col)
    one = np.ones(len(u))
    A = np.column_stack(cols + [one, -one])
    x, rnorm = nnls(A, y, maxiter=50 * A.shape[1])
    out = {
        "source": a.csv.split("/")[-1],
        "solver": f"scipy.optimize.nnls {scipy.__version__}",
        "thresholds": r,
        "weights": list(x[:n]),
        "offset": x[n] - x[n + 1],
        "rmse": rnorm / len(u) ** 0.5,
    }
    with open(a.out, "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
