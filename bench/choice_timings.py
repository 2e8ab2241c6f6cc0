"""How long the choices made from the data take (issue 44): the diagnosis's band search and each
joint's Coulomb law, and identification's laws with its cut-offs, on real logs and a long
simulated one. Each time is the median of RUNS calls; the choice's share is the call with the
choice left to the data less the same call with the choice given as the data made it.

    .venv/bin/python bench/choice_timings.py [RUNS]     # default 5; needs ../shared/data
"""

import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))
import arash  # noqa: E402

SHARED = ROOT.parent / "shared" / "data"


def tx40():
    read = lambda name: np.loadtxt(ROOT / "data" / "staubli_tx40" / name, delimiter=",", skiprows=1)  # noqa: E731
    theta, tau_m = read("pos_read_data.csv.gz"), read("curr_data.csv.gz")
    transmission = arash.Transmission([32, 32, 45, -48, 45, 32], coupling=[(6, 5, 32.0)],
                                      offsets=[0, -np.pi / 2, np.pi / 2, 0, 0, 0])
    q, tau = transmission.to_joints(theta, tau_m)
    urdf = ROOT / "data" / "staubli_tx40" / "tx40_mdh_modified.urdf"
    return "TX40 motor-side, 9 s at 5 kHz", urdf, (np.arange(len(q)) / 5000.0, q, tau)


def kuka():
    data = np.load(SHARED / "kuka_lwr4" / "measurements_1.npz")
    log = (data["times"] - data["times"][0], data["positions"], data["torques"])
    return "KUKA run 1, 25 s at 200 Hz", SHARED / "kuka_lwr4" / "kuka_lwr4.urdf", log


def simulated():
    run = arash.simulate(ROOT / "scenarios" / "cogging.toml", ROOT / "trajectories" / "excitation_L5_T15.json",
                         controller="idc-cad", duration=300.0, seed=1)
    return "simulated rig, 300 s at 1 kHz", None, (run["t"], run["q"], run["tau_meas"])


def median_time(call, runs):
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        result = call()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    warnings.simplefilter("ignore")
    print("| log | diagnosis, band and laws chosen (s) | same, band and laws given (s) | the choices (s) "
          "| identification, cut-offs and laws chosen (s) | same, given (s) | the choices (s) |")
    print("|---|---|---|---|---|---|---|")
    for make in (tx40, kuka, simulated):
        name, urdf, log = make()
        robot = arash.Robot.arash_asist() if urdf is None else arash.Robot.from_urdf(urdf)
        chosen_time, d = median_time(lambda: arash.diagnose(robot, *log, effects=[]), runs)
        laws = d.settings["friction_velocities"]
        declared = (arash.Robot.arash_asist(friction_velocities=laws) if urdf is None
                    else arash.Robot.from_urdf(urdf, friction_velocities=laws))
        given_time, _ = median_time(lambda: arash.diagnose(
            declared, *log, effects=[], cutoff_hz=d.settings["cutoff_hz"],
            friction_cutoff_hz=d.settings["friction_cutoff_hz"]), runs)
        id_chosen, ident = median_time(lambda: arash.identify(robot, *log), runs)
        id_declared = (arash.Robot.arash_asist(friction_velocities=ident.robot.friction_velocities) if urdf is None
                       else arash.Robot.from_urdf(urdf, friction_velocities=ident.robot.friction_velocities))
        id_given, _ = median_time(lambda: arash.identify(
            id_declared, *log, cutoff_hz=ident.settings["cutoff_hz"],
            friction_cutoff_hz=ident.settings["friction_cutoff_hz"]), runs)
        print(f"| {name} | {chosen_time:.2f} | {given_time:.2f} | {chosen_time - given_time:.2f} "
              f"| {id_chosen:.2f} | {id_given:.2f} | {id_chosen - id_given:.2f} |", flush=True)


if __name__ == "__main__":
    main()
