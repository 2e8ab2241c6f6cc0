"""Type stubs of the compiled module; ``python -m mypy.stubtest arash`` checks them against it."""

from os import PathLike
from typing import Any, Optional, Sequence, Union, final

import numpy as np
import numpy.typing as npt

_Array = npt.NDArray[np.float64]
_ArrayLike = npt.ArrayLike

__all__ = [
    "BaseParameters",
    "DiagnoseOptions",
    "Diagnosis",
    "Effect",
    "Excitation",
    "Identification",
    "Robot",
    "SimulatedMotors",
    "Transmission",
    "__version__",
    "_design_excitation",
    "_diagnose",
    "_identify",
    "_identify_with_load",
    "_repair_log",
    "_simulate",
    "butter",
    "consistent_least_squares",
    "external_force",
    "filtfilt",
    "fixture_bounds",
    "load_model",
    "paper_validation_trajectory",
    "read_log",
    "render_fixtures",
]

__version__: str

@final
class Transmission:
    """Motor angles and torques to joint space: θ = R (q − q₀), τ = Rᵀ τ_m; a singular R is refused."""
    def __new__(
        cls,
        gear_ratios: Sequence[float],
        coupling: Optional[Sequence[tuple[int, int, float]]] = None,
        offsets: Optional[Sequence[float]] = None,
    ) -> Transmission: ...
    @property
    def matrix(self) -> _Array: ...
    def to_joints(self, theta: _ArrayLike, tau_motor: _ArrayLike) -> tuple[_Array, _Array]: ...

@final
class Robot:
    """A robot model: kinematic tree with mimic couplings and CAD parameters.

    Parameter vector layout (P = 10·bodies + 3·dof): per body
    ``[m, mx, my, mz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`` about the body frame origin (``Ixy`` is the
    tensor element ``-∫xy dm``, as in URDF), then ``[fv, fc]`` per joint, then ``ke`` per joint.
    """

    @staticmethod
    def from_urdf(
        path: Union[str, PathLike[str]],
        coulomb_epsilon: Optional[float] = None,
        friction_velocities: Optional[Sequence[Optional[float]]] = None,
    ) -> Robot:
        """Its Coulomb laws are chosen from the data by ``identify`` and ``diagnose`` unless
        declared: ``coulomb_epsilon`` declares tanh(q̇/ε) on every joint, ``friction_velocities``
        one law per joint (v of tanh(q̇/v), None for sign(q̇))."""
    @staticmethod
    def arash_asist(
        coulomb_epsilon: Optional[float] = None, friction_velocities: Optional[Sequence[Optional[float]]] = None
    ) -> Robot: ...
    @property
    def friction_velocities(self) -> list[Optional[float]]:
        """Each joint's v of its Coulomb law tanh(q̇/v); None for sign(q̇)."""
    @property
    def coulomb_laws_declared(self) -> bool: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def concerns(self) -> list[dict[str, Any]]:
        """The warnings as data: ``code`` (``semidefinite_inertia``), ``link``, ``eigenvalues``
        (kg·m²) and ``text``."""
    @property
    def dof(self) -> int: ...
    @property
    def num_params(self) -> int: ...
    @property
    def name(self) -> str: ...
    def joint_names(self) -> list[str]: ...
    def body_names(self) -> list[str]: ...
    def position_limits(self) -> list[tuple[float, float]]: ...
    def velocity_limits(self) -> list[float]: ...
    def parameter_names(self) -> list[str]: ...
    def cad_parameters(self) -> _Array: ...
    def coupling_matrix(self) -> _Array: ...
    def regressor(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, *, out: Optional[_Array] = None) -> _Array:
        """Y(q, q̇, q̈): (N, dof) in, (N, dof, P) out."""
    def slotine_li_regressor(self, q: _ArrayLike, qd: _ArrayLike, qd_r: _ArrayLike, qdd_r: _ArrayLike) -> _Array:
        """Y_S(q, q̇, q̇_r, q̈_r): (N, dof) in, (N, dof, P) out."""
    def inverse_dynamics(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike, params: Optional[_ArrayLike] = None) -> _Array: ...
    def mass_matrix(self, q: _ArrayLike, params: Optional[_ArrayLike] = None) -> _Array: ...
    def coriolis_matrix(self, q: _ArrayLike, qd: _ArrayLike, params: Optional[_ArrayLike] = None) -> _Array: ...
    def gravity(self, q: _ArrayLike, params: Optional[_ArrayLike] = None) -> _Array: ...
    def forward_dynamics(self, q: _ArrayLike, qd: _ArrayLike, tau: _ArrayLike, params: Optional[_ArrayLike] = None) -> _Array: ...
    def base_parameters(self, samples: Optional[int] = None, seed: Optional[int] = None, regroup_weak: bool = False) -> BaseParameters:
        """The exact base parameters (Y π = Y_r β to round-off); regroup_weak=True regroups the
        weak combinations no trajectory within the limits separates (then Y π = Y_r β on such
        trajectories, to their residual), the set ``identify`` fits by default (``diagnose`` fits
        the exact ones)."""

