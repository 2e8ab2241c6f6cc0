"""arash: dynamics, calibration and control of the ARASH:ASiST haptic robot.

Arrays are numpy float64 in SI units (rad, m, s, N·m, N). A batch of states is an ``(N, dof)``
array; a single ``(dof,)`` vector gives a result without the batch axis.

>>> import arash
>>> robot = arash.Robot.arash_asist()
>>> robot.base_parameters().p
23
"""

from ._arash import (
    BaseParameters,
    Excitation,
    Identification,
    Robot,
    __version__,
    butter,
    consistent_least_squares,
    design_excitation,
    filtfilt,
    identify,
    load_model,
    paper_validation_trajectory,
)

__all__ = [
    "BaseParameters",
    "Excitation",
    "Identification",
    "Robot",
    "__version__",
    "butter",
    "consistent_least_squares",
    "design_excitation",
    "filtfilt",
    "identify",
    "load_model",
    "paper_validation_trajectory",
]
