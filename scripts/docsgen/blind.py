"""The blind proof's archived reports (docs/blind-proof/*.md, each written by
`scripts/blind_proof/run.py --report` for one master seed): their index, the latest results
of chapter 10 and the whole history of chapter 11, read from the reports themselves and from
docs/blind-proof/provenance.toml (which binary ran the older reports, what it changed). No
runs: a new master seed is a new report in the folder (a quarter of an hour of diagnosis, by
hand), then `--write --only blind`."""

import math
import re
import tomllib

from docsgen._util import count_words, markdown_table

FRAGMENTS = ["blind-index", "blind-latest", "blind-pooled", "blind-seeds", "blind-oracle",
             "blind-seed-details"]
# The blind proof's aims, as its issue set them: exact singles, exact pairs, false alarms on
# nulls at most, seconds a case at most.
AIMS = {"singles": 0.95, "pairs": 0.85, "false_alarms": 0.05, "worst_s": 60.0}
VERDICTS = ["not found alone", "split", "named set better supported", "truth better supported"]
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
    over = re.search(r"; over 60 s: (\d+)", text)
    binary = re.search(r"^Binary: commit `(\w+)`", text, re.M)
    oracle = []
    sec = re.search(r"^## Failed pairs against the truth alone.*?\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    if sec:
        for line in sec.group(1).splitlines():
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if line.startswith("| case-") and len(cells) >= 7:
                oracle.append({"case": cells[0], "dbic": float(cells[4]), "ratio": float(cells[5]),
                               "verdict": cells[6]})
    return {"seed": re.search(r"blind-proof-(\d+)\.md", path.name).group(1),
            "binary": binary.group(1) if binary else None,
            "over_60": int(over.group(1)) if over else None, "oracle": oracle if sec else None,
            "singles": count("all singles"), "pairs": count("pairs"),
            "false_alarms": [int(fa.group(1)), int(fa.group(2))] if fa else None,
            "wall_median_s": float(wall.group(1)) if wall else None,
            "wall_worst_s": float(wall.group(2)) if wall else None,
            "failed": failed}


def collect(ctx):
    reports = [parse(p) for p in (ctx.root / "docs" / "blind-proof").glob("blind-proof-*.md")]
    # Newest first: the dated master seeds in descending order, the first (77003311) last.
    reports.sort(key=lambda r: (r["seed"].startswith("2026"), r["seed"]), reverse=True)
    prov = tomllib.loads((ctx.root / "docs" / "blind-proof" / "provenance.toml").read_text())
    for r in reports:
        p = prov.get(r["seed"], {})
        for key in ("change", "note"):
            bare = re.sub(r"`[^`]*`|\b[Cc]ases? \d+(?:(?:, | and )\d+)*", "", p.get(key, ""))
            if re.search(r"\d", bare):
                raise ValueError(f"provenance.toml [{r['seed']}] {key}: a number; numbers come "
                                 f"from the reports: {p[key]!r}")
        r["binary"] = r["binary"] or p.get("binary")
        r["since"] = bool(p.get("since"))
        r["change"], r["note"] = p.get("change"), p.get("note")
    return {"reports": reports}


def total(key, group):
    """A count pooled over reports: [hits, cases]."""
    return [sum(r[key][0] for r in group), sum(r[key][1] for r in group)]


def render(d):
    rs, f = d["reports"], {}
    f["blind-index"] = markdown_table(
        ["master seed", "report", "all singles", "pairs", "false alarms on nulls"],
        [[r["seed"], f"[blind-proof-{r['seed']}.md](blind-proof-{r['seed']}.md)",
          rate(*r["singles"]), rate(*r["pairs"]), rate(*r["false_alarms"])] for r in rs],
        right=[False] * 5)
    last, three = rs[0], rs[:3]

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
    history(rs, f)
    return f


def pct(k, n):
    return f"{100 * k / n:.1f} %" if n else "–"


def rate1(k, n):
    """A pooled rate with one decimal, its Wilson interval."""
    lo, hi = wilson(k, n)
    return f"{k}/{n} = {pct(k, n)} [{lo}, {hi}]"


def failure(c):
    named = c["named"] if c["named"] not in ("", "none") else "nothing named"
    return f"{c['case']} {c['truth']} → {named}"


def history(rs, f):
    """Chapter 11: pooled results since the first binary of the pooled run, every seed's row,
    the oracle's verdicts and each seed's failures."""
    pool = [r for r in rs if r["since"]]
    first = pool[-1]

    binaries = list(dict.fromkeys(r["binary"] for r in reversed(pool)))
    s, p, fa = total("singles", pool), total("pairs", pool), total("false_alarms", pool)
    over = sum(r["over_60"] or 0 for r in pool)
    worst = max(r["wall_worst_s"] for r in pool)

    def verdict(ok):
        return "met" if ok else "**not met**"

    f["blind-pooled"] = (
        f"Pooled over the {len(pool)} master seeds drawn since `{first['binary']}` "
        f"({first['seed']} to {pool[0]['seed']}, {len(binaries)} binaries, each seed run by the "
        f"binary current when it was drawn, before anyone looked at its cases): singles "
        f"{rate1(*s)}, pairs {rate1(*p)}, false alarms {rate1(*fa)}, {count_words(over)} case"
        f"{'' if over == 1 else 's'} over 60 s (worst {worst:.1f} s). Against the aims: singles at least "
        f"{100 * AIMS['singles']:.0f} %: {verdict(s[0] >= AIMS['singles'] * s[1])}; pairs at "
        f"least {100 * AIMS['pairs']:.0f} %: {verdict(p[0] >= AIMS['pairs'] * p[1])}; false "
        f"alarms at most {100 * AIMS['false_alarms']:.0f} %: "
        f"{verdict(fa[0] <= AIMS['false_alarms'] * fa[1])}; no case over "
        f"{AIMS['worst_s']:.0f} s: {verdict(worst <= AIMS['worst_s'])}. By binary:\n\n"
        + markdown_table(
            ["binary", "seeds", "singles", "pairs", "false alarms", "worst case"],
            [[f"`{b}`", str(len(g)), rate1(*total("singles", g)), rate1(*total("pairs", g)),
              rate1(*total("false_alarms", g)), f"{max(r['wall_worst_s'] for r in g):.1f} s"]
             for b in binaries for g in [[r for r in pool if r["binary"] == b]]],
            right=[False, True, False, False, False, True]))

    f["blind-seeds"] = markdown_table(
        ["master seed", "binary", "all singles", "pairs", "false alarms", "median", "worst",
         "over 60 s"],
        [[f"[{r['seed']}](blind-proof/blind-proof-{r['seed']}.md)",
          f"`{r['binary']}`" if r["binary"] else "–", rate(*r["singles"]), rate(*r["pairs"]),
          rate(*r["false_alarms"]), f"{r['wall_median_s']:.1f} s", f"{r['wall_worst_s']:.1f} s",
          "–" if r["over_60"] is None else str(r["over_60"])] for r in rs],
        right=[False, False, False, False, False, True, True, True])

    with_oracle = [r for r in pool if r["oracle"] is not None]
    counts = {v: sum(1 for r in with_oracle for o in r["oracle"] if o["verdict"] == v)
              for v in VERDICTS}
    failed = sum(counts.values())
    n_pairs = total("pairs", with_oracle)[1]
    bound = n_pairs - counts["not found alone"] - counts["named set better supported"]
    unknown = sum(1 for r in with_oracle for o in r["oracle"] if o["verdict"] not in VERDICTS)
    f["blind-oracle"] = (
        f"Over the {len(with_oracle)} seeds since `{first['binary']}`, the {failed} failed pairs "
        f"by the oracle's verdict: {counts['not found alone']} *not found alone* (the tool does "
        f"not name both even when nothing else is offered), {counts['split']} *split* (neither "
        f"set better on both criteria), {counts['named set better supported']} *the named set "
        f"better supported*, and {counts['truth better supported']} search errors (*truth "
        f"better supported*){f', {unknown} with another verdict' if unknown else ''}. A search "
        f"that made no error and won every split would have named at most {n_pairs} - "
        f"{counts['not found alone']} - {counts['named set better supported']} = {bound} of the "
        f"{n_pairs} pairs, {pct(bound, n_pairs)}.")

    out = []
    for r in rs:
        head = f"**{r['seed']}**" + (f" (`{r['binary']}`" + (f": {r['change']}" if r["change"]
                                                            else "") + ")" if r["binary"] else "")
        oracle = {o["case"]: o for o in r["oracle"] or []}

        def one(c):
            o = oracle.get(c["case"])
            if not o:
                return failure(c)
            extra = "" if o["verdict"] == "not found alone" else \
                f", ΔBIC {o['dbic']:+,.0f}, validation ratio {o['ratio']:.3f}"
            return f"{failure(c)} ({o['verdict']}{extra})"

        fails = "; ".join(one(c) for c in r["failed"]) or "none"
        n = len(r["failed"])
        out.append(f"- {head}. {count_words(n).capitalize()} failure{'' if n == 1 else 's'}: "
                   f"{fails}." + (f" {r['note']}" if r["note"] else ""))
    f["blind-seed-details"] = "\n".join(out)
