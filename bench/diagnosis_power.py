"""How often arash.diagnose finds an effect of a given size (issue 19's power curve).

Each log comes from the independent Pinocchio generator (tests/python/support/independent.py): the
declared ARASH:ASiST model, 1 kHz, 16-bit encoders, 1 % torque noise, sign(q̇) Coulomb friction, an
aperiodic trajectory, plus one injected effect whose torque has an RMS of the given share of its
joint's RMS torque. No validation log: the held-out error is judged on the log's own odd blocks,
as on a short real log. A detection is the effect named first, on its joint. An offset also
counts when named as asymmetric Coulomb friction: under sign(q̇), |sign(q̇)| = 1 is the offset's
column.

Prints a markdown table (detections per seeds for each effect, length and size) and, where
matplotlib is installed, draws docs/figures/diagnosis_power.png.

    .venv/bin/python bench/diagnosis_power.py [SEEDS]     # default 10 seeds (300 s logs: half)
"""

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))
import arash  # noqa: E402
from support.independent import Condition, Injected, make_log  # noqa: E402

EFFECTS = [("offset", 0), ("configuration_disturbance", 2), ("armature", 2), ("stribeck", 2)]
DURATIONS = [10.0, 30.0, 300.0]
SIZES = [0.025, 0.05, 0.1, 0.2]
SAME_COLUMN = {"offset": {"offset", "coulomb_asymmetry"}}


def detected(d, effect):
    if not d.accepted:
        return False
    first = d.accepted[0]
    return first.name in SAME_COLUMN.get(effect.kind, {effect.kind}) and effect.joint in first.joints


def main():
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 10
    rates, times = {}, []
    print("| effect, joint | log | " + " | ".join(f"{100 * s:g} %" for s in SIZES) + " |")
    print("|---|---|" + "---|" * len(SIZES))
    for kind, joint in EFFECTS:
        for duration in DURATIONS:
            n = seeds if duration < 100 else max(1, seeds // 2)
            row = []
            for size in SIZES:
                hits = 0
                for s in range(n):
                    c = Condition("arash_asist", 1000, 16, 0.01, "sign", None, duration, seed=31 * s + 5)
                    robot, train, _ = make_log(c, effect=Injected(kind, joint, size))
                    t0 = time.perf_counter()
                    hits += detected(arash.diagnose(robot, *train), Injected(kind, joint, size))
                    times.append(time.perf_counter() - t0)
                rates[kind, joint, duration, size] = hits / n
                row.append(f"{hits}/{n}")
            name = robot.joint_names()[joint]
            print(f"| {kind}, {name} | {duration:g} s | " + " | ".join(row) + " |", flush=True)
    times.sort()
    print(f"\nmedian diagnosis time {times[len(times) // 2]:.2f} s over {len(times)} logs")
    draw(rates)


def draw(rates):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no figure")
        return
    fig, axes = plt.subplots(1, len(EFFECTS), figsize=(4 * len(EFFECTS), 3.2), sharey=True)
    for ax, (kind, joint) in zip(axes, EFFECTS):
        # Lines that coincide (all found) are drawn with different markers and widths.
        for duration, marker, width in zip(DURATIONS, "os^", (2.5, 1.5, 0.8)):
            ax.plot([100 * s for s in SIZES], [rates[kind, joint, duration, s] for s in SIZES], marker + "-",
                    linewidth=width, markersize=4 + width, label=f"{duration:g} s")
        ax.set_title(f"{kind} (joint {joint})", fontsize=9)
        ax.set_xscale("log")
        ax.set_xticks([100 * s for s in SIZES], [f"{100 * s:g}" for s in SIZES])
        ax.minorticks_off()
        ax.set_xlabel("effect RMS, % of the joint's RMS torque")
        ax.set_ylim(-0.05, 1.05)
    axes[0].set_ylabel("named first")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    out = ROOT / "docs" / "figures" / "diagnosis_power.png"
    fig.savefig(out, dpi=110)
    print(f"figure: {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
