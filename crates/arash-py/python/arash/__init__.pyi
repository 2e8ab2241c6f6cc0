from ._arash import (
    BaseParameters as BaseParameters,
    Excitation as Excitation,
    Identification as Identification,
    Robot as Robot,
    __version__ as __version__,
    butter as butter,
    consistent_least_squares as consistent_least_squares,
    design_excitation as design_excitation,
    filtfilt as filtfilt,
    identify as identify,
    load_model as load_model,
    paper_validation_trajectory as paper_validation_trajectory,
    read_log as read_log,
)

import os
from typing import Any, Optional, Union

def simulate(
    scenario: Optional[Union[str, os.PathLike]] = None,
    trajectory: Optional[Union[str, os.PathLike, dict]] = None,
    *,
    controller: str = "robust",
    params: Any = None,
    duration: Optional[float] = None,
    seed: Optional[int] = None,
    robot: Optional[Robot] = None,
    gain_units: str = "si",
    log: Optional[Union[str, os.PathLike]] = None,
    log_truth: bool = False,
) -> dict[str, Any]: ...

class Effect:
    name: str
    joints: list[int]
    coefficients: Any
    p_value: float
    heldout_gain: float
    mass_kg: Optional[float]
    body: Optional[str]

class Diagnosis:
    accepted: list[Effect]
    rejected: list[dict]
    error_before: dict[str, Any]
    error_after: dict[str, Any]
    error_before_training: dict[str, Any]
    error_after_training: dict[str, Any]
    model: Identification
    model_consistent: Optional[Identification]
    @property
    def series(self) -> dict: ...
    def report(self) -> str: ...
    def to_json(self) -> str: ...

def diagnose(
    robot: Robot,
    t: Any,
    q: Any,
    tau: Any,
    *,
    model: Optional[Identification] = None,
    validation: Optional[tuple] = None,
    **options: Any,
) -> Diagnosis: ...
