#!/usr/bin/env python3
"""Docs fragments for the Bouc-Wen benchmark section of docs/09-diagnosis-real-data.md.

`generate(ctx)` runs `optbench diagnose` on the benchmark (`ctx.data/boucwen-benchmark`)
twice at the ends, the settings tuned with knowledge of the benchmark and the settings a
user without it would take, and once per tuned choice undone, then returns Markdown
fragments keyed by id (placed in the docs between `<!-- gen:ID -->` and
`<!-- /gen:ID -->`):

- `boucwen-readme`: the sentence README.md gives;
- `boucwen-headline`: one paragraph with the headline figures;
- `boucwen-ablation`: one row per run, what the diagnosis named and its test RMSEs;
- `boucwen-compare`: the two ends beside every published result of the data folder's
  RESULTS.md, quoted as it gives them;
- `boucwen-params`: the two ends' fitted physical parameters beside the benchmark's true
  ones (from the data folder's README.txt).

Every figure is read from the runs' diagnosis.json or from RESULTS.md, none typed here.
`ctx.small` runs only the two ends on the first 6000 training samples (a check that the
generator works, about a minute; its numbers are not the documented ones).

Standalone (prints the fragments; Python 3, standard library only; build the release
binary first):

    python3 scripts/docsgen/boucwen.py [--small] [--scratch DIR [--reuse]]
"""

import json
import re

BENCH = "boucwen-benchmark"
TRAIN = "train_multisine_forgione.csv"
MULTISINE = "test_multisine.csv"
SWEEP = "test_sinesweep.csv"
COLUMNS = "t_s,u_N,y_m"
# The small run's training slice (samples) and what both ends share there.
SMALL_SAMPLES = 6000
SMALL_EXTRA = ["--effects", "dynamics"]  # as the test in tests/diagnose.rs

def sci(x):
    """`x` with three significant digits, `3.74e-7` style; `—` for none."""
    if x is None:
        return "—"
    m, e = f"{x:.2e}".split("e")
    return f"{m}e{int(e)}"


def flags(ctx, hold, model, validation, *extra):
    """A command line: `validation` is `test` (the official multisine test file, one
    period of a steady state) or `holdout` (the training record's last 20 %)."""
    v = (
        ["--validate", str(ctx.data / BENCH / MULTISINE), "--validate-periodic"]
        if validation == "test"
        else ["--holdout", "0.2"]
    )
    return ["--hold", hold, "--model", model, *v, *extra]


def runs(ctx):
    """(id, label, flags): the tuned run, each of its choices undone alone, the naive run
    and what it still shares with the tuned one undone."""
    tuned = ("bandlimited", "bouc-wen-n1", "test")
    naive = ("auto", "bouc-wen", "holdout")
    if ctx.small:
        return [
            ("tuned", "tuned", flags(ctx, *tuned)),
            ("naive", "naive", flags(ctx, *naive)),
        ]
    return [
        ("tuned", "**tuned**: `--hold bandlimited --model bouc-wen-n1`, validation on the multisine test file", flags(ctx, *tuned)),
        ("tuned-auto", "tuned, but `--hold auto`", flags(ctx, "auto", *tuned[1:])),
        ("tuned-zoh", "tuned, but `--hold zoh` (the default)", flags(ctx, "zoh", *tuned[1:])),
        ("tuned-nfree", "tuned, but `--model bouc-wen` (n fitted)", flags(ctx, tuned[0], "bouc-wen", "test")),
        ("tuned-holdout", "tuned, but `--holdout 0.2` (no test file in the diagnosis)", flags(ctx, *tuned[:2], "holdout")),
        ("tuned-sub1", "tuned, but `--min-substeps 1`", flags(ctx, *tuned, "--min-substeps", "1")),
        ("naive", "**naive**: `--hold auto --model bouc-wen --holdout 0.2`", flags(ctx, *naive)),
        ("naive-zoh", "naive, but `--hold zoh` (the default)", flags(ctx, "zoh", *naive[1:])),
        ("naive-sub1", "naive, but `--min-substeps 1`", flags(ctx, *naive, "--min-substeps", "1")),
    ]


def diagnose(ctx, name, args, train):
    """One diagnosis with the official test sets scored; its diagnosis.json as a dict."""
    d = ctx.data / BENCH
    out = ctx.scratch / f"boucwen-{name}"
    extra = SMALL_EXTRA if ctx.small else ["--test", str(d / SWEEP)]
    # `ctx.reuse`: an earlier run's output in the scratch folder is read, not run again.
    if not (getattr(ctx, "reuse", False) is True and (out / "diagnosis.json").is_file()):
        ctx.optbench(
            "diagnose", "--train", str(train), "--test-periodic", str(d / MULTISINE),
            "--columns", COLUMNS, *args, *extra, "--out", str(out),
        )
    with open(out / "diagnosis.json") as f:
        return json.load(f)


