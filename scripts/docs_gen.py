#!/usr/bin/env python3
"""Generates every number, table, output block and figure of README.md and docs/ from runs.

    python3 scripts/docs_gen.py --write [--only MODULE ...]   # full size: run, store, rewrite
    python3 scripts/docs_gen.py --check                        # what CI runs (small size)
    python3 scripts/docs_gen.py --check --full [--only ...]    # full size, by hand: rerun, compare
    python3 scripts/docs_gen.py --render [--only MODULE ...]  # rewrite from the stored data only
    python3 scripts/docs_gen.py --list                         # modules, fragments, where they sit
    python3 scripts/docs_gen.py --audit                        # numbers outside markers: CI too

Generated text sits between marker comments, as a block

    <!-- gen:ID -->
    ...
    <!-- /gen:ID -->

or inline in a sentence (`<!-- gen:ID -->0.0078<!-- /gen:ID -->`). Nobody edits between
markers: `--write` replaces the text.

Each module in scripts/docsgen/ (one per chapter or experiment) has

    FRAGMENTS = [ids]             # what it writes
    collect(ctx) -> data          # runs the tool (at ctx.small or full size) and extracts
                                  # what the docs quote: numbers, tables, stdout, figures
    render(data) -> {id: text}    # Markdown from data alone: no runs, no files
    VOLATILE = [regex, ...]       # optional: parts of data that differ run to run (wall time)
    FULL_ONLY = [key, ...]        # optional: top-level data keys a small run need not produce

`--write` stores each module's data in docs/generated/MODULE.json beside the docs, so the
check needs no full-size run:

  1. render(stored data) must equal the text between the markers, byte for byte (a number
     typed by hand between markers, or data edited by hand without the docs, fails);
  2. every module runs at small size (ctx.small: few trials, small budgets) and its data
     must have the stored data's shape (same keys and types), and render it without error:
     the commands, files and fields the docs rely on still exist;
  3. every marker in the docs has a module, and every fragment a marker.

`--check --full` reruns at full size and compares the fresh data with the stored data
exactly (outside VOLATILE): runs are seeded, so a difference is a changed result.
Figures are copied into docs/figures by `--write`; the data holds their SHA-256, so a full
check also catches a changed figure.

`--audit` (also in CI) fails on any number outside markers, in the docs or in the prose a
module's render() types, that is not an input listed with its reason in
scripts/docsgen/inputs.toml (a suite's setting, a constant of the code, a test's threshold);
a reason naming a file is checked against that file.

Needs the release binary (`cargo build --release`); the data folder from $OPTBENCH_DATA
(default ../shared/data): modules that need it and find it absent say so and are skipped.
Standard library only (Python 3.11+).
"""

import argparse
import ast
import hashlib
import importlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from check_docs import markdown_files as doc_files

ROOT = Path(__file__).resolve().parent.parent
# Modules import this file as `docs_gen` (for Skip); run as a script it is `__main__`.
sys.modules.setdefault("docs_gen", sys.modules[__name__])
sys.path.insert(0, str(ROOT / "scripts"))
STORE = ROOT / "docs" / "generated"
FIGURES = ROOT / "docs" / "figures"
MARKER_RE = re.compile(r"<!-- gen:([A-Za-z0-9_.-]+) -->(.*?)<!-- /gen:\1 -->", re.S)
OPEN_RE = re.compile(r"<!-- /?gen:([A-Za-z0-9_.-]+) -->")


class Skip(Exception):
    """A module cannot run here (e.g. the data folder is absent)."""


