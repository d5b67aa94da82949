#!/usr/bin/env python3
"""Reference values of COCO's 24 bbob functions, from cocoex itself, written into
tests/reference/bbob_cocoex.json, which tests/bbob.rs checks optbench's `bbob` kind against.

    python3 scripts/bbob_reference.py            # write the table
    python3 scripts/bbob_reference.py --check    # compare the stored table with cocoex now

Needs cocoex (pip `coco-experiment`, written with 2.8.2) and numpy; exits 3 when either is
missing. For every function 1-24, instance in INSTANCES and dimension in DIMENSIONS it
stores the optimum's location as cocoex reports it (`Problem._best_parameter("print")`,
which writes a file in the working directory) with the value there, and the values at a few
points drawn by numpy's default_rng, seeded per problem: inside [-5, 5]^d and with one
coordinate outside it (where COCO's boundary penalties act). Points are rounded to 6
decimals so the table stays small; every float is written with repr, which round-trips.
"""

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

try:
    import cocoex
    import numpy as np
except ImportError as e:  # the checks' convention: 3 = a needed package is missing
    print(f"bbob_reference.py needs cocoex and numpy ({e}); pip install coco-experiment")
    sys.exit(3)

TABLE = Path(__file__).resolve().parent.parent / "tests/reference/bbob_cocoex.json"
INSTANCES = [1, 2, 7, 15, 101]
DIMENSIONS = [2, 3, 5, 10, 20, 40]
# Points per problem: inside the box and outside it; fewer in 20-D and 40-D (size).
INSIDE = {2: 3, 3: 3, 5: 3, 10: 3, 20: 2, 40: 1}
OUTSIDE = 1
# --check: cocoex on another machine (another libm) may differ in the last bits.
CHECK_RTOL = 1e-14


def best_parameter(problem):
    """The optimum's location as cocoex reports it (it prints it to a file)."""
    with tempfile.TemporaryDirectory() as d:
        old = os.getcwd()
        os.chdir(d)
        try:
            problem._best_parameter("print")
            text = Path("._bbob_problem_best_parameter.txt").read_text()
        finally:
            os.chdir(old)
    return [float(v) for v in text.split()]


def points(f, dim, instance):
    rng = np.random.default_rng([f, dim, instance])
    out = [np.round(rng.uniform(-5, 5, dim), 6) for _ in range(INSIDE[dim])]
    for _ in range(OUTSIDE):
        x = np.round(rng.uniform(-5, 5, dim), 6)
        k = int(rng.integers(dim))
        x[k] = round(float(np.sign(x[k]) or 1.0) * rng.uniform(5.5, 8.0), 6)
        out.append(x)
    return [[float(v) for v in x] for x in out]


def table():
    suite = cocoex.Suite(
        "bbob",
        "instances: " + ",".join(map(str, INSTANCES)),
        "dimensions: " + ",".join(map(str, DIMENSIONS)),
    )
    entries = []
    for problem in suite:
        f, dim, inst = problem.id_function, problem.dimension, problem.id_instance
        xopt = best_parameter(problem)
        pts = points(f, dim, inst)
        entries.append(
            {
                "function": f,
                "dim": dim,
                "instance": inst,
                "id": problem.id,
                "xopt": xopt,
                "f_xopt": float(problem(np.array(xopt))),
                "points": pts,
                "values": [float(problem(np.array(x))) for x in pts],
            }
        )
    entries.sort(key=lambda e: (e["function"], e["dim"], e["instance"]))
    return {
        "generator": "scripts/bbob_reference.py",
        "cocoex": cocoex.__version__,
        "entries": entries,
    }


def close(a, b):
    return a == b or abs(a - b) <= CHECK_RTOL * max(abs(a), abs(b))


def check(stored, fresh):
    bad = 0
    key = lambda e: (e["function"], e["dim"], e["instance"])
    fresh_by = {key(e): e for e in fresh["entries"]}
    for e in stored["entries"]:
        g = fresh_by.get(key(e))
        if g is None:
            print(f"{e['id']}: not in cocoex's suite now")
            bad += 1
            continue
        pairs = [(e["f_xopt"], g["f_xopt"], "f(xopt)")]
        pairs += [(a, b, f"point {i}") for i, (a, b) in enumerate(zip(e["values"], g["values"]))]
        pairs += [(a, b, "xopt") for a, b in zip(e["xopt"], g["xopt"])]
        if e["points"] != g["points"]:
            print(f"{e['id']}: the points differ (numpy's generator changed?)")
            bad += 1
        for a, b, what in pairs:
            if not close(a, b):
                print(f"{e['id']} {what}: stored {a!r}, cocoex {cocoex.__version__} gives {b!r}")
                bad += 1
    n = len(stored["entries"])
    if len(fresh["entries"]) != n:
        print(f"{n} stored problems, cocoex has {len(fresh['entries'])}")
        bad += 1
    print(f"{n} problems checked against cocoex {cocoex.__version__}: {bad} differences")
    return bad == 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare the stored table with cocoex")
    args = ap.parse_args()
    fresh = table()
    if args.check:
        stored = json.loads(TABLE.read_text())
        sys.exit(0 if check(stored, fresh) else 1)
    TABLE.parent.mkdir(parents=True, exist_ok=True)
    tmp = TABLE.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(fresh, separators=(",", ":")) + "\n")
    tmp.replace(TABLE)
    print(f"wrote {TABLE} ({len(fresh['entries'])} problems, {TABLE.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