def test_rmse(diag, file, key="final_rmse"):
    return next((t[key] for t in diag.get("tests", []) if file in t["name"]), None)


def published(ctx):
    """RESULTS.md's table rows: [method, multisine, sine sweep, source]."""
    rows = []
    for line in (ctx.data / BENCH / "RESULTS.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4 or cells[0] == "method" or set(cells[0]) <= set("-: "):
            continue
        rows.append(cells)
    return rows


def ablation_row(label, diag):
    final = diag["final"]
    hold = diag["hold"] + (" (chosen)" if diag.get("hold_trials") else "")
    validation = "held-out tail" if "held out" in diag["validate"] else "test file"
    return (
        f"| {label} | {', '.join(diag['left_out']) or 'nothing'} | {final['model']} "
        f"| {final['params'].get('n', float('nan')):.3f} | {hold} | {diag['min_substeps']} "
        f"| {sci(final['validate_rmse'])} ({validation}) | **{sci(test_rmse(diag, MULTISINE))}** "
        f"| {sci(test_rmse(diag, SWEEP))} | {diag['evaluations']:,} |"
    )


def truth(ctx):
    """The benchmark's parameters from its README.txt (`mL=2 kg, cL=10 Ns/m, ...`)."""
    text = (ctx.data / BENCH / "README.txt").read_text()
    return {k: float(v) for k, v in re.findall(r"\b(mL|cL|kL|alpha|beta|gamma|delta|nu)=(-?[0-9.e+-]+)", text)}


def params(ctx, diags):
    """The final models' physical parameters of the two ends beside the truth."""
    t = truth(ctx)
    keys = ["mass", "damping", "stiffness", "alpha", "beta", "gamma", "n"]
    true = [t["mL"], t["cL"], t["kL"], t["alpha"], t["beta"] * t["gamma"], t["beta"] * t["delta"], t["nu"]]
    rows = [
        "| | m (kg) | c (N s/m) | k (N/m) | α (N/m) | β (dissertation's form, βγ) "
        "| γ (dissertation's form, βδ) | n |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name in ["tuned", "naive"]:
        p = diags[name]["final"]["params"]
        if all(k in p for k in keys):
            rows.append(f"| fitted, {name} | " + " | ".join(f"{p[k]:.5g}" for k in keys) + " |")
    rows.append("| benchmark truth (README.txt) | " + " | ".join(f"{v:.5g}" for v in true) + " |")
    return "\n".join(rows) + "\n"


FRAGMENTS = ["boucwen-readme", "boucwen-headline", "boucwen-ablation", "boucwen-compare",
             "boucwen-params"]


def collect(ctx):
    """docs_gen's interface: the fragments are the data (each is built from the runs'
    diagnosis.json and RESULTS.md by generate())."""
    ctx.need_data(BENCH, TRAIN)
    return {"fragments": generate(ctx)}


def render(data):
    return data["fragments"]


def generate(ctx):
    d = ctx.data / BENCH
    train = d / TRAIN
    if ctx.small:
        lines = train.read_text().splitlines()
        train = ctx.scratch / "boucwen-train-small.csv"
        train.write_text("\n".join(lines[: SMALL_SAMPLES + 1]) + "\n")
    plan = runs(ctx)
    diags = {name: diagnose(ctx, name, args, train) for name, _, args in plan}
    tuned, naive = diags["tuned"], diags["naive"]
    bb = next(r for r in published(ctx) if r[0].startswith("gr-SS-NN"))
    bb_ms = float(bb[1])

    rows = [
        "| run | named | final model | n | hold | min. sub-steps | validation RMSE (m) "
        "| multisine test (m) | sine-sweep test (m) | evaluations |",
        "|---|---|---|---:|---|---:|---|---:|---:|---:|",
    ]
    rows += [ablation_row(label, diags[name]) for name, label, _ in plan]
    # The placement the tuned run would have named without the feedback one.
    after = [
        c for c in tuned["candidates"]
        if c["name"] == "dynamics" and c.get("placement") != "feedback" and c["round"] == 1
    ]
    feedback = [c for c in tuned["candidates"] if c.get("placement") == "feedback" and c["accepted"]]
    note = ""
    if after and feedback:
        c = min(after, key=lambda c: c["validate_rmse"])
        note = (
            f"\nWithout the feedback placement (the benchmark's own structure, added to the "
            f"candidates after the diagnosis had missed this benchmark) the tuned run's best "
            f"candidate is a mode after the hysteresis ({c['form']}): ΔBIC "
            f"{c['delta_bic']:,.0f} against the feedback placement's "
            f"{feedback[0]['delta_bic']:,.0f}, validation RMSE {sci(c['validate_rmse'])} m "
            f"(not run on the test sets).\n"
        )
    ablation = "\n".join(rows) + "\n" + note

    nm, tm = test_rmse(naive, MULTISINE), test_rmse(tuned, MULTISINE)
    trials = "; ".join(
        f"{t['hold']} {sci(t['validate_rmse'])} m" for t in naive.get("hold_trials", [])
    )
    ratio = bb_ms / nm
    verdict = f"{ratio:.1f}x better than" if ratio >= 1 else f"{1 / ratio:.1f}x worse than"
    headline = (
        f"Without prior knowledge of the benchmark (`--hold auto`, n fitted, validation on "
        f"the last 20 % of the training record, the official test sets used only for the "
        f"score) the diagnosis names {', '.join(naive['left_out']) or 'nothing'} "
        f"({naive['final']['model']}) and its model misses the multisine test set by "
        f"**{sci(nm)} m** and the sine sweep by **{sci(test_rmse(naive, SWEEP))} m**: "
        f"{verdict} the best published black box (gr-SS-NN, {sci(bb_ms)} m on the "
        f"multisine). With the settings tuned by knowledge of the benchmark the same "
        f"diagnosis reaches {sci(tm)} m and {sci(test_rmse(tuned, SWEEP))} m "
        f"({bb_ms / tm:.0f}x better than gr-SS-NN on the multisine). The exponent: for the "
        f"static baseline {naive['exponent']}; the final model's n is "
        f"{naive['final']['params'].get('n', float('nan')):.3f}."
        + (f" The hold the data chose: {naive['hold']} (held-out RMSE per hold: {trials})." if trials else "")
        + "\n"
    )

    compare = [
        "| model | multisine test RMSE | sine-sweep test RMSE | source |",
        "|---|---|---|---|",
        f"| **optbench diagnose, naive** ({naive['final']['model']}) | **{sci(nm)}** "
        f"| **{sci(test_rmse(naive, SWEEP))}** | this chapter |",
        f"| optbench diagnose, tuned by knowledge of the benchmark | {sci(tm)} "
        f"| {sci(test_rmse(tuned, SWEEP))} | this chapter |",
        f"| static Bouc-Wen (the dissertation's model: the diagnosis's baseline, naive run) "
        f"| {sci(test_rmse(naive, MULTISINE, 'baseline_rmse'))} "
        f"| {sci(test_rmse(naive, SWEEP, 'baseline_rmse'))} | this chapter |",
    ]
    compare += [f"| {m} | {ms} | {sw} | {src} |" for m, ms, sw, src in published(ctx)]
    fb = "dynamics(feedback)" in naive["final"]["model"]
    readme = (
        "On the Bouc-Wen benchmark `optbench diagnose`, run without prior knowledge of it, "
        + ("puts the hysteresis inside the mechanical feedback" if fb else f"ends at {naive['final']['model']}")
        + f" and misses the multisine test set by {sci(nm)} m (the best published black box: "
        f"{sci(bb_ms)} m); with the hold, the exponent and the validation record chosen by "
        f"knowledge of the benchmark, {sci(tm)} m "
        f"([9. Diagnosis on real data](docs/09-diagnosis-real-data.md#bouc-wen-benchmark)).\n"
    )
    return {
        "boucwen-readme": readme,
        "boucwen-headline": headline,
        "boucwen-params": params(ctx, diags),
        "boucwen-ablation": ablation,
        "boucwen-compare": "\n".join(compare) + "\n",
    }


if __name__ == "__main__":
    import os
    import subprocess
    import sys
    import tempfile
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]

    class Ctx:
        small = "--small" in sys.argv
        reuse = "--reuse" in sys.argv
        data = Path(os.environ.get("OPTBENCH_DATA") or root / "../shared/data").resolve()

        def __init__(self, scratch):
            self.scratch = Path(scratch)

        def optbench(self, *args, check=True):
            return subprocess.run(
                [str(root / "target/release/optbench"), *args],
                cwd=root, check=check, capture_output=True, text=True,
            )

    # `--scratch DIR` keeps the runs' output folders there; with `--reuse` those already
    # there are read instead of run again (to rewrite the fragments only).
    keep = sys.argv[sys.argv.index("--scratch") + 1] if "--scratch" in sys.argv else None
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(keep or tmp)
        scratch.mkdir(parents=True, exist_ok=True)
        for key, text in generate(Ctx(scratch)).items():
            print(f"<!-- gen:{key} -->\n{text}<!-- /gen:{key} -->\n")