class Ctx:
    """What a module's collect() gets: the binary, the data folder, scratch space, the size."""

    def __init__(self, small, scratch, write_figures, reuse=None):
        self.small = small
        self.root = ROOT
        self.bin = ROOT / "target" / "release" / "optbench"
        self.data = Path(os.environ.get("OPTBENCH_DATA", ROOT.parent / "shared" / "data"))
        self.scratch = Path(scratch)
        self.write_figures = write_figures
        self._runs = {}
        self.reuse = reuse or {}

    def need_data(self, *parts):
        """The data path, or Skip when the data folder (or that file) is absent."""
        p = self.data.joinpath(*parts)
        if not p.exists():
            raise Skip(f"{p} is absent (set OPTBENCH_DATA to the data folder)")
        return p

    def optbench(self, *args, check=True, env=None):
        """Runs the release binary from the repository root; text stdout/stderr."""
        if not self.bin.exists():
            sys.exit(f"error: {self.bin} is missing: run `cargo build --release` first")
        e = dict(os.environ, OPTBENCH_DATA=str(self.data), **(env or {}))
        r = subprocess.run([str(self.bin), *map(str, args)], cwd=ROOT, env=e,
                           capture_output=True, text=True)
        if check and r.returncode != 0:
            raise RuntimeError(f"optbench {' '.join(map(str, args))} exited {r.returncode}:\n"
                               f"{r.stderr[-3000:]}")
        return r

    def run_suite(self, suite, small_args=(), extra=()):
        """Runs a suite once per generation (shared by modules) and returns its folder.

        `small_args` (e.g. --trials 3 --budget 2000) apply only at small size."""
        args = tuple(map(str, extra)) + (tuple(map(str, small_args)) if self.small else ())
        key = (str(suite), args)
        if key not in self._runs and str(suite) in self.reuse and not self.small and not extra:
            out = Path(self.reuse[str(suite)])
            # The stored traces are reused; the report is rebuilt by this binary.
            self.optbench("report", out)
            print(f"    reused {out} for {suite} (report rebuilt)", file=sys.stderr)
            self._runs[key] = out
        if key not in self._runs:
            out = self.scratch / f"run{len(self._runs)}-{Path(suite).stem}"
            t0 = time.time()
            self.optbench("run", suite, "--out", out, "-q", *args)
            print(f"    ran {suite} {' '.join(args)} in {time.time() - t0:.0f} s", file=sys.stderr)
            self._runs[key] = out
        return self._runs[key]

    def figure(self, src, name):
        """Publishes a figure as docs/figures/NAME (when writing); returns its SHA-256."""
        src = Path(src)
        if not src.exists():
            raise RuntimeError(f"figure {src} was not written")
        if self.write_figures:
            FIGURES.mkdir(exist_ok=True)
            shutil.copyfile(src, FIGURES / name)
        return hashlib.sha256(src.read_bytes()).hexdigest()


def modules():
    names = sorted(p.stem for p in (ROOT / "scripts" / "docsgen").glob("*.py")
                   if not p.stem.startswith("_"))
    return {n: importlib.import_module(f"docsgen.{n}") for n in names}




def markers():
    """{id: (path, text between markers)}; errors for duplicates and unpaired markers."""
    found, errors = {}, []
    for f in doc_files():
        text = f.read_text()
        for m in MARKER_RE.finditer(text):
            if m.group(1) in found:
                errors.append(f"{f.relative_to(ROOT)}: gen:{m.group(1)} appears twice")
            found[m.group(1)] = (f, m.group(2))
        for i, line in enumerate(text.splitlines(), 1):
            if re.match(r"<!-- gen:\S+ -->\S", line):
                errors.append(f"{f.relative_to(ROOT)}:{i}: text follows an opening marker "
                              "that starts the line: CommonMark reads such a line as raw "
                              "HTML (put the marker on a line of its own, or after text)")
        paired = {m.group(1) for m in MARKER_RE.finditer(text)}
        for m in OPEN_RE.finditer(text):
            if m.group(1) not in paired:
                errors.append(f"{f.relative_to(ROOT)}: gen:{m.group(1)} has no closing "
                              "marker (or it is nested)")
    return found, errors


def place(old, new):
    """New text between markers, in the block or inline form the old text had."""
    if old.startswith("\n") and old.endswith("\n"):
        return "\n" + new.strip("\n") + "\n"
    if old.startswith("\n"):
        # The opening marker on a line of its own, the text ending in the closing marker:
        # a line that starts with `<!--` is an HTML block in CommonMark, so text may not
        # follow an opening marker that starts a line.
        if "\n" in new.strip("\n"):
            raise ValueError("a multi-line fragment needs block markers (on their own lines)")
        return "\n" + new.strip("\n")
    if "\n" in new.strip("\n"):
        raise ValueError("a multi-line fragment needs block markers (on their own lines)")
    return new.strip("\n")


