"""Chapter 8's speed of the diagnosis: `scripts/diagnose-speed.sh` with `n` free and with
`bouc-wen-n1` (a 20 s + 20 s twin pair with a concealed 1 ms delay), and at full size
`cargo bench --bench models -- diagnose_eval` (one evaluation, the projected solve against
the direct Gram-Schmidt one in the same process). Times: run it on an idle machine."""

import json
import os
import re
import subprocess

FRAGMENTS = ["diagnose-speed-runs", "diagnose-speed-bench"]
FULL_ONLY = ["bench"]          # the bench build takes minutes: full size only
VOLATILE = [r"\"wall_s\": [0-9.e-]+", r"\"(projected|reference)_ms\": [0-9.e-]+",
            r"\"(ratio|over_plain)\": [0-9.e-]+"]
MODELS = ["bouc-wen", "bouc-wen-n1"]
LINE = re.compile(r"^\s+(\S+)\s+projected\s+([0-9.]+) ms, reference\s+([0-9.]+) ms: "
                  r"reference / projected = ([0-9.]+)x, projected / plain = ([0-9.]+)x", re.M)


def collect(ctx):
    runs = {}
    for model in MODELS:
        keep = ctx.scratch / f"diagnose-speed-{model}"
        env = dict(os.environ, DURATION="4" if ctx.small else "20", KEEP=str(keep))
        r = subprocess.run(["bash", str(ctx.root / "scripts" / "diagnose-speed.sh"), model],
                           cwd=ctx.root, env=env, capture_output=True, text=True, check=True)
        d = json.loads((keep / "diagnosis.json").read_text())
        runs[model] = {
            "samples": d["samples"], "evaluations": d["evaluations"],
            "wall_s": float(re.search(r"diagnose wall time: ([0-9.]+) s", r.stdout).group(1)),
            "named": d["left_out"], "exponent": d["exponent"]}
    data = {"runs": runs}
    if not ctx.small:
        r = subprocess.run(["cargo", "bench", "-q", "--bench", "models", "--", "diagnose_eval"],
                           cwd=ctx.root, capture_output=True, text=True, check=True)
        data["bench"] = [{"structure": m.group(1), "projected_ms": float(m.group(2)),
                          "reference_ms": float(m.group(3)), "ratio": float(m.group(4)),
                          "over_plain": float(m.group(5))} for m in LINE.finditer(r.stdout)]
        if not data["bench"]:
            raise RuntimeError("cargo bench printed no diagnose_eval ratios:\n" + r.stdout)
    return data


def render(d):
    free, n1 = d["runs"]["bouc-wen"], d["runs"]["bouc-wen-n1"]

    def named(r):
        return ", ".join(f"`{e}`" for e in r["named"]) or "nothing"

    f = {"diagnose-speed-runs": (
        f"On this machine the script takes **{free['wall_s']:.1f} s** with `n` free "
        f"({free['evaluations']:,} evaluations, {free['samples'][0]:,} + "
        f"{free['samples'][1]:,} samples, finding {named(free)}; {free['exponent']}), which "
        f"runs every candidate on the slower general-`n` kernel, where the series does not "
        f"apply, and **{n1['wall_s']:.1f} s** with `bouc-wen-n1` ({n1['evaluations']:,} "
        f"evaluations, finding {named(n1)}).")}
    bench = d.get("bench")
    if bench is None:
        f["diagnose-speed-bench"] = "(not measured at this size)"
    else:
        parts = [f"{b['structure']} {b['projected_ms']:.2f} ms (reference {b['ratio']:.1f}x "
                 f"slower)" for b in bench]
        f["diagnose-speed-bench"] = "; ".join(parts)
    return f
