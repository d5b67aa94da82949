"""Chapter 12: suites/control.toml (Table 4.1 and section 4.2.1 on the twin), its pairwise
table, and two single `optbench control` runs the chapter quotes."""

import json
import math
import statistics
import tomllib

from docsgen._util import first_table, parse_table, read_json, sig

SUITE = "suites/control.toml"
SMALL = ["--trials", "3", "--budget", "750"]
FIGURES = {   # docs/figures name: the suite's figure (trial 0 of the cell)
    "control_imc_1-2hz_time.png": "IMC-RBF_twin_sweep-1-2hz_time.png",
    "control_imc_1-2hz_compensation.png": "IMC-RBF_twin_sweep-1-2hz_compensation.png",
    "control_pid_1-2hz_compensation.png": "PID-tuned_twin_sweep-1-2hz_compensation.png",
}
REFS = ["sweep-1-2hz", "sweep-1-3hz", "sweep-1-4hz", "sweep-1-10hz"]
FRAGMENTS = [
    "control-failed-run", "control-setup", "control-section421", "control-table41",
    "control-steady", "control-pairwise", "control-claims", "control-stability",
    "control-table41-ff", "control-ff", "readme-ff",
]
FF = ["FF-PI", "FF-BW", "FF-PI-PID", "FF-BW-PID"]   # the suite's feedforward controllers
VOLATILE = [r'"wall_s": [0-9.e+-]+']
# `optbench control` runs the chapter quotes: a failed run, and the dissertation's PID gains
# on a twin without its bending mode.
FAILED_RUN = ["control", "--controller", "imc-rbf", "--reference",
              "sine:freq=5,amp=0.2,offset=0.3", "--duration", "3", "--model-twin", "mode=off",
              "--plant", "creep=on", "--seed", "1"]
PID_NO_MODE = ["control", "--controller", "pid", "--reference", "sweep-1-2hz", "--controller-param",
               "kp=1.0", "--controller-param", "ki=0.8", "--controller-param", "kd=0.6", "--plant", "mode=off"]


def collect(ctx):
    out = ctx.run_suite(SUITE, small_args=SMALL)
    prov = read_json(out / "provenance.json")
    suite = tomllib.loads((out / "suite.toml").read_text())
    cells = {f"{c['plant']}|{c['controller']}|{c['reference']}": {
        "median": c["rmse"]["median"], "ci": c["rmse"]["ci"], "trials": c["trials"],
        "failures": c["failures"], "fail_s": c["median_failure_s"],
        "steady": c["rmse_steady"]["median"]}
        for c in read_json(out / "summary.json")}
    report = (out / "report.md").read_text()
    pairs = parse_table(report[report.index("**Pairwise comparisons**"):])
    models = {}
    for line in (out / "models.jsonl").read_text().splitlines():
        m = json.loads(line)
        # IMC models have a fit `mode`; inverted (feedforward) models a `model` kind.
        kind = m["config"].get("model", {}).get("kind", "rbf")
        models.setdefault(str(m["setting"]), {"mode": m["config"].get("mode", kind),
                                              "twin": m["config"]["twin"], "free_run": []})
        models[str(m["setting"])]["free_run"].append(m["free_run_rmse_mm"])
    published = {}
    for t in suite.get("table", []):
        for row in t["rows"]:
            for cell, v in zip(row["cells"], row.get("seed", row.get("published", []))):
                if v == v:   # nan: no published value
                    published[cell] = v
    runs = {}
    for key, args in (("failed", FAILED_RUN), ("pid_no_mode", PID_NO_MODE)):
        d = ctx.scratch / f"control-{key}"
        r = ctx.optbench(*args, "--out", d)
        runs[key] = {"stdout": r.stdout.replace(str(d), "results/control-" + args[2]),
                     "metrics": read_json(d / "summary.json")["metrics"]}
    return {
        "suite": {"seed": suite["seed"], "trials": prov.get("trials", suite["trials"]),
                  "wall_s": prov.get("wall_s")},
        "cells": cells,
        "tables": {t: first_table((out / "tables" / f"{t}.md").read_text())
                   for t in ("section4.2.1", "table4.1", "table4.1-ff")},
        "titles": {t: (out / "tables" / f"{t}.md").read_text().split("\n\n")[0]
                   for t in ("section4.2.1", "table4.1", "table4.1-ff")},
        "pairwise_head": report[report.index("**Pairwise comparisons**"):].split("\n\n")[0],
        "pairwise_table": first_table(report[report.index("**Pairwise comparisons**"):]),
        "pairwise": pairs,
        "models": models,
        "published": published,
        "runs": runs,
        "figures": {name: ctx.figure(out / "figures" / src, name)
                    for name, src in FIGURES.items()},
    }


