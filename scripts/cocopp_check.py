#!/usr/bin/env python3
"""Post-processes the COCO export of an optbench results folder (`DIR/coco`) with COCO's own
`cocopp` and checks what it loads against the run itself (`DIR/suite.toml`,
`DIR/traces.jsonl`):

- `cocopp.main` runs on every optimizer's folder (output in a temporary folder, no
  browser) without an exception;
- `cocopp.load` of each optimizer's folder gives one data set per (function, dimension)
  the suite ran it on, no other, each with one run per trial: the instance numbers are
  those the suite's `instances` lists assign (trial t runs instances[t mod n]);
- per data set, the final f - f_opt and the evaluations cocopp reads equal the traces'
  (best - optimum, clipped at 0, to the 10 digits COCO's files hold), in run order;
  so do the evaluations, as read from the .info file and from the .dat lines (where cocopp
  stops at the evaluation that reached its precision 1e-8).

The suite is read independently of optbench: its `[bbob]` section and `kind = "bbob"`
objectives (defaults as in docs/03-suites-and-results.md: functions 1-24, instances 1-15,
instance 1).

Usage: python3 scripts/cocopp_check.py RESULTS_DIR
Exit 0 when everything matches, 1 on a mismatch (each is printed), 2 on bad input,
3 when cocopp is not installed (`pip install cocopp`).
"""

import io
import json
import sys
import tempfile
import tomllib
import warnings
from contextlib import redirect_stdout
from pathlib import Path


# COCO's final target, the `Precision` of the .info files.
PRECISION = 1e-8


def fail(msg, code=2):
    print(f"cocopp_check: {msg}", file=sys.stderr)
    sys.exit(code)


def numbers(v, what):
    """An instance or function list: "1-15", "1-3, 7" or [1, 2]."""
    if isinstance(v, int):
        return [v]
    if isinstance(v, list):
        return [int(x) for x in v]
    if isinstance(v, str):
        out = []
        for part in v.split(","):
            a, _, b = part.strip().partition("-")
            out.extend(range(int(a), int(b or a) + 1))
        return out
    fail(f"{what}: cannot read {v!r}")


def expected_runs(suite):
    """{(optimizer, objective id): (function, dim, [instance of trial t])} for the suite's
    BBOB objectives."""
    trials = suite["trials"]
    optimizers = [o.get("id", o["kind"]) for o in suite.get("optimizer", [])]
    entries = []
    b = suite.get("bbob")
    if b is not None:
        inst = numbers(b.get("instances", "1-15"), "[bbob] instances")
        for d in numbers(b["dimensions"], "[bbob] dimensions"):
            for f in numbers(b.get("functions", "1-24"), "[bbob] functions"):
                entries.append((f"bbob-f{f:02}-d{d:02}", f, d, inst, b.get("optimizers")))
    for o in suite.get("objective", []):
        if o["kind"] != "bbob":
            continue
        inst = numbers(o.get("instances", o.get("instance", 1)), "instances")
        oid = o.get("id", f"bbob-{o['dim']}d")
        entries.append((oid, o["function"], o["dim"], inst, o.get("optimizers")))
    out = {}
    for oid, f, d, inst, only in entries:
        for opt in optimizers:
            if only is None or opt in only:
                out[(opt, oid)] = (f, d, [inst[t % len(inst)] for t in range(trials)])
    return out


