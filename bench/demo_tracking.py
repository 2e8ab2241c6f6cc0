"""How much each model cuts the demo rig's tracking error against CAD, on the simulator alone
(no daemon, so deterministic): the robust controller on the paper's ω = 0.5 trajectory, two
periods, the maximum encoder error over the second. Without model files it gives the rig's own
parameters of the declared model (docs/demo.md, "What the declared model can do on this rig").

    .venv/bin/python bench/demo_tracking.py [MODEL.json ...]     # e.g. RUN/model_idim-iv-consistent.json
"""

import sys
from pathlib import Path

import numpy as np

import arash

ROOT = Path(__file__).resolve().parents[1]
OMEGA = 0.5
PERIOD = 2 * np.pi / OMEGA


def max_error(controller, params):
    run = arash.simulate(ROOT / "scenarios" / "demo.toml", {"kind": "paper-validation", "omega": OMEGA},
                         controller=controller, params=params, duration=2 * PERIOD, seed=1)
    second = run["t"] >= run["t"][0] + PERIOD
    return np.abs(run["q"][second] - run["q_des"][second]).max(axis=0)


def main():
    cad = max_error("idc-cad", "cad")
    print(f"inverse dynamics, CAD: max error {np.degrees(cad[0]):.4f}°, {np.degrees(cad[1]):.4f}°, "
          f"{cad[2] * 1e6:.1f} µm")
    rows = [("robust, the rig's own parameters", "truth")]
    rows += [(f"robust, {path}", arash.load_model(path)) for path in sys.argv[1:]]
    for label, params in rows:
        cut = cad / max_error("robust", params)
        print(f"{label}: cut by {cut[0]:.2f}×, {cut[1]:.2f}×, {cut[2]:.2f}× (yaw, pitch, insertion)")


if __name__ == "__main__":
    main()
