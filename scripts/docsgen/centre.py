"""Chapter 4's section without the centre, and the README's verdict on it:
suites/functions-shifted.toml (the dissertation's 2-D Griewank and Schwefel setting, as
the formula defines each function and with its minimiser moved, then moved and rotated, in
three instances each) against the ranking of the dissertation's Tables 2.3/2.4."""

from docsgen._util import markdown_table, read_json, sig, thousands
from docsgen.functions import dissertation_tables

SUITE = "suites/functions-shifted.toml"
SMALL = ["--trials", "4", "--budget", "4000"]
THREE = ["MSGA", "GA", "PSO"]                 # the dissertation's methods, its row order
FLOOR = "RS"
METHODS = THREE + [FLOOR]
HIT_TEXT = "1e-4"                             # "within 1e-4 of the global minimum"
HIT = float(HIT_TEXT)
ALPHA = 0.05
FUNCTIONS = {"griewank-2d": "Griewank", "schwefel-2d": "Schwefel"}
# An objective id is FUNCTION[-shift|-rot]-iN (suites/functions-shifted.toml).
VARIANTS = [("", "as the formula defines it"), ("-shift", "minimiser moved"),
            ("-rot", "moved and rotated")]
FRAGMENTS = ["centre-setup", "centre-table", "centre-ranking", "centre-readme"]
VOLATILE = [r'"wall_s": [0-9.e+-]+']


def variant_of(obj):
    """(function id, variant suffix, instance label) of an objective id."""
    for f in FUNCTIONS:
        if obj == f:
            return f, "", ""
        if obj.startswith(f + "-"):
            v, _, i = obj[len(f):].rpartition("-")
            return f, v, i
    raise RuntimeError(f"{SUITE}: objective {obj} is none of {list(FUNCTIONS)}")


def collect(ctx):
    out = ctx.run_suite(SUITE, small_args=SMALL)
    analysis = read_json(out / "analysis.json")
    prov = read_json(out / "provenance.json")
    cells, holm, objectives = {}, {}, []
    for o in analysis["objectives"]:
        objectives.append(o["id"])
        for cell in o["cells"]:
            st = cell["stats"]
            cells.setdefault(o["id"], {})[cell["optimizer"]] = {
                "median": st["median"], "mean": st["mean"],
                "ci": list(cell["median_ci"]), "trials": st["n"],
                "hits": sum(x <= HIT for x in cell["errors"]),
                "errors": cell["errors"]}
        holm[o["id"]] = {f"{p['a']}|{p['b']}": p["p_holm"] for p in o["pairs"]}
    return {
        "suite": {"seed": analysis["seed"], "trials": prov["trials"],
                  "threads": prov["threads"], "wall_s": prov["wall_s"],
                  "budget": analysis["objectives"][0]["budget"],
                  "objectives": objectives},
        "dissertation": {obj: {m: r["z_min"] for m, r in rows.items()}
                         for obj, rows in dissertation_tables(ctx).items()},
        "cells": cells,
        "holm": holm,
    }


def median(xs):
    s = sorted(xs)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def ordered(stats, methods):
    """Methods best first: lower median error, then more runs within HIT, then lower mean."""
    return sorted(methods, key=lambda m: (stats[m]["median"], -stats[m]["hits"],
                                          stats[m]["mean"]))


def ranking_text(order, differs):
    """`A < B ≈ C`: `<` where the neighbours differ (Holm-corrected p < ALPHA), else `≈`."""
    text = order[0]
    for a, b in zip(order, order[1:]):
        text += (" < " if differs(a, b) else " ≈ ") + b
    return text


def pooled(d, function, variant):
    """Every run of a variant, over its instances: median, mean and runs within HIT."""
    objs = [o for o in d["suite"]["objectives"] if variant_of(o)[:2] == (function, variant)]
    out = {}
    for m in METHODS:
        errors = [x for o in objs for x in d["cells"][o][m]["errors"]]
        out[m] = {"median": median(errors), "mean": sum(errors) / len(errors),
                  "hits": sum(x <= HIT for x in errors), "runs": len(errors)}
    return objs, out


