#!/usr/bin/env bash
# The rig's memory budget (docs/daemon.md, "Memory"): start `arash-daemon` against the mock
# motor with the real-time set-up (mlockall needs root or CAP_IPC_LOCK; RT=ignore runs without),
# read its resident, peak and locked memory idle and after a DURATION-second run, and say where
# the resident memory goes: the binary's pages, each thread's stack, the heap and other
# anonymous memory, and the shared libraries.
# Usage: bench/daemon_memory.sh [DURATION_S=30] [RT=require|ignore]
set -euo pipefail
cd "$(dirname "$0")/.."
duration=${1:-30}
rt=${2:-require}
cargo build --release --locked -q -p arash-daemon -p arash-cli
daemon_bin=$PWD/target/release/arash-daemon
arash=$PWD/target/release/arash
dir=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$dir"' EXIT
"$arash" mock-motor > "$dir/pty" 2> /dev/null &
sleep 0.5
"$daemon_bin" --port "$(cat "$dir/pty")" --rt "$rt" --socket "$dir/s.sock" --log-dir "$dir/logs" 2> "$dir/daemon.err" &
daemon=$!
while [ ! -S "$dir/s.sock" ]; do sleep 0.1; done
sleep 1
figures() { grep -E "^(VmRSS|VmHWM|VmLck|Threads)" "/proc/$daemon/status" | tr -s ' \t' ' ' | tr '\n' ';'; echo; }
echo "idle:              $(figures)"
"$arash" ctl --socket "$dir/s.sock" enable > /dev/null
"$arash" ctl --socket "$dir/s.sock" run trajectories/paper_validation_0.9.json --duration "$duration" --label memory --wait > /dev/null
echo "after a ${duration} s run: $(figures)"
python3 - "$daemon" <<'PY'
import sys
pid = sys.argv[1]
stacks = {}
for tid in __import__("os").listdir(f"/proc/{pid}/task"):
    name = open(f"/proc/{pid}/task/{tid}/comm").read().strip()
    fields = open(f"/proc/{pid}/task/{tid}/syscall").read().split()
    if len(fields) >= 3:
        stacks[int(fields[-2], 16)] = name
groups, current = {}, None
for line in open(f"/proc/{pid}/smaps"):
    parts = line.split()
    if "-" in parts[0] and ":" not in parts[0]:
        start, end = (int(x, 16) for x in parts[0].split("-"))
        path = parts[5] if len(parts) > 5 else ""
        thread = next((n for sp, n in stacks.items() if start <= sp < end), None)
        if thread:
            current = f"stack of {thread}"
        elif path.endswith("arash-daemon"):
            current = "the binary (code and data)"
        elif path.startswith("/"):
            current = "shared libraries"
        elif path == "[heap]" or not path:
            current = "heap and other anonymous memory"
        else:
            current = path
    elif parts[0] == "Rss:":
        groups[current] = groups.get(current, 0) + int(parts[1])
print("| where | resident (kB) |\n|---|---|")
for name, kb in sorted(groups.items(), key=lambda g: -g[1]):
    print(f"| {name} | {kb:,} |")
PY
kill -TERM "$daemon"
wait "$daemon"