@final
class SimulatedMotors:
    """The simulated rig's motor side (plant, amplifiers, encoders, current sensing), one control
    cycle at a time: what ``arash mock-motor`` serves, for a drive simulator to put behind its
    process data. ``scenario`` is a scenario's TOML ("" for the nominal rig)."""

    def __new__(
        cls,
        robot: Robot,
        scenario: str,
        counts_per_rev: Sequence[float],
        transmission: Sequence[float],
        seed: Optional[int] = None,
    ) -> SimulatedMotors: ...
    def apply(self, dt: float, tau: Sequence[float]) -> None: ...
    def encoder_counts(self) -> list[int]: ...
    def measured_torque(self) -> list[float]: ...
    def q(self) -> list[float]: ...
    def truth_header(self) -> str: ...
    def truth_row(self) -> str: ...
    def time(self) -> float: ...

@final
class BaseParameters:
    """β = B π: the identifiable combinations of the standard parameters."""

    @property
    def p(self) -> int: ...
    @property
    def B(self) -> _Array: ...
    @property
    def names(self) -> list[str]: ...
    @property
    def expressions(self) -> list[str]: ...
    @property
    def independent(self) -> list[int]: ...
    @property
    def weak(self) -> list[tuple[str, float, str]]:
        """(name, residual, expression) of each weak base parameter regrouped."""
    def weak_report(self) -> str: ...
    def project(self, params: _ArrayLike) -> _Array: ...
    def reduced_regressor(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike) -> _Array:
        """Y_r(q, q̇, q̈): (N, dof) in, (N, dof, p) out, with Y π = Y_r β (exactly unless regroup_weak=True)."""

def butter(order: int, cutoff_hz: float, sample_rate_hz: float) -> tuple[_Array, _Array]:
    """Butterworth low-pass (b, a), as scipy.signal.butter(order, cutoff_hz, fs=sample_rate_hz)."""

def filtfilt(x: _ArrayLike, cutoff_hz: float, sample_rate_hz: float, order: Optional[int] = None) -> _Array:
    """Zero-phase Butterworth low-pass along axis 0 (filtfilt's padding, second-order sections)."""

def external_force(
    robot: Robot,
    t: _ArrayLike,
    q: _ArrayLike,
    tau: _ArrayLike,
    *,
    qd: Optional[_ArrayLike] = None,
    model: Optional[Identification] = None,
    params: Optional[_ArrayLike] = None,
    bandwidth_hz: Optional[Union[float, Sequence[float]]] = None,
    epsilon: Optional[Union[float, Sequence[float]]] = None,
    sigma: Optional[Union[float, Sequence[float]]] = None,
    frame: Optional[str] = None,
    about: Optional[str] = None,
    min_lever_m: Optional[float] = None,
    torque: str = "sampled",
    currents: bool = False,
    thresholds: Optional[Union[str, tuple[Union[float, Sequence[float]], Union[float, Sequence[float]]]]] = None,
    contact_sigmas: Optional[float] = None,
    collision_sigmas: Optional[float] = None,
    zero_phase: bool = False,
) -> dict[str, Any]:
    """The external joint torque by the momentum observer ("tau_ext", its σ "sigma_joint"), the force
    at ``frame``, and with ``thresholds`` ("sigma", or ``(contact, collision)`` in N·m and N) each
    sample's "level" (0 free, 1 contact, 2 collision) and the "episodes" found. What was chosen
    from the model (bandwidth, σ, q̇) is in "reasons". ``zero_phase=True``: offline, without the
    observer's lag and in a hand's 5 Hz band; the levels stay the causal observer's."""