def main():
    if len(sys.argv) != 2:
        fail("usage: python3 scripts/cocopp_check.py RESULTS_DIR")
    try:
        import cocopp
    except ImportError:
        fail("cocopp is not installed (pip install -r scripts/requirements-checks.txt)", 3)
    root = Path(sys.argv[1])
    coco = root / "coco"
    if not coco.is_dir():
        fail(f"{coco}: no COCO export (run `optbench report {root}` on a suite with BBOB objectives)")
    try:
        suite = tomllib.loads((root / "suite.toml").read_text())
        traces = [json.loads(l) for l in (root / "traces.jsonl").read_text().splitlines() if l]
    except (OSError, ValueError) as e:
        fail(f"{root}: cannot read the suite or traces: {e}")
    expected = expected_runs(suite)
    if not expected:
        fail(f"{root}/suite.toml: no BBOB objective")

    # What each (optimizer, function, dim) must hold, runs in suite order then trial order.
    order = [o.get("id") for o in suite.get("objective", [])]
    want = {}
    for r in sorted(traces, key=lambda r: r["trial"]):
        key = (r["optimizer"], r["objective"])
        if key not in expected:
            continue
        f, d, inst = expected[key]
        err = max(float(r["best"]) - r["optimum"], 0.0)
        # cocopp stops reading a run where it reaches its precision, 1e-8: its maxevals.
        hit = next((e for e, v in r["improvements"]
                    if float(v) - r["optimum"] <= PRECISION), r["evaluations"])
        want.setdefault((r["optimizer"], f, d), []).append(
            (r["objective"], inst[r["trial"]], (r["evaluations"], hit), err))
    problems = []
    for (opt, oid), (f, d, inst) in expected.items():
        got = len([w for w in want.get((opt, f, d), []) if w[0] == oid])
        if got != len(inst):
            problems.append(f"{opt} {oid}: {got} traces, the suite plans {len(inst)}")

    warnings.simplefilter("ignore")  # cocopp warns about the missing internet, among others
    for opt in sorted({k[0] for k in want}):
        folder = coco / opt
        if not folder.is_dir():
            problems.append(f"{folder}: missing")
            continue
        with redirect_stdout(io.StringIO()):
            dsl = cocopp.load(str(folder))
        loaded = {(ds.funcId, ds.dim): ds for ds in dsl}
        cells = {(f, d) for (o, f, d) in want if o == opt}
        if set(loaded) != cells:
            problems.append(f"{opt}: cocopp loaded (function, dim) {sorted(loaded)}, "
                            f"the suite ran {sorted(cells)}")
        for (f, d) in sorted(cells & set(loaded)):
            ds = loaded[(f, d)]
            runs = want[(opt, f, d)]
            runs.sort(key=lambda w: order.index(w[0]) if w[0] in order else -1)
            inst = [w[1] for w in runs]
            if list(ds.instancenumbers) != inst:
                problems.append(f"{opt} f{f} {d}-D: instances {list(ds.instancenumbers)}, "
                                f"expected {inst}")
                continue
            n = ds.nbRuns_raw  # as read; `evals` replicates runs to balance instances
            if n != len(runs) or len(ds._maxevals) != len(runs):
                problems.append(f"{opt} f{f} {d}-D: {n} runs, expected {len(runs)}")
                continue
            for i, (_, _, evals, err) in enumerate(runs):
                got = (int(ds.readmaxevals[i]), int(ds._maxevals[i]))
                got_f = float(ds.finalfunvals[i])
                if got != evals:
                    problems.append(f"{opt} f{f} {d}-D run {i}: (evaluations, to 1e-8 or end) "
                                    f"{got}, traces {evals}")
                if abs(got_f - err) > 1e-9 * max(abs(err), 1e-300) and not (got_f == err):
                    problems.append(f"{opt} f{f} {d}-D run {i}: final f - f_opt {got_f!r}, "
                                    f"traces {err!r}")
    if problems:
        for p in problems:
            print(f"cocopp_check: {p}", file=sys.stderr)
        sys.exit(1)

    # The whole post-processing, as a user runs it.
    folders = [str(coco / opt) for opt in sorted({k[0] for k in want})]
    with tempfile.TemporaryDirectory() as out:
        try:
            with redirect_stdout(io.StringIO()):
                cocopp.main(["--no-interactive", "-o", out] + folders)
        except Exception as e:  # noqa: BLE001 - any failure of cocopp is the finding
            fail(f"cocopp.main failed on {folders}: {type(e).__name__}: {e}", 1)
        if not (Path(out) / "index.html").is_file():
            fail(f"cocopp.main wrote no index.html for {folders}", 1)
    n = sum(len(v) for v in want.values())
    print(f"cocopp_check: {len(folders)} optimizers, {len({(f, d) for (_, f, d) in want})} "
          f"(function, dimension) pairs, {n} runs: loaded and post-processed as run")


if __name__ == "__main__":
    main()
