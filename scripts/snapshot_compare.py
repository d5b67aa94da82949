#!/usr/bin/env python3
"""Compare two result trees written by scripts/snapshot.sh with two builds.

Every file must be byte-identical except what records when and where it ran: wall times
(`wall_s`, `started`, `finished`), the build and commit, the command line, paths naming
the output folder, the progress lines' checksums and the folder's lock file. JSON and JSON Lines are compared with those keys left out (the progress
log as a set of lines: it is appended in the order trials finish), CSV without its `wall_s`
column; every other file (Markdown, LaTeX, PNG, SVG, IOH data) byte for byte.

usage: scripts/snapshot_compare.py BEFORE AFTER   (exit 1 on any difference)
"""
import csv
import io
import json
import os
import sys

# Keys that record the run, not its results.
# `crc` checksums a progress line, wall time included.
RUN_KEYS = {"wall_s", "started", "finished", "build", "git_commit", "git_dirty", "rustc", "cpu_model", "command", "out", "outputs", "suite_file", "fingerprint", "crc"}
# Files that record who held the folder, not results.
RUN_FILES = {".optbench.lock"}


def strip(v, a, b):
    if isinstance(v, dict):
        return {k: strip(x, a, b) for k, x in v.items() if k not in RUN_KEYS}
    if isinstance(v, list):
        return [strip(x, a, b) for x in v]
    if isinstance(v, str):
        for root in sorted((a, b), key=len, reverse=True):
            v = v.replace(root, "ROOT")
        return v
    return v


def load(path, root, other):
    with open(path, "rb") as fh:
        raw = fh.read()
    name = os.path.basename(path)
    if name.endswith(".jsonl"):
        rows = [strip(json.loads(line), root, other) for line in raw.decode().splitlines() if line.strip()]
        # The progress log is appended in the order trials finish, which the threads decide.
        return sorted(json.dumps(r, sort_keys=True) for r in rows) if name == "progress.jsonl" else rows
    if name.endswith(".json"):
        return strip(json.loads(raw), root, other)
    if name.endswith(".csv"):
        rows = list(csv.reader(io.StringIO(raw.decode())))
        if rows and "wall_s" in rows[0]:
            k = rows[0].index("wall_s")
            rows = [r[:k] + r[k + 1:] for r in rows]
        return rows
    return raw


def files(root):
    out = set()
    for d, _, fs in os.walk(root):
        for f in fs:
            if f in RUN_FILES:
                continue
            out.add(os.path.relpath(os.path.join(d, f), root))
    return out


def main(argv):
    if len(argv) != 3:
        sys.exit(__doc__)
    a, b = (os.path.abspath(x) for x in argv[1:])
    fa, fb = files(a), files(b)
    bad = [f"only in {a}: {f}" for f in sorted(fa - fb)] + [f"only in {b}: {f}" for f in sorted(fb - fa)]
    for f in sorted(fa & fb):
        if load(os.path.join(a, f), a, b) != load(os.path.join(b, f), a, b):
            bad.append(f"differs: {f}")
    for line in bad:
        print(line)
    print(f"{len(fa & fb)} files compared, {len(bad)} differences")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
