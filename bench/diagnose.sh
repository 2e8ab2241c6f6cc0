#!/usr/bin/env bash
# Diagnosis speed: 300 s of the simulated rig at 1 kHz (300,000 samples × 3 joints, the paper's
# logging run) with the cogging scenario, the full catalogue, five runs; prints each time and
# the median. Usage: bench/diagnose.sh [runs]
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-5}
cargo build --release -q -p arash-cli
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
target/release/arash simulate --scenario scenarios/cogging.toml --trajectory trajectories/excitation_L5_T15.json \
    --controller idc-cad --duration 300 -o "$dir/run.mcap" >/dev/null 2>&1
times=()
for i in $(seq "$runs"); do
    t=$(target/release/arash diagnose "$dir/run.mcap" -o "$dir/out" 2>&1 >/dev/null | sed -n 's/^diagnosed in \([0-9.]*\) s$/\1/p')
    echo "run $i: diagnosis of 300,000 samples in $t s"
    times+=("$t")
done
printf '%s\n' "${times[@]}" | sort -g | awk '{a[NR]=$1} END {print "median: " a[int((NR+1)/2)] " s"}'
