"""Chapter 8's figures of the method, each from `optbench diagnose` on a real recording (the
PI P-885 stack): the judging rule (the validation residual with the lead and the forecast
origins), the core chosen by the data (each core's final model on the validation record)
and the structure outside the vocabulary (the residual against the feature it depends on
most), from the identification sine against the ramped test record; the creep/drift
evidence (the residual over the drive's holds) from the test record as training, the one
real record with holds, against the identification sine. Needs the data folder."""

from docsgen._util import read_json, sig

FOLDER = "pea_p885_dbo"
IDENT, TEST = "dbo_identification_1Hz_sine.csv", "dbo_test_ramped_sine_with_holds.csv"
COMMON = ["--columns", "t_s,u_V,y_um", "--trim-start", "1"]
# The step figure needs no core search: Bouc-Wen pinned keeps that run short.
RUNS = {
    "main": ([IDENT, TEST], []),
    "steps": ([TEST, IDENT], ["--model", "bouc-wen"]),
}
SMALL = ["--model", "bouc-wen-n1", "--effects", "delay", "--bootstrap", "2"]
# docs/figures name: (run, the figure diagnose writes)
FIGURES = {
    "method_judging.png": ("main", "validate_residual_time.png"),
    "method_steps.png": ("steps", "train_steps.png"),
    "method_cores.png": ("main", "validate_cores.png"),
    "method_unexplained.png": ("main", "validate_unexplained.png"),
}
FRAGMENTS = ["method-figure-judging", "method-figure-steps", "method-figure-cores",
             "method-figure-unexplained"]
# Written only by the full run (the small one searches no other core).
FULL_ONLY = ["cores", "unexplained"]
VOLATILE = []


def collect(ctx):
    base = ctx.need_data(FOLDER)
    d = {}
    for rid, ((train, validate), extra) in RUNS.items():
        out = ctx.scratch / f"method-{rid}"
        ctx.optbench("diagnose", "--train", base / train, "--validate", base / validate,
                     *COMMON, *extra, "--out", out, *(SMALL if ctx.small else []))
        d[rid] = (out, read_json(out / "diagnosis.json"))

    def figure(name):
        rid, src = FIGURES[name]
        return ctx.figure(d[rid][0] / src, name)

    out, m = d["main"]
    j = m["validation_judging"][0]
    data = {
        "judging": {
            "samples": j["samples"], "scored": j["scored"], "dt": m["sampling_intervals_s"][1],
            "baseline": m["baseline"]["validate_rmse"], "final": m["final"]["validate_rmse"],
            "final_model": m["final"]["model"], "unit": m["unit"],
            "figure": figure("method_judging.png"),
        },
    }
    _, s = d["steps"]
    ev = s["step_evidence"]
    data["steps"] = {
        "holds": ev["holds"],
        "verdicts": {k: (ev[k]["verdict"] if ev.get(k) else "too few holds")
                     for k in ("baseline", "final")},
        "figure": figure("method_steps.png"),
    }
    c = m.get("core_choice")
    if c and len(c["trials"]) > 1:
        data["cores"] = {
            "trials": [{"core": t["core"], "model": t["model"], "rmse": t["validate_rmse"],
                        "chosen": t["chosen"]} for t in c["trials"]],
            "band": c["trials"][0]["validate_band"],
            "figure": figure("method_cores.png"),
        }
    o = m.get("outside_vocabulary")
    if o and (out / "validate_unexplained.png").exists():
        top = (o["depends_on"] or o["ranked"])[0]
        data["unexplained"] = {
            "feature": top["feature"], "gain": top["gain"], "band": top["gain_band"],
            "predicts": o["predicts"], "figure": figure("method_unexplained.png"),
        }
    return data


def render(d):
    f = {}
    j = d["judging"]
    u = j["unit"]
    lead = j["samples"] - j["scored"]
    f["method-figure-judging"] = (
        "![P-885 validation residual over time, the lead shaded and the forecast origins "
        "marked](figures/method_judging.png)\n\n"
        f"*P-885, the identification sine against the ramped test record (`optbench "
        f"diagnose`, `validate_residual_time.png`): the residual (measured − model) of the "
        f"baseline and of the final model `{j['final_model']}` on the test record, whose "
        f"first {lead} samples ({sig(lead * j['dt'])} s, shaded) are the lead, fitted and "
        f"never scored, and whose {j['scored']} samples from the first dashed forecast origin "
        f"on are each predicted from the samples before their origin, to "
        f"{sig(j['final'])} {u} RMS (baseline {sig(j['baseline'])} {u}).*")
    s = d["steps"]
    n = s["holds"]
    v = s["verdicts"]
    holds = "one hold" if n == 1 else f"{n} holds"
    verdict = (f"too few for a verdict, so both residuals are shown as points without the "
               f"correlation's line" if v["baseline"] == v["final"] == "too few holds"
               else f"the baseline's residual {v['baseline']}, the final model's {v['final']}")
    f["method-figure-steps"] = (
        "![P-885 residual change over each hold of the drive against the move before "
        "it](figures/method_steps.png)\n\n"
        f"*P-885 with the roles swapped, the ramped test record as training (`train_steps.png`; "
        f"the identification sine has no holds): the test drive has {holds} the rule counts "
        f"(the other is reached by a move under a tenth of the range), {verdict}.*")
    if "cores" in d:
        c = d["cores"]
        kept = next(t for t in c["trials"] if t["chosen"])
        others = ", ".join(f"`{t['model']}` {sig(t['rmse'])} {u}"
                           for t in c["trials"] if not t["chosen"])
        f["method-figure-cores"] = (
            "![P-885 each core's final model predicting the validation record: residual RMS "
            "over time per core](figures/method_cores.png)\n\n"
            f"*P-885, the same run (`validate_cores.png`): the residual RMS over time of each "
            f"core's final model on the test record, where `{kept['model']}` (kept, "
            f"{sig(kept['rmse'])} {u}) stays below the others ({others}) after the lead, "
            f"below Bouc-Wen's band ({sig(c['band'][0])}-{sig(c['band'][1])} {u}).*")
    if "unexplained" in d:
        x = d["unexplained"]
        pct = lambda v: f"{100 * v:.0f} %"   # noqa: E731
        f["method-figure-unexplained"] = (
            "![P-885 final residual against the feature it depends on most, binned, on "
            "training and validation, with the correction fitted on "
            "training](figures/method_unexplained.png)\n\n"
            f"*P-885, the same run (`validate_unexplained.png`): the final residual binned by "
            f"the {x['feature']}, the feature it depends on most, and the correction fitted "
            f"on training, which removes {pct(x['gain'])} of the validation mean square alone "
            f"(95 % {pct(x['band'][0])} to {pct(x['band'][1])}): "
            + ("it predicts the held-out record." if x["predicts"] else
               "the band reaches zero, so it does not predict the held-out record and no "
               "dependence is claimed.") + "*")
    return f
