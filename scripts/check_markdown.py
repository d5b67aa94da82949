#!/usr/bin/env python3
"""Renders every Markdown file optbench wrote with a real GFM renderer and checks its tables.

    python3 scripts/check_markdown.py RESULTS_DIR_OR_FILE [...]

Needs markdown-it-py (`pip install markdown-it-py`); exits 3 with a message when it is
missing (tests skip on that). Each .md file found (folders are searched recursively) is
parsed with markdown-it-py (CommonMark with GFM tables), and every table-looking block of
the source (consecutive lines starting with `|`, outside code blocks) must:

  - become one <table> spanning exactly those lines (a header whose cell count differs from
    its delimiter row leaves a paragraph of pipes; a paragraph line glued under a table
    becomes one more row);
  - have, on every row, the header's cell count in the source (GFM pads short rows and
    drops the excess of long ones silently, so the rendered table cannot tell).

Prints one line per file (tables found) and every problem with file and line; exit 1 on
any problem, 0 otherwise.
"""

import argparse
import sys

from _outputs import files_in


def cells(line):
    """A table line's cells, split at unescaped `|` as GFM does (outer pipes optional)."""
    t = line.strip()
    if t.startswith("|"):
        t = t[1:]
    if t.endswith("|") and not t.endswith("\\|"):
        t = t[:-1]
    out, cur, escaped = [], "", False
    for ch in t:
        if ch == "|" and not escaped:
            out.append(cur)
            cur = ""
        else:
            cur += ch
        escaped = ch == "\\" and not escaped
    out.append(cur)
    return [c.strip() for c in out]


def check_text(md, text, name):
    """Problems of one document (a list of 'name:line: what')."""
    tokens = md.parse(text)
    code = set()
    tables = {}   # first line -> (end line, [cell count of each rendered row])
    current = None
    for t in tokens:
        if t.type in ("fence", "code_block") and t.map:
            code.update(range(*t.map))
        elif t.type == "table_open":
            current = (t.map[0], t.map[1], [])
        elif t.type == "tr_open" and current:
            current[2].append(0)
        elif t.type in ("th_open", "td_open") and current:
            current[2][-1] += 1
        elif t.type == "table_close" and current:
            tables[current[0]] = (current[1], current[2])
            current = None
    lines = text.split("\n")
    problems, found, i = [], 0, 0
    while i < len(lines):
        if i in code or not lines[i].lstrip().startswith("|"):
            i += 1
            continue
        start = i
        while i < len(lines) and i not in code and lines[i].lstrip().startswith("|"):
            i += 1
        where = f"{name}:{start + 1}"
        if start not in tables:
            problems.append(f"{where}: {i - start} lines of pipes that do not render as a table")
            continue
        end, rows = tables[start]
        if end != i:
            problems.append(f"{where}: the table spans lines {start + 1}-{end}, "
                            f"its pipes lines {start + 1}-{i} (text glued under it?)")
        head = len(cells(lines[start]))
        for k in range(start + 2, i):
            n = len(cells(lines[k]))
            if n != head:
                problems.append(f"{name}:{k + 1}: {n} cells, the header has {head}")
        if rows and any(r != head for r in rows):
            problems.append(f"{where}: rendered rows have {sorted(set(rows))} cells, "
                            f"the header {head}")
        found += 1
    return found, problems


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="+", help="results folders or .md files")
    args = ap.parse_args(argv[1:])
    try:
        from markdown_it import MarkdownIt
    except ImportError:
        print("check_markdown: markdown-it-py is not installed "
              "(pip install markdown-it-py); nothing checked", file=sys.stderr)
        return 3
    md = MarkdownIt("commonmark").enable(["table", "strikethrough"])
    files = files_in(args.paths, ".md", "check_markdown")
    problems, total = [], 0
    for f in files:
        found, p = check_text(md, f.read_text(encoding="utf-8"), str(f))
        total += found
        problems += p
        print(f"{f}: {found} tables" + (f", {len(p)} problems" if p else ""))
    for p in problems:
        print(p, file=sys.stderr)
    print(f"{len(files)} files, {total} tables, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
