#!/usr/bin/env python3
"""Run `optbench diagnose` on every blind-proof case and score the names it gives.

  python3 scripts/blind_proof/run.py --cases DIR [--jobs 1] [--optbench PATH]
      [--extra-args "..."] [--force] --report OUT.md --json OUT.json

Each case's diagnosis goes to DIR/case-XXXX/diagnosis/ (skipped when its
diagnosis.json exists, unless --force).  The tool gets --hold zoh always: it
fits the timing convention itself, the truth's hold would leak.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import shlex
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import score  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def default_bin():
    return os.environ.get("OPTBENCH_BIN") or os.path.join(REPO, "target", "release", "optbench")


def binary_commit(binary):
    """The commit the binary was built from, as far as the checkout can tell: HEAD, marked
    when the working tree differs from it or the binary is older than HEAD's commit."""
    try:
        git = ["git", "-C", REPO]
        head = subprocess.run(git + ["rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
        dirty = subprocess.run(git + ["status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, check=True).stdout.strip()
        when = int(subprocess.run(git + ["log", "-1", "--format=%ct"], capture_output=True,
                                  text=True, check=True).stdout.strip())
    except (OSError, subprocess.CalledProcessError, ValueError):
        return None
    notes = (["with uncommitted changes"] if dirty else []) + \
        (["binary older than this commit"] if os.path.getmtime(binary) < when else [])
    return {"commit": head, "notes": notes}


def run_case(case_dir, binary, extra, force):
    out = os.path.join(case_dir, "diagnosis")
    dj = os.path.join(out, "diagnosis.json")
    wall_file = os.path.join(out, "wall_s.txt")
    if os.path.exists(dj) and not force:
        wall = float(open(wall_file).read()) if os.path.exists(wall_file) else None
        return wall, "skipped"
    os.makedirs(out, exist_ok=True)
    cmd = [binary, "diagnose", "--train", os.path.join(case_dir, "train.csv"),
           "--validate", os.path.join(case_dir, "validate.csv"), "--model", "bouc-wen-n1",
           "--columns", "t,u,y", "--hold", "zoh", "--seed", "1", "--out", out] + extra
    t0 = time.perf_counter()
    with open(os.path.join(out, "stdout.txt"), "w") as so, open(os.path.join(out, "stderr.txt"), "w") as se:
        rc = subprocess.call(cmd, stdout=so, stderr=se)
    wall = time.perf_counter() - t0
    with open(wall_file, "w") as fh:
        fh.write(f"{wall:.3f}\n")
    return wall, f"rc={rc}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", required=True)
    ap.add_argument("--jobs", type=int, default=1, help="cases at once (default 1: the tool uses both cores)")
    ap.add_argument("--optbench", default=default_bin())
    ap.add_argument("--extra-args", default="", help="extra arguments for optbench diagnose (one string)")
    ap.add_argument("--force", action="store_true")
    ap.add_argument("--score-only", action="store_true", help="only score the diagnoses that exist")
    ap.add_argument("--report", default=None)
    ap.add_argument("--json", default=None)
    ap.add_argument("--min-overall", type=float, default=None,
                    help="exit 1 if the overall exact-match rate is below this fraction (a regression guard for CI)")
    ap.add_argument("--max-false-alarms", type=int, default=None,
                    help="exit 1 if more null cases than this get a name")
    ap.add_argument("--min-oov", type=float, default=None,
                    help="exit 1 if the out-of-vocabulary pass rate is below this fraction (or there are no such cases)")
    argv = list(sys.argv[1:] if argv is None else argv)
    for i, x in enumerate(argv[:-1]):  # "--extra-args '--bootstrap 9'": a value that starts with a dash
        if x == "--extra-args":
            argv[i:i + 2] = ["--extra-args=" + argv[i + 1]]
            break
    a = ap.parse_args(argv)
    dirs = sorted(d for d in glob.glob(os.path.join(a.cases, "case-*")) if os.path.isfile(os.path.join(d, "truth.json")))
    if not dirs:
        sys.exit(f"no cases in {a.cases}")
    extra = shlex.split(a.extra_args)
    if not a.score_only:
        if not os.access(a.optbench, os.X_OK):
            sys.exit(f"optbench binary not found: {a.optbench} (build it, or pass --optbench / set OPTBENCH_BIN)")

        def one(d):
            wall, st = run_case(d, a.optbench, extra, a.force)
            named = "?"
            dj = os.path.join(d, "diagnosis", "diagnosis.json")
            if os.path.exists(dj):
                named = ",".join(score.named_set(json.load(open(dj)))) or "none"
            t = json.load(open(os.path.join(d, "truth.json")))
            truth = f"oov:{t['oov']}" if t.get("oov") else ",".join(t["effects"]) or "none"
            print(f"{os.path.basename(d)} truth={truth:28s} named={named:28s} "
                  f"{'' if wall is None else f'{wall:.1f}s'} {st}", flush=True)

        with ThreadPoolExecutor(max_workers=max(1, a.jobs)) as ex:
            list(ex.map(one, dirs))
    results = []
    for d in dirs:
        dj = os.path.join(d, "diagnosis", "diagnosis.json")
        wf = os.path.join(d, "diagnosis", "wall_s.txt")
        diag = json.load(open(dj)) if os.path.exists(dj) else None
        wall = float(open(wf).read()) if os.path.exists(wf) else (diag or {}).get("wall_s")
        results.append({"id": os.path.basename(d), "truth": json.load(open(os.path.join(d, "truth.json"))),
                        "diagnosis": diag, "wall_s": wall})
    s = score.score(results)
    if not a.score_only:
        s["binary"] = binary_commit(a.optbench)
    md = score.markdown(s)
    if a.report:
        with open(a.report, "w") as fh:
            fh.write(md)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(s, fh, indent=1)
    print(md)
    failed = []
    if any(r["diagnosis"] is None for r in results):
        failed.append("a case has no diagnosis.json (see its diagnosis/stderr.txt)")
    ov = s["overall"]
    if a.min_overall is not None and ov["k"] < a.min_overall * ov["n"]:
        failed.append(f"overall exact match {ov['k']}/{ov['n']} below {a.min_overall:.0%}")
    fa = s["nulls_false_alarm"]
    if a.max_false_alarms is not None and fa["k"] > a.max_false_alarms:
        failed.append(f"{fa['k']} false alarms on {fa['n']} null cases (allowed {a.max_false_alarms})")
    if a.min_oov is not None:
        ov = s.get("oov", {}).get("overall", {"k": 0, "n": 0})
        if ov["n"] == 0:
            failed.append("--min-oov given but no out-of-vocabulary case was scored")
        elif ov["k"] < a.min_oov * ov["n"]:
            failed.append(f"out-of-vocabulary passes {ov['k']}/{ov['n']} below {a.min_oov:.0%}")
    if failed:
        sys.exit("blind proof: " + "; ".join(failed))


if __name__ == "__main__":
    main()
