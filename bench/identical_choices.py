"""Whether a change to how the choices are computed keeps them: identify and diagnose the three
logs of bench/choice_timings.py (the TX40, KUKA run 1, the 300 s simulated log) with the
defaults, save β, the cut-offs, the friction velocities and the diagnosis's band, and compare
two such files bit for bit.

    .venv/bin/python bench/identical_choices.py save BEFORE.npz   # with the wheel before
    .venv/bin/python bench/identical_choices.py save AFTER.npz    # with the wheel after
    .venv/bin/python bench/identical_choices.py compare BEFORE.npz AFTER.npz
"""

import sys
import warnings

import numpy as np

import choice_timings
import arash


def save(path):
    warnings.simplefilter("ignore")
    out = {}
    for make in (choice_timings.tx40, choice_timings.kuka, choice_timings.simulated):
        name, urdf, log = make()
        robot = arash.Robot.arash_asist() if urdf is None else arash.Robot.from_urdf(urdf)
        r = arash.identify(robot, *log)
        laws = [np.nan if v is None else v for v in r.robot.friction_velocities]
        out[f"{name}: beta"] = np.asarray(r.beta)
        out[f"{name}: cut-offs and laws"] = np.array([r.settings["cutoff_hz"], r.settings["friction_cutoff_hz"]] + laws)
        out[f"{name}: diagnosis band"] = np.array([arash.diagnose(robot, *log, effects=[]).settings["cutoff_hz"]])
    np.savez(path, **out)
    print(f"saved {path}")


def compare(before, after):
    a, b = np.load(before), np.load(after)
    differ = 0
    for key in a.files:
        same = key in b.files and np.array_equal(a[key], b[key], equal_nan=True)
        differ += not same
        print(f"{key}: {'identical' if same else 'DIFFERENT'}")
    sys.exit(1 if differ else 0)


if __name__ == "__main__":
    match sys.argv[1:]:
        case ["save", path]:
            save(path)
        case ["compare", before, after]:
            compare(before, after)
        case _:
            sys.exit(__doc__)
