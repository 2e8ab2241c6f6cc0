#!/usr/bin/env bash
# Soak the daemon against the mock motor: enable, play an excitation trajectory for DURATION
# seconds at 1 kHz, stop with SIGTERM, and print the daemon's whole-run timing summary
# (|period − 1 ms| and execution-time quantiles, µs) with the missed-cycle and link counters.
# Usage: bench/daemon_soak.sh [DURATION_S=600] [RT=require|ignore]
set -euo pipefail
cd "$(dirname "$0")/.."
duration=${1:-600}
rt=${2:-require}
cargo build --release --locked -q
arash=$PWD/target/release/arash
dir=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$dir"' EXIT
"$arash" mock-motor > "$dir/pty" 2> /dev/null &
sleep 0.5
"$arash" daemon --port "$(cat "$dir/pty")" --rt "$rt" --socket "$dir/s.sock" --log-dir "$dir/logs" 2> "$dir/daemon.err" &
daemon=$!
while [ ! -S "$dir/s.sock" ]; do sleep 0.1; done
"$arash" excite --restarts 1 --rate 10 -o "$dir/excitation.json" 2> /dev/null > /dev/null
"$arash" ctl --socket "$dir/s.sock" enable > /dev/null
"$arash" ctl --socket "$dir/s.sock" run "$dir/excitation.json" --duration "$duration" --label soak --wait > /dev/null
"$arash" ctl --socket "$dir/s.sock" status | grep -E '"(missed_cycles|log_dropped|crc_errors|lost|stale|faults)"' || true
kill -TERM "$daemon"
wait "$daemon"
echo "kernel: $(uname -r)"
grep -E "control thread|timing" "$dir/daemon.err"
