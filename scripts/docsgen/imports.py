"""Chapter 15's module import graph: `scripts/import_graph.py` on today's src/ (with the
chapter's layering) and on src/ at commit 4f4a316, before the restructuring of issue 16
(exported with `git archive`, the same script run on it). Skipped where that commit is
absent (a shallow clone). The figures themselves are drawn from `--dot` by hand."""

import re
import shutil
import subprocess
import sys

from docsgen._util import count_words

FRAGMENTS = ["imports-after-summary", "imports-after-figure", "imports-before",
             "imports-before-figure"]
# Imports the chapter names in the graph before the restructuring: (module, imported).
NAMED = [("optimizer", "harness"), ("harness", "optimizer"), ("physics", "speed")]
BEFORE = "4f4a316"
LAYERS = ("base;data;physics;objective;harness;optimizer;stats;registry;render;pipeline;speed;"
          "report;diagnose,control;cmd")


def graph(root, *args):
    r = subprocess.run([sys.executable, str(root / "scripts" / "import_graph.py"), *args],
                       cwd=root, capture_output=True, text=True)
    m = re.search(r"^(\d+) edges, (\d+) cycles, (\d+) upward$", r.stdout, re.M)
    if not m:
        raise RuntimeError(f"import_graph.py printed no summary:\n{r.stdout[-2000:]}{r.stderr}")
    edges = {(a, t) for a, ts in re.findall(r"^(\w+) -> (.*)$", r.stdout, re.M)
             for t in ts.split(", ")}
    return {"edges": int(m.group(1)), "cycles": int(m.group(2)), "upward": int(m.group(3)),
            "named": [f"{a} -> {t}" for a, t in NAMED if (a, t) in edges]}


def collect(ctx):
    from docs_gen import Skip
    if subprocess.run(["git", "cat-file", "-e", f"{BEFORE}^{{commit}}"], cwd=ctx.root,
                      capture_output=True).returncode:
        raise Skip(f"commit {BEFORE} is not in this clone (shallow?)")
    old = ctx.scratch / f"src-{BEFORE}"
    shutil.rmtree(old, ignore_errors=True)
    (old / "scripts").mkdir(parents=True)
    tar = subprocess.run(["git", "archive", BEFORE, "src"], cwd=ctx.root, capture_output=True,
                         check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(old)], input=tar, check=True)
    shutil.copy(ctx.root / "scripts" / "import_graph.py", old / "scripts")
    loose = [p.name for p in (old / "src").glob("*.rs") if p.name not in ("main.rs", "lib.rs")]
    after = graph(ctx.root, "--layers", LAYERS)
    del after["named"]   # what the chapter names of the old graph only
    return {"after": after,
            "before": dict(graph(old), loose_files=len(loose))}


def render(d):
    a, b = d["after"], d["before"]
    if a["cycles"] or a["upward"]:
        raise RuntimeError(f"today's import graph has {a['cycles']} cycles, "
                           f"{a['upward']} upward imports: the chapter says none")
    if len(b["named"]) != len(NAMED):
        raise RuntimeError(f"the graph at {BEFORE} lacks imports the chapter names: {b['named']}")
    return {
        "imports-after-summary": (f"`{a['edges']} edges, {a['cycles']} cycles, "
                                  f"{a['upward']} upward`"),
        "imports-after-figure": (f"![Module imports after the restructuring: {a['edges']} edges, "
                                 "no cycle](figures/imports-after.png)"),
        "imports-before": (
            f"{b['edges']} edges, {b['cycles']} cycles: `optimizer` and `harness` imported "
            f"each other, `physics` imported `speed`, {count_words(b['loose_files'])} loose "
            "files beside `main.rs` and `lib.rs` at the top of `src/`"),
        "imports-before-figure": (f"![Module imports before the restructuring: {b['edges']} "
                                  f"edges, {b['cycles']} cycles](figures/imports-before.png)"),
    }
