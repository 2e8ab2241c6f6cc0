#!/usr/bin/env bash
# Soak the daemon against the mock motor: enable, play an excitation trajectory for DURATION
# seconds at 1 kHz, stop with SIGTERM, and print the daemon's whole-run timing summary
# (|period − 1 ms| and execution-time quantiles, µs) with the missed-cycle and link counters.
# With LIVE=stuck the daemon also serves the live stream (--live) to a client that subscribes to
# every topic and never reads (tests/python/foxglove_client.py; needs the venv of scripts/setup),
# and the stream's counters are printed too.
# With LINK=canopen the rig is the simulated one behind three CiA 402 drives
# (python -m arash.cia402_sim, on a pty playing an slcan adapter; needs the venv of
# scripts/setup), the daemon its CANopen master, and the drives' side is printed too: SYNCs
# received, their intervals, late SYNCs and the bus load (docs/canopen.md).
# A run that ends with a fault keeps its directory (daemon and simulator logs, the flight logs)
# and says where, so that the fault can be read afterwards.
# Usage: bench/daemon_soak.sh [DURATION_S=600] [RT=require|ignore] [LIVE=off|stuck] [LINK=serial|canopen]
set -euo pipefail
cd "$(dirname "$0")/.."
duration=${1:-600}
rt=${2:-require}
live=${3:-off}
link=${4:-serial}
live_args=()
if [ "$live" = stuck ]; then live_args=(--live 127.0.0.1:0); fi
cargo build --release --locked -q
arash=$PWD/target/release/arash
dir=$(mktemp -d)
keep=0
trap 'kill $(jobs -p) 2>/dev/null || true; if [ "$keep" = 1 ]; then echo "fault: run kept in $dir" >&2; else rm -rf "$dir"; fi' EXIT
case "$link" in
    serial) "$arash" mock-motor > "$dir/pty" 2> /dev/null & ;;
    canopen) .venv/bin/python -m arash.cia402_sim > "$dir/pty" 2> "$dir/sim.err" & ;;
    *) echo "LINK must be serial or canopen, not $link" >&2; exit 2 ;;
esac
simulator=$!
while [ ! -s "$dir/pty" ]; do sleep 0.1; done
"$arash" daemon --link "$link" --port "$(cat "$dir/pty")" --rt "$rt" --socket "$dir/s.sock" --log-dir "$dir/logs" "${live_args[@]}" 2> "$dir/daemon.err" &
daemon=$!
while [ ! -S "$dir/s.sock" ]; do sleep 0.1; done
if [ "$live" = stuck ]; then
    address=$("$arash" ctl --socket "$dir/s.sock" status | .venv/bin/python -c 'import json,sys; print(json.load(sys.stdin)["live"]["address"])')
    .venv/bin/python tests/python/foxglove_client.py stuck "$address" $((duration + 600)) &
fi
"$arash" excite --restarts 1 --rate 10 -o "$dir/excitation.json" 2> /dev/null > /dev/null
"$arash" ctl --socket "$dir/s.sock" enable > /dev/null
"$arash" ctl --socket "$dir/s.sock" run "$dir/excitation.json" --duration "$duration" --label soak --wait > /dev/null
"$arash" ctl --socket "$dir/s.sock" status > "$dir/status.json"
if ! .venv/bin/python -c 'import json,sys; sys.exit(1 if json.load(open(sys.argv[1]))["faults"] else 0)' "$dir/status.json"; then keep=1; fi
.venv/bin/python -c 'import json,sys
s = json.load(open(sys.argv[1]))
print({k: s[k] for k in ("cycle", "missed_cycles", "log_dropped", "faults")}, s["link"])
if s["live"]: print("live:", {k: s["live"][k] for k in ("clients", "sent", "dropped")})' "$dir/status.json"
kill -TERM "$daemon"
wait "$daemon"
if [ "$link" = canopen ]; then
    kill -TERM "$simulator"
    wait "$simulator" || true
    grep "arash.cia402_sim: {" "$dir/sim.err"
fi
echo "kernel: $(uname -r)"
grep -E "control thread|timing" "$dir/daemon.err"
