"""The blind proof's archived reports (docs/blind-proof/*.md, each written by
`scripts/blind_proof/run.py --report` for one master seed): their index and the latest
results of chapter 10, read from the reports themselves. No runs: a new master seed is a new
report in the folder (about 14 min of diagnosis, by hand), then `--write --only blind`."""

import math
import re

from docsgen._util import markdown_table

FRAGMENTS = ["blind-index", "blind-latest"]
COUNT = r"(\d+)/(\d+) = \d+ % \[\d+, \d+\]"


def wilson(k, n, z=1.959963984540054):
    """Wilson 95 % interval, in percent, as the reports print it."""
    if n == 0:
        return (0, 100)
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (round(100 * max(0.0, c - h)), round(100 * min(1.0, c + h)))


def rate(k, n):
    lo, hi = wilson(k, n)
    return f"{k}/{n} = {round(100 * k / n) if n else 0} % [{lo}, {hi}]"


def parse(path):
    text = path.read_text()

    def count(label):
        m = re.search(rf"^\| \*\*{label}\*\* \| {COUNT} \|", text, re.M)
        return [int(m.group(1)), int(m.group(2))] if m else None

    fa = re.search(rf"^False alarms on nulls \(any name\): {COUNT}", text, re.M)
    wall = re.search(r"^Wall time per case: median ([0-9.]+) s, worst ([0-9.]+) s", text, re.M)
    failed = []
    sec = re.search(r"^## Failed cases\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    if sec:
        for line in sec.group(1).splitlines():
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if line.startswith("| case-") and len(cells) >= 3:
                failed.append({"case": cells[0], "truth": cells[1], "named": cells[2]})
    return {"seed": re.search(r"blind-proof-(\d+)\.md", path.name).group(1),
            "singles": count("all singles"), "pairs": count("pairs"),
            "false_alarms": [int(fa.group(1)), int(fa.group(2))] if fa else None,
            "wall_median_s": float(wall.group(1)) if wall else None,
            "wall_worst_s": float(wall.group(2)) if wall else None,
            "failed": failed}


def collect(ctx):
    reports = [parse(p) for p in (ctx.root / "docs" / "blind-proof").glob("blind-proof-*.md")]
    # Newest first: the dated master seeds in descending order, the first (77003311) last.
    reports.sort(key=lambda r: (r["seed"].startswith("2026"), r["seed"]), reverse=True)
    return {"reports": reports}


def render(d):
    rs, f = d["reports"], {}
    f["blind-index"] = markdown_table(
        ["master seed", "report", "all singles", "pairs", "false alarms on nulls"],
        [[r["seed"], f"[blind-proof-{r['seed']}.md](blind-proof-{r['seed']}.md)",
          rate(*r["singles"]), rate(*r["pairs"]), rate(*r["false_alarms"])] for r in rs],
        right=[False] * 5)
    last, three = rs[0], rs[:3]

    def total(key, group):
        return [sum(r[key][0] for r in group), sum(r[key][1] for r in group)]

    fails = "; ".join(f"{c['case']} ({c['truth']}; named {c['named'] or 'nothing'})"
                      for c in last["failed"])
    f["blind-latest"] = (
        f"Latest: master seed **{last['seed']}**: singles {rate(*last['singles'])}, pairs "
        f"{rate(*last['pairs'])}, false alarms {rate(*last['false_alarms'])}, median "
        f"{last['wall_median_s']:.1f} s a case, worst {last['wall_worst_s']:.1f} s "
        f"([`docs/blind-proof/blind-proof-{last['seed']}.md`]"
        f"(blind-proof/blind-proof-{last['seed']}.md)). Its failures: {fails or 'none'}. "
        f"Over the last three seeds ({', '.join(r['seed'] for r in three)}): singles "
        f"{rate(*total('singles', three))}, pairs {rate(*total('pairs', three))}, false "
        f"alarms {rate(*total('false_alarms', three))}, worst case "
        f"{max(r['wall_worst_s'] for r in three):.1f} s.")
    return f
