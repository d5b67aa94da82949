"""Chapter 13: `optbench bench` run three times (rates move between runs on a shared VM: the
chapter gives the last run's output and the range over the three), and
`scripts/compare-peers` (numpy/scipy/pyswarms at equal budgets, its own virtualenv). Run it
on an idle machine: every figure here is a time."""

import json
import re
import subprocess

from docsgen._util import first_table

RUNS = 3
FRAGMENTS = ["speed-bench-output", "speed-bench-ranges", "speed-figures", "speed-peers",
             "speed-numpy-output"]
FULL_ONLY = ["peers"]       # compare-peers needs its own virtualenv: full size only
VOLATILE = [r"-?[0-9]+\.[0-9]+(e-?[0-9]+)?"]   # every rate and time differs run to run


def collect(ctx):
    runs, text = [], ""
    for k in range(1 if ctx.small else RUNS):
        path = ctx.scratch / f"bench-{k}.json"
        r = ctx.optbench("bench", "--json", path, *(["--quick"] if ctx.small else []))
        runs.append(json.loads(path.read_text()))
        text = r.stdout
    data = {"runs": [{"rows": r["rows"], "harness_overhead": r["harness_overhead"],
                      "msga": r["msga_threads_speedup"],
                      "msga_lagged": r["msga_threads_speedup_lagged"],
                      "threads": r["threads"], "accelerated": r["accelerated"]} for r in runs],
            "output": text.rstrip("\n")}
    if not ctx.small:
        r = subprocess.run(["bash", str(ctx.root / "scripts" / "compare-peers"), "--trials", "3",
                            "--bench-json", str(ctx.scratch / f"bench-{RUNS - 1}.json")],
                           cwd=ctx.root, capture_output=True, text=True, check=True,
                           env={"OPTBENCH": str(ctx.bin), "PATH": "/usr/bin:/bin"})
        out = re.sub(r"work folder \S+", "work folder (temporary)", r.stdout)
        data["peers"] = {"table": first_table(out),
                         "header": out.splitlines()[0],
                         "numpy": out[out.index("The dissertation's Bouc-Wen recurrence"):]
                         .rstrip("\n")}
    return data


def render(d):
    f, runs = {}, d["runs"]
    f["speed-bench-output"] = "```text\n" + d["output"] + "\n```"
    names = [r["name"] for r in runs[0]["rows"]]

    def span(values, fmt):
        lo, hi = fmt(min(values)), fmt(max(values))
        return lo if lo == hi else f"{lo}-{hi}"

    rows = []
    for i, name in enumerate(names):
        rs = [run["rows"][i] for run in runs]
        rows.append(f"| {name} | {span([r['batched'] for r in rs], lambda v: f'{v:.0f}')} | "
                    f"{span([r['threads'] for r in rs], lambda v: f'{v:.0f}')} | "
                    f"{span([r['batched_over_scalar'] for r in rs], lambda v: f'{v:.1f}x')} |")
    rows.append("| harness overhead, griewank-30 | "
                + span([r["harness_overhead"] * 100 for r in runs], lambda v: f"{v:+.1f} %")
                + " | | |")
    rows.append("| msga 5 threads / 1, dissertation's rule | "
                + span([r["msga"] for r in runs], lambda v: f"{v:.2f}x") + " | | |")
    rows.append("| msga 5 threads / 1, `migration_lag = 1` | "
                + span([r["msga_lagged"] for r in runs], lambda v: f"{v:.2f}x") + " | | |")
    f["speed-bench-ranges"] = (
        f"Over the {len(runs)} runs of this generation (per core; M samples/s or M evals/s):\n\n"
        "| row | batched | all threads | b/s |\n|---|---:|---:|---:|\n" + "\n".join(rows))
    by = {r["name"]: r for r in runs[-1]["rows"]}
    ex, fast = by["bouc-wen (explicit recurrence)"], by["bouc-wen"]
    acc = by["bouc-wen (accurate kernel)"]
    f["speed-figures"] = (
        f"In the last run: the dissertation's recurrence (`scheme = \"explicit\"`) at "
        f"{ex['batched']:.0f} M samples/s per core, {ex['batched_over_scalar']:.1f} times its "
        f"scalar reference with `powf`; the default fitting scheme (`scheme = \"fast\"`) at "
        f"{fast['batched']:.0f}, {fast['batched_over_scalar']:.1f} times its scalar reference "
        f"and {fast['batched'] / acc['batched']:.0f} times the accurate kernel per individual; "
        f"MSGA on 5 membrane threads {runs[-1]['msga']:.2f}x one thread with the "
        f"dissertation's communication rule, {runs[-1]['msga_lagged']:.2f}x with "
        "`migration_lag = 1`.")
    p = d.get("peers")
    f["speed-peers"] = (p["header"] + "\n\n" + p["table"]) if p else ""
    f["speed-numpy-output"] = ("```text\n" + p["numpy"] + "\n```") if p else ""
    return f
