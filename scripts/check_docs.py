#!/usr/bin/env python3
"""Checks README.md and the book in docs/ (Python 3, standard library only).

    python3 scripts/check_docs.py                 # static checks; exit 1 on any error
    python3 scripts/check_docs.py --list          # also list every documented command
    python3 scripts/check_docs.py --run [--timeout 600] [--only TEXT] [--keep-going]

Static checks (errors make the exit status 1):
  - README.md has at most 150 lines;
  - every relative link and image in README.md and docs/**/*.md points to an existing file
    or folder, and every `#anchor` (in the same file or in another Markdown file) to an
    existing heading, by GitHub's slug rules;
  - every table's header row has as many cells as its delimiter row, and no body row has
    more cells than the header (GitHub drops the extra cells silently).

Documented commands: every line of a fenced code block marked sh, bash, shell or console
(continuation lines joined, `# comments` dropped) that starts with `optbench`, `cargo run`,
`target/release/optbench`, `./target/release/optbench`, `python3 scripts/` or `bash`.
Variable assignments at the start of a line (`D=...`) are kept and run before the block's
later commands. `--run` runs them in document order (README first, then the book), from the
repository root, with `target/release` first on PATH (so `optbench` is the release binary:
build it first with `cargo build --release`), each with a timeout, and reports pass or fail
(exit 1 if any failed). A command that appears twice runs once.

A block that must not be run is marked by an HTML comment on the line right before its
opening fence, with the reason:

    <!-- check: skip (the full blind proof: about 14 min on 2 cores) -->

Keep such skips few: for commands that are genuinely long or need what a plain checkout
does not have. Synopses with placeholders belong in `text` blocks, which are not commands.
"""

import argparse
import os
import re
import subprocess
import sys
import time
import unicodedata
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README_MAX_LINES = 150
SHELL_LANGS = {"sh", "bash", "shell", "console"}
PREFIXES = ("optbench", "cargo run", "target/release/optbench", "./target/release/optbench",
            "python3 scripts/", "bash")
SKIP_RE = re.compile(r"<!--\s*check:\s*skip\s*\((.+?)\)\s*-->", re.S)
FENCE_RE = re.compile(r"^( {0,3})(`{3,}|~{3,})(.*)$")
ASSIGN_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*=\S")


def markdown_files():
    files = [ROOT / "README.md"]
    files += sorted((ROOT / "docs").rglob("*.md"))
    return files


def rel(path):
    try:
        return str(path.relative_to(ROOT))
    except ValueError:
        return str(path)


# ---------------------------------------------------------------- parsing


def split_blocks(text):
    """Yields ('text', lineno, line) for lines outside fences and
    ('fence', lineno, lang, lines, skip_reason) for each fenced block."""
    lines = text.split("\n")
    out = []
    i = 0
    while i < len(lines):
        m = FENCE_RE.match(lines[i])
        if m:
            marker, info = m.group(2), m.group(3).strip()
            lang = info.split()[0].lower() if info else ""
            start = i
            body = []
            i += 1
            while i < len(lines):
                m2 = FENCE_RE.match(lines[i])
                if m2 and m2.group(2)[0] == marker[0] and len(m2.group(2)) >= len(marker) \
                        and not m2.group(3).strip():
                    break
                body.append(lines[i])
                i += 1
            # the skip marker: the nearest non-blank line before the fence
            j = start - 1
            while j >= 0 and not lines[j].strip():
                j -= 1
            skip = None
            if j >= 0:
                s = SKIP_RE.search(lines[j])
                if s:
                    skip = " ".join(s.group(1).split())
            out.append(("fence", start + 1, lang, body, skip))
            i += 1
            continue
        out.append(("text", i + 1, lines[i]))
        i += 1
    return out


def strip_code_spans(line):
    """Replaces inline code spans by spaces so links inside them are not seen."""
    out = []
    i = 0
    while i < len(line):
        if line[i] == "`":
            n = len(line) - len(line[i:].lstrip("`"))
            ticks = line[i:i + n]
            end = line.find(ticks, i + n)
            if end == -1:
                out.append(line[i:i + n])
                i += n
                continue
            out.append(" " * (end + n - i))
            i = end + n
            continue
        out.append(line[i])
        i += 1
    return "".join(out)


LINK_RE = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^()\s<>]+(?:\([^()\s]*\))?)>?(?:\s+\"[^\"]*\")?\s*\)")
HTML_LINK_RE = re.compile(r"<(?:a|img)\s[^>]*?(?:href|src)\s*=\s*\"([^\"]+)\"", re.I)
REF_DEF_RE = re.compile(r"^ {0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s.*)?$")


def links_of(path, text):
    """(lineno, target) of every link and image outside code."""
    found = []
    for kind, lineno, *rest in split_blocks(text):
        if kind != "text":
            continue
        line = strip_code_spans(rest[0])
        for m in LINK_RE.finditer(line):
            found.append((lineno, m.group(1)))
        for m in HTML_LINK_RE.finditer(line):
            found.append((lineno, m.group(1)))
        m = REF_DEF_RE.match(line)
        if m:
            found.append((lineno, m.group(1)))
    return found


