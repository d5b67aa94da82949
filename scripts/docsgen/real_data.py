"""Chapter 9 on measured data: `optbench diagnose` on an MR damper (from position and from
velocity), the PI P-885 stack (as recorded, and with its start-up trimmed) and the CubeSpec
mirror (one amplitude, and two at once). Needs the data folder.

What the chapter quotes of each run is the tool's own text: a verbatim excerpt of the report
(the header, the accepted candidates with their notes and flags, and everything from "left
out" on; the other candidates' lines are elided as `...`), and a sentence of figures read
from diagnosis.json."""

import re

from docsgen._util import read_json, sig, thousands

# id: (data folder, diagnose arguments after --train/--validate); paths relative to it.
RUNS = {
    "mr-position": ("mr-damper-labcontrol", ["--train", "ensaio_A_5.csv", "--validate",
                    "ensaio_vali_A_1.csv", "--columns", "t_s,position_mm,force_N"]),
    "mr-velocity": ("mr-damper-labcontrol", ["--train", "ensaio_A_5.csv", "--validate",
                    "ensaio_vali_A_1.csv", "--columns", "t_s,velocity_mm_per_s,force_N"]),
    "p885": ("pea_p885_dbo", ["--train", "dbo_identification_1Hz_sine.csv", "--validate",
             "dbo_test_ramped_sine_with_holds.csv", "--columns", "t_s,u_V,y_um", "--suggest"]),
    "p885-trim": ("pea_p885_dbo", ["--train", "dbo_identification_1Hz_sine.csv", "--validate",
                  "dbo_test_ramped_sine_with_holds.csv", "--columns", "t_s,u_V,y_um",
                  "--trim-start", "1", "--suggest"]),
    "cubespec": ("fsm_cubespec_piezo", ["--train", "fsm_300mV_train_r0.csv", "--validate",
                 "fsm_300mV_test_r0.csv", "--columns", "t_s,u1_V,y1_um", "--hold",
                 "bandlimited"]),
    "cubespec-joint": ("fsm_cubespec_piezo", ["--train", "fsm_100mV_train_r0.csv", "--train",
                       "fsm_300mV_train_r0.csv", "--validate", "fsm_200mV_test_r0.csv",
                       "--columns", "t_s,u1_V,y1_um", "--hold", "bandlimited", "--suggest"]),
}
SMALL = ["--model", "bouc-wen-n1", "--effects", "delay", "--bootstrap", "2"]
SMALL_RUNS = ["mr-position"]
FRAGMENTS = [f"real-{r}-{k}" for r in RUNS for k in ("figures", "excerpt")]
VOLATILE = [r'"wall_s": [0-9.e+-]+', r"evaluations, [0-9.]+ s"]
KEEP = re.compile(r"^(noise floor|core:|exponent|baseline|left out|final|plausibility|unexplained|"
                  r"no structure|next experiment|search ended|\d+ evaluations|\s*coupling|"
                  r"round \d+)|^  \[time\] .*starts in motion|^  \+ |^      (note|!)|^  (!|also)|"
                  r"^  [* ] (bouc-wen|pi|preisach) ")


def excerpt(report, data):
    """The report's key lines verbatim; elided runs of lines become one `...`."""
    lines = report.replace(str(data), "$OPTBENCH_DATA").splitlines()
    out, elided, tail = [lines[0]], False, False
    for line in lines[1:]:
        if line.startswith("diagnosis.json and figures"):
            break
        tail = tail or line.startswith("left out")
        if tail or KEEP.search(line):
            out.append(line)
            elided = False
        elif not elided:
            out.append("    ...")
            elided = True
    while out and not out[-1].strip():
        out.pop()
    return "\n".join(out)


def collect(ctx):
    runs = []
    for rid, (folder, args) in RUNS.items():
        if ctx.small and rid not in SMALL_RUNS:
            continue
        base = ctx.need_data(folder)
        full = [str(base / a) if a.endswith(".csv") else a for a in args]
        out = ctx.scratch / f"diagnose-{rid}"
        r = ctx.optbench("diagnose", *full, "--out", out, *(SMALL if ctx.small else []))
        d = read_json(out / "diagnosis.json")
        accepted = [{"name": c["name"], "form": c.get("form"), "round": c["round"],
                     "delta_bic": c["delta_bic"], "validate_rmse": c["validate_rmse"]}
                    for c in d["candidates"] if c.get("accepted")]
        runs.append({
            "id": rid, "unit": d["unit"], "noise_floor": d["noise_floor"],
            "baseline": {"model": d["baseline"]["model"],
                         "validate_rmse": d["baseline"]["validate_rmse"]},
            "final": {"model": d["final"]["model"], "validate_rmse": d["final"]["validate_rmse"]},
            "left_out": d["left_out"], "accepted": accepted, "unexplained": d["unexplained"],
            "evaluations": d["evaluations"], "wall_s": d["wall_s"],
            "excerpt": excerpt(r.stdout, ctx.data),
        })
    return {"runs": runs}


def render(d):
    f = {}
    for run in d["runs"]:
        u, nf = run["unit"], run["noise_floor"]
        b, fin = run["baseline"]["validate_rmse"], run["final"]["validate_rmse"]
        named = ", ".join(f"`{n}`" for n in run["left_out"]) or "nothing"
        f[f"real-{run['id']}-figures"] = (
            f"names {named} (validation RMSE {sig(b)} -> {sig(fin)} {u}, {fin / nf:.1f}x the "
            f"noise floor of {sig(nf)} {u}; "
            + ("structure left unexplained" if run["unexplained"] else "nothing left the "
               "residual tests can tell from noise")
            + f"; {thousands(run['evaluations'])} evaluations, {run['wall_s']:.0f} s)")
        f[f"real-{run['id']}-excerpt"] = "```text\n" + run["excerpt"] + "\n```"
    return f
