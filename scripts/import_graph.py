#!/usr/bin/env python3
"""The module import graph of src/: which top-level module uses which (`crate::x` paths,
test code included), the cycles, and the imports that run against a given layering.

usage: scripts/import_graph.py [--dot FILE] [--layers a,b;c;d,e ...]
  --layers: modules from the ground floor up, floors separated by ';'. A module may import
  its own floor (no cycle) and the floors below; anything else is reported.
"""
import argparse
import os
import re
import sys

SRC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src")
USE = re.compile(r"\bcrate::([a-z_][a-z0-9_]*)")


def top_module(path):
    rel = os.path.relpath(path, SRC)
    head = rel.split(os.sep)[0]
    return head[:-3] if head.endswith(".rs") else head


def graph():
    edges = {}
    for d, _, fs in os.walk(SRC):
        for f in fs:
            if not f.endswith(".rs"):
                continue
            p = os.path.join(d, f)
            m = top_module(p)
            if m in ("main", "lib"):
                continue
            # Comments name modules without importing them (`//!` docs link upward freely).
            text = "\n".join(line.split("//")[0] for line in open(p, encoding="utf-8"))
            for t in USE.findall(text):
                if t != m:
                    edges.setdefault(m, {}).setdefault(t, set()).add(os.path.relpath(p, SRC))
    return edges


def cycles(edges):
    found, seen = [], set()

    def walk(n, stack):
        for t in sorted(edges.get(n, {})):
            if t in stack:
                c = stack[stack.index(t):] + [t]
                key = frozenset(c)
                if key not in seen:
                    seen.add(key)
                    found.append(c)
            elif len(stack) < 12:
                walk(t, stack + [t])

    for n in sorted(edges):
        walk(n, [n])
    return found


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dot")
    ap.add_argument("--layers")
    a = ap.parse_args()
    edges = graph()
    for m in sorted(edges):
        print(f"{m} -> {', '.join(sorted(edges[m]))}")
    cyc = cycles(edges)
    for c in cyc:
        print("cycle:", " -> ".join(c))
    bad = 0
    if a.layers:
        floor = {}
        for i, fl in enumerate(a.layers.split(";")):
            for m in fl.split(","):
                if m:
                    floor[m.strip()] = i
        for m, ts in sorted(edges.items()):
            for t, where in sorted(ts.items()):
                if m in floor and t in floor and floor[t] > floor[m]:
                    bad += 1
                    print(f"upward: {m} (floor {floor[m]}) -> {t} (floor {floor[t]}) in {', '.join(sorted(where))}")
        missing = sorted(set(edges) - set(floor))
        if missing:
            print("not in any floor:", ", ".join(missing))
    if a.dot:
        with open(a.dot, "w") as fh:
            fh.write("digraph imports {\n  rankdir=BT;\n")
            for m, ts in sorted(edges.items()):
                for t in sorted(ts):
                    fh.write(f'  "{m}" -> "{t}";\n')
            fh.write("}\n")
    print(f"{sum(len(t) for t in edges.values())} edges, {len(cyc)} cycles, {bad} upward")
    return 1 if cyc or bad else 0


if __name__ == "__main__":
    sys.exit(main())
