"""Simulator speed and flight-log size: `arash simulate` for 300 s of rig time (the paper's
logging run) on the excitation, per scenario, median of repeated runs.

Run from the repository root after `cargo build --release`:
    .venv/bin/python bench/simulator_speed.py [--repeats 5]
"""

import argparse
import subprocess
import tempfile
from pathlib import Path

from timing import median_seconds

ROOT = Path(__file__).resolve().parents[1]
BINARY = ROOT / "target" / "release" / "arash"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        trajectory = tmp / "excite.json"
        subprocess.run([BINARY, "excite", "--restarts", "1", "-o", trajectory], check=True, capture_output=True)
        print(f"| scenario | truth logged | 300 s of rig time (median of {args.repeats}) | × real time | log size per minute |")
        print("|---|---|---|---|---|")
        for scenario, truth in [("nominal", False), ("nominal", True), ("compliance", False), ("stribeck", False)]:
            log = tmp / "run.mcap"
            command = [BINARY, "simulate", "--scenario", ROOT / "scenarios" / f"{scenario}.toml",
                       "--trajectory", trajectory, "--controller", "robust", "--duration", "300", "-o", log]
            if truth:
                command.append("--truth")
            seconds = median_seconds(lambda: subprocess.run(command, check=True, capture_output=True), args.repeats)
            per_minute = log.stat().st_size / 5 / 1e6
            print(f"| {scenario} | {'yes' if truth else 'no'} | {seconds:.2f} s | {300 / seconds:.0f}× | {per_minute:.1f} MB |")


if __name__ == "__main__":
    main()
