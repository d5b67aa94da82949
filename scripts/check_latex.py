#!/usr/bin/env python3
"""Compiles every LaTeX table optbench wrote with pdflatex and checks that its bold shows.

    python3 scripts/check_latex.py RESULTS_DIR_OR_FILE [...] [--png DIR]

Needs pdflatex (Debian: texlive-latex-base and texlive-latex-recommended for booktabs) and
pdffonts (Debian: poppler-utils); exits 3 with a message when either is missing (tests skip
on that). Standard library otherwise.

Each .tex file found (folders are searched recursively) is wrapped in a minimal document
(article, booktabs, an A4 landscape page: eight optimizers fit) and compiled with
`pdflatex -halt-on-error -no-shell-escape` in a temporary folder. A file fails when:

  - pdflatex stops (an undefined control sequence, a character it has no glyph for such as
    a bare `_` or `∞`, unbalanced braces), or its log names a missing character;
  - a row of a tabular has fewer or more cells than the tabular's columns;
  - it marks cells bold (`\\boldmath`, `\\bfseries`, `\\textbf`, `\\mathbf`) but the PDF has no
    bold font (CMBX, CMMIB or CMBSY in `pdffonts`), or the same document with the bold
    commands made no-ops has the same bold fonts: the bold changes nothing that prints
    (`\\textbf{$0$}` is such a case: math digits stay regular).

`--png DIR` also writes each compiled table as DIR/NAME.png (pdftoppm, 150 dpi) to look at.
Prints one line per file; exit 1 on any failure, 0 otherwise.
"""

import argparse
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile

from _outputs import files_in

# OT1 (no fontenc): the bold check reads Computer Modern font names (T1 would give EC).
PREAMBLE = r"""\documentclass{article}
\usepackage{booktabs}
\usepackage[a4paper,landscape,margin=1cm]{geometry}
\pagestyle{empty}
\begin{document}
"""

BOLD_COMMANDS = re.compile(r"\\(boldmath|bfseries|textbf|mathbf)\b")
BOLD_FONTS = re.compile(r"\b(CMBX|CMMIB|CMBSY)\w*")


def compile_tex(body, work, name):
    """Compiles `body` wrapped in the preamble; returns (pdf path or None, log text)."""
    tex = work / f"{name}.tex"
    tex.write_text(PREAMBLE + body + "\n\\end{document}\n", encoding="utf-8")
    run = subprocess.run(
        ["pdflatex", "-interaction=nonstopmode", "-halt-on-error", "-no-shell-escape",
         tex.name],
        cwd=work, capture_output=True, text=True, errors="replace", timeout=120)
    log_path = work / f"{name}.log"
    log = log_path.read_text(errors="replace") if log_path.exists() else run.stdout
    pdf = work / f"{name}.pdf"
    return (pdf if run.returncode == 0 and pdf.exists() else None), log


def bold_fonts(pdf):
    out = subprocess.run(["pdffonts", str(pdf)], capture_output=True, text=True).stdout
    return set(m.group(1) for m in BOLD_FONTS.finditer(out))


def first_error(log):
    lines = log.splitlines()
    for i, line in enumerate(lines):
        if line.startswith("!"):
            return " ".join(x.strip() for x in lines[i:i + 3])
    return "pdflatex failed (no '!' line in its log)"


def short_rows(path, body):
    """Rows of a tabular with fewer cells than its columns (LaTeX accepts them silently,
    and a number then sits under the wrong heading)."""
    problems = []
    for m in re.finditer(r"\\begin\{tabular\}\{([^}]*)\}(.*?)\\end\{tabular\}", body, re.S):
        columns = len(re.findall(r"[lrc]", m.group(1)))
        for row in re.split(r"\\\\", m.group(2)):
            row = re.sub(r"\\(toprule|midrule|bottomrule)", "", row).strip()
            if not row:
                continue
            n = len(re.split(r"(?<!\\)&", row))
            if n != columns:
                line = body[:m.start(2)].count("\n") + 1
                problems.append(f"{path}: a row of the tabular at line {line} has {n} "
                                f"cells for {columns} columns: {row[:80]}")
    return problems


def check(path, work, png_dir):
    """Problems of one .tex file (empty when it compiles and its bold shows)."""
    body = path.read_text(encoding="utf-8")
    # The results folder's name first: every folder has a summary.tex.
    folder = path.resolve().parent.parent.name if path.parent.name == "tables" else ""
    name = re.sub(r"[^A-Za-z0-9_-]", "-", f"{folder}_{path.stem}".strip("_"))
    pdf, log = compile_tex(body, work, name)
    if pdf is None:
        return [f"{path}: does not compile: {first_error(log)}"]
    problems = short_rows(path, body)
    missing = re.findall(r"Missing character: There is no (.+?) in font", log)
    if missing:
        problems.append(f"{path}: characters with no glyph: {sorted(set(missing))}")
    if BOLD_COMMANDS.search(body):
        bold = bold_fonts(pdf)
        if not bold:
            problems.append(f"{path}: marks cells bold, but the PDF has no bold font")
        # The control: bold commands made no-ops must lose the bold fonts.
        plain = BOLD_COMMANDS.sub(lambda m: r"\relax" if m.group(1) in
                                  ("boldmath", "bfseries") else "", body)
        ctrl, clog = compile_tex(plain, work, name + "-plain")
        if ctrl is None:
            problems.append(f"{path}: the no-bold control does not compile: {first_error(clog)}")
        elif bold and bold_fonts(ctrl) >= bold:
            problems.append(f"{path}: the bold commands change no font that prints "
                            f"({sorted(bold)} with and without them)")
    if png_dir is not None:
        subprocess.run(["pdftoppm", "-png", "-r", "150", "-singlefile", str(pdf),
                        str(png_dir / name)], check=False)
    return problems


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("paths", nargs="+", help="results folders or .tex files")
    ap.add_argument("--png", type=pathlib.Path, help="write each table as a PNG here")
    args = ap.parse_args(argv[1:])
    png_dir = args.png
    for tool, package in (("pdflatex", "texlive-latex-base texlive-latex-recommended"),
                          ("pdffonts", "poppler-utils")):
        if shutil.which(tool) is None:
            print(f"check_latex: {tool} not found (Debian: apt-get install {package}); "
                  "nothing checked", file=sys.stderr)
            return 3
    if png_dir is not None:
        png_dir.mkdir(parents=True, exist_ok=True)
    files = files_in(args.paths, ".tex", "check_latex")
    problems = []
    with tempfile.TemporaryDirectory(prefix="check_latex-") as tmp:
        for f in files:
            p = check(f, pathlib.Path(tmp), png_dir)
            bolded = "bold shown" if BOLD_COMMANDS.search(f.read_text(encoding="utf-8")) \
                else "no bold"
            print(f"{f}: " + (f"{len(p)} problems" if p else f"compiles, {bolded}"))
            for x in p:
                print(f"  {x}")
            problems += p
    print(f"{len(files)} files, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
