"""Started from the identification on logs of the declared model: is any joint predicted worse?

Issue 59 asks that `arash.diagnose(..., start="identified")` never leave a joint predicting a
held-out run worse than `arash.identify`'s model of the same log. For each null condition of
tests/python/test_diagnosis_independent.py (Pinocchio's dynamics of the declared robot, nothing
undeclared), the diagnosis is held out on one run and judged on it and on a third run, on the
tests' independent 8 Hz yardstick (tests/python/support/yardstick.py). Prints, per condition and
run: whether the refit was kept or the identified parameters held, the effects accepted, and per
joint ‖e‖/‖τ‖ of the diagnosis over the identification's and the excess in standard errors
(worse beyond 2 fails the issue's rule).

    .venv/bin/python bench/from_identified_nulls.py
"""

import sys
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "python"))
import arash  # noqa: E402
from support.yardstick import SIGMAS, excess_in_sigmas, relative, yardstick  # noqa: E402
from test_diagnosis_independent import NULL, logs  # noqa: E402


def main():
    worse = 0
    for c in NULL:
        robot, train, held, third = logs(c, more=1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            identified = arash.identify(robot, *train)
            d = arash.diagnose(robot, *train, validation=held, start="identified")
        path = "refit kept" if d.settings["choices"][0].get("refitted") else "identified held"
        for label, run in (("held out", held), ("third run", third)):
            (e_i, e_d), tau, batch = yardstick([identified, d.model], *run)
            z = excess_in_sigmas(e_d, e_i, batch)
            worse += int(np.any(z > SIGMAS))
            print(f"{c.label:45s} {label:9s} {path:15s} accepted {[a.label for a in d.accepted]}  "
                  f"ratio {np.round(relative(e_d, tau) / relative(e_i, tau), 3)}  σ {np.round(z, 1)}", flush=True)
    print(f"runs with a joint worse beyond {SIGMAS} standard errors: {worse} of {2 * len(NULL)}")


if __name__ == "__main__":
    main()
