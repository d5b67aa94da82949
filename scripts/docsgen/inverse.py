"""Chapter 9's PI P-885 section with a Prandtl-Ishlinskii core: `optbench diagnose --model
pi` on the stack (start-up trimmed), and `optbench invert` against the authors' own
inverse-model (discrete backlash operator) feedforward in the test record, beside the
free run of a Bouc-Wen fit (`optbench fit`) on the same stretches. Needs the data folder.

Stretches of the test record (its README): 37-47 s and 56-70.8 s are driven by the
authors' inverse-model command, the rest (sines, ramps, holds) by a linear map of the
desired trajectory. Tracking is scored as the authors compare it: the measured output one
sample after the command (their sensor's lag), with each stretch's mean error removed."""

import math

from docsgen._util import markdown_table, read_csv, read_json, sig, thousands
from docsgen.real_data import excerpt

FOLDER = "pea_p885_dbo"
TRAIN, TEST = "dbo_identification_1Hz_sine.csv", "dbo_test_ramped_sine_with_holds.csv"
WINDOWS = {"compensated": [(37.0, 47.0), (56.0, 70.8)],
           "uncompensated": [(0.0, 37.0), (47.0, 56.0)]}
FRAGMENTS = ["pi-p885-figures", "pi-p885-excerpt", "invert-p885-table", "invert-p885-figures"]
VOLATILE = [r'"wall_s": [0-9.e+-]+', r"evaluations, [0-9.]+ s"]
SMALL_DIAGNOSE = ["--effects", "delay", "--bootstrap", "2"]


def window_arg(name):
    return f"{name}=" + ",".join(f"{a:g}:{b:g}" for a, b in WINDOWS[name])


def rmse(rows, name, column, lag):
    """RMS of `column` (a residual) over window `name`, raw and with its mean removed."""
    e = [float(r[column]) for k, r in enumerate(rows) if k >= lag and
         any(a <= float(r["t_s"]) < b for a, b in WINDOWS[name])]
    m = sum(e) / len(e)
    return {"rmse": math.sqrt(sum(x * x for x in e) / len(e)),
            "rmse_centred": math.sqrt(sum((x - m) ** 2 for x in e) / len(e))}


def collect(ctx):
    base = ctx.need_data(FOLDER)
    train, test = base / TRAIN, base / TEST
    out = ctx.scratch / "invert-p885"
    r = ctx.optbench("invert", "--train", train, "--columns", "t_s,u_V,y_um", "--desired", test,
                     "--time-column", "t_s", "--desired-column", "yref_um",
                     "--compare-command", "u_V", "--compare-output", "y_um",
                     "--desired-offset", "train-mean", "--lag", "1",
                     "--window", window_arg("compensated"), "--window",
                     window_arg("uncompensated"), "--out", out)
    inv = read_json(out / "invert.json")
    fit = ctx.scratch / "fit-bw-p885"
    ctx.optbench("fit", "--model", "bouc-wen", "--train", train, "--validate", test,
                 "--columns", "t_s,u_V,y_um", "--model-param", "d0=true",
                 "--model-param", "lower=-1.5", *(["--budget", "600"] if ctx.small else []),
                 "-q", "--out", fit)
    rows = read_csv(fit / "validate_predicted.csv")
    bw = {w: rmse(rows, w, "residual_y_um", 1) for w in WINDOWS}
    diag = ctx.scratch / "diagnose-pi-p885"
    d = ctx.optbench("diagnose", "--model", "pi", "--train", train, "--validate", test,
                     "--columns", "t_s,u_V,y_um", "--trim-start", "1", "--out", diag,
                     *(SMALL_DIAGNOSE if ctx.small else []))
    dj = read_json(diag / "diagnosis.json")
    return {
        "invert": {"train_rmse": inv["train_rmse"], "operators": inv["operators"],
                   "command_range": inv["command_range"], "windows": inv["windows"],
                   "report": r.stdout.replace(str(ctx.data), "$OPTBENCH_DATA")},
        "bouc_wen": bw,
        "diagnose": {"unit": dj["unit"], "noise_floor": dj["noise_floor"],
                     "baseline": dj["baseline"]["validate_rmse"],
                     "final": dj["final"]["validate_rmse"], "left_out": dj["left_out"],
                     "unexplained": dj["unexplained"], "evaluations": dj["evaluations"],
                     "wall_s": dj["wall_s"], "excerpt": excerpt(d.stdout, ctx.data)},
    }


def render(d):
    f = {}
    g = d["diagnose"]
    u, nf = g["unit"], g["noise_floor"]
    named = ", ".join(f"`{n}`" for n in g["left_out"]) or "nothing"
    f["pi-p885-figures"] = (
        f"names {named} (validation RMSE {sig(g['baseline'])} -> {sig(g['final'])} {u}, "
        f"{g['final'] / nf:.1f}x the noise floor of {sig(nf)} {u}; "
        + ("structure left unexplained" if g["unexplained"] else "nothing left the residual "
           "tests can tell from noise")
        + f"; {thousands(g['evaluations'])} evaluations, {g['wall_s']:.0f} s)")
    f["pi-p885-excerpt"] = "```text\n" + g["excerpt"] + "\n```"
    inv, bw = d["invert"], d["bouc_wen"]
    rows = []
    by = {w["name"]: w for w in inv["windows"]}
    for name in WINDOWS:
        w = by[name]
        c = lambda t: sig(t["rmse_centred"])   # noqa: E731
        rows.append([name, thousands(w["samples"]), c(w["model_free_run"]), c(bw[name]),
                     c(w["recorded_measured"]), sig(w["command_rms_difference"]),
                     c(w["recorded_predicted"]), sig(w["ours_predicted"]["rmse"])])
    f["invert-p885-table"] = markdown_table(
        ["stretch", "samples", "PI free run (um)", "Bouc-Wen free run (um)",
         "authors' command, measured tracking (um)", "their command - ours, RMS (V)",
         "authors' command, PI-predicted tracking (um)", "our command, PI-predicted (um)"],
        rows)
    comp = by["compensated"]
    f["invert-p885-figures"] = (
        f"the plain PI model ({inv['operators']} plays, training RMSE "
        f"{sig(inv['train_rmse'])} um) computes a command within "
        f"{sig(comp['command_rms_difference'])} V RMS of the authors' on their compensated "
        f"stretch; their command tracked to {sig(comp['recorded_measured']['rmse_centred'])} "
        f"um there in reality (our model predicts "
        f"{sig(comp['recorded_predicted']['rmse_centred'])} um for it), and ours is predicted "
        f"to track to {sig(comp['ours_predicted']['rmse'])} um")
    return f
