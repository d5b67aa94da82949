#!/usr/bin/env bash
# Builds the Python package's wheel (maturin, release), installs it into python/.venv (a
# venv that sees the system's site packages, so cocoex and scipy installed there count),
# builds the CLI the tests call (`optbench report`, `optbench merge`) and runs python/tests
# with pytest. Exits non-zero when anything fails.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(dirname "$here")"
cd "$here"

python3 -m venv --system-site-packages .venv
py="$here/.venv/bin/python"
# The pinned check packages (maturin, pytest, scipy, cocoex among them); maturin's command
# in the venv itself, also when the system already has the package.
"$py" -m pip install -q -r "$root/scripts/requirements-checks.txt"
maturin_version=$(sed -n 's/^maturin==//p' "$root/scripts/requirements-checks.txt")
[ -x .venv/bin/maturin ] || "$py" -m pip install -q --ignore-installed "maturin==$maturin_version"

rm -rf target/wheels
start=$(date +%s)
.venv/bin/maturin build --release --quiet --interpreter "$py" --out target/wheels
echo "wheel built in $(( $(date +%s) - start )) s: $(ls target/wheels)"
"$py" -m pip install -q --force-reinstall --no-deps target/wheels/optbench-*.whl

# The CLI: $OPTBENCH_BIN if set, else the repository's release build.
if [ -z "${OPTBENCH_BIN:-}" ]; then
    (cd "$root" && cargo build --release --quiet)
    export OPTBENCH_BIN="$root/target/release/optbench"
fi

# Run from outside python/, so `import optbench` is the installed wheel, not the source.
cd "$root"
"$py" -m pytest -q -p no:cacheprovider python/tests
