"""OLS against IDIM-IV and DIDIM on closed-loop logs with known truth (issue 18's coverage table).

Each log comes from the independent PD loop on Pinocchio (tests/python/support/closed_loop.py,
``pd_gravity_log``): ARASH:ASiST with perturbed inertials, friction and stiffness
(tests/python/support/simulated.py), four 10 s periods of a random Fourier excitation at 1 kHz, 16-bit
encoders that the controller differences, and a drive disturbance of the given share of the RMS
torque in a 2 Hz band. Prints, per disturbance and method, the share of base parameters within
3σ of the truth over all seeds, the worst seed's share, the parameters whose mean error over the
seeds exceeds 1σ (a bias), and the median time per fit.

    .venv/bin/python bench/closed_loop_iv.py [SEEDS] [DISTURBANCE...]   # default 20 seeds, 0.1 0.3
    .venv/bin/python bench/closed_loop_iv.py timing [REPEATS]              # 300,000 samples, default 3
    .venv/bin/python bench/closed_loop_iv.py rig [SEEDS]                   # arash's simulated rig, default 20

``timing`` fits a 300 s run of arash's simulated rig under PD (nominal scenario, the designed
excitation, 300,000 samples at 1 kHz) with each method and prints the median seconds of each
and its ratio to OLS. ``rig`` makes the same coverage table on arash's own simulated rig: the
nominal scenario (its true parameters drawn from the seed), the designed excitation for 60 s
(four periods) under PD with gravity compensation from CAD, and the robot declared with the rig's
tanh(q̇/0.001) Coulomb law.
"""

import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
import arash  # noqa: E402
from support.closed_loop import pd_gravity_log  # noqa: E402
from support.paths import ROBOT_FILES  # noqa: E402
from support.independent import Condition  # noqa: E402
from support.simulated import true_parameters  # noqa: E402

METHODS = ["ols", "idim-iv", "didim"]


def one_seed(seed, disturbance):
    robot = arash.Robot.from_urdf(ROBOT_FILES["arash_asist"])
    truth = true_parameters(robot, np.random.default_rng(seed))
    condition = Condition("arash_asist", 1000, 16, 0.0, "tanh", 4, 40.0, seed=seed)
    robot, log, reference, controller = pd_gravity_log(condition, truth, actuator_noise=disturbance, noise_hz=2.0)
    given = dict(reference=reference, controller=controller)
    fitted = robot.base_parameters(regroup_weak=True)  # the base parameters identify fits
    return fitted.names, fits(robot, log, given, fitted.project(truth))


def coverage_rows(label, names, results, failures):
    """Print one table row per method from each seed's (z, error, seconds) results."""
    for method in METHODS:
        if not results[method]:
            print(f"| {label} | {method} | – | – | {len(failures[method])} | – | – |")
            continue
        z = np.array([r[0] for r in results[method]])
        inside = np.abs(z) <= 3
        biased = [f"{names[i]} {np.mean(z[:, i]):+.1f}σ" for i in range(z.shape[1]) if abs(np.mean(z[:, i])) > 1]
        seconds = np.median([r[2] for r in results[method]])
        print(f"| {label} | {method} | {100 * inside.mean():.1f} % | {100 * inside.mean(axis=1).min():.0f} % "
              f"| {len(failures[method])} | {', '.join(biased) or 'none'} | {seconds:.2f} |")


def fits(robot, log, given, beta_true):
    """Each method's (z, error, seconds), or (None, None, message) where it refused."""
    out = {}
    for method in METHODS:
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            try:
                model = arash.identify(robot, *log, method=method, **(given if method != "ols" else {}))
            except ValueError as error:
                out[method] = (None, None, str(error))
                continue
        seconds = time.perf_counter() - start
        sigma = np.abs(model.sigma_percent / 100 * model.beta)
        out[method] = ((model.beta - beta_true) / sigma, model.beta - beta_true, seconds)
    return out


def rig(seeds):
    root = Path(__file__).resolve().parents[1]
    robot = arash.Robot.arash_asist(coulomb_epsilon=1e-3)
    fitted = robot.base_parameters(regroup_weak=True)  # the base parameters identify fits
    results, failures = {m: [] for m in METHODS}, {m: [] for m in METHODS}
    for seed in range(seeds):
        run = arash.simulate(root / "scenarios" / "nominal.toml", root / "trajectories" / "excitation_L5_T15.json",
                             controller="pd", duration=60.0, seed=seed)
        log = (run["t"], run["q"], run["tau_meas"])
        given = dict(reference=(run["q_des"], run["qd_des"], run["qdd_des"]), controller=run["logged_controller"])
        beta_true = fitted.project(run["true_params"])
        for method, (z, error, extra) in fits(robot, log, given, beta_true).items():
            (failures if z is None else results)[method].append(extra if z is None else (z, error, extra))
        print(f"  seed {seed} done", file=sys.stderr, flush=True)
    print("| log | method | within 3σ (all seeds) | worst seed | failed | mean error beyond 1σ | s per fit (median) |")
    print("|---|---|---|---|---|---|---|")
    coverage_rows("rig, PD, 4 × 15 s", fitted.names, results, failures)


def timing(repeats):
    root = Path(__file__).resolve().parents[1]
    robot = arash.Robot.arash_asist(coulomb_epsilon=1e-3)
    run = arash.simulate(root / "scenarios" / "nominal.toml", root / "trajectories" / "excitation_L5_T15.json",
                         controller="pd", duration=300.0)
    log = (run["t"], run["q"], run["tau_meas"])
    given = dict(reference=(run["q_des"], run["qd_des"], run["qdd_des"]), controller=run["logged_controller"])
    medians = {}
    print(f"| method | median s ({repeats} runs, {len(run['t'])} samples) | × OLS | iterations |")
    print("|---|---|---|---|")
    for method in ["ols", "consistent", "idim-iv", "idim-iv-consistent", "didim", "didim-consistent"]:
        seconds = []
        for _ in range(repeats):
            start = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)
                model = arash.identify(robot, *log, method=method, **(given if "i" in method[:2] else {}))
            seconds.append(time.perf_counter() - start)
        medians[method] = float(np.median(seconds))
        loop = next((c for c in model.settings["choices"] if c["code"] == "closed_loop"), None)
        iterations = loop["iterations"] if loop else "–"
        print(f"| {method} | {medians[method]:.2f} | {medians[method] / medians['ols']:.2f} | {iterations} |")


def main():
    if sys.argv[1:2] == ["timing"]:
        timing(int(sys.argv[2]) if len(sys.argv) > 2 else 3)
        return
    if sys.argv[1:2] == ["rig"]:
        rig(int(sys.argv[2]) if len(sys.argv) > 2 else 20)
        return
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    disturbances = [float(a) for a in sys.argv[2:]] or [0.1, 0.3]
    print("| disturbance | method | within 3σ (all seeds) | worst seed | failed | mean error beyond 1σ | s per fit (median) |")
    print("|---|---|---|---|---|---|---|")
    for disturbance in disturbances:
        results = {m: [] for m in METHODS}
        failures = {m: [] for m in METHODS}
        for seed in range(seeds):
            names, out = one_seed(seed, disturbance)
            for method, (z, error, extra) in out.items():
                if z is None:
                    failures[method].append(extra)
                else:
                    results[method].append((z, error, extra))
            print(f"  seed {seed} done", file=sys.stderr, flush=True)
        coverage_rows(f"{disturbance:g}", names, results, failures)

if __name__ == "__main__":
    main()
