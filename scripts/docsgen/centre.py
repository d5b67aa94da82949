"""Chapter 4's section without the centre, and the README's verdict on it:
suites/functions-shifted.toml (the dissertation's 2-D Griewank and Schwefel setting, as
the formula defines each function and with its minimiser moved, then moved and rotated, in
three instances each) against the ranking of the dissertation's Tables 2.3/2.4."""

import resource

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
FIGURE = "convergence_griewank-2d-shift-i1.png"
FRAGMENTS = ["centre-setup", "centre-table", "centre-ranking", "centre-readme"]
VOLATILE = [r'"wall_s": [0-9.e+-]+', r'"cpu_s": [0-9.e+-]+']


def variant_of(obj):
    """(function id, variant suffix, instance label) of an objective id."""
    for f in FUNCTIONS:
        if obj == f:
            return f, "", ""
        if obj.startswith(f + "-"):
            v, _, i = obj[len(f):].rpartition("-")
            return f, v, i
    raise RuntimeError(f"{SUITE}: objective {obj} is none of {list(FUNCTIONS)}")


def children_cpu():
    """Processor seconds of this process's finished children (the optbench runs)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def collect(ctx):
    # The processor time beside the wall time: on a busy machine the wall time says little.
    reused = SUITE in ctx.reuse and not ctx.small
    cpu0 = children_cpu()
    out = ctx.run_suite(SUITE, small_args=SMALL)
    cpu = None if reused else children_cpu() - cpu0
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
                  "threads": prov["threads"], "wall_s": prov["wall_s"], "cpu_s": cpu,
                  "budget": analysis["objectives"][0]["budget"],
                  "objectives": objectives},
        "dissertation": {obj: {m: r["z_min"] for m, r in rows.items()}
                         for obj, rows in dissertation_tables(ctx).items()},
        "cells": cells,
        "holm": holm,
        "figures": {FIGURE: ctx.figure(out / "plots" / FIGURE, FIGURE)},
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
        f"trials of {thousands(s['budget'])} evaluations: {s['wall_s']:.0f} s wall with "
        f"{s['threads']} threads on this 2-core machine"
        + (f", for {s['cpu_s']:.0f} s of processor time" if s["cpu_s"] is not None else "")
        + ")")

    def cell(x):
        return f"{sig(x['median'], 2)} [{sig(x['ci'][0], 2)}, {sig(x['ci'][1], 2)}] ({x['hits']})"

    ranking = {}   # objective -> ranking text of the dissertation's three
    rows = []
    for obj in s["objectives"]:
        fn, v, i = variant_of(obj)
        holm = d["holm"][obj]

        def differs(a, b, holm=holm):
            return holm.get(f"{a}|{b}", holm.get(f"{b}|{a}", 1.0)) < ALPHA

        ranking[obj] = ranking_text(ordered(c[obj], THREE), differs)
        label = dict(VARIANTS)[v] + (f", instance {i[1:]}" if i else "")
        rows.append([FUNCTIONS[fn], label] + [cell(c[obj][m]) for m in METHODS]
                    + [ranking[obj]])
    f["centre-table"] = (
        f"Median error to the optimum over {n} trials at {thousands(s['budget'])} evaluations, "
        f"[95 % bootstrap interval of the median] and (runs within {HIT_TEXT} of the "
        f"optimum); the ranking orders the dissertation's three methods by median, then by "
        f"runs within {HIT_TEXT}, with `<` where the two neighbours differ (Mann-Whitney, "
        f"Holm-corrected over the objective's pairs, p < {ALPHA}) and `≈` where they do not:\n\n"
        + markdown_table(["function", "variant"] + METHODS + ["ranking"], rows,
                         right=[False, False] + [True] * len(METHODS) + [False]))

    lines, pools = [], {}
    for fn, name in FUNCTIONS.items():
        parts = []
        for v, label in VARIANTS:
            objs, p = pooled(d, fn, v)
            pools[fn, v] = p
            order = ordered(p, THREE)
            runs = p[THREE[0]]["runs"]
            parts.append(
                f"{label}" + (f" ({len(objs)} instances, {runs} runs)" if len(objs) > 1 else "")
                + ": " + ", ".join(f"{m} {sig(p[m]['median'], 2)} ({p[m]['hits']}/{runs})"
                                   for m in order))
        lines.append(f"- **{name}** (the dissertation's Table "
                     f"{'2.3' if fn == 'griewank-2d' else '2.4'}: {', '.join(seed_order[fn])}): "
                     + "; ".join(parts) + ".")
    f["centre-ranking"] = (
        "Every run of a variant's instances pooled, best median first (median error; runs "
        f"within {HIT_TEXT} of the optimum):\n\n" + "\n".join(lines))

    moved = [o for o in s["objectives"] if variant_of(o)[1]]
    counts = {}
    for o in moved:
        counts[ranking[o]] = counts.get(ranking[o], 0) + 1
    common = sorted(counts.items(), key=lambda t: -t[1])
    msga_first = sum(ranking[o].startswith("MSGA") for o in moved)
    seeds = {", ".join(o) for o in seed_order.values()}
    seed_text = " and ".join(sorted(seeds))
    if len(common) == 1:
        moved_text = f"the ranking is {common[0][0]} on all {len(moved)}"
    else:
        moved_text = "the rankings are " + ", ".join(f"{r} on {k}" for r, k in common)
    plain = ", ".join(f"{FUNCTIONS[fn]} {ranking[fn]}" for fn in FUNCTIONS)
    ga = {fn: [pools[fn, v]["GA"]["median"] for v, _ in VARIANTS] for fn in FUNCTIONS}
    g, w = ga["griewank-2d"], ga["schwefel-2d"]
    # Griewank's minimiser leaves the centre, Schwefel's comes in from near the corner.
    centre_pull = min(g[1:]) > g[0] and max(w[1:]) < w[0]
    f["centre-readme"] = (
        f"Without the centre the dissertation's ranking ({seed_text}) does not come back"
        + ("" if msga_first == 0 else f" except on {msga_first}")
        + f": on {len(moved)} instances of 2-D Griewank and Schwefel with the minimiser "
        f"moved, or moved and rotated ({n} runs each), {moved_text} (`<`: Holm p < {ALPHA}; "
        f"the functions as defined: {plain}). GA's median error"
        + (", as a pull toward the centre would have it," if centre_pull else "")
        + f" goes from {sig(g[0], 2)} on Griewank as defined to {sig(g[1], 2)} moved and "
        f"{sig(g[2], 2)} rotated, and on Schwefel, whose minimiser the move brings in from "
        f"near the corner, from {sig(w[0], 2)} to {sig(w[1], 2)} and {sig(w[2], 2)} "
        "([4. Test functions](docs/04-test-functions.md#without-the-centre)).")
    return f
