#!/usr/bin/env python3
"""Checks a results folder's report.html: self-contained, well-formed, and rendered by a
real browser into a page that shows its tables and figures.

    python3 scripts/check_html.py RESULTS_DIR [...] [--shots DIR]

Static checks (Python standard library):
  - every element opened is closed, in order (void elements aside);
  - no <script>, <link>, <iframe> or <object>; every `src` is a `data:image/` URI and every
    `href` an anchor (`#id`) whose id exists: nothing is loaded from a file or the network;
  - at least one <table>; one <figure> with an embedded image per figure file (stem) in the
    folder's plots/ or figures/;
  - the text holds no raw `<` or `&` that is not markup or an entity (escaped text).

Rendered (needs Chromium: Debian package `chromium`; without it these are skipped with a
message and exit 3 once the static checks pass): headless Chromium takes two screenshots,
the page's top (1280 x 2400) and the figures alone (the rest of the page hidden by an
extra style in a temporary copy). The first must not be blank (some dark text pixels,
more than 2 % of pixels not white), the second must show coloured pixels (the figures'
palette) when the folder has figures. `--shots DIR` keeps the screenshots as
DIR/NAME-top.png and DIR/NAME-figures.png to look at.

Exit 0 when all passes, 1 on a failed check, 2 on bad arguments, 3 when Chromium is missing.
"""

import argparse
import html.parser
import pathlib
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import zlib

VOID = {"meta", "img", "br", "hr", "input", "link", "source", "col", "area", "base", "wbr"}
FORBIDDEN = {"script", "link", "iframe", "object", "embed"}


class Checker(html.parser.HTMLParser):
    def __init__(self):
        super().__init__(convert_charrefs=False)
        self.stack, self.problems, self.ids, self.hrefs = [], [], set(), []
        self.tables = self.figures = self.images = 0
        self.in_figure = False

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag in FORBIDDEN:
            self.problems.append(f"<{tag}> found: the page must load nothing")
        if "id" in a:
            self.ids.add(a["id"])
        if "src" in a:
            if not (a["src"] or "").startswith("data:image/"):
                self.problems.append(f"external src: {a['src'][:80]}")
            elif tag == "img":
                self.images += 1
        if "href" in a:
            if not (a["href"] or "").startswith("#"):
                self.problems.append(f"external href: {a['href'][:80]}")
            else:
                self.hrefs.append(a["href"][1:])
        if tag == "table":
            self.tables += 1
        if tag == "figure":
            self.figures += 1
        if tag not in VOID:
            self.stack.append((tag, self.getpos()[0]))

    def handle_endtag(self, tag):
        if tag in VOID:
            return
        if not self.stack or self.stack[-1][0] != tag:
            open_ = self.stack[-1] if self.stack else None
            self.problems.append(f"line {self.getpos()[0]}: </{tag}> closes {open_}")
            return
        self.stack.pop()

    def handle_data(self, data):
        if "<" in data:
            self.problems.append(f"line {self.getpos()[0]}: raw '<' in text: {data[:60]!r}")

    def unknown_decl(self, data):
        self.problems.append(f"unknown declaration {data[:40]!r}")


def static_checks(page, folder):
    c = Checker()
    text = page.read_text(encoding="utf-8")
    c.feed(text)
    c.close()
    problems = list(c.problems)
    if c.stack:
        problems.append(f"never closed: {c.stack[-5:]}")
    for h in c.hrefs:
        if h not in c.ids:
            problems.append(f"anchor #{h} has no element with that id")
    if c.tables == 0:
        problems.append("no <table>")
    # A bare '&' that starts no entity is unescaped text.
    for m in re.finditer(r"&(?!(?:[a-zA-Z]+|#\d+|#x[0-9a-fA-F]+);)", text):
        line = text.count("\n", 0, m.start()) + 1
        problems.append(f"line {line}: unescaped '&'")
        break
    stems = set()
    for sub in ("plots", "figures"):
        d = folder / sub
        if d.is_dir():
            stems |= {p.stem for p in d.iterdir() if p.suffix in (".svg", ".png")}
    if c.figures != len(stems) or c.images != len(stems):
        problems.append(f"{len(stems)} figure files but {c.figures} <figure> and "
                        f"{c.images} embedded images")
    return problems, c.tables, len(stems)


