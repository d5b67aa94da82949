"""Scoring of blind-proof cases: exact match, Wilson intervals, confusion, report."""
from __future__ import annotations

import json
import math
import statistics
from collections import Counter, defaultdict

EFFECTS = ["delay", "input-lag", "saturation", "asymmetry", "rate-dependence", "creep", "dynamics", "offset-drift"]
OOV_KINDS = ["backlash", "sensor-nonlinearity", "thermal", "dead-zone", "mains", "feed-through"]
# An out-of-vocabulary case the named effects approximate to this many times the tool's noise floor passes.
OOV_APPROXIMATED = 1.15


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


def is_oov(truth):
    return bool(truth.get("oov"))


def outside_vocabulary(diagnosis):
    """What a diagnosis says lies outside its names (`outside_vocabulary`): None when absent,
    else the features of its `depends_on` list (or a note of the field's value)."""
    ov = diagnosis.get("outside_vocabulary")
    if ov is None:
        return None
    if isinstance(ov, dict):
        dep = ov.get("depends_on")
        if not isinstance(dep, list):
            return [json_short(ov)]
        return [str(x.get("feature", json_short(x))) if isinstance(x, dict) else str(x) for x in dep]
    if isinstance(ov, list):
        return [str(x) for x in ov]
    if ov is True and isinstance(diagnosis.get("depends_on"), list):
        return [str(x) for x in diagnosis["depends_on"]]
    return [json_short(ov)]


def json_short(x):
    t = json.dumps(x, sort_keys=True)
    return t if len(t) <= 80 else t[:77] + "..."


def oov_verdict(diagnosis):
    """Pass or fail of an out-of-vocabulary case (no name of the vocabulary is right).

    Passes when the tool reports it as unexplained with what it depends on (`unexplained`
    true and its `outside_vocabulary` characterisation present, even if that finds no
    feature that predicts), or when what it named (or the plain model, if nothing)
    approximates it to the noise: final validation RMSE / noise floor <= OOV_APPROXIMATED.
    Fails when `unexplained` is false while the final validation RMSE is above that: a
    name claimed with confidence that does not fit ("confident wrong name"), nothing
    named and the structure left unflagged ("silent"), or flagged without saying what it
    depends on ("not characterised")."""
    named = named_set(diagnosis)
    unexplained = bool(diagnosis.get("unexplained"))
    fin = (diagnosis.get("final") or {}).get("validate_rmse")
    floor = diagnosis.get("noise_floor")
    ratio = fin / floor if fin is not None and floor else None
    approximated = ratio is not None and ratio <= OOV_APPROXIMATED
    characterised = diagnosis.get("outside_vocabulary") is not None
    if unexplained and not characterised and not approximated:
        outcome = "not characterised"
    elif unexplained:
        outcome = "unexplained (named, not claimed)" if named else "unexplained"
    elif approximated:
        outcome = "approximated by the names" if named else "plain model at the noise"
    else:
        outcome = "confident wrong name" if named else "silent"
    # Stricter, reported only: a name beside `unexplained` still points the user at the wrong physics.
    strict = approximated or (unexplained and characterised and not named)
    return {"pass": (unexplained and characterised) or approximated, "strict": strict, "outcome": outcome, "named": named,
            "unexplained": unexplained, "final_over_floor": ratio,
            "outside_vocabulary": outside_vocabulary(diagnosis)}


def tie_partners(diagnosis):
    """Per accepted candidate's effect, the effects the tool declared it tied with (`ties`):
    the records could not tell them apart."""
    out = defaultdict(set)
    for c in diagnosis.get("candidates") or []:
        if c.get("accepted") and not c.get("dropped"):
            for part in str(c.get("name", "")).split("+"):
                out[normalise(part)] |= {normalise(str(t.get("name", "")).split()[0]) for t in c.get("ties") or []}
    return out