def fixture_bounds(
    robot: Robot,
    fixtures: str,
    *,
    params: Optional[_ArrayLike] = None,
    viscous_compensation: float = 0.0,
    period_s: float = 1e-3,
    latency_s: Optional[float] = None,
) -> dict[str, Any]:
    """Whether the fixtures of a fixture file's TOML text render passively: each fixture's least
    "damping_left", its "stiffness_bound" and largest "share" of the damping, and the share of all
    "together" (Colgate and Schenkel's b > K·(T/2 + latency) + |B|). ValueError names the field
    over its bound."""

def render_fixtures(robot: Robot, fixtures: str, q: _ArrayLike, qd: _ArrayLike) -> dict[str, Any]:
    """The fixtures' joint "torque", the "force" at the instrument and its "moment" about the entry
    point (base frame), the "energy" their springs hold and whether a wall or cone is in "contact",
    at each sample of q and q̇."""

@final
class Identification:
    """An identified model (see docs/identification.md)."""

    @property
    def method(self) -> str: ...
    @property
    def beta(self) -> _Array: ...
    @property
    def sigma_percent(self) -> _Array: ...
    @property
    def fp_percent(self) -> _Array: ...
    @property
    def fp_percent_ols(self) -> _Array: ...
    @property
    def relative_error(self) -> _Array: ...
    @property
    def rms(self) -> _Array: ...
    @property
    def params(self) -> Optional[_Array]: ...
    @property
    def min_pseudo_inertia_eigenvalue(self) -> _Array: ...
    @property
    def cutoff_hz(self) -> float: ...
    @property
    def settings(self) -> dict[str, Any]:
        """The preprocessing as used, with ``reasons`` (what chose each value) and ``warnings`` as
        sentences, and ``choices`` and ``concerns`` as the same data (``code``, figures, ``text``)."""
    @property
    def condition_number(self) -> float: ...
    @property
    def drive_gains(self) -> Optional[dict[str, Any]]:
        """The drive gains of a model identified from currents with a known load, else None."""
    @property
    def determination(self) -> Optional[dict[str, Any]]:
        """What sets each σ% besides the noise: "apart" (1/√VIF of each base parameter's column),
        "leans_on" (index of the column it leans on most, or None), "column_over_torque",
        "torque_share" and "cause" (why a σ% is above 10 %, else None). None for a model file
        written without them."""
    @property
    def base(self) -> BaseParameters: ...
    @property
    def robot(self) -> Robot: ...
    def predict(self, q: _ArrayLike, qd: _ArrayLike, qdd: _ArrayLike) -> _Array: ...
    def validate(self, t: _ArrayLike, q: _ArrayLike, tau: _ArrayLike, *, periods: Optional[int] = None) -> dict[str, Any]:
        """FP% ("fp_percent"), ‖e‖/‖τ‖ ("rel") and RMS ("rms") per joint on a validation log, with the
        cut-off it was filtered at ("cutoff_hz") and its preprocessing reasons ("reasons"), of the
        declared part (``arash.heldout_errors`` scores a diagnosis's effects too)."""
    @property
    def held_out(self) -> Optional[dict[str, Any]]:
        """The model's residual on held-out data, as its file records it: "rms" per joint,
        "samples", "cutoff_hz", "source" and "observer" (None, or the force observer run hand-free
        on the held-out runs: "bandwidth_hz" and "sigma" per joint, the force estimate's defaults,
        "grid_hz", "grid_sigma", "reason" and "peak"); None when it records none."""
    def with_held_out(
        self, runs: Sequence[tuple[_ArrayLike, _ArrayLike, _ArrayLike]], *, torque: str = "sampled"
    ) -> Identification:
        """The same model with its residual on the held-out ``runs`` (each ``(t, q, tau)``) recorded:
        per joint, the RMS over all their samples, in the model's band, no periods averaged (a
        diagnosis's model keeps its diagnosis's), and the force observer run hand-free on them,
        whose bandwidth and σ a force estimate then uses (``torque``: "sampled", "held" or
        "preceding", as for ``external_force``)."""
    def without_effects(self, which: Optional[Sequence[int]] = None) -> Identification:
        """The same model without the effects a diagnosis added (``which``: the indices of those to
        drop, in the file's order; default all, which leaves the declared part alone)."""
    def table(self) -> str: ...
    def to_json(self) -> str: ...
    def save(self, path: Union[str, PathLike[str]]) -> None: ...

