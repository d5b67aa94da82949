"""Chapter 7's plausibility example and chapter 5's 'starts in motion' quote, from one run:
`optbench diagnose` on the PI P-885 stack (the 1 Hz sine for training, the ramped sine with
holds for validation), as chapter 7 prints the command. Needs the data folder.

What the docs quote is the tool's own text: the first accepted candidate's line and its
`! accepted although` flags, the `left out` line, the line of the candidates refused for
their own parameters, and the report's finding that a record starts in motion."""

import re

from docsgen._util import read_json

FOLDER = "pea_p885_dbo"
ARGS = ["--train", "dbo_identification_1Hz_sine.csv", "--validate",
        "dbo_test_ramped_sine_with_holds.csv", "--columns", "t_s,u_V,y_um"]
# A few seconds at small size: n = 1 is not tried against the fitted n, one effect only.
SMALL = ["--effects", "creep", "--bootstrap", "2"]
FRAGMENTS = ["p885-motion", "p885-flags"]
VOLATILE = [r'"wall_s": [0-9.e+-]+']
# How the prose names a flagged creep parameter.
WORDS = {"creep_tau_s": "its fast element at the fastest time constant allowed",
         "creep_gain": "its fast gain at the bound",
         "creep_gain_slow": "its slow gain at the bound",
         "creep_tau_slow_s": "its slow time constant at the bound"}
MOTION = re.compile(r"the (?:training|validation) record starts in motion: its first .*? of the "
                    r"residual power")


def collect(ctx):
    base = ctx.need_data(FOLDER)
    out = ctx.scratch / "diagnose-p885-examples"
    full = [str(base / a) if a.endswith(".csv") else a for a in ARGS]
    r = ctx.optbench("diagnose", *full, "--out", out, *(SMALL if ctx.small else []))
    d = read_json(out / "diagnosis.json")
    lines = r.stdout.splitlines()
    accepted = []
    for c in d["candidates"]:
        if not c.get("accepted"):
            continue
        label = f"+ {c['name']}" + (f" [{c['form']}]" if c.get("form") else "")
        at = next(i for i, l in enumerate(lines) if l.strip().startswith(label + " "))
        flags = []
        for l in lines[at + 1:]:
            if not l.startswith("      "):
                break
            if l.strip().startswith("! accepted although"):
                flags.append(l)
        accepted.append({"name": c["name"], "round": c["round"], "line": lines[at],
                         "flag_lines": flags,
                         "flags": [{"parameter": p["parameter"], "kind": p["kind"]}
                                   for p in c.get("plausibility") or []]})
    motion = next((m.group(0) for f in d["located"] for m in [MOTION.search(f["detail"])]
                   if m), "")
    return {
        "command": ["optbench", "diagnose"] + [f"$D/{a}" if a.endswith(".csv") else a
                                               for a in ARGS],
        "accepted": accepted,
        "left_out_line": next(l for l in lines if l.startswith("left out")),
        "refused_line": next((l for l in lines
                              if l.startswith("not named although the gate passed")), ""),
        "refused": [{"name": c["name"], "form": c.get("form"), "round": c["round"],
                     "held": "held at" in c["evidence"]}
                    for c in d["candidates"] if c.get("refused")],
        "core": (d.get("core_choice") or {}).get("chosen"),
        "held_named": [c["name"] for c in d["candidates"]
                       if c.get("accepted") and "named at the edge of plausible" in c["evidence"]],
        "motion": motion,
        "wall_s": d["wall_s"],
    }


def render(d):
    f = {"p885-motion": d["motion"]}
    block = ["$ " + " ".join(d["command"]), "    ..."]
    first = d["accepted"][0] if d["accepted"] else None
    if first:
        block += [first["line"], *first["flag_lines"], "    ..."]
    block.append(d["left_out_line"])
    if d.get("refused_line"):
        block += ["    ...", d["refused_line"]]
    if first:
        bound = [WORDS.get(p["parameter"], f"`{p['parameter']}` at a bound")
                 for p in first["flags"] if p["kind"] == "at-bound"]
        other = [f"`{p['parameter']}` flagged `{p['kind']}`" for p in first["flags"]
                 if p["kind"] != "at-bound"]
        said = " and ".join(bound) if bound else "no parameter at a bound"
        reading = (f"{first['name'].capitalize()} is accepted in round {first['round']} with "
                   f"{said}" + (f", and {' and '.join(other)}" if other else "") + ".")
    else:
        reading = "No candidate is accepted."
    if d.get("core") and d["core"] != "bouc-wen":
        reading = (f"The data reject the Bouc-Wen core and the search goes on with the "
                   f"`{d['core']}` core (`--model auto`). ") + reading
    refused = d.get("refused") or []
    if refused:
        held = sum(1 for r in refused if r["held"])
        reading += (f" {len(refused)} candidate(s) passed the gate with their own parameters "
                    f"implausible or at a bound and were not named"
                    + (f"; {held} of them creep that no longer passed when held at a quarter "
                       f"of the drive" if held else "") + ".")
    if d.get("held_named"):
        reading += (f" Named with creep held at a quarter of the drive (the stronger test "
                    f"passed): {', '.join(d['held_named'])}.")
    f["p885-flags"] = ("```text\n" + "\n".join(block) + "\n```\n\n" + reading
                       + f" The diagnosis took {d['wall_s']:.0f} s in this generation.")
    return f
