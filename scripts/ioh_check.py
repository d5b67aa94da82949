#!/usr/bin/env python3
"""Loads the IOH export of an optbench results folder (`DIR/ioh`) with the IOH project's
own loader, `iohinspector`, and checks it against `DIR/summary.json`:

- every run is loaded: the number of runs per (function id, dimension, algorithm) equals
  the trials of the summary's cells of that objective kind and dimension;
- per (objective, optimizer), the final best values iohinspector reads, both from the meta
  files (`best_y`) and as the last point of each run's trajectory in the `.dat` files, equal
  the summary's finals minus the known optimum (clipped at 0), exactly, in trial order.

Usage: python3 scripts/ioh_check.py RESULTS_DIR
Exit 0 when everything matches, 1 on a mismatch (each is printed), 2 on bad input,
3 when iohinspector is not installed (`pip install iohinspector`).
"""

import csv
import json
import sys
import warnings
from pathlib import Path

SUMMARY_FORMAT_VERSION = 1

# The objective kinds' function ids (src/report/ioh.rs, FUNCTION_IDS).
# An independent copy on purpose: a renumbering in Rust alone fails this check.
FUNCTION_IDS = {"sphere": 25, "griewank": 26, "schwefel": 27, "rastrigin": 28,
                "rosenbrock": 29, "ackley": 30, "bouc-wen": 101, "rbf": 102,
                "pi": 103, "preisach": 104}


def fail(msg, code=2):
    print(f"ioh_check: {msg}", file=sys.stderr)
    sys.exit(code)


def read_summary(path):
    try:
        s = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        fail(f"{path}: cannot read: {e}")
    version = s.get("format_version", 1)
    if version > SUMMARY_FORMAT_VERSION:
        fail(f"{path}: format_version {version} is newer than this script reads "
             f"({SUMMARY_FORMAT_VERSION}); update scripts/ioh_check.py")
    return s


def as_float(v):
    """summary.json spells infinities as strings."""
    return float(v) if isinstance(v, str) else v


def exported(value, optimum):
    return value if optimum is None else max(value - optimum, 0.0)


def main():
    if len(sys.argv) != 2:
        fail("usage: python3 scripts/ioh_check.py RESULTS_DIR")
    try:
        import iohinspector
        import polars as pl
    except ImportError as e:
        fail(f"iohinspector is not installed ({e}); pip install iohinspector", 3)
    root = Path(sys.argv[1])
    summary = read_summary(root / "summary.json")
    try:
        with open(root / "ioh" / "instances.csv", newline="") as f:
            instances = {r["objective"]: r for r in csv.DictReader(f)}
    except OSError as e:
        fail(f"{root / 'ioh' / 'instances.csv'}: cannot read: {e}")

    dm = iohinspector.DataManager()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dm.add_folder(str(root / "ioh"))
    problems = [f"iohinspector warned: {w.message}" for w in caught]
    ov = dm.overview

    # What summary.json expects, per (fid, dim, algorithm) and per objective x optimizer.
    expected_counts = {}
    cells = []
    for c in summary["results"]:
        inst = instances.get(c["objective"])
        if inst is None:
            problems.append(f"objective {c['objective']} missing from ioh/instances.csv")
            continue
        fid, dim = int(inst["function_id"]), int(inst["dimension"])
        if inst["function_name"] == "bbob":
            # COCO's BBOB functions keep IOH's numbers for BBOB, 1-24.
            if not 1 <= fid <= 24:
                problems.append(f"{c['objective']}: bbob function id {fid} is not in 1-24")
        elif FUNCTION_IDS.get(inst["function_name"]) != fid:
            problems.append(f"{c['objective']}: function id {fid} is not "
                            f"{inst['function_name']}'s fixed id")
        key = (fid, dim, c["optimizer"])
        expected_counts[key] = expected_counts.get(key, 0) + c["trials"]
        cells.append((c, fid, dim, int(inst["instance"])))

    counts = {}
    for r in ov.group_by(["function_id", "dimension", "algorithm_name"]).len().iter_rows():
        counts[(r[0], r[1], r[2])] = r[3]
    for key in sorted(set(expected_counts) | set(counts)):
        want, got = expected_counts.get(key, 0), counts.get(key, 0)
        if want != got:
            problems.append(f"f{key[0]} DIM {key[1]} {key[2]}: {got} runs loaded, "
                            f"summary.json has {want}")

    # The trajectories as iohinspector reads them from the .dat files (every line: the
    # monotonic view drops the last evaluation when it brings no improvement).
    data = dm.load(monotonic=False, include_meta_data=True)
    last = (data.sort("evaluations").group_by("data_id")
            .agg(pl.col("raw_y").last(), pl.col("evaluations").max()))
    last = {r[0]: (r[1], r[2]) for r in last.iter_rows()}

    for c, fid, dim, instance in cells:
        runs = ov.filter((pl.col("function_id") == fid) & (pl.col("dimension") == dim)
                         & (pl.col("instance") == instance)
                         & (pl.col("algorithm_name") == c["optimizer"]))
        optimum = c["optimum"]
        want = [exported(as_float(v), optimum) for v in c["finals"]]
        got = [None if y is None else y for y in runs["best_y"].to_list()]
        # Runs of one instance are the cell's trials in trial order (the meta file's order).
        if len(got) != len(want) or any(
                g != w and not (g is None and w == float("inf")) for g, w in zip(got, want)):
            problems.append(f"{c['objective']} x {c['optimizer']}: best_y {got} "
                            f"!= summary finals - f* {want}")
            continue
        for data_id, evals, w in zip(runs["data_id"].to_list(), runs["evals"].to_list(), want):
            y, e = last.get(data_id, (None, None))
            if y != w:
                problems.append(f"{c['objective']} x {c['optimizer']} run {data_id}: "
                                f".dat ends at {y}, summary final - f* is {w}")
            elif evals > 0 and e != evals:
                problems.append(f"{c['objective']} x {c['optimizer']} run {data_id}: "
                                f".dat ends at evaluation {e}, meta says {evals}")

    total = sum(expected_counts.values())
    print(f"iohinspector {getattr(iohinspector, '__version__', '')} loaded {dm.n_runs} runs "
          f"of {total} in {len(counts)} (function, dimension, algorithm) groups "
          f"from {root / 'ioh'}")
    for p in problems:
        print(f"MISMATCH: {p}")
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