def _identify(
    robot: Robot, log: tuple[_ArrayLike, _ArrayLike, _ArrayLike], method: Optional[str], options: dict[str, Any]
) -> Identification: ...

def _identify_with_load(
    robot: Robot,
    runs: list[tuple[_ArrayLike, _ArrayLike, _ArrayLike, bool]],
    load: tuple[str, float, Optional[list[float]], Optional[list[float]]],
    method: Optional[str],
    options: dict[str, Any],
    gains: tuple[Optional[list[tuple[float, float]]], Optional[str]],
) -> Identification: ...

def _repair_log(
    t: _ArrayLike, signals: list[tuple[str, _ArrayLike]]
) -> tuple[_Array, list[_Array], list[dict[str, Any]]]: ...

def load_model(path: Union[str, PathLike[str]]) -> Identification: ...

def consistent_least_squares(
    robot: Robot, w: _ArrayLike, tau: _ArrayLike, *, pull: Optional[float] = None,
    stiffness_bounds: Optional[tuple[float, float]] = None,
) -> _Array: ...

def paper_validation_trajectory(omega: float, t: _ArrayLike) -> tuple[_Array, _Array, _Array]: ...

@final
class Excitation:
    @property
    def condition_number(self) -> float: ...
    @property
    def condition_number_with_weak(self) -> float: ...
    @property
    def period_s(self) -> float: ...
    @property
    def harmonics(self) -> int: ...
    def sample(self, rate_hz: Optional[float] = None, periods: int = 1) -> tuple[_Array, _Array, _Array, _Array]: ...
    def to_json(self) -> str: ...

def _design_excitation(robot: Robot, options: dict[str, Any], quiet: bool) -> Excitation: ...

def read_log(path: Union[str, PathLike[str]]) -> dict[str, Any]:
    """A flight log as numpy arrays (docs/flightlog.md): ``t``, ``q``, ``tau_meas``… as logged
    (``tau_ext`` and ``frame_force``, the daemon's force observer, None where it ran none),
    and ``uniform``: ``t``, ``q``, ``tau_meas``, ``q_des``, ``qd_des``, ``qdd_des`` on a uniform time
    grid (a daemon log repeats a time where telemetry was late) with ``repaired``, the samples
    that took; what ``identify`` and ``diagnose`` take."""
def _simulate(
    robot: Robot,
    scenario: tuple[str, str],
    trajectory_json: str,
    control: tuple[str, Any, str],
    run: tuple[Optional[float], Optional[int]],
    output: tuple[Optional[Union[str, PathLike[str]]], bool],
) -> dict[str, Any]: ...

@final
class DiagnoseOptions:
    """The diagnosis's settings; ``DiagnoseOptions()`` holds the defaults."""

    def __new__(cls, **kwargs: Any) -> DiagnoseOptions: ...
    @property
    def cutoff_hz(self) -> Optional[float]:
        """The cut-off set, or None: the diagnosis's own (20 Hz, at most a fifth of the rate,
        narrower where the encoder's noise would bias q̈; ``settings["reasons"]`` says why)."""
    @property
    def friction_cutoff_hz(self) -> Optional[float]:
        """The friction velocity's cut-off set, or None: the diagnosis's cut-off, slower where
        the encoder's steps would make up more than 0.25 % of a joint's RMS speed."""
    @property
    def order(self) -> int: ...
    @property
    def block_s(self) -> float: ...
    @property
    def batch_s(self) -> Optional[float]:
        """The Wald test's batch length set (s), or None: each test chooses from its scores."""
    @property
    def alpha(self) -> float: ...
    @property
    def min_gain(self) -> float: ...
    @property
    def max_effects(self) -> int: ...
    @property
    def max_delay_s(self) -> float: ...
    @property
    def max_vif(self) -> float: ...
    @property
    def transmission(self) -> Optional[list[float]]: ...
    @property
    def effects(self) -> list[str]: ...
    @property
    def torque_from_currents(self) -> bool:
        """The torque came from motor currents: ``drive_gain`` is searched too."""
    @property
    def refit(self) -> bool: ...
    @property
    def hold_friction(self) -> bool: ...
    @property
    def start(self) -> str:
        """Without a model, what the diagnosis starts from: ``"identified"`` or ``"declared"``."""
    @property
    def consistent(self) -> bool: ...
    @property
    def consistent_cutoff_hz(self) -> Optional[float]: ...