def heading_text(raw):
    """The rendered text of a heading's Markdown, roughly as GitHub renders it."""
    t = raw.strip()
    t = re.sub(r"\s+#+\s*$", "", t)                           # closing hashes
    t = re.sub(r"!\[([^\]]*)\]\([^)]*\)", r"\1", t)           # images
    t = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", t)            # links
    t = re.sub(r"<[^>]+>", "", t)                              # HTML tags
    t = t.replace("`", "")
    t = re.sub(r"(\*\*|__)(.+?)\1", r"\2", t)
    t = re.sub(r"(?<![\w*])\*(?!\s)(.+?)(?<!\s)\*", r"\1", t)
    return t


def github_slug(text):
    """GitHub's anchor of a heading: lower case, punctuation other than '-' and '_'
    dropped, spaces turned into '-'."""
    s = text.strip().lower()
    out = []
    for ch in s:
        cat = unicodedata.category(ch)
        if ch in "-_" or ch == " ":
            out.append("-" if ch == " " else ch)
        elif cat[0] in "LN" or cat == "Mn" or cat == "Mc":
            out.append(ch)
    return "".join(out)


_anchor_cache = {}


def anchors_of(path):
    if path in _anchor_cache:
        return _anchor_cache[path]
    text = path.read_text(encoding="utf-8")
    seen = {}
    anchors = set()
    lines = [(k, n, *r) for k, n, *r in split_blocks(text)]
    prev_text = None
    for item in lines:
        if item[0] != "text":
            prev_text = None
            continue
        line = item[2]
        slug_src = None
        m = re.match(r"^ {0,3}(#{1,6})\s+(.*)$", line)
        if m:
            slug_src = m.group(2)
        elif prev_text and prev_text.strip() and re.match(r"^ {0,3}(=+|-+)\s*$", line) \
                and not prev_text.lstrip().startswith(("-", "*", "|", ">")):
            slug_src = prev_text                               # setext heading
        if slug_src is not None:
            base = github_slug(heading_text(slug_src))
            n = seen.get(base, 0)
            anchors.add(base if n == 0 else f"{base}-{n}")
            seen[base] = n + 1
        for m2 in re.finditer(r"<a\s[^>]*?(?:name|id)\s*=\s*\"([^\"]+)\"", line, re.I):
            anchors.add(m2.group(1))
        prev_text = line
    _anchor_cache[path] = anchors
    return anchors


def table_cells(line):
    """Cells of a table row by GitHub's rules: split on unescaped '|' (also inside code
    spans), the outer pipes optional."""
    s = line.strip()
    cells = re.split(r"(?<!\\)\|", s)
    if s.startswith("|"):
        cells = cells[1:]
    if s.endswith("|") and not s.endswith("\\|"):
        cells = cells[:-1]
    return cells


DELIM_CELL_RE = re.compile(r"^\s*:?-+:?\s*$")


def check_tables(path, text):
    errors = []
    items = split_blocks(text)
    lines = [(it[1], it[2]) if it[0] == "text" else (it[1], None) for it in items]
    i = 0
    while i < len(lines) - 1:
        n, line = lines[i]
        n2, nxt = lines[i + 1]
        if line is not None and nxt is not None and "|" in line and "|" in nxt \
                and all(DELIM_CELL_RE.match(c) for c in table_cells(nxt)) and table_cells(nxt):
            head = len(table_cells(line))
            delim = len(table_cells(nxt))
            if head != delim:
                errors.append(f"{rel(path)}:{n}: table header has {head} cells, its delimiter row {delim}")
            j = i + 2
            while j < len(lines) and lines[j][1] is not None and lines[j][1].strip() \
                    and "|" in lines[j][1]:
                cells = len(table_cells(lines[j][1]))
                if cells > head:
                    errors.append(f"{rel(path)}:{lines[j][0]}: table row has {cells} cells, "
                                  f"the header {head} (GitHub drops the extra ones)")
                j += 1
            i = j
            continue
        i += 1
    return errors


def check_links(path, text):
    errors = []
    for lineno, target in links_of(path, text):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("//"):
            continue                                           # http:, mailto:, ...
        target_path, _, anchor = target.partition("#")
        if target_path:
            dest = (path.parent / target_path).resolve()
            if not dest.exists():
                errors.append(f"{rel(path)}:{lineno}: link to a missing file: {target}")
                continue
        else:
            dest = path
        if anchor:
            if dest.is_dir() or dest.suffix.lower() != ".md":
                continue
            if anchor not in anchors_of(dest):
                errors.append(f"{rel(path)}:{lineno}: link to a missing heading: {target}")
    return errors


# ---------------------------------------------------------------- commands


