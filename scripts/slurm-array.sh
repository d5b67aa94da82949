#!/usr/bin/env bash
# Runs an optbench suite as a Slurm job array: one shard per array task, then one merge.
# Documented, not run in CI (CI has no Slurm).
#
#   scripts/slurm-array.sh SUITE N [RESULTS_DIR] [-- extra `optbench run` flags]
#
# submits
#   1. an array of N tasks; task i runs `optbench run SUITE --shard i/N --resume
#      --out RESULTS_DIR/shard-i-of-N` (N = 1..N, --threads from the task's CPUs);
#   2. a merge job that starts after every task succeeded (afterok) and writes
#      RESULTS_DIR/merged: the same results folder and summary.json as one
#      `optbench run SUITE` on one machine.
#
# Requeued or preempted tasks lose nothing: --resume keeps every trial stored before the
# kill (see results/README.md), so `scontrol requeue JOBID` or resubmitting the same array
# finishes the missing trials only. If a task fails, fix the cause and resubmit the array
# with the same arguments; the merge refuses incomplete or mismatched shards.
#
# Environment: OPTBENCH (binary, default target/release/optbench, built beforehand with
# `cargo build --release`), SBATCH_ARGS (extra sbatch options, e.g. "--partition=short
# --time=02:00:00"), CPUS (CPUs per task, default 2).
set -euo pipefail

usage() { sed -n '2,8p' "$0" >&2; exit 2; }
[ $# -ge 2 ] || usage
suite=$1
n=$2
shift 2
results=results/$(basename "$suite" .toml)-slurm
if [ $# -gt 0 ] && [ "$1" != "--" ]; then results=$1; shift; fi
[ "${1:-}" = "--" ] && shift
extra=("$@")
case $n in '' | *[!0-9]* | 0) echo "N must be a positive integer, got '$n'" >&2; exit 2 ;; esac
[ -f "$suite" ] || { echo "suite not found: $suite" >&2; exit 2; }
bin=$(realpath "${OPTBENCH:-target/release/optbench}")
[ -x "$bin" ] || { echo "binary not found: $bin (cargo build --release)" >&2; exit 2; }
command -v sbatch >/dev/null || { echo "sbatch not found: this script needs Slurm" >&2; exit 2; }
cpus=${CPUS:-2}
suite=$(realpath "$suite")
mkdir -p "$results/logs"
results=$(realpath "$results")

# Validate the suite once before submitting anything (exit 2 with file:line on errors).
"$bin" run "$suite" --trials 1 --budget 1 --out "$results/.check" -q >/dev/null
rm -rf "$results/.check"

# shellcheck disable=SC2086
array=$(sbatch --parsable ${SBATCH_ARGS:-} \
    --job-name=optbench-shards --array=1-"$n" --cpus-per-task="$cpus" \
    --output="$results/logs/shard-%a.out" \
    --wrap="'$bin' run '$suite' --shard \${SLURM_ARRAY_TASK_ID}/$n --resume \
--threads \${SLURM_CPUS_PER_TASK:-$cpus} -q \
--out '$results/shard-'\${SLURM_ARRAY_TASK_ID}'-of-$n' ${extra[*]:-}")

shards=""
for i in $(seq 1 "$n"); do shards="$shards '$results/shard-$i-of-$n'"; done
# shellcheck disable=SC2086
merge=$(sbatch --parsable ${SBATCH_ARGS:-} \
    --job-name=optbench-merge --dependency=afterok:"$array" --cpus-per-task=1 \
    --output="$results/logs/merge.out" \
    --wrap="'$bin' merge $shards --out '$results/merged'")

echo "submitted shards: job $array (array 1-$n), merge: job $merge"
echo "results: $results/merged (logs in $results/logs)"
