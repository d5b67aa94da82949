#!/usr/bin/env python3
"""Ask, for every pair the diagnosis got wrong, whether any search could have got it right.

  python3 scripts/blind_proof/oracle.py --cases DIR [--optbench PATH] [--report OUT.md]

Run after run.py (it reads DIR/report.json and each case's diagnosis).  For each failed
pair the tool is run again with `--effects` set to the true pair only (to
DIR/case-XXXX/oracle/): nothing else competes.  Its final model is then set against the
final model of the free search on the same records:

- not found alone: even with only the true effects offered, the tool does not name both
  (one does not pass the gate on top of the other: the data, at this size, hold no
  evidence the gate accepts);
- truth better supported: the true pair's model has lower training BIC (by more than 10)
  and lower validation RMSE: the free search missed a better model (a search error);
- named set better supported: the named model is better on both (no selection rule that
  reads these data can name the truth);
- split: the two criteria disagree, or differ by less than the margin (a tie).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from run import default_bin  # noqa: E402

MARGIN = 10.0

KINDS = ["not found alone", "truth better supported", "named set better supported", "split"]


def classify(truth, restricted_named, restricted_final, free_final):
    if sorted(restricted_named) != sorted(truth):
        return "not found alone"
    d_bic = restricted_final["bic"] - free_final["bic"]
    ratio = restricted_final["validate_rmse"] / free_final["validate_rmse"]
    if d_bic < -MARGIN and ratio < 1.0:
        return "truth better supported"
    if d_bic > MARGIN and ratio > 1.0:
        return "named set better supported"
    return "split"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cases", required=True)
    ap.add_argument("--optbench", default=default_bin())
    ap.add_argument("--report", help="write the table as Markdown here too")
    args = ap.parse_args(argv)
    report = os.path.join(args.cases, "report.json")
    if not os.path.exists(report):
        sys.exit(f"{report}: not found; run scripts/blind_proof/run.py on {args.cases} first")
    failed = json.load(open(report))["failed"]
    rows = []
    for f in failed:
        if len(f["truth"]) != 2:
            continue
        case = os.path.join(args.cases, f["id"])
        free = json.load(open(os.path.join(case, "diagnosis", "diagnosis.json")))
        out = os.path.join(case, "oracle")
        dj = os.path.join(out, "diagnosis.json")
        if not os.path.exists(dj):
            os.makedirs(out, exist_ok=True)
            cmd = [args.optbench, "diagnose", "--train", os.path.join(case, "train.csv"),
                   "--validate", os.path.join(case, "validate.csv"), "--model", "bouc-wen-n1",
                   "--columns", "t,u,y", "--hold", "zoh", "--seed", "1",
                   "--effects", ",".join(f["truth"]), "--out", out]
            rc = subprocess.call(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            if rc != 0:
                sys.exit(f"{f['id']}: optbench diagnose exited {rc}: {' '.join(cmd)}")
        res = json.load(open(dj))
        kind = classify(f["truth"], res["left_out"], res["final"], free["final"])
        rows.append((f["id"], "+".join(sorted(f["truth"])), "+".join(sorted(res["left_out"])) or "nothing",
                     "+".join(sorted(free["left_out"])) or "nothing",
                     res["final"]["bic"] - free["final"]["bic"],
                     res["final"]["validate_rmse"] / free["final"]["validate_rmse"], kind))
    lines = ["| case | truth | named, truth only offered | named, free search | ΔBIC (truth-only - free) | validation RMSE ratio | verdict |",
             "|---|---|---|---|---:|---:|---|"]
    for r in rows:
        lines.append(f"| {r[0]} | {r[1]} | {r[2]} | {r[3]} | {r[4]:.0f} | {r[5]:.3f} | {r[6]} |")
    counts = {k: sum(r[6] == k for r in rows) for k in KINDS}
    lines.append("")
    lines.append("Failed pairs: " + str(len(rows)) + "; " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    text = "\n".join(lines)
    print(text)
    if args.report:
        with open(args.report, "w") as fh:
            fh.write(text + "\n")


if __name__ == "__main__":
    main()
