"""Shared helpers of the docs generators: number formats as the tool prints them, tables."""

import csv
import json
import math
import re
from pathlib import Path


def sig(x, digits=3):
    """`x` with `digits` significant digits, as optbench's tables print it (render::table::sig):
    fixed for 1e-3 <= |x| < 1e6, else scientific without a plus or leading zero (7.03e-4)."""
    if x is None:
        return "—"
    if not math.isfinite(x):
        return "inf" if x > 0 else ("-inf" if x < 0 else "NaN")
    if x == 0:
        return "0"
    mag = math.floor(math.log10(abs(x)))
    if -3 <= mag < 6:
        return f"{x:.{max(digits - 1 - mag, 0)}f}"
    m, e = f"{x:.{digits - 1}e}".split("e")
    return f"{m}e{int(e)}"


def thousands(n):
    """An integer with a comma every three digits (40,000)."""
    return f"{int(n):,}"


def minus(s):
    """A typographic minus for prose and tables (−837.9658)."""
    return s.replace("-", "−") if s.startswith("-") else s


def read_json(path):
    return json.loads(Path(path).read_text())


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def markdown_table(header, rows, right=None):
    """An aligned Markdown table (as optbench writes them); `right`: right-aligned columns."""
    right = right or [False] + [True] * (len(header) - 1)
    cells = [[str(c).replace("|", "\\|") for c in r] for r in [header] + rows]
    width = [max(len(r[i]) for r in cells) for i in range(len(header))]

    def line(r):
        return "| " + " | ".join(c.rjust(w) if a else c.ljust(w)
                                 for c, w, a in zip(r, width, right)) + " |"

    sep = "| " + " | ".join(("-" * (w - 1) + ":") if a else "-" * w
                            for w, a in zip(width, right)) + " |"
    return "\n".join([line(cells[0]), sep] + [line(r) for r in cells[1:]])


def section(md, heading):
    """The text of a Markdown file's section (from `heading` to the next heading)."""
    m = re.search(rf"^#+ {re.escape(heading)}\n(.*?)(?=^#+ |\Z)", md, re.S | re.M)
    if not m:
        raise RuntimeError(f"no section {heading!r}")
    return m.group(1).strip("\n")


def first_table(md):
    """The first Markdown table in a text."""
    lines = md.splitlines()
    start = next(i for i, l in enumerate(lines) if l.startswith("|"))
    end = start
    while end < len(lines) and lines[end].startswith("|"):
        end += 1
    return "\n".join(lines[start:end])


def count_words(n):
    """Small counts in words, as prose writes them."""
    words = ["no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine",
             "ten", "eleven", "twelve"]
    return words[n] if 0 <= n < len(words) else str(n)


def parse_table(md):
    """The rows of the first Markdown table in a text, as dicts by header."""
    lines = first_table(md).splitlines()
    cells = [[c.strip() for c in l.strip().strip("|").split("|")] for l in lines]
    return [dict(zip(cells[0], r)) for r in cells[2:]]