def render(d):
    c, s = d["cells"], d["suite"]
    n = s["trials"]
    seed_order = {f: sorted(THREE, key=lambda m: d["dissertation"][f][m]) for f in FUNCTIONS}
    f = {}
    f["centre-setup"] = (
        f"(seed {s['seed']}, {len(s['objectives'])} objectives x {len(METHODS)} methods x {n} "
        f"trials of {thousands(s['budget'])} evaluations, {s['threads']} threads, "
        f"{s['wall_s']:.0f} s wall on this 2-core machine)")

    def cell(x):
        return f"{sig(x['median'], 2)} [{sig(x['ci'][0], 2)}, {sig(x['ci'][1], 2)}] ({x['hits']})"

    rows = []
    for obj in s["objectives"]:
        fn, v, i = variant_of(obj)
        holm = d["holm"][obj]

        def differs(a, b, holm=holm):
            return holm.get(f"{a}|{b}", holm.get(f"{b}|{a}", 1.0)) < ALPHA

        label = dict(VARIANTS)[v] + (f", instance {i[1:]}" if i else "")
        rows.append([FUNCTIONS[fn], label] + [cell(c[obj][m]) for m in METHODS]
                    + [ranking_text(ordered(c[obj], THREE), differs)])
    f["centre-table"] = (
        f"Median error to the optimum over {n} trials at {thousands(s['budget'])} evaluations, "
        f"[95 % bootstrap interval of the median] and (runs within {HIT_TEXT} of the "
        f"optimum); the ranking orders the dissertation's three methods by median, then by "
        f"runs within {HIT_TEXT}, with `<` where the two neighbours differ (Mann-Whitney, "
        f"Holm-corrected over the objective's pairs, p < {ALPHA}) and `≈` where they do not:\n\n"
        + markdown_table(["function", "variant"] + METHODS + ["ranking"], rows,
                         right=[False, False] + [True] * len(METHODS) + [False]))

    lines, verdict = [], {}
    for fn, name in FUNCTIONS.items():
        per = []
        for v, label in VARIANTS:
            objs, p = pooled(d, fn, v)
            order = ordered(p, THREE)
            per.append((v, label, order, p, len(objs)))
        verdict[fn] = per
        seed = seed_order[fn]
        lines.append(
            f"- **{name}** (the dissertation's Table {'2.3' if fn == 'griewank-2d' else '2.4'}: "
            f"{', '.join(seed)}): "
            + "; ".join(
                f"{label}"
                + (f" ({k} instances, {p[THREE[0]]['runs']} runs each)" if k > 1 else "")
                + f": {', '.join(order)} (median "
                + ", ".join(f"{m} {sig(p[m]['median'], 2)}" for m in order)
                + "; within " + HIT_TEXT + ": "
                + ", ".join(f"{m} {p[m]['hits']}/{p[m]['runs']}" for m in order) + ")"
                for v, label, order, p, k in per) + ".")
    f["centre-ranking"] = (
        "Ranking per variant, every run of its instances pooled (median error; runs within "
        f"{HIT_TEXT} of the optimum):\n\n" + "\n".join(lines))

    parts = []
    for fn, name in FUNCTIONS.items():
        seed = seed_order[fn]
        orders = [o for _, _, o, _, _ in verdict[fn]]
        plain, moved = orders[0], orders[1:]
        best = {o[0] for o in moved}
        if all(o == seed for o in orders):
            what = f"keeps the dissertation's order {', '.join(seed)} with and without the centre"
        elif all(o == plain for o in moved):
            what = (f"orders them {', '.join(plain)} as the formula defines it and the same "
                    f"with the minimiser moved and rotated (the dissertation: {', '.join(seed)})")
        else:
            what = (f"orders them {', '.join(plain)} as the formula defines it, "
                    + ", ".join(f"{', '.join(o)} {label}"
                                for (_, label, o, _, _) in verdict[fn][1:])
                    + f" (the dissertation: {', '.join(seed)})")
        best_text = (f"{next(iter(best))} is best once the centre is gone" if len(best) == 1
                     else "no method is best on every moved variant")
        parts.append(f"{name} {what}; {best_text}")
    msga_first = all(o[0] == "MSGA" for fn in FUNCTIONS for _, _, o, _, _ in verdict[fn][1:])
    f["centre-readme"] = (
        "Moving the minimiser off the centre and rotating the axes (3 instances each, "
        f"{n} runs per instance): " + "; ".join(parts) + ". The dissertation's \"MSGA is "
        "best\" " + ("survives" if msga_first else "does not survive")
        + " the move ([4. Test functions](docs/04-test-functions.md#without-the-centre)).")
    return f
