"""Print the median of every Criterion benchmark from its last run (target/criterion/*/new).

Run after `cargo bench -p arash-core --bench dynamics`:
    python3 bench/criterion_medians.py
"""

import json
from pathlib import Path

root = Path(__file__).resolve().parents[1] / "target" / "criterion"
for estimates in sorted(root.glob("*/new/estimates.json")):
    bench = json.loads((estimates.parent / "benchmark.json").read_text())["title"]
    median = json.loads(estimates.read_text())["median"]
    lo, hi = median["confidence_interval"]["lower_bound"], median["confidence_interval"]["upper_bound"]
    print(f"{bench:45s} median {median['point_estimate']:8.1f} ns  (95% CI {lo:.1f}–{hi:.1f})")