def declared_tie(truth_effects, named, diagnosis):
    """A miss the tool itself declared undecidable: every true effect not named is a declared
    tie partner of a named effect that is not true, and each such named effect is tied with a
    missed one. Reported beside the exact match, never in it."""
    miss, extra = set(truth_effects) - set(named), set(named) - set(truth_effects)
    if not miss or len(miss) != len(extra):
        return False
    ties = tie_partners(diagnosis)
    return all(any(m in ties.get(e, ()) for e in extra) for m in miss) and \
        all(any(m in ties.get(e, ()) for m in miss) for e in extra)


def generator_notes(truth):
    """What the generator flags about a case: target not reached, sizes outside the nominal range or at a bound."""
    notes = []
    if (truth.get("effects") or is_oov(truth)) and not truth.get("target_reached", True):
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
    done_all = [r for r in results if r.get("diagnosis") is not None]
    for r in done_all:
        r["named"] = named_set(r["diagnosis"])
        r["exact"] = set(r["named"]) == set(r["truth"]["effects"])
    # Out-of-vocabulary cases have no right name: scored on their own (`oov`), not in the groups below.
    oov_done = [r for r in done_all if is_oov(r["truth"])]
    done = [r for r in done_all if not is_oov(r["truth"])]
    singles = [r for r in done if len(r["truth"]["effects"]) == 1]
    pairs = [r for r in done if len(r["truth"]["effects"]) == 2]
    nulls = [r for r in done if not r["truth"]["effects"]]
    out = {"cases": len(results), "scored": len(done_all), "missing": [r["id"] for r in results if r.get("diagnosis") is None]}
    out["singles"] = rate(sum(r["exact"] for r in singles), len(singles))
    out["pairs"] = rate(sum(r["exact"] for r in pairs), len(pairs))
    out["nulls_false_alarm"] = rate(sum(bool(r["named"]) for r in nulls), len(nulls))
    out["overall"] = rate(sum(r["exact"] for r in done), len(done))
    for r in done:
        r["declared_tie"] = not r["exact"] and declared_tie(r["truth"]["effects"], r["named"], r["diagnosis"])
    out["declared_ties"] = {g: sum(r["declared_tie"] for r in rs) for g, rs in
                            (("singles", singles), ("pairs", pairs))}
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
    walls = [(r["wall_s"], r["id"]) for r in done_all if r.get("wall_s") is not None]
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
                      "named": r["named"], "declared_tie": r["declared_tie"],
                      "notes": generator_notes(r["truth"]), **r["ratios"]}
                     for r in done if not r["exact"]]
    out["generator_flags"] = {r["id"]: generator_notes(r["truth"]) for r in done_all if generator_notes(r["truth"])}
    if oov_done:
        out["oov"] = score_oov(oov_done)
    return out