def write_docs(rendered):
    by_file = {}
    found, errors = markers()
    if errors:
        sys.exit("\n".join(errors))
    for fid, text in rendered.items():
        if fid not in found:
            continue
        by_file.setdefault(found[fid][0], {})[fid] = text
    for f, frags in by_file.items():
        src = f.read_text()

        def sub(m, frags=frags):
            if m.group(1) not in frags:
                return m.group(0)
            return f"<!-- gen:{m.group(1)} -->{place(m.group(2), frags[m.group(1)])}<!-- /gen:{m.group(1)} -->"

        new = MARKER_RE.sub(sub, src)
        if new != src:
            tmp = f.with_suffix(".md.tmp")
            tmp.write_text(new)
            tmp.replace(f)
            print(f"  wrote {f.relative_to(ROOT)}")


NUMBER_RE = re.compile(r"(?<![\w./#-])[-−]?\d+(?:[.,]\d+)*(?:e[-+]?\d+)?(?:\s?%|x\b)?")


# A reference to a numbered part of the dissertation or the docs, or a name that is a number
# (a master seed, a blind case), not a value.
REFERENCE_RE = re.compile(
    r"\b(?:Tables?|Figs?\.|Figures?|eqs?\.|[Ss]ections?|[Cc]hapters?|(?:master )?seeds?|"
    r"cases?)\s+\**\d+(?:\.\d+)*\**"
    r"(?:\s*(?:[-/,–]|and)\s*\**\d+(?:\.\d+)*\**)*")
INPUTS = ROOT / "scripts" / "docsgen" / "inputs.toml"


def audit(root=None, files=None):
    """Lines with numbers outside markers that look like measurements (a decimal point, an
    exponent, a percent, a ratio or three digits and more), per file, with a count, and the
    same in the text the modules' render functions write. Numbers
    that are inputs (a suite's setting, a constant of the code, a version) are listed with
    their reason in scripts/docsgen/inputs.toml and pass. A reason that starts with a file
    of the repository and a colon ("suites/functions.toml: the budget") is checked: the
    number (without thousands commas; a percentage also as its fraction, a negative number
    also as its magnitude) must occur in that file. An entry no
    longer in its doc file is an error too, so the list cannot hide a number that has since
    changed. Returns the number of problems."""
    import tomllib
    root = root or ROOT
    inputs_file = root / INPUTS.relative_to(ROOT)
    inputs = tomllib.loads(inputs_file.read_text()) if inputs_file.exists() else {}
    total, used = 0, set()
    for f in (files if files is not None else doc_files()):
        if re.fullmatch(r"blind-proof-\d+\.md", f.name):
            continue   # a blind-proof report, written whole by scripts/blind_proof/run.py
        rel = str(f.relative_to(root))
        allowed = inputs.get(rel, {})
        text = MARKER_RE.sub("", f.read_text())
        text = re.sub(r"```.*?```", "", text, flags=re.S)
        hits = []
        for i, line in enumerate(text.splitlines(), 1):
            if line.startswith("#"):
                continue
            plain = re.sub(r"`[^`]*`|\]\([^)]*\)|<!--.*?-->", "", line)
            plain = REFERENCE_RE.sub("", plain)
            nums = [m.group(0) for m in NUMBER_RE.finditer(plain)
                    if re.search(r"[.,e%x]", m.group(0)) or len(m.group(0)) >= 3]
            used.update((rel, n) for n in nums if n in allowed)
            nums = [n for n in nums if n not in allowed]
            if nums:
                hits.append(f"  {' '.join(nums[:6])}: {line.strip()[:90]}")
        if hits:
            print(f"{rel}: {len(hits)} line(s)")
            print("\n".join(hits))
            total += len(hits)
    # The prose a module's render() writes is docs too: its string literals (outside
    # collect(), which only runs the tool) may hold inputs, listed like the docs' own.
    for f in sorted((root / "scripts" / "docsgen").glob("*.py")):
        if f.name.startswith("_"):
            continue
        rel = str(f.relative_to(root))
        allowed = inputs.get(rel, {})
        hits = []
        tree = ast.parse(f.read_text())
        for fn in (n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name != "collect"):
            doc = ast.get_docstring(fn, clean=False)
            for node in ast.walk(fn):
                if not (isinstance(node, ast.Constant) and isinstance(node.value, str)) \
                        or node.value == doc:
                    continue
                plain = REFERENCE_RE.sub("", re.sub(r"`[^`]*`|\]\([^)]*\)", "", node.value))
                if not re.search(r"[A-Za-z]{3}", plain):
                    continue   # a format spec, a separator, a regex
                nums = [m.group(0) for m in NUMBER_RE.finditer(plain)
                        if re.search(r"[.,e%x]", m.group(0)) or len(m.group(0)) >= 3]
                used.update((rel, n) for n in nums if n in allowed)
                nums = [n for n in nums if n not in allowed]
                if nums:
                    hits.append(f"  {' '.join(nums[:6])}: line {node.lineno}: "
                                f"{node.value.strip()[:70]!r}")
        if hits:
            print(f"{rel} (render text): {len(hits)} string(s)")
            print("\n".join(hits))
            total += len(hits)
    stale = [(f, n) for f, t in inputs.items() for n in t if (f, n) not in used]
    for f, n in stale:
        print(f"{inputs_file.relative_to(root)}: [\"{f}\"] \"{n}\" is no longer in that file: "
              "remove the entry")
    for f, t in inputs.items():
        for n, why in t.items():
            src = why.split(":", 1)[0]
            if ":" not in why or not (root / src).is_file():
                continue
            bare = re.sub(r"\s?%$|x$", "", n.replace(",", "").replace("−", "-"))
            text = re.sub(r"(?<=\d)_(?=\d)", "", (root / src).read_text())
            forms = [bare, bare.lstrip("-")] + ([repr(float(bare) / 100)] if n.endswith("%")
                                                else [])
            if not any(re.search(rf"(?<![\w.]){re.escape(b)}(?:\.0+)?(?![\w.]*\d)", text)
                       for b in forms):
                print(f"{inputs_file.relative_to(root)}: [\"{f}\"] \"{n}\": {bare} is not in {src}")
                stale.append((f, n))
    print(f"{total} line(s) with numbers outside gen markers and not listed as inputs; "
          f"{len(stale)} stale input entr{'y' if len(stale) == 1 else 'ies'}")
    return total + len(stale)