def strip_comment(line):
    """Drops a trailing `# comment` that is outside quotes and after a blank."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i].rstrip()
    return line.rstrip()


def commands_of(path, text):
    """(lineno, command, env assignments, skip reason) of every documented command."""
    found = []
    for item in split_blocks(text):
        if item[0] != "fence":
            continue
        _, start, lang, body, skip = item
        if lang not in SHELL_LANGS:
            continue
        assigns = []
        k = 0
        while k < len(body):
            lineno = start + 1 + k
            line = body[k]
            while line.rstrip().endswith("\\") and k + 1 < len(body):
                k += 1
                line = line.rstrip()[:-1].rstrip() + " " + body[k].strip()
            k += 1
            cmd = strip_comment(line).strip()
            if lang == "console" and cmd.startswith("$ "):
                cmd = cmd[2:]
            if not cmd:
                continue
            if ASSIGN_RE.match(cmd) and " " not in cmd.split("=", 1)[0]:
                assigns.append(cmd)
                continue
            if cmd.startswith(PREFIXES):
                found.append((lineno, cmd, list(assigns), skip))
    return found


def run_commands(commands, timeout, only, keep_going):
    env = dict(os.environ)
    env["PATH"] = str(ROOT / "target" / "release") + os.pathsep + env.get("PATH", "")
    if not (ROOT / "target" / "release" / "optbench").exists():
        print("note: target/release/optbench is missing: run `cargo build --release` first",
              file=sys.stderr)
    done = {}
    failed = 0
    results = []
    for path, lineno, cmd, assigns, skip in commands:
        where = f"{rel(path)}:{lineno}"
        script = "\n".join(assigns + [cmd])
        if only and only not in cmd:
            continue
        if skip:
            results.append(("SKIP", where, cmd, 0.0, skip))
            print(f"SKIP  {where}: {cmd}\n      ({skip})", flush=True)
            continue
        if script in done:
            results.append(("SAME", where, cmd, 0.0, f"ran at {done[script]}"))
            print(f"SAME  {where}: {cmd} (ran at {done[script]})", flush=True)
            continue
        done[script] = where
        print(f"RUN   {where}: {cmd}", flush=True)
        t0 = time.monotonic()
        try:
            p = subprocess.run(["bash", "-c", "set -eo pipefail\n" + script], cwd=ROOT, env=env,
                               stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, timeout=timeout)
            dt = time.monotonic() - t0
            ok = p.returncode == 0
            tail = p.stdout.decode("utf-8", "replace").strip().split("\n")[-6:]
            status = "PASS" if ok else "FAIL"
            note = "" if ok else f"exit {p.returncode}: " + " | ".join(tail)
        except subprocess.TimeoutExpired:
            dt = time.monotonic() - t0
            ok, status, note = False, "FAIL", f"timed out after {timeout:.0f} s"
        results.append((status, where, cmd, dt, note))
        print(f"{status}  {dt:7.1f} s" + (f"  {note}" if note else ""), flush=True)
        if not ok:
            failed += 1
            if not keep_going:
                break
    print("\nsummary:")
    for status, where, cmd, dt, note in results:
        print(f"  {status:4} {dt:7.1f} s  {where}: {cmd}" + (f"  [{note}]" if note and status != 'PASS' else ""))
    counts = {s: sum(1 for r in results if r[0] == s) for s in ("PASS", "FAIL", "SKIP", "SAME")}
    print("  " + ", ".join(f"{v} {k.lower()}" for k, v in counts.items()))
    return failed


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--list", action="store_true", help="list every documented command")
    ap.add_argument("--run", action="store_true", help="run every documented command")
    ap.add_argument("--timeout", type=float, default=600, help="seconds per command (default 600)")
    ap.add_argument("--only", default="", help="run only the commands containing this text")
    ap.add_argument("--keep-going", action="store_true", default=True,
                    help="go on after a failed command (the default)")
    ap.add_argument("--stop", dest="keep_going", action="store_false",
                    help="stop at the first failed command")
    args = ap.parse_args()

    errors = []
    readme = ROOT / "README.md"
    n = len(readme.read_text(encoding="utf-8").splitlines())
    if n > README_MAX_LINES:
        errors.append(f"README.md: {n} lines, at most {README_MAX_LINES}")
    commands = []
    files = markdown_files()
    for path in files:
        text = path.read_text(encoding="utf-8")
        errors += check_links(path, text)
        errors += check_tables(path, text)
        commands += [(path, *c) for c in commands_of(path, text)]

    for e in errors:
        print("error: " + e)
    skips = sum(1 for c in commands if c[4])
    print(f"checked {len(files)} files: README.md {n} lines (max {README_MAX_LINES}), "
          f"{len(errors)} errors, {len(commands)} documented commands ({skips} marked skip)")
    if args.list and not args.run:
        for path, lineno, cmd, assigns, skip in commands:
            pre = "; ".join(assigns) + "; " if assigns else ""
            print(f"  {rel(path)}:{lineno}: {pre}{cmd}" + (f"   [skip: {skip}]" if skip else ""))
    status = 1 if errors else 0
    if args.run:
        if run_commands(commands, args.timeout, args.only, args.keep_going):
            status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
