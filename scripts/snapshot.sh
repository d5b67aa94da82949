#!/usr/bin/env bash
# Runs every suite (functions.toml in full, the others at a small size) with binary BIN into
# OUT, so two builds can be compared file by file (scripts/snapshot_compare.py): a
# restructuring must leave every summary.json and report file byte-identical.
# usage: scripts/snapshot.sh BIN OUT
set -euo pipefail
bin=$(realpath "$1"); out=$2
here=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
cd "$here"
"$bin" run suites/functions.toml --out "$out/functions" -q --threads 2
for s in hysteresis boucwen-benchmark mr-damper; do
  "$bin" run "suites/$s.toml" --out "$out/$s" -q --threads 2 --trials 2 --budget 400
done
"$bin" run suites/control.toml --out "$out/control" -q --threads 2 --trials 2
