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
             "method-figure-unexplained", "method-core-p885"]
# Written only by the full run (the small one searches no other core).
FULL_ONLY = ["cores", "unexplained"]
VOLATILE = []


def collect(ctx):
    base = ctx.need_data(FOLDER)
    d = {}
    for rid, ((train, validate), extra) in RUNS.items():
        out = ctx.scratch / f"method-{rid}"
        ctx.optbench("diagnose", "--train", base / train, "--validate", base / validate,
                     *COMMON, *(SMALL if ctx.small else extra), "--out", out)
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
            "band": c["trials"][0]["validate_band"], "noise_floor": m["noise_floor"],
            "figure": figure("method_cores.png"),
        }
    o = m.get("outside_vocabulary")
    if o and (out / "validate_unexplained.png").exists():
        top = (o["depends_on"] or o["ranked"])[0]
        data["unexplained"] = {
            "feature": top["feature"], "gain": top["gain"], "band": top["gain_band"],
            "predicts": o["predicts"], "figure": figure("method_unexplained.png"),
            # The features of the combined correction (a spectral line not coherent with
            # the drive is listed with no gain, outside it).
            "features": [d["feature"] for d in o["depends_on"] or [] if d["gain"] > 0],
            "combined_gain": o["gain"], "combined_band": o["gain_band"],
        }
    return data


def render(d):
    f = {}
    j = d["judging"]
    u = j["unit"].replace("um", "µm")
    lead = j["samples"] - j["scored"]
    f["method-figure-judging"] = (
        "![P-885 validation residual over time, the lead shaded and the forecast origins "
        "marked](figures/method_judging.png)\n\n"
        "*P-885, the identification sine against the ramped test record (`optbench diagnose "
        "... --trim-start 1`, its `validate_residual_time.png`): the test record's residual "
        f"(measured − model) for the baseline and the final model `{j['final_model']}`; its "
        f"first {lead} samples ({sig(lead * j['dt'])} s, shaded) are the lead, fitted and "
        f"never scored, and each of the {j['scored']} samples from the first dashed forecast "
        "origin on is predicted from the samples before its origin, the final model to "
        f"{sig(j['final'])} {u} RMS (the baseline {sig(j['baseline'])} {u}).*")
    s = d["steps"]
    n = s["holds"]
    few = all(v == "too few holds" for v in s["verdicts"].values())
    if few:
        what = ("one point per model (its residual's change over the hold against the move "
                "before it) and no correlation line: " if n == 1 else
                "a point per hold and model, and no correlation line: ")
        what += ("too few holds for a verdict, which needs two after rises, two after "
                 "falls and five in all")
    else:
        what = (f"a point per hold and model and the line through the origin the "
                f"correlation measures: the baseline's residual {s['verdicts']['baseline']}, "
                f"the final model's {s['verdicts']['final']}")
    holds = "one hold" if n == 1 else f"{n} holds"
    f["method-figure-steps"] = (
        "![P-885 residual change over each hold of the drive against the move before "
        "it](figures/method_steps.png)\n\n"
        "*P-885 with the records' roles swapped, the ramped test record as training and the "
        "identification sine (which has no holds) as validation (`--model bouc-wen`, its "
        f"`train_steps.png`): the rule counts {holds} in the test drive"
        + (" (its first hold is reached by a move under a tenth of the range)" if n == 1
           else "") + f", so the figure shows {what}.*")
    if "cores" in d:
        c = d["cores"]
        kept = next(t for t in c["trials"] if t["chosen"])
        others = ", ".join(f"`{t['model']}` {sig(t['rmse'])} {u}"
                           for t in c["trials"] if not t["chosen"])
        f["method-figure-cores"] = (
            "![P-885 each core's final model predicting the validation record: residual RMS "
            "over time per core](figures/method_cores.png)\n\n"
            "*P-885, the run of the first figure (its `validate_cores.png`): the residual "
            "RMS over time of each core's final model on the test record, the kept "
            f"`{kept['model']}` at or below the others throughout; over the scored samples it "
            f"predicts to {sig(kept['rmse'])} {u}, below the Bouc-Wen model's band "
            f"({sig(c['band'][0])}-{sig(c['band'][1])} {u}; the others: {others}).*")
        # The chapter's sentence on P-885's core choice, from the same run.
        by = {t["core"]: t for t in c["trials"]}
        bw = by["bouc-wen"]
        parts = [f"the Bouc-Wen search ends at {bw['rmse'] / c['noise_floor']:.1f}x the noise "
                 f"floor ({sig(bw['rmse'])} {u} predicted)"]
        band = f"Bouc-Wen's band ({sig(c['band'][0])}-{sig(c['band'][1])} {u})"
        for core, name in (("pi", "the PI core"), ("preisach", "the 6-level Preisach core")):
            t = by.get(core)
            if t is None:
                continue
            where = "below" if t["rmse"] < c["band"][0] else "not below"
            parts.append(f"{name} reaches `{t['model']}` at {sig(t['rmse'])} {u}, {where} "
                         + (band if len(parts) == 1 else "the band")
                         + (", and is kept" if t["chosen"] else ""))
        f["method-core-p885"] = "; ".join(parts)
    if "unexplained" in d:
        x = d["unexplained"]

        def pct(v):
            return f"{100 * v:.0f} %"

        def alone(x):
            """What the figure's one feature shows, and what the report claims."""
            if not x["predicts"]:
                return ("the training residual follows it, the validation residual does not lie on "
                        "it and the band reaches below zero, so no dependence is claimed.")
            single = x["band"][0] > 0
            others = [f for f in x.get("features") or [] if f != x["feature"]]
            if not others:
                return ("the validation residual follows it, and it predicts the held-out record."
                        if single else "the correction predicts the held-out record only in part.")
            return (("" if single else "alone its band reaches below zero; ")
                    + f"the report's claim is the correction on it and the {', '.join(others)} "
                    f"together, which removes {pct(x['combined_gain'])} (95 % "
                    f"{pct(x['combined_band'][0])} to {pct(x['combined_band'][1])}) of the held-out "
                    "record's mean square")

        f["method-figure-unexplained"] = (
            "![P-885 final residual against the feature it depends on most, binned, on "
            "training and validation, with the correction fitted on "
            "training](figures/method_unexplained.png)\n\n"
            "*P-885, the run of the first figure (its `validate_unexplained.png`): the final "
            f"residual in bins of the {x['feature']}, the feature whose correction alone "
            "removes most of the validation mean square, on training (solid) and on the test "
            "record's scored samples (dashed), with the correction fitted on training "
            f"(dotted), which removes {pct(x['gain'])} (95 % {pct(x['band'][0])} to "
            f"{pct(x['band'][1])}): " + alone(x) + "*")
    return f
