"""Chapter 6, extended Table 3.4: suites/models.toml (Bouc-Wen, the RBF network and the
Prandtl-Ishlinskii operator models on the twin at 1 and 28 Hz and on the P-885 stack)."""

import json
import statistics

from docsgen._util import markdown_table, read_json, sig, thousands

SUITE = "suites/models.toml"
SMALL = ["--trials", "2", "--budget", "1500"]
FRAGMENTS = ["models-setup", "models-tables", "models-optimum", "models-claims"]
VOLATILE = [r'"wall_s": [0-9.e+-]+']

MODELS = [("bw", "Bouc-Wen"), ("rbf", "RBF 3-7-1"), ("pi-plain", "PI plain"),
          ("pi-asym", "PI asymmetric"), ("pi-rate", "PI rate-dependent")]
SETS = [("1hz", "twin, fitted at 1 Hz", "mm"), ("28hz", "twin, fitted at 28 Hz", "mm"),
        ("p885", "P-885 stack", "um")]
OPTIMIZERS = ["MSGA", "CMA-ES"]


def metric_names(model, unit):
    """(training, validation) free-run RMSE metric names of a model."""
    if model == "rbf":
        return f"train free-run RMSE [{unit}]", f"validate free-run RMSE [{unit}]"
    return f"train RMSE [{unit}]", f"validate RMSE [{unit}]"


def collect(ctx):
    ctx.need_data("pea_p885_dbo", "dbo_identification_1Hz_sine.csv")
    out = ctx.run_suite(SUITE, small_args=SMALL)
    prov = read_json(out / "provenance.json")
    analysis = read_json(out / "analysis.json")
    walls = {}
    for line in (out / "traces.jsonl").read_text().splitlines():
        r = json.loads(line)
        walls.setdefault(f"{r['objective']}:{r['optimizer']}", []).append(r["wall_s"])
    cells = {}
    for o in analysis["objectives"]:
        for c in o["cells"]:
            key = f"{o['id']}:{c['optimizer']}"
            cells[key] = {
                "dim": o["dim"],
                "wall_s": statistics.median(walls[key]),
                "metrics": {m["name"]: {"median": m["stats"]["median"], "ci": m["median_ci"]}
                            for m in c["metrics"]},
            }
    return {
        "suite": {"seed": analysis["seed"], "trials": prov["trials"], "wall_s": prov["wall_s"],
                  "budget": analysis["objectives"][0]["budget"]},
        "cells": cells,
    }


def render(d):
    c = d["cells"]

    def med(cell, metric):
        return c[cell]["metrics"][metric]["median"]

    def shown(cell, metric):
        m = c[cell]["metrics"][metric]
        lo, hi = m["ci"]
        return f"{sig(m['median'])} [{sig(lo)}, {sig(hi)}]"

    f = {}
    s = d["suite"]
    f["models-setup"] = (f"{s['trials']} trials per cell, {thousands(s['budget'])} evaluations "
                         f"each, seed {s['seed']}; {s['wall_s'] / 60:.0f} min wall for the "
                         "whole suite in this generation on 2 shared cores")
    tables = []
    for key, title, unit in SETS:
        rows = []
        for model, label in MODELS:
            tr, va = metric_names(model, unit)
            for opt in OPTIMIZERS:
                cell = f"{model}-{key}:{opt}"
                rows.append([f"{label}, {opt}", str(c[cell]["dim"]), shown(cell, tr),
                             shown(cell, va), sig(c[cell]["wall_s"], 2)])
        tables.append(f"**{title}** (free-run RMSE [{unit}], median [95% CI] over trials; "
                      "fit time: median wall seconds of one trial)\n\n"
                      + markdown_table(["model, optimizer", "parameters", "train RMSE",
                                        "validation RMSE", "fit time [s]"], rows))
    f["models-tables"] = "\n\n".join(tables)
    rows = []
    for key, title, unit in SETS:
        for model, label in MODELS[2:]:
            rows.append([f"{label}, {title.split(',')[0]}{'' if key == 'p885' else ' ' + key}",
                         *[shown(f"{model}-{key}:{o}", f"train RMSE above the optimum [{unit}]")
                           for o in OPTIMIZERS]])
    f["models-optimum"] = markdown_table(["PI fit (RMSE above the optimum, mm or um)",
                                          *OPTIMIZERS], rows)

    tr = {(m, k): med(f"{m}-{k}:CMA-ES", metric_names(m, u)[0]) for m, _ in MODELS
          for k, _, u in SETS}
    va = {(m, k): med(f"{m}-{k}:CMA-ES", metric_names(m, u)[1]) for m, _ in MODELS
          for k, _, u in SETS}
    pis = [m for m, _ in MODELS[2:]]
    best_pi = {k: min(pis, key=lambda m: va[(m, k)]) for k, _, _ in SETS}
    label = dict(MODELS)
    ms = {k: max(med(f"{m}-{k}:MSGA", f"train RMSE above the optimum [{u}]") for m in pis)
          for k, _, u in SETS}
    f["models-claims"] = " ".join([
        "With CMA-ES (medians): on the twin at 1 Hz Bouc-Wen fits best, training "
        f"{sig(tr[('bw', '1hz')])} mm and held-out {sig(va[('bw', '1hz')])} mm, against "
        f"{sig(va[(best_pi['1hz'], '1hz')])} mm held-out for the best PI form "
        f"({label[best_pi['1hz']]}); at 28 Hz Bouc-Wen's held-out error is "
        f"{sig(va[('bw', '28hz')])} mm and the best PI form's "
        f"{sig(va[(best_pi['28hz'], '28hz')])} mm. The twin is a Bouc-Wen actuator with "
        "rate effects, so Bouc-Wen has the right structure there by construction.",
        "On the real P-885 stack the ranking is not Bouc-Wen's: PI plain reaches "
        f"{sig(tr[('pi-plain', 'p885')])} um in training and {sig(va[('pi-plain', 'p885')])} "
        f"um held-out with 11 parameters, Bouc-Wen with its offset {sig(tr[('bw', 'p885')])} "
        f"and {sig(va[('bw', 'p885')])} um, the RBF network {sig(tr[('rbf', 'p885')])} and "
        f"{sig(va[('rbf', 'p885')])} um in free run; the asymmetric and rate-dependent PI "
        f"forms fit the training run closer ({sig(tr[('pi-asym', 'p885')])} and "
        f"{sig(tr[('pi-rate', 'p885')])} um) but generalise worse "
        f"({sig(va[('pi-asym', 'p885')])} and {sig(va[('pi-rate', 'p885')])} um held-out).",
        "So the dissertation's choice of Bouc-Wen over operator models is borne out on its own "
        "twin but not on this measured stack, where a plain PI model fitted exactly by "
        "least squares (no search needed) is as good on held-out data as the best Bouc-Wen "
        "fit. What the dissertation's method choice hides: MSGA, its optimizer, stays far "
        f"from the PI optimum (up to {sig(ms['p885'])} um above it on the P-885 stack, "
        f"{sig(ms['1hz'])} mm on the twin at 1 Hz), while CMA-ES reaches it to rounding on "
        "the plain and asymmetric forms: on a convex fitting problem the choice of "
        "optimizer, not of model, decides the error a GA-family method reports.",
    ])
    return f
