"""Chapter 5's several-record fit on the twin: the 1 Hz run and the same run cut at 0.7 s
(mid-loop) and shifted by 0.03 mm, validated on the chirp cut at 2.3 s and shifted by
-0.02 mm; fitted with CMA-ES with and without initial states, and with MSGA at its
default budget."""

import csv

from docsgen._util import read_json, sig, thousands

FRAGMENTS = ["multirecord-fit"]
VOLATILE = []
CUT = {"rec2": ("sine-1hz.csv", 0.7, 0.03), "val": ("validation-chirp-10-1hz.csv", 2.3, -0.02)}


def cut(src, dst, t0, dy):
    """The record from `t0` on, its output shifted by `dy`: a run joined mid-loop."""
    with open(src, newline="") as f:
        rows = list(csv.reader(f))
    h = rows[0]
    ti, yi = h.index("t_s"), h.index("y_mm")
    out = [h] + [[*r[:yi], repr(float(r[yi]) + dy), *r[yi + 1:]]
                 for r in rows[1:] if float(r[ti]) >= t0 - 1e-12]
    with open(dst, "w", newline="") as f:
        csv.writer(f).writerows(out)


def fit(ctx, name, args):
    out = ctx.scratch / f"multirecord-{name}"
    ctx.optbench("fit", "--train", ctx.scratch / "mr-twin" / "sine-1hz.csv",
                 "--train", ctx.scratch / "rec2.csv", "--validate", ctx.scratch / "val.csv",
                 "--columns", "t_s,u_V,y_mm", "--model", "bouc-wen", "--model-param", "d0=true",
                 *args, "--out", out)
    d = read_json(out / "fit.json")
    m = {x["name"]: x["value"] for x in d["metrics"]}
    p = {k: v for k, v in d["params"]}
    return {"train": [m["train1 RMSE [mm]"], m["train2 RMSE [mm]"]],
            "validate": m["validate RMSE [mm]"], "budget": d["budget"],
            "d0": [p["d0 [mm]"], p["d0@2 [mm]"]],
            "validate_d0": next(v for k, v in p.items() if k.startswith("validate")
                                and " d0 " in k)}


def collect(ctx):
    ctx.optbench("simulate", "--columns", "t_s,u_V,y_mm", "--out", ctx.scratch / "mr-twin")
    for name, (src, t0, dy) in CUT.items():
        cut(ctx.scratch / "mr-twin" / src, ctx.scratch / f"{name}.csv", t0, dy)
    small = ["--budget", "3000"] if ctx.small else []
    return {
        "cmaes": fit(ctx, "cmaes", ["--optimizer", "cmaes",
                                    *(small or ["--budget", "100000"])]),
        "cmaes_rest": fit(ctx, "cmaes-rest", ["--optimizer", "cmaes", "--model-param", "h0=false",
                                              *(small or ["--budget", "100000"])]),
        "msga": fit(ctx, "msga", ["--optimizer", "msga", *small]),
    }


def render(d):
    c, r, g = d["cmaes"], d["cmaes_rest"], d["msga"]

    def um(x):
        return sig(1000 * x, 2)

    return {"multirecord-fit": (
        f"train RMSE {um(c['train'][0])} and {um(c['train'][1])} um (the 0.3 um sensor "
        f"noise), offsets {sig(c['d0'][1] - c['d0'][0], 3)} mm apart, the chirp's refitted "
        f"offset {sig(c['validate_d0'] - c['d0'][0], 3)} mm from the first record's, chirp "
        f"RMSE {um(c['validate'])} um ({thousands(c['budget'])} evaluations); from rest "
        f"(`h0=false`) {um(r['train'][0])} and {um(r['train'][1])} um. The two extra "
        f"dimensions make the search harder: MSGA at its default {thousands(g['budget'])} "
        f"evaluations stops at {um(g['train'][0])} and {um(g['train'][1])} um there")}
