"""The zero-phase Butterworth filter against scipy's on the diagnosis's largest signal: 300 s at
1 kHz, four channels side by side (one filter pass of four candidate columns), order 5 at 14 Hz.

Run from the repository root with the test venv:
    .venv/bin/python bench/filter_vs_scipy.py [repeats]
Medians of repeated runs; the machine is shared.
"""

import sys
from pathlib import Path

import numpy as np
from scipy import signal

import arash

sys.path.insert(0, str(Path(__file__).resolve().parent))
from timing import median_seconds  # noqa: E402

FS, CUTOFF, ORDER, SAMPLES, CHANNELS = 1000.0, 14.0, 5, 300_000, 4


def main(repeats):
    rng = np.random.default_rng(0)
    x = np.cumsum(rng.standard_normal((SAMPLES, CHANNELS)), axis=0)
    b, a = signal.butter(ORDER, CUTOFF, fs=FS)
    sos = signal.butter(ORDER, CUTOFF, fs=FS, output="sos")
    ours = arash.filtfilt(x, CUTOFF, FS, order=ORDER)
    theirs = signal.filtfilt(b, a, x, axis=0)
    scale = np.abs(theirs).max()
    print(f"largest difference from scipy.signal.filtfilt: {np.abs(ours - theirs).max() / scale:.1e} of the signal's peak")
    rows = [
        ("arash.filtfilt", lambda: arash.filtfilt(x, CUTOFF, FS, order=ORDER)),
        ("scipy.signal.filtfilt(b, a, axis=0)", lambda: signal.filtfilt(b, a, x, axis=0)),
        ("scipy.signal.sosfiltfilt(sos, axis=0)", lambda: signal.sosfiltfilt(sos, x, axis=0)),
    ]
    times = {name: median_seconds(fn, repeats) for name, fn in rows}
    base = times["arash.filtfilt"]
    print(f"| {SAMPLES:,} × {CHANNELS}, order {ORDER}, {CUTOFF} Hz at {FS:.0f} Hz | median of {repeats} | ratio to arash |")
    print("|---|---|---|")
    for name, t in times.items():
        print(f"| {name} | {t * 1e3:.1f} ms | {t / base:.1f}× |")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 21)