def png_pixels(path):
    """(width, height, rows of RGB tuples) of an 8-bit RGB/RGBA PNG (standard library)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path}: not a PNG"
    pos, idat, w, h, bpp = 8, b"", 0, 0, 3
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, color = struct.unpack(">IIBB", body[:10])
            assert depth == 8 and color in (2, 6), f"{path}: PNG type {color}/{depth}"
            bpp = 3 if color == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = zlib.decompress(idat)
    stride = w * bpp
    rows, prev = [], bytearray(stride)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
        rows.append(line)
        prev = line
    return w, h, bpp, rows


def pixel_stats(path, step=3):
    """Shares of non-white, dark and coloured pixels (sampled every `step` pixels); with
    Pillow when it is installed (fast), else by the standard-library decoder above."""
    try:
        from PIL import Image
        img = Image.open(path).convert("RGB")
        w, h, bpp = img.width, img.height, 3
        raw = img.tobytes()
        rows = [raw[y * w * 3:(y + 1) * w * 3] for y in range(h)]
    except ImportError:
        w, h, bpp, rows = png_pixels(path)
    total = nonwhite = dark = coloured = 0
    for y in range(0, h, step):
        row = rows[y]
        for x in range(0, w, step):
            r, g, b = row[x * bpp], row[x * bpp + 1], row[x * bpp + 2]
            total += 1
            if min(r, g, b) < 235:
                nonwhite += 1
            if max(r, g, b) < 100:
                dark += 1
            if max(r, g, b) - min(r, g, b) > 60:
                coloured += 1
    return nonwhite / total, dark / total, coloured / total


def screenshot(chromium, page, out, height):
    subprocess.run(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
         "--virtual-time-budget=5000", f"--window-size=1280,{height}",
         f"--screenshot={out}", page.resolve().as_uri()],
        capture_output=True, timeout=180, check=False)
    return out.exists()


def rendered_checks(chromium, page, figures, shots, name):
    problems = []
    with tempfile.TemporaryDirectory(prefix="check_html-") as tmp:
        tmp = pathlib.Path(tmp)
        top = tmp / "top.png"
        if not screenshot(chromium, page, top, 2400):
            return [f"Chromium wrote no screenshot of {page}"]
        nonwhite, dark, _ = pixel_stats(top)
        print(f"  top: {nonwhite:.1%} not white, {dark:.2%} dark")
        if nonwhite < 0.02 or dark < 0.001:
            problems.append(f"the rendered page is blank ({nonwhite:.1%} not white)")
        if figures:
            only = tmp / "figures.html"
            text = page.read_text(encoding="utf-8").replace(
                "</style>", "#report,#statistics,#provenance,nav,h1{display:none}</style>", 1)
            only.write_text(text, encoding="utf-8")
            figs = tmp / "figures.png"
            if not screenshot(chromium, only, figs, 2000):
                return problems + ["Chromium wrote no screenshot of the figures"]
            nonwhite, _, coloured = pixel_stats(figs)
            print(f"  figures: {nonwhite:.1%} not white, {coloured:.2%} coloured")
            if coloured < 0.002:
                problems.append("the figures render without colour: images not shown?")
        if shots:
            shutil.copy(top, shots / f"{name}-top.png")
            if figures:
                shutil.copy(figs, shots / f"{name}-figures.png")
    return problems


def main(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", nargs="+", type=pathlib.Path, help="results folders")
    ap.add_argument("--shots", type=pathlib.Path, help="keep the screenshots here")
    a = ap.parse_args(argv[1:])
    args, shots = a.folders, a.shots
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if shots:
        shots.mkdir(parents=True, exist_ok=True)
    failed = skipped = False
    for folder in args:
        page = folder / "report.html"
        if not page.is_file():
            print(f"check_html: {page}: no such file (run `optbench report {folder}`)",
                  file=sys.stderr)
            return 2
        problems, tables, figures = static_checks(page, folder)
        print(f"{page}: {tables} tables, {figures} figures")
        if chromium and not problems:
            problems += rendered_checks(chromium, page, figures, shots, folder.name)
        elif not chromium:
            skipped = True
        for p in problems:
            print(f"  {page}: {p}")
        failed |= bool(problems)
    if failed:
        return 1
    if skipped:
        print("check_html: chromium not found (Debian: apt-get install chromium); "
              "the page was checked but not rendered", file=sys.stderr)
        return 3
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