def render(d):
    c, n = d["cells"], d["suite"]["trials"]

    def cell(plant, ctrl, ref):
        return c[f"{plant}|{ctrl}|{ref}"]

    def pair(plant, ref, second):
        return next(p for p in d["pairwise"] if p["plant"] == plant and p["reference"] == ref
                    and p["pair"] == f"IMC-RBF vs {second}")

    def fails(plant, ctrl):
        return [cell(plant, ctrl, r)["failures"] for r in REFS]

    def hz(ref):
        return ref.replace("sweep-", "").replace("hz", " Hz")

    f = {}
    run = d["runs"]["failed"]
    f["control-failed-run"] = "```text\n" + run["stdout"].rstrip("\n") + "\n```"
    f["control-setup"] = (f"(`optbench run suites/control.toml`, seed {d['suite']['seed']}, "
                          f"{n} trials)")
    for t, fid in (("section4.2.1", "control-section421"), ("table4.1", "control-table41"),
                   ("table4.1-ff", "control-table41-ff")):
        f[fid] = d["titles"][t] + "\n\n" + d["tables"][t]
    # Table 4.1's controllers (the feedforward rows have their own paragraph).
    ratios = [cc["steady"] / cc["median"] for k, cc in c.items()
              if k.split("|")[1] not in FF and cc["median"] and cc["steady"] and cc["median"] > 0]
    f["control-steady"] = (
        f"After the first second the medians are between {100 * (1 - min(ratios)):.0f} % "
        f"lower and {100 * (max(ratios) - 1):.0f} % higher (`tables/table4.1-steady.md`).")
    f["control-pairwise"] = d["pairwise_head"] + "\n\n" + d["pairwise_table"]

    imc = {r: cell("twin", "IMC-RBF", r) for r in REFS}
    pid = {r: cell("twin", "PID-tuned", r) for r in REFS}
    seedpid = cell("twin", "PID-seed", "sweep-1-2hz")
    pt = {r: pair("twin", r, "PID-tuned") for r in REFS}
    wins = pt["sweep-1-2hz"]["first wins"]
    k, m = (int(x) for x in wins.split("/"))
    sign_p = min(1.0, 2 * sum(math.comb(m, i) for i in range(k, m + 1)) / 2 ** m)
    fixed = {r: cell("twin", "RBF-fixed-sensitivity", r) for r in REFS}
    pf = {r: pair("twin", r, "RBF-fixed-sensitivity") for r in REFS}
    floor = fails("twin", "IMC-RBF-floor")
    inst = fails("twin", "IMC-RBF-instant")
    one = {r: cell("twin", "IMC-RBF-one-step", r) for r in REFS}
    mis = {r: cell("mismatch", "IMC-RBF", r) for r in REFS}
    pub = d["published"]
    pub12 = pub["IMC-RBF/twin/sweep-1-2hz"]
    pub110 = pub["IMC-RBF/twin/sweep-1-10hz"]
    setting = {m["mode"]: m for m in d["models"].values() if m["twin"] in ("", "default")}
    one_free = statistics.median(setting["one-step"]["free_run"])
    pid_nm = d["runs"]["pid_no_mode"]["metrics"]["rmse_mm"]
    ratio = {r: float(pt[r]["ratio"]) for r in REFS}
    pw = {r: pt[r]["p (Wilcoxon)"] for r in REFS}
    pmw = {r: pt[r]["p (MW)"] for r in REFS}

    def mm(x):
        return sig(x, 2)

    f["control-claims"] = "\n".join([
        "- **IMC with two RBF networks beats incremental PID** — "
        + ("*in the median and in most trials, but not by the paired test: the IMC diverges "
           "in some trials.*" if float(pw["sweep-1-2hz"]) >= 0.05 else
           "*confirmed by the paired test at 1-2 Hz.*")
        + f" With the dissertation's gains the PID does not run at all on our twin: the 103 Hz "
        f"bending mode (damping 0.04) makes it oscillate and it diverges at "
        f"{sig(seedpid['fail_s'], 2)} s in "
        f"{'every trial' if seedpid['failures'] == seedpid['trials'] else str(seedpid['failures']) + ' trials'}"
        f" (without the mode it tracks at {mm(pid_nm)} mm: `optbench control --controller pid "
        f"--reference sweep-1-2hz --controller-param kp=1.0 --controller-param ki=0.8 --controller-param kd=0.6 --plant "
        f"mode=off`). Against a PID tuned on the twin the IMC's median RMSE is lower by "
        + ", ".join(f"{ratio[r]:.3g}x at {hz(r)}" for r in REFS)
        + f" ({sig(imc['sweep-1-10hz']['median'])} vs {sig(pid['sweep-1-10hz']['median'])} mm "
        f"at 1-10 Hz). The trials are paired (both controllers of a trial see the same noise "
        f"realisation), so the test to read is the Wilcoxon signed-rank test over the {n} "
        f"pairs: p = " + ", ".join(f"{pw[r]} at {hz(r)}" for r in REFS)
        + f". The IMC is lower in {k} of {m} pairs at 1-2 Hz (a sign test would give "
        f"p = {sig(sign_p, 2)}), but it diverges in "
        + ", ".join(f"{imc[r]['failures']}" for r in REFS[:-1])
        + f" and {imc['sweep-1-10hz']['failures']} of the {n} trials (1-2, 1-3, 1-4, 1-10 Hz), "
        "and those losses are the largest differences, so the signed-rank test "
        + ("does not call the IMC better" if float(pw["sweep-1-2hz"]) >= 0.05 else
           "still calls the IMC better")
        + ". The unpaired Mann-Whitney test, which ignores the pairing, gives p = "
        + f"{pmw['sweep-1-2hz']} (1-2 Hz) and {pmw['sweep-1-10hz']} (1-10 Hz). The "
        "compensation pictures show why the median favours the IMC: the PID's output lags "
        "the reference into a loop, the IMC's stays on the diagonal.",
        f"- **The dissertation's numbers are not reached**: {mm(imc['sweep-1-2hz']['median'])} "
        f"against {sig(pub12, 2)} mm at 1-2 Hz and {mm(imc['sweep-1-10hz']['median'])} against "
        f"{sig(pub110, 2)} mm at 1-10 Hz. On our twin no feedback loop at 1 kHz tracks a 10 Hz "
        "sinusoid to a few µm: the lightly damped 103 Hz mode caps the loop's bandwidth (the "
        "PID's integral gain must stay low, see the tuned PID in the suite), and the error at "
        "10 Hz grows with the mode's response (the dissertation itself saw oscillations at "
        "10 Hz and blamed a low resonance).",
        "- **Reliability is the cost.** The IMC diverged in "
        + ", ".join(f"{imc[r]['failures']}" for r in REFS)
        + f" of {n} trials (1-2, 1-3, 1-4, 1-10 Hz), each time because of its PSO-fitted "
        "model (a sensitivity of the wrong sign near 0 V, where the loop starts, or far too "
        "large). A floor of 0.05 mm/V on the sensitivity (a piezo extends with voltage) "
        "leaves " + ", ".join(str(x) for x in floor) + " (same order). Trained through the "
        "model's literal ∂y(k)/∂u(k) instead of its response to a held command, the loop "
        f"diverges in {min(inst)}-{max(inst)} of {n} trials. The tuned PID diverges in "
        + ("none" if not any(fails("twin", "PID-tuned")) else
           ", ".join(str(x) for x in fails("twin", "PID-tuned"))) + ".",
        "- **The internal model does not earn its place.** The controller network trained "
        "through a constant 0.15 mm/V, no model at all, tracks at "
        + ", ".join(f"{mm(fixed[r]['median'])}" for r in REFS)
        + " mm (1-2, 1-3, 1-4, 1-10 Hz; Wilcoxon against the IMC: p = "
        + ", ".join(pf[r]["p (Wilcoxon)"] for r in REFS)
        + f") and diverges in {sum(fails('twin', 'RBF-fixed-sensitivity'))} of "
        f"{n * len(REFS)} runs. What beats the PID is the online-trained controller network. "
        "Our reading of why: its weight updates with momentum β = 0.9 act like a filtered "
        "double integrator, which tracks a sinusoid with less lag than the PID's single "
        "integrator at the same stability margin.",
        "- **Mismatch**: identified without the mode and creep and run with both, the IMC "
        f"tracks at {mm(mis['sweep-1-2hz']['median'])} mm at 1-2 Hz and "
        f"{mm(mis['sweep-1-10hz']['median'])} at 1-10 Hz and diverges in "
        + ", ".join(str(mis[r]["failures"]) for r in REFS)
        + f" of {n} (1-2 ... 1-10 Hz): models fitted to the smoother mode-free twin have "
        "better-behaved sensitivities; against the tuned PID here the paired test gives p = "
        + ", ".join(pair("mismatch", r, "PID-tuned")["p (Wilcoxon)"] for r in REFS) + ".",
        f"- The dissertation's one-step model fit (Table 3.3's cost) makes a poor internal "
        f"model: its free run is off by {mm(one_free)} mm (median over {n} fits) and the loop "
        f"tracks at {mm(one['sweep-1-2hz']['median'])} mm at 1-2 Hz, "
        f"{float(pair('twin', 'sweep-1-2hz', 'IMC-RBF-one-step')['ratio']):.2g} times worse "
        "than with the free-run fit.",
    ])
    f["control-ff"] = ff_paragraph(d, cell, pair, hz)
    best = min(FF[:2], key=lambda k: cell("twin", k, "sweep-1-10hz")["median"])
    f["readme-ff"] = (
        "On the twin's 1-10 Hz sweep the "
        + {"FF-PI": "PI", "FF-BW": "Bouc-Wen"}[best]
        + f"-inverse feedforward tracks at {sig(cell('twin', best, 'sweep-1-10hz')['median'], 2)}"
        f" mm against the dissertation's IMC at "
        f"{sig(cell('twin', 'IMC-RBF', 'sweep-1-10hz')['median'], 2)} mm (medians of {n} "
        "trials); with the model identified without the creep and the mode that the plant "
        "has, the PI inverse plus integral feedback tracks at "
        f"{sig(cell('mismatch', 'FF-PI-PID', 'sweep-1-10hz')['median'], 2)} mm, the IMC at "
        f"{sig(cell('mismatch', 'IMC-RBF', 'sweep-1-10hz')['median'], 2)} mm"
    )
    f["control-stability"] = (
        "These figures move between builds: the internal models are PSO fits, and a change "
        "in the last bits of the RBF cost sends PSO down other paths. On this build the "
        f"IMC-over-PID ratio at 1-10 Hz is {ratio['sweep-1-10hz']:.3g}x with a paired "
        f"p = {pw['sweep-1-10hz']}: "
        + ("the claim at 1-10 Hz is not established." if float(pw["sweep-1-10hz"]) >= 0.05
           else "significant on this build, but earlier builds put it on either side of "
                "the 5 % line.")
        + f" The low-frequency median ratios ({ratio['sweep-1-2hz']:.3g}x at 1-2 Hz) are "
        "large, but with the divergent trials counted the paired test does not establish "
        "them either." if float(pw["sweep-1-2hz"]) >= 0.05 else "")
    return f


