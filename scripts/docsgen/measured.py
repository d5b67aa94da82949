"""Chapter 6 on recorded data: suites/boucwen-benchmark.toml (the dissertation's static
models on the Bouc-Wen benchmark) and suites/mr-damper.toml (real MR-damper runs). Needs the
data folder."""

from docsgen._util import read_json, sig, thousands

BENCH, DAMPER = "suites/boucwen-benchmark.toml", "suites/mr-damper.toml"
SMALL = ["--trials", "2", "--budget", "400"]
FRAGMENTS = ["measured-benchmark", "measured-damper"]
VOLATILE = [r'"wall_s": [0-9.e+-]+']


def metrics(out):
    analysis = read_json(out / "analysis.json")
    cells = {}
    for o in analysis["objectives"]:
        for c in o["cells"]:
            cells[f"{o['id']}:{c['optimizer']}"] = {
                m["name"]: {"median": m["stats"]["median"], "max": m["stats"]["max"],
                            "ci": m["median_ci"]} for m in c["metrics"]}
    return analysis, cells


def collect(ctx):
    ctx.need_data("boucwen-benchmark", "train_multisine_forgione.csv")
    ctx.need_data("mr-damper-labcontrol")
    bench = ctx.run_suite(BENCH, small_args=SMALL)
    damper = ctx.run_suite(DAMPER, small_args=SMALL)
    ab, cb = metrics(bench)
    ad, cd = metrics(damper)
    pb, pd = read_json(bench / "provenance.json"), read_json(damper / "provenance.json")
    return {
        "bench": {"trials": pb["trials"], "budget": ab["objectives"][0]["budget"],
                  "wall_s": pb["wall_s"], "cells": cb,
                  "table": (bench / "tables" / "benchmark.md").read_text().strip("\n")},
        "damper": {"trials": pd["trials"], "budget": ad["objectives"][0]["budget"],
                   "wall_s": pd["wall_s"], "cells": cd,
                   "objectives": [o["id"] for o in ad["objectives"]]},
    }


def render(d):
    b, f = d["bench"], {}
    c = b["cells"]
    ms, sw = "test_multisine RMSE [m]", "test_sinesweep RMSE [m]"
    bw = {o: (c[f"bw-static:{o}"][ms]["median"], c[f"bw-static:{o}"][sw]["median"])
          for o in ("MSGA", "PSO", "GA")}
    rbf = {o: c[f"rbf-narx:{o}"]["test_multisine free-run RMSE [m]"]
           for o in ("MSGA", "PSO", "GA")}
    f["measured-benchmark"] = (
        f"`optbench run suites/boucwen-benchmark.toml` ({b['trials']} trials x "
        f"{thousands(b['budget'])} evaluations, one period of the training multisine; "
        f"{b['wall_s']:.0f} s wall in this generation): the dissertation's static Bouc-Wen "
        "model, force -> displacement, reaches a median free-run RMSE on the official "
        "multisine test set of "
        + ", ".join(f"{sig(v[0], 2)} m ({o})" for o, v in bw.items())
        + " and on the sine sweep of "
        + ", ".join(f"{sig(v[1], 2)} m ({o})" for o, v in bw.items())
        + ", two orders of magnitude above the best published model (the table's reference "
        "column, from the data folder's `RESULTS.md`). The 3-7-1 RBF network, trained "
        "one-step-ahead, does no better in free run (multisine: "
        + ", ".join(f"{sig(rbf[o]['median'], 2)} m ({o}, worst run {sig(rbf[o]['max'], 2)})"
                    for o in rbf)
        + "). The benchmark system is a Bouc-Wen element inside a mass-spring-damper: a "
        "static hysteresis model cannot follow its dynamics, which is the missing physics "
        "`optbench diagnose` is for ([7. Diagnosis](07-diagnosis.md), and the benchmark "
        "diagnosed in [9](09-diagnosis-real-data.md#bouc-wen-benchmark)).\n\n" + b["table"])
    dm = d["damper"]
    cd = dm["cells"]
    bws = [o for o in dm["objectives"] if o.startswith("bw-")]
    opts = ("MSGA", "PSO", "GA")

    def best(obj):
        return min(opts, key=lambda o: cd[f"{obj}:{o}"]["train RMSE [N]"]["median"])

    winners = {o: best(o) for o in bws}
    tr = [cd[f"{o}:{winners[o]}"]["train RMSE [N]"]["median"] for o in bws]
    val = [v["median"] for o in bws for k, v in cd[f"{o}:{winners[o]}"].items()
           if k.endswith("RMSE [N]") and not k.startswith("train")]
    hi = max(v["ci"][1] for o in bws for opt in opts for k, v in cd[f"{o}:{opt}"].items()
             if k.endswith("RMSE [N]") and not k.startswith("train") and v["ci"][1])
    rb = [o for o in dm["objectives"] if o.startswith("rbf-")]
    one = [v["median"] for o in rb for opt in opts for k, v in cd[f"{o}:{opt}"].items()
           if "one-step RMSE" in k and not k.startswith("train")]
    fr = [v["median"] for o in rb for opt in opts for k, v in cd[f"{o}:{opt}"].items()
          if "free-run RMSE" in k and not k.startswith("train")]
    f["measured-damper"] = (
        f"`optbench run suites/mr-damper.toml` (real MR-damper runs, position -> force, "
        f"{dm['trials']} trials x {thousands(dm['budget'])} evaluations, {dm['wall_s']:.0f} s "
        "wall): Bouc-Wen from position explains little of the force: median training RMSE "
        f"{sig(min(tr), 2)}-{sig(max(tr), 2)} N and {sig(min(val), 2)}-{sig(max(val), 2)} N "
        "on the held-out runs (of the method with the lowest training error on each of the "
        f"{len(bws)} training runs: " + ", ".join(sorted(set(winners.values()))) + "), and "
        "single fits that extrapolate badly on held-out runs (upper confidence bounds of the "
        f"held-out medians up to {sig(hi, 2)} N). A damper's force follows velocity, not "
        "position; the RBF network sees past forces and predicts one step ahead at "
        f"{sig(min(one), 2)}-{sig(max(one), 2)} N on held-out runs, but in free run it is as "
        f"poor ({sig(min(fr), 2)}-{sig(max(fr), 2)} N).")
    return f
