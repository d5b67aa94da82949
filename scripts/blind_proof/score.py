"""Scoring of blind-proof cases: exact match, Wilson intervals, confusion, report."""
from __future__ import annotations

import math
import statistics
from collections import Counter, defaultdict

EFFECTS = ["delay", "input-lag", "saturation", "asymmetry", "rate-dependence", "creep", "dynamics", "offset-drift"]


def wilson(k, n, z=1.959963984540054):
    """Wilson score interval (lo, hi) for k successes in n trials; (0, 1) for n = 0."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    den = 1 + z * z / n
    c = (p + z * z / (2 * n)) / den
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return max(0.0, c - h), min(1.0, c + h)


def normalise(name):
    """The tool's effect name onto the generator's vocabulary ('dynamics…' -> dynamics)."""
    name = name.strip()
    return "dynamics" if name.startswith("dynamics") else name


def named_set(diagnosis):
    return sorted({normalise(n) for n in diagnosis.get("left_out", [])})


def generator_notes(truth):
    """What the generator flags about a case: target not reached, sizes outside the nominal range or at a bound."""
    notes = []
    if truth.get("effects") and not truth.get("target_reached", True):
        notes.append("target not reached")
    for n, e in (truth.get("effect_settings") or {}).items():
        if e.get("in_nominal_range") is False:
            notes.append(f"{n} outside nominal range")
        if e.get("at_bound"):
            notes.append(f"{n} at calibration bound")
    return notes


def rate(k, n):
    lo, hi = wilson(k, n)
    return {"k": k, "n": n, "rate": (k / n) if n else None, "lo": lo, "hi": hi}


def score(results):
    """results: list of dicts with id, truth (truth.json), diagnosis (diagnosis.json or None), wall_s."""
    done = [r for r in results if r.get("diagnosis") is not None]
    for r in done:
        r["named"] = named_set(r["diagnosis"])
        r["exact"] = set(r["named"]) == set(r["truth"]["effects"])
    singles = [r for r in done if len(r["truth"]["effects"]) == 1]
    pairs = [r for r in done if len(r["truth"]["effects"]) == 2]
    nulls = [r for r in done if not r["truth"]["effects"]]
    out = {"cases": len(results), "scored": len(done), "missing": [r["id"] for r in results if r.get("diagnosis") is None]}
    out["singles"] = rate(sum(r["exact"] for r in singles), len(singles))
    out["pairs"] = rate(sum(r["exact"] for r in pairs), len(pairs))
    out["nulls_false_alarm"] = rate(sum(bool(r["named"]) for r in nulls), len(nulls))
    out["overall"] = rate(sum(r["exact"] for r in done), len(done))
    per = {}
    confusion = {e: Counter() for e in EFFECTS}
    for e in EFFECTS:
        rs = [r for r in singles if r["truth"]["effects"] == [e]]
        per[e] = rate(sum(r["exact"] for r in rs), len(rs))
        for r in rs:
            if not r["named"]:
                confusion[e]["none"] += 1
            for n in r["named"]:
                confusion[e][n] += 1
    out["per_effect"] = per
    out["confusion"] = {e: dict(c) for e, c in confusion.items()}
    spurious, misses = Counter(), Counter()
    for r in done:
        for n in set(r["named"]) - set(r["truth"]["effects"]):
            spurious[n] += 1
        for n in set(r["truth"]["effects"]) - set(r["named"]):
            misses[n] += 1
    out["spurious"] = dict(spurious)
    out["misses"] = dict(misses)
    forms = defaultdict(list)
    for r in singles + pairs:
        for e, f in r["truth"]["forms"].items():
            forms[f"{e}/{f}"].append(r["exact"])
    out["per_form"] = {k: rate(sum(v), len(v)) for k, v in sorted(forms.items())}
    walls = [(r["wall_s"], r["id"]) for r in done if r.get("wall_s") is not None]
    if walls:
        out["wall_s"] = {"median": statistics.median(w for w, _ in walls), "worst": max(walls)[0],
                         "worst_case": max(walls)[1], "total": sum(w for w, _ in walls),
                         # the bar: every case within 60 s
                         "over_60s": sorted([(i, w) for w, i in walls if w > 60.0], key=lambda x: -x[1])}
    ratios = []
    for r in done:
        t, d = r["truth"], r["diagnosis"]
        sig = t["noise_sigma_mm"]
        base = (d.get("baseline") or {}).get("validate_rmse")
        fin = (d.get("final") or {}).get("validate_rmse")
        r["ratios"] = {"target": t["target_ratio"], "linearised": t["achieved_ratio_linearised"],
                       "baseline": base / sig if base is not None else None,
                       "final": fin / sig if fin is not None else None,
                       "noise_floor": d.get("noise_floor", float("nan")) / sig if d.get("noise_floor") else None}
        ratios.append({"id": r["id"], "effects": t["effects"], **r["ratios"]})
    out["ratios"] = ratios
    eff_r = [x for x in ratios if x["effects"] and x["baseline"] is not None]
    if eff_r:
        rel = [x["baseline"] / x["target"] for x in eff_r]
        out["baseline_over_target"] = {"median": statistics.median(rel), "min": min(rel), "max": max(rel)}
    out["failed"] = [{"id": r["id"], "truth": r["truth"]["effects"], "forms": r["truth"]["forms"],
                      "named": r["named"], "notes": generator_notes(r["truth"]), **r["ratios"]}
                     for r in done if not r["exact"]]
    out["generator_flags"] = {r["id"]: generator_notes(r["truth"]) for r in done if generator_notes(r["truth"])}
    return out


def _fmt(x):
    if x["n"] == 0:
        return "– (0 cases)"
    return f"{x['k']}/{x['n']} = {100 * x['rate']:.0f} % [{100 * x['lo']:.0f}, {100 * x['hi']:.0f}]"


def _num(x, f="{:.2f}"):
    return "–" if x is None else f.format(x)


def markdown(s, title="Blind proof of optbench diagnose"):
    b = s.get("binary")
    L = [f"# {title}", "", f"Cases: {s['cases']}, scored: {s['scored']}"
         + (f", missing: {', '.join(s['missing'])}" if s["missing"] else ""), ""]
    if b:
        L += [f"Binary: commit `{b['commit']}`" + "".join(f" ({n})" for n in b["notes"]), ""]
    L += ["Exact match = the named set equals the truth set. Intervals: Wilson 95 %.", "",
          "| group | exact match |", "|---|---|"]
    for e in EFFECTS:
        L.append(f"| {e} (single) | {_fmt(s['per_effect'][e])} |")
    L += [f"| **all singles** | {_fmt(s['singles'])} |", f"| **pairs** | {_fmt(s['pairs'])} |",
          f"| **overall** | {_fmt(s['overall'])} |", "",
          f"False alarms on nulls (any name): {_fmt(s['nulls_false_alarm'])}", "",
          "## Confusion (singles: truth x named, counts)", "",
          "| truth \\ named | " + " | ".join(EFFECTS + ["none"]) + " |",
          "|---" * (len(EFFECTS) + 2) + "|"]
    for e in EFFECTS:
        c = s["confusion"][e]
        L.append(f"| {e} | " + " | ".join(str(c.get(n, 0) or "") for n in EFFECTS + ["none"]) + " |")
    L += ["", "Spurious names (named, not in truth; all cases): "
          + (", ".join(f"{k} {v}" for k, v in sorted(s["spurious"].items())) or "none"),
          "", "Misses (in truth, not named): " + (", ".join(f"{k} {v}" for k, v in sorted(s["misses"].items())) or "none"),
          "", "## Exact match per truth form (singles and pairs)", "", "| form | exact |", "|---|---|"]
    for k, v in s["per_form"].items():
        L.append(f"| {k} | {_fmt(v)} |")
    if "wall_s" in s:
        w = s["wall_s"]
        over = w.get("over_60s", [])
        listed = ", ".join(f"{i} {t:.1f} s" for i, t in over) if over else "none"
        L += ["", f"Wall time per case: median {w['median']:.1f} s, worst {w['worst']:.1f} s ({w['worst_case']}), "
              f"total {w['total']:.0f} s; over 60 s: {len(over)} ({listed})"]
    if "baseline_over_target" in s:
        b = s["baseline_over_target"]
        L += ["", "Tool's baseline validation RMSE / noise sigma over the generator's target ratio (effect cases): "
              f"median {b['median']:.2f}, range {b['min']:.2f}-{b['max']:.2f}"]
    L += ["", "## Ratios (validation RMSE / noise sigma)", "",
          "| case | truth | target | linearised | tool baseline | tool final | tool noise floor / sigma |",
          "|---|---|---|---|---|---|---|"]
    for x in s["ratios"]:
        L.append(f"| {x['id']} | {'+'.join(x['effects']) or 'none'} | {_num(x['target'])} | {_num(x['linearised'])} | "
                 f"{_num(x['baseline'])} | {_num(x['final'])} | {_num(x['noise_floor'])} |")
    L += ["", "## Failed cases", ""]
    if not s["failed"]:
        L.append("none")
    else:
        L += ["| case | truth (forms) | named | target | linearised | tool baseline | generator notes |",
              "|---|---|---|---|---|---|---|"]
        for f in s["failed"]:
            tr = ", ".join(f"{e} ({f['forms'][e]})" for e in f["truth"]) or "none"
            L.append(f"| {f['id']} | {tr} | {', '.join(f['named']) or 'none'} | {_num(f['target'])} | "
                     f"{_num(f['linearised'])} | {_num(f['baseline'])} | {'; '.join(f['notes'])} |")
    L += ["", f"Cases the generator flags: {len(s.get('generator_flags', {}))}"
          + "".join(f"\n- {k}: {'; '.join(v)}" for k, v in s.get("generator_flags", {}).items())]
    return "\n".join(L) + "\n"
