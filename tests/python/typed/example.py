"""A small analysis written against arash's type stubs; `mypy --strict` checks it (test_typing.py).

It is never run: it only has to type-check, so that a wrong or missing stub fails the suite.
"""

import numpy as np
import numpy.typing as npt

import arash


def residual_rms(robot: arash.Robot, t: npt.NDArray[np.float64], q: npt.NDArray[np.float64],
                 tau: npt.NDArray[np.float64]) -> float:
    model: arash.Identification = arash.identify(robot, t, q, tau, method="consistent", periods=4, pull=1e-3)
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    predicted: npt.NDArray[np.float64] = model.predict(q, qd, qdd)
    fp: npt.NDArray[np.float64] = model.fp_percent
    assert fp.shape == (robot.dof,)
    return float(np.sqrt(np.mean((tau - predicted) ** 2)))


def first_effect(robot: arash.Robot, t: npt.NDArray[np.float64], q: npt.NDArray[np.float64],
                 tau: npt.NDArray[np.float64]) -> str | None:
    defaults = arash.DiagnoseOptions()
    d: arash.Diagnosis = arash.diagnose(robot, t, q, tau, alpha=defaults.alpha / 2, effects=["offset", "armature"])
    for effect in d.accepted:
        sigma: npt.NDArray[np.float64] = effect.sigma
        print(effect.label, effect.coefficients, sigma, effect.p_value, effect.mass_kg)
    for rejection in d.rejected:
        print(rejection["label"], rejection["reason"])
    after: npt.NDArray[np.float64] = d.error_after["rms"]
    print(after, d.model.table(), d.settings["cutoff_hz"])
    return d.accepted[0].name if d.accepted else None


def excite(robot: arash.Robot) -> float:
    e: arash.Excitation = arash.design_excitation(robot, harmonics=5, seed=3, quiet=True)
    t, q, qd, qdd = e.sample(rate_hz=1000.0, periods=2)
    run = arash.simulate(trajectory={"kind": "paper-validation", "omega": 0.5}, controller="pd", duration=1.0)
    return e.condition_number + float(t[-1]) + float(len(run["t"]))