def shape(x):
    """The structure of data, without its values: keys, types, element shapes."""
    if isinstance(x, dict):
        return {k: shape(v) for k, v in sorted(x.items())}
    if isinstance(x, list):
        return ["list", shape(x[0]) if x else None]
    if isinstance(x, bool):
        return "bool"
    if isinstance(x, (int, float)) or x is None:
        return "number"   # a statistic may be null (no finite value) at small size
    return type(x).__name__


def shape_diff(a, b, path="data"):
    """First place where shapes a (stored) and b (fresh) differ, or None."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in b:
                return f"{path}.{k}: in the stored data, not produced now"
            if k not in a:
                return f"{path}.{k}: produced now, not in the stored data"
            d = shape_diff(a[k], b[k], f"{path}.{k}")
            if d:
                return d
        return None
    if isinstance(a, list) and isinstance(b, list):
        if a[1] is None or b[1] is None:
            return None
        return shape_diff(a[1], b[1], f"{path}[]")
    return None if a == b else f"{path}: stored {a}, now {b}"


def masked(data, volatile):
    s = json.dumps(data, indent=1)
    for rx in volatile:
        s = re.sub(rx, "<volatile>", s)
    return s


def store_path(name):
    return STORE / f"{name}.json"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--write", action="store_true", help="run at full size, store, rewrite docs")
    g.add_argument("--check", action="store_true", help="compare docs with generation")
    g.add_argument("--render", action="store_true",
                   help="rewrite the docs from the stored data, without running anything "
                        "(after a change to a module's render())")
    g.add_argument("--list", action="store_true")
    g.add_argument("--audit", action="store_true",
                   help="list the lines whose numbers sit outside gen markers (prose and "
                        "tables; code blocks, links and inline code are left out): inputs and "
                        "constants are fine there, results are not")
    ap.add_argument("--full", action="store_true", help="with --check: rerun at full size")
    ap.add_argument("--only", nargs="+", default=None, help="modules to run")
    ap.add_argument("--reuse", nargs="+", default=[], metavar="SUITE=DIR",
                    help="with --write: take a full-size run of SUITE from DIR (e.g. an "
                         "earlier `optbench run` of the same build) instead of running it")
    ap.add_argument("--keep", default=None, help="scratch folder to keep (default: a temp dir)")
    a = ap.parse_args()

    mods = modules()
    if a.only:
        unknown = [n for n in a.only if n not in mods]
        if unknown:
            sys.exit(f"error: unknown module(s) {unknown}; known: {sorted(mods)}")
    selected = {n: m for n, m in mods.items() if not a.only or n in a.only}
    found, errors = markers()
    owner = {}
    for n, m in mods.items():
        for fid in m.FRAGMENTS:
            if fid in owner:
                errors.append(f"fragment {fid} is declared by {owner[fid]} and {n}")
            owner[fid] = n
    errors += [f"{found[f][0].relative_to(ROOT)}: gen:{f} has no module" for f in found
               if f not in owner]
    errors += [f"fragment {f} of {owner[f]} has no marker in README.md or docs/"
               for f in owner if f not in found]

    if a.audit:
        sys.exit(1 if audit() else 0)
    if a.list:
        for n, m in mods.items():
            print(n)
            for fid in m.FRAGMENTS:
                where = found[fid][0].relative_to(ROOT) if fid in found else "(no marker)"
                print(f"  {fid:32} {where}")
        for e in errors:
            print("error:", e)
        sys.exit(1 if errors else 0)

    if a.render:
        for n, m in selected.items():
            if not store_path(n).exists():
                errors.append(f"{n}: docs/generated/{n}.json is missing: run --write --only {n}")
                continue
            write_docs(m.render(json.loads(store_path(n).read_text())))
        for e in errors:
            print("error:", e)
        sys.exit(1 if errors else 0)

    scratch = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="docs-gen-"))
    scratch.mkdir(parents=True, exist_ok=True)
    small = a.check and not a.full
    reuse = dict(r.split("=", 1) for r in a.reuse)
    ctx = Ctx(small=small, scratch=scratch, write_figures=a.write, reuse=reuse)
    skipped = []
    for n, m in selected.items():
        t0 = time.time()
        print(f"{n}: {'small' if small else 'full'} size", file=sys.stderr)
        stored = json.loads(store_path(n).read_text()) if store_path(n).exists() else None
        if a.check and stored is None:
            errors.append(f"{n}: docs/generated/{n}.json is missing: run --write --only {n}")
            continue
        if a.check:
            # 1. the docs are what the stored data renders.
            for fid, text in m.render(stored).items():
                if fid in found and found[fid][1] != place(found[fid][1], text):
                    errors.append(f"{found[fid][0].relative_to(ROOT)}: gen:{fid} differs from "
                                  f"what docs/generated/{n}.json renders (edited by hand? run "
                                  f"`python3 scripts/docs_gen.py --write --only {n}`)")
        try:
            data = m.collect(ctx)
        except Skip as s:
            print(f"  skipped: {s}", file=sys.stderr)
            skipped.append(n)
            continue
        data = json.loads(json.dumps(data))   # what would be stored: JSON types only
        rendered = m.render(data)
        missing = set(m.FRAGMENTS) - set(rendered)
        if missing and not small:   # a small run may cover fewer cases
            errors.append(f"{n}: render() did not produce {sorted(missing)}")
        if a.write:
            STORE.mkdir(exist_ok=True)
            tmp = store_path(n).with_suffix(".tmp")
            tmp.write_text(json.dumps(data, indent=1) + "\n")
            tmp.replace(store_path(n))
            write_docs(rendered)
        elif small:
            full_only = getattr(m, "FULL_ONLY", [])
            # A full-size-only key may be absent from a small run; if the small run has it
            # (its records happen to show it), its shape must be the stored one.
            d = shape_diff(shape({k: v for k, v in stored.items() if k not in full_only or k in data}),
                           shape(data))
            if d:
                errors.append(f"{n}: the small run's data differ in shape from the stored: {d}")
        else:
            vol = getattr(m, "VOLATILE", [])
            if masked(stored, vol) != masked(data, vol):
                old = masked(stored, vol).splitlines()
                new = masked(data, vol).splitlines()
                diff = [f"    stored {o.strip()}\n    now    {w.strip()}"
                        for o, w in zip(old, new) if o != w][:8]
                errors.append(f"{n}: full-size data differ from docs/generated/{n}.json:\n"
                              + "\n".join(diff))
        print(f"  {n}: {time.time() - t0:.0f} s", file=sys.stderr)
    if not a.keep:
        shutil.rmtree(scratch, ignore_errors=True)
    for e in errors:
        print("error:", e)
    if skipped:
        print(f"skipped (data absent): {', '.join(skipped)}")
    print("docs generation:", "FAILED" if errors else "ok",
          f"({len(selected) - len(skipped)} module(s) {'written' if a.write else 'checked'})")
    sys.exit(1 if errors else 0)


if __name__ == "__main__":
    main()
