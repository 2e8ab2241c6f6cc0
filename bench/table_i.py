"""Issue 18's Table I where the model is complete: every identifiable base parameter's σ% and its
distance from the truth, on arash's simulated rig with no undeclared effect.

The nominal scenario (its truth drawn from the seed) runs `arash excite`'s default design (seeded)
under inverse dynamics control with CAD, as the demo logs its excitation; IDIM-IV fits it with
the rig's friction law declared (tanh(q̇/0.001)), or with the URDF's sign(q̇) given ``--sign``.
Prints the table in Markdown and how many parameters have σ% ≤ 10 % and lie within 3σ. The
column "apart" is the part of the parameter's normalised column (over one period of the design at
200 Hz) outside the span of all the others, with the one it leans on most: what its σ pays for.

    .venv/bin/python bench/table_i.py [DURATION_S] [--sign]     # default 300 s (the paper's)
"""

import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import arash

ROOT = Path(__file__).resolve().parents[1]
SEED = 1


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    duration = float(args[0]) if args else 300.0
    sign = "--sign" in sys.argv
    robot = arash.Robot.arash_asist() if sign else arash.Robot.arash_asist(coulomb_epsilon=1e-3)
    started = time.perf_counter()
    design = arash.design_excitation(robot, seed=SEED, quiet=True)
    run = arash.simulate(ROOT / "scenarios" / "nominal.toml", json.loads(design.to_json()), controller="idc-cad",
                         duration=duration, seed=SEED)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        model = arash.identify(robot, run["t"], run["q"], run["tau_meas"], method="idim-iv",
                               reference=(run["q_des"], run["qd_des"], run["qdd_des"]),
                               controller=run["logged_controller"])
    truth = model.base.project(run["true_params"])
    sigma = model.sigma_percent / 100 * np.abs(model.beta)
    z = (model.beta - truth) / sigma
    law = "sign(q̇)" if sign else "tanh(q̇/0.001)"
    print(f"{duration:.0f} s, design κ {design.condition_number:.0f}, fit κ {model.condition_number:.0f}, "
          f"Coulomb law {law}, training FP% {np.round(model.fp_percent, 2)}, {time.perf_counter() - started:.0f} s\n")
    print("| parameter | truth | IDIM-IV | σ | σ% | (est. − truth)/σ | apart (leans on) |")
    print("|---|---|---|---|---|---|---|")
    rows = zip(model.base.names, model.beta, sigma, model.sigma_percent, truth, z, apart(model.base, design))
    for name, b, s, p, t, zz, (r, other) in rows:
        print(f"| `{name}` | {t:.3e} | {b:.3e} | {s:.1e} | {p:.1f} | {zz:+.1f} | {r:.3f} ({other}) |")
    print(f"\nσ% ≤ 10 %: {int((model.sigma_percent <= 10).sum())} of {len(z)}; "
          f"within 3σ of the truth: {int((np.abs(z) <= 3).sum())} of {len(z)}")


def apart(base, design):
    """Each column's relative part outside the others' span, and the name it leans on most."""
    _, q, qd, qdd = design.sample(200.0)
    w = base.reduced_regressor(q, qd, qdd).reshape(-1, base.p)
    w = w / np.linalg.norm(w, axis=0)
    out = []
    for k in range(base.p):
        others = np.delete(w, k, axis=1)
        c, *_ = np.linalg.lstsq(others, w[:, k], rcond=None)
        names = base.names[:k] + base.names[k + 1:]
        out.append((np.linalg.norm(w[:, k] - others @ c), names[int(np.argmax(np.abs(c)))]))
    return out


if __name__ == "__main__":
    main()