def ff_paragraph(d, cell, pair, hz):
    """What the feedforward rows say about the dissertation's choice of feedback IMC."""
    n = d["suite"]["trials"]

    def med(plant, ctrl, ref):
        return cell(plant, ctrl, ref)["median"]

    def row(plant, ctrl):
        return ", ".join(sig(med(plant, ctrl, r), 2) for r in REFS)

    def steady(plant, ctrl):
        return ", ".join(sig(cell(plant, ctrl, r)["steady"], 2) for r in REFS)

    def fails(plant, ctrl):
        return sum(cell(plant, ctrl, r)["failures"] for r in REFS)

    free = {m["mode"]: statistics.median(m["free_run"]) for m in d["models"].values()
            if m["twin"] in ("", "default") and m["mode"] in ("pi", "bouc-wen")}
    best_ff = min(FF[:2], key=lambda c: med("twin", c, "sweep-1-10hz"))
    r10 = med("twin", "IMC-RBF", "sweep-1-10hz") / med("twin", best_ff, "sweep-1-10hz")
    r2 = med("twin", "IMC-RBF", "sweep-1-2hz") / med("twin", best_ff, "sweep-1-2hz")
    ff_fail = sum(fails(p, c) for p in ("twin", "mismatch") for c in FF)
    p10 = pair("twin", "sweep-1-10hz", best_ff)["p (Wilcoxon)"]
    imc_better = [r for r in REFS if med("mismatch", "IMC-RBF", r)
                  < min(med("mismatch", c, r) for c in FF[:2])]
    return " ".join([
        "On the twin the feedforward controllers beat the dissertation's IMC at every "
        f"frequency: the PI inverse tracks at {row('twin', 'FF-PI')} mm and the Bouc-Wen "
        f"inverse at {row('twin', 'FF-BW')} mm (1-2, 1-3, 1-4, 1-10 Hz; medians over {n} "
        f"trials), against {row('twin', 'IMC-RBF')} mm for the IMC and "
        f"{row('twin', 'PID-tuned')} mm for the tuned PID: the best inverse is "
        f"{r2:.3g}x better than the IMC at 1-2 Hz and {r10:.3g}x at 1-10 Hz (paired "
        f"Wilcoxon p = {p10} at 1-10 Hz), and the {len(FF)} feedforward controllers "
        f"diverged in {ff_fail} of {2 * len(FF) * len(REFS) * n} runs. The models fit their "
        f"identification record to {sig(free['pi'], 2)} mm (PI) and "
        f"{sig(free['bouc-wen'], 2)} mm (Bouc-Wen) in free run (medians), and that is what "
        "the inverse tracks to; the 103 Hz mode, which caps every feedback loop here, barely "
        "enters a feedforward that does not excite it. Most of the feedforward's error is "
        "the start, where the first step excites the mode: after the first second the PI "
        f"inverse tracks at {steady('twin', 'FF-PI')} mm and the Bouc-Wen inverse at "
        f"{steady('twin', 'FF-BW')} mm.",
        "Under mismatch (models identified without the mode and creep, run with both) the "
        f"inverses alone track at {row('mismatch', 'FF-PI')} mm (PI) and "
        f"{row('mismatch', 'FF-BW')} mm (Bouc-Wen): creep is outside both models"
        + (", and there the IMC, whose feedback sees the creep, has the lower median at "
           + ", ".join(f"{hz(r)} (paired Wilcoxon p = "
                       + " and ".join(pair("mismatch", r, c)["p (Wilcoxon)"] for c in FF[:2])
                       + " against the two inverses)" for r in imc_better)
           if imc_better else "")
        + ". Integral "
        f"feedback on the error brings that to {row('mismatch', 'FF-PI-PID')} mm and "
        f"{row('mismatch', 'FF-BW-PID')} mm"
        + (", below the IMC's " if all(
            max(med("mismatch", c, r) for c in FF[2:]) < med("mismatch", "IMC-RBF", r)
            for r in REFS) else ", against the IMC's ")
        + f"{row('mismatch', 'IMC-RBF')} mm.",
        "What this says about the dissertation's choice: on this twin, feedback IMC is not "
        "what tracking needs; an inverted hysteresis model does better, and a little feedback "
        "on top handles what the model misses. Two caveats keep this from being a verdict on "
        "real actuators: the twin's hysteresis is itself a rate-independent Bouc-Wen model, "
        "exactly the structure the Bouc-Wen inverse assumes (the PI model, a different "
        "structure, does about as well), and the feedforward uses the next reference sample, "
        "which a known trajectory allows and the feedback loops do not use.",
    ])