@final
class Effect:
    """An effect the diagnosis accepted, with its evidence."""

    @property
    def name(self) -> str: ...
    @property
    def joints(self) -> list[int]: ...
    @property
    def label(self) -> str: ...
    @property
    def columns(self) -> list[str]: ...
    @property
    def coefficients(self) -> _Array: ...
    @property
    def sigma(self) -> _Array: ...
    @property
    def statistic(self) -> float: ...
    @property
    def batches(self) -> int:
        """B, the batches its Wald test summed over (the statistic is F(k, B − k))."""
    @property
    def p_value(self) -> float: ...
    @property
    def threshold(self) -> float: ...
    @property
    def heldout_gain(self) -> float: ...
    @property
    def aliases(self) -> list[str]: ...
    @property
    def mass_kg(self) -> Optional[float]: ...
    @property
    def mass_sigma_kg(self) -> Optional[float]:
        """A payload's mass σ (kg); on torque from currents, it counts the drive gains' σ."""
    @property
    def sigma_from_gains(self) -> Optional[_Array]:
        """Per coefficient, the part of ``sigma`` the calibrated drive gains give, else None."""
    @property
    def body(self) -> Optional[str]: ...
    @property
    def centre_of_mass_m(self) -> Optional[list[Optional[float]]]: ...
    @property
    def round(self) -> int: ...
    @property
    def scale(self) -> Optional[float]:
        """The term's constant: a Stribeck or friction velocity, a travel, a cogging count."""
    @property
    def refined(self) -> Optional[dict[str, Any]]:
        """Where the scale was refined between the grid's points: grid, bracket, residual_drop."""

@final
class Diagnosis:
    """What ``arash.diagnose`` found (docs/diagnosis.md)."""

    @property
    def accepted(self) -> list[Effect]: ...
    @property
    def rejected(self) -> list[dict[str, Any]]: ...
    @property
    def reverted(self) -> list[dict[str, Any]]:
        """What was put back so that no joint predicts held-out data worse than the starting model:
        ``joint``, ``code`` (``hold_friction``, ``drop_effect``, or ``unshifted``: the delay found
        taken off the joint's torque), for a dropped effect ``label``, for the delay ``samples``,
        for either ``helped`` and ``sigmas``; and ``start_rms``, ``rms_before``, ``rms_after``."""
    @property
    def still_worse(self) -> list[dict[str, Any]]:
        """Joints still worse than the starting model beyond the comparison's noise: ``joint``,
        ``start_rms``, ``rms``, ``sigmas``."""
    @property
    def too_heavy(self) -> Optional[dict[str, Any]]:
        """Set when the search stopped because the model is heavier than the data: ``body``,
        ``mass_kg`` (the mass the data lack), ``mass_sigma_kg``, ``mass_sigma_from_gains_kg``,
        ``p_value``, ``heldout_gain``, ``round``."""
    @property
    def settings(self) -> dict[str, Any]:
        """The settings it ran with; ``reasons`` says what chose the cut-offs, ``warnings`` what the
        data support weakly, and ``choices`` and ``concerns`` are the same as data."""
    @property
    def joint_names(self) -> list[str]: ...
    @property
    def error_before(self) -> dict[str, _Array]: ...
    @property
    def error_after(self) -> dict[str, _Array]: ...
    @property
    def noise_floor(self) -> _Array:
        """The held-out error no model of the motion removes, RMS per joint; gains are judged above it."""
    @property
    def sensor_noise(self) -> _Array:
        """The torque's white noise in the band, RMS per joint."""
    @property
    def error_before_training(self) -> dict[str, _Array]: ...
    @property
    def error_after_training(self) -> dict[str, _Array]: ...
    @property
    def model(self) -> Identification: ...
    @property
    def model_consistent(self) -> Optional[Identification]: ...
    @property
    def series(self) -> dict[str, Any]: ...
    def report(self) -> str: ...
    def to_json(self) -> str: ...

def _diagnose(
    robot: Robot,
    log: tuple[_ArrayLike, _ArrayLike, _ArrayLike],
    options: DiagnoseOptions,
    model: Optional[Identification] = None,
    validation: Optional[tuple[_ArrayLike, _ArrayLike, _ArrayLike]] = None,
    validation_starts: list[int] = ...,
    repair_report: Optional[list[dict[str, Any]]] = None,
) -> Diagnosis: ...