def score_oov(rs):
    """Per out-of-vocabulary case its verdict; per kind and overall the pass rate."""
    cases = []
    for r in rs:
        t, d = r["truth"], r["diagnosis"]
        v = oov_verdict(d)
        sig = t["noise_sigma_mm"]
        fin = (d.get("final") or {}).get("validate_rmse")
        base = (d.get("baseline") or {}).get("validate_rmse")
        cases.append({"id": r["id"], "kind": t["oov"], "form": t.get("oov_form"), **v,
                      "target": t["target_ratio"], "linearised": t["achieved_ratio_linearised"],
                      "baseline_over_sigma": base / sig if base is not None else None,
                      "final_over_sigma": fin / sig if fin is not None else None,
                      "floor_over_sigma": d["noise_floor"] / sig if d.get("noise_floor") else None,
                      "notes": generator_notes(t)})
    kinds = sorted({c["kind"] for c in cases}, key=lambda k: (OOV_KINDS.index(k) if k in OOV_KINDS else 99, k))
    per = {}
    for k in kinds:
        cs = [c for c in cases if c["kind"] == k]
        per[k] = {**rate(sum(c["pass"] for c in cs), len(cs)), "strict": rate(sum(c["strict"] for c in cs), len(cs)),
                  "named": dict(Counter(n for c in cs for n in c["named"])),
                  "outcomes": dict(Counter(c["outcome"] for c in cs))}
    return {"threshold_final_over_floor": OOV_APPROXIMATED,
            "overall": rate(sum(c["pass"] for c in cases), len(cases)),
            "strict": rate(sum(c["strict"] for c in cases), len(cases)),
            "per_kind": per, "cases": cases,
            "outcomes": dict(Counter(c["outcome"] for c in cases))}


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
          f"| **overall** | {_fmt(s['overall'])} |", ""]
    ties = s.get("declared_ties") or {}
    if any(ties.values()):
        L += [f"Not exact, but declared by the tool as a tie with the truth (the records cannot tell the "
              f"named effect from the true one; counted as misses above): singles {ties.get('singles', 0)}, "
              f"pairs {ties.get('pairs', 0)}.", ""]
    L += [f"False alarms on nulls (any name): {_fmt(s['nulls_false_alarm'])}", "",
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
            named = (', '.join(f['named']) or 'none') + (" (declared tie)" if f.get("declared_tie") else "")
            L.append(f"| {f['id']} | {tr} | {named} | {_num(f['target'])} | "
                     f"{_num(f['linearised'])} | {_num(f['baseline'])} | {'; '.join(f['notes'])} |")
    L += ["", f"Cases the generator flags: {len(s.get('generator_flags', {}))}"
          + "".join(f"\n- {k}: {'; '.join(v)}" for k, v in s.get("generator_flags", {}).items())]
    if "oov" in s:
        L += [""] + markdown_oov(s["oov"])
    return "\n".join(L) + "\n"


def markdown_oov(o):
    """The out-of-vocabulary section of the report."""
    thr = o["threshold_final_over_floor"]
    L = ["## Out of vocabulary", "",
         "Physics outside the eight names; no name is right. A case passes when the tool says structure is "
         f"left (`unexplained`) or what it named approximates it to the noise (final validation RMSE / "
         f"noise floor <= {thr}); it fails when it claims a name with confidence (`unexplained` false) "
         "above that, or names nothing and flags nothing. Strict (reported, not a threshold): no name beside "
         "`unexplained`, unless the names fit to the noise. Intervals: Wilson 95 %.", "",
         "| kind | passes | strict | named (cases) | outcomes |", "|---|---|---|---|---|"]
    for k, v in o["per_kind"].items():
        named = ", ".join(f"{n} {c}" for n, c in sorted(v["named"].items())) or "nothing"
        outs = ", ".join(f"{n} {c}" for n, c in sorted(v["outcomes"].items()))
        L.append(f"| {k} | {_fmt(v)} | {_fmt(v['strict'])} | {named} | {outs} |")
    L += [f"| **all** | {_fmt(o['overall'])} | {_fmt(o['strict'])} | | "
          + ", ".join(f"{n} {c}" for n, c in sorted(o["outcomes"].items())) + " |", "",
          "| case | kind (form) | named | unexplained | final / floor | final / sigma | tool baseline / sigma | "
          "target | verdict | outside vocabulary (depends on) |",
          "|---|---|---|---|---|---|---|---|---|---|"]
    for c in o["cases"]:
        ov = "–" if c["outside_vocabulary"] is None else (", ".join(c["outside_vocabulary"]) or "(empty)")
        L.append(f"| {c['id']} | {c['kind']} ({c['form']}) | {', '.join(c['named']) or 'nothing'} | "
                 f"{'yes' if c['unexplained'] else 'no'} | {_num(c['final_over_floor'])} | "
                 f"{_num(c['final_over_sigma'])} | {_num(c['baseline_over_sigma'])} | {_num(c['target'])} | "
                 f"{'pass' if c['pass'] else 'FAIL'}: {c['outcome']} | {ov} |")
    return L
