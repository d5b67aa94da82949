"""Chapter 6, extended Table 3.4: suites/models.toml (Bouc-Wen, the RBF network and the
Prandtl-Ishlinskii operator models on the twin at 1 and 28 Hz and on the P-885 stack)."""

import json
import statistics

from docsgen._util import markdown_table, read_json, sig, thousands

SUITE = "suites/models.toml"
SMALL = ["--trials", "2", "--budget", "1500"]
FRAGMENTS = [
    "models-setup", "models-tables", "models-optimum", "models-claims", "readme-models",
]
VOLATILE = [r'"wall_s": [0-9.e+-]+']

MODELS = [("bw", "Bouc-Wen"), ("rbf", "RBF 3-7-1"), ("pi-plain", "PI plain"),
          ("pi-asym", "PI asymmetric"), ("pi-rate", "PI rate-dependent"),
          ("preisach", "Preisach 10 levels")]
SETS = [("1hz", "twin, fitted at 1 Hz", "mm"), ("28hz", "twin, fitted at 28 Hz", "mm"),
        ("p885", "P-885 stack", "um")]
OPTIMIZERS = ["MSGA", "CMA-ES"]
TIE = 0.05  # held-out errors this close (relative) read "as good as"


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
            where = "P-885 stack" if key == "p885" else f"twin {key[:-2]} Hz"
            rows.append([f"{label}, {where}",
                         *[shown(f"{model}-{key}:{o}", f"train RMSE above the optimum [{unit}]")
                           for o in OPTIMIZERS]])
    f["models-optimum"] = markdown_table(["operator fit (RMSE above the optimum, mm or um)",
                                          *OPTIMIZERS], rows)

    tr = {(m, k): med(f"{m}-{k}:CMA-ES", metric_names(m, u)[0]) for m, _ in MODELS
          for k, _, u in SETS}
    va = {(m, k): med(f"{m}-{k}:CMA-ES", metric_names(m, u)[1]) for m, _ in MODELS
          for k, _, u in SETS}
    pis = [m for m, _ in MODELS if m.startswith("pi-")]
    best_pi = {k: min(pis, key=lambda m: va[(m, k)]) for k, _, _ in SETS}
    label = dict(MODELS)

    def versus(a, b):
        """How held-out error `a` compares with `b`: within TIE of it counts as a tie."""
        if abs(a - b) <= TIE * b:
            return "as good as"
        return f"{a / b:.1f} times worse than" if a > b else f"{b / a:.1f} times better than"

    above = {(m, k, o): med(f"{m}-{k}:{o}", f"train RMSE above the optimum [{u}]")
             for m in pis for k, _, u in SETS for o in OPTIMIZERS}
    ms_worst = {k: max(above[(m, k, "MSGA")] for m in pis) for k, _, _ in SETS}
    exact = [m for m in pis if all(above[(m, k, "CMA-ES")] < 1e-9 for k, _, _ in SETS)]
    rbf_never = all(va[("rbf", k)] > min(va[(m, k)] for m in ["bw"] + pis) for k, _, _ in SETS)
    b1, b28 = best_pi["1hz"], best_pi["28hz"]
    where = {"1hz": "the twin at 1 Hz", "28hz": "the twin at 28 Hz", "p885": "the P-885 stack"}
    wins = [where[k] for k, _, _ in SETS if va[("bw", k)] < (1 - TIE) * va[(best_pi[k], k)]]
    loses = [where[k] for k, _, _ in SETS if where[k] not in wins]
    f["readme-models"] = (
        "Beside the operator models the dissertation set aside (extended Table 3.4, "
        "held-out free-run RMSE, CMA-ES medians), Bouc-Wen is the better model "
        f"{'on ' + ' and '.join(wins) if wins else 'nowhere'}"
        + (f", not on {' or '.join(loses)}" if loses else "")
        + f": on the measured P-885 stack a plain Prandtl-Ishlinskii model "
        f"({sig(va[('pi-plain', 'p885')])} um) is "
        f"{versus(va[('pi-plain', 'p885')], va[('bw', 'p885')])} Bouc-Wen "
        f"({sig(va[('bw', 'p885')])} um), the RBF network run free "
        f"{sig(va[('rbf', 'p885')])} um and a 10-level Preisach model "
        f"{sig(va[('preisach', 'p885')])} um"
    )
    f["models-claims"] = " ".join([
        "Held-out errors with CMA-ES (medians): on the twin at 1 Hz the best PI form "
        f"({label[b1]}, {sig(va[(b1, '1hz')])} mm) is {versus(va[(b1, '1hz')], va[('bw', '1hz')])} "
        f"Bouc-Wen ({sig(va[('bw', '1hz')])} mm); at 28 Hz the best ({label[b28]}, "
        f"{sig(va[(b28, '28hz')])} mm) is {versus(va[(b28, '28hz')], va[('bw', '28hz')])} "
        f"Bouc-Wen ({sig(va[('bw', '28hz')])} mm). The twin is a Bouc-Wen actuator with a "
        "structural mode, so Bouc-Wen has the right structure there by construction.",
        f"On the measured P-885 stack PI plain ({sig(va[('pi-plain', 'p885')])} um held-out, "
        f"{sig(tr[('pi-plain', 'p885')])} um in training, 11 parameters) is "
        f"{versus(va[('pi-plain', 'p885')], va[('bw', 'p885')])} Bouc-Wen with its offset "
        f"({sig(va[('bw', 'p885')])} um, {sig(tr[('bw', 'p885')])} um in training); the "
        "asymmetric and rate-dependent forms fit the training run closer "
        f"({sig(tr[('pi-asym', 'p885')])} and {sig(tr[('pi-rate', 'p885')])} um) but do worse "
        f"held-out ({sig(va[('pi-asym', 'p885')])} and {sig(va[('pi-rate', 'p885')])} um)"
        + (", and the RBF network, run free, is nowhere the best held-out model "
           f"(P-885: {sig(va[('rbf', 'p885')])} um)." if rbf_never else "."),
        f"So the dissertation's preference for Bouc-Wen over operator models is borne out "
        f"{'on ' + ' and '.join(wins) if wins else 'nowhere'} (held-out, CMA-ES)"
        + (f", not on {' or '.join(loses)}" if loses else "")
        + "; on the real stack a plain PI model, whose best weights are one non-negative "
        "least-squares solve instead of a search, predicts the held-out record "
        + {"as good as": "as well as"}.get(v := versus(va[("pi-plain", "p885")],
                                                        va[("bw", "p885")]), v) + " Bouc-Wen.",
        "A Preisach model on a 10-level relay grid (56 coefficients, CMA-ES) predicts the "
        f"held-out records with {sig(va[('preisach', '1hz')])} mm (twin, 1 Hz), "
        f"{sig(va[('preisach', '28hz')])} mm (28 Hz) and {sig(va[('preisach', 'p885')])} um "
        f"(stack): {versus(va[('preisach', 'p885')], va[(best_pi['p885'], 'p885')])} the best "
        "PI form on the stack. Its output is a staircase that moves only where the input "
        "crosses one of its 10 thresholds, so the grid caps its accuracy (chapter 5); CMA-ES "
        "ends "
        f"{sig(med('preisach-p885:CMA-ES', 'train RMSE above the optimum [um]'))} um above its "
        "exact optimum on the stack.",
        "The optimizer matters more than the model here: CMA-ES ends at the exact optimum "
        f"to rounding on the {' and '.join(label[m].split(' ', 1)[1] for m in exact)} "
        "forms, while the dissertation's MSGA ends up to "
        f"{sig(ms_worst['p885'])} um above it on the stack ({sig(ms_worst['1hz'])} mm on the "
        "twin at 1 Hz); on the stack its median curve is still descending at the end of the "
        "budget (the suite's convergence plots), from a coefficient box (`coefficient_bound`) "
        "whose random points are orders of magnitude off: its PI numbers measure the search, "
        "not the model.",
    ])
    return f
