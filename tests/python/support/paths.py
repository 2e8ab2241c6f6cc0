"""Where the robots, the fixtures, the measured data and the built binary are, and random
states and physical parameters for a robot."""

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[3]
FIXTURES = ROOT / "tests" / "fixtures"
SHARED_DATA = ROOT.parent / "shared" / "data"
# The `arash` binary that `cargo build --release` makes (scripts/test builds it first).
ARASH = ROOT / "target" / "release" / "arash"

# For the rig's tests of what the log and the stream hold, not of the link's faults: a host kept
# busy stalls a pseudo-terminal's kernel worker (ordinary priority, whatever the daemon's and the
# mock's) past the 20 ms link timeout and the mock's 100 ms watchdog now and then, and the fault
# would end the run. The link timeout is tested by crates/arash-daemon/tests/safety.rs and
# crates/arash-cli/tests/daemon_e2e.rs.
HOST_STALL_MS = 250


def loaded_host_config(d):
    """A daemon configuration (`--config`) whose link times out after HOST_STALL_MS."""
    path = d / "loaded-host.toml"
    path.write_text(f"[link]\ntimeout_ms = {HOST_STALL_MS}.0\n")
    return path


def mock_motor_args():
    """`arash mock-motor` with its watchdog at HOST_STALL_MS."""
    return [ARASH, "mock-motor", "--watchdog-ms", str(HOST_STALL_MS)]


ROBOT_FILES = {
    "arash_asist": ROOT / "robots" / "arash_asist.urdf",
    "planar_2link": FIXTURES / "planar_2link.urdf",
    "serial_3dof": FIXTURES / "serial_3dof.urdf",
}


def kuka_urdf():
    path = SHARED_DATA / "kuka_lwr4" / "kuka_lwr4.urdf"
    if not path.exists():
        pytest.skip(f"measured-data URDF not found at {path}; ../shared/data is absent")
    return path


def kuka_run(i):
    """KUKA LWR4+ run ``i`` (1–3) of ../shared/data: t on the controller's 200 Hz grid, q, τ."""
    path = SHARED_DATA / "kuka_lwr4" / f"measurements_{i}.npz"
    if not path.exists():
        pytest.skip(f"measured data not found at {path}; ../shared/data is absent")
    z = np.load(path)
    # The time stamps are the logging computer's and jitter by ±1.5 ms around 5 ms; the samples
    # are the controller's, at its fixed 200 Hz.
    n = len(z["times"])
    return np.arange(n) * 0.005, z["positions"], z["torques"]


def tx40_urdf():
    """Upstream's Stäubli TX40 description: its link_6 has a mass and no rotational inertia."""
    path = SHARED_DATA / "staubli_tx40" / "tx40_mdh_modified.urdf"
    if not path.exists():
        pytest.skip(f"measured-data URDF not found at {path}; ../shared/data is absent")
    return path


def urdf_couplings(path):
    """Independent reading of the URDF's joints: name -> (type, mimic target, multiplier, offset)."""
    joints = {}
    for j in ET.parse(path).getroot().findall("joint"):
        mimic = j.find("mimic")
        target = None if mimic is None else mimic.get("joint")
        mult = 1.0 if mimic is None else float(mimic.get("multiplier", "1"))
        off = 0.0 if mimic is None else float(mimic.get("offset", "0"))
        joints[j.get("name")] = (j.get("type"), target, mult, off)
    return joints


def random_states(robot, n, rng):
    """Uniform positions within the limits, speeds within the speed limits, and accelerations."""
    lo, hi, vmax = [], [], []
    for (a, b), v in zip(robot.position_limits(), robot.velocity_limits()):
        lo.append(a if math.isfinite(a) else -math.pi)
        hi.append(b if math.isfinite(b) else math.pi)
        vmax.append(v if math.isfinite(v) else 2.0)
    lo, hi, vmax = map(np.array, (lo, hi, vmax))
    q = rng.uniform(lo, hi, size=(n, robot.dof))
    qd = rng.uniform(-vmax, vmax, size=(n, robot.dof))
    qdd = rng.uniform(-10 * vmax, 10 * vmax, size=(n, robot.dof))
    return q, qd, qdd


def random_physical_params(robot, rng):
    """Each body a solid box with random mass, size, centre and orientation (valid by construction)."""
    from scipy.spatial.transform import Rotation

    blocks = []
    for _ in robot.body_names():
        m = rng.uniform(0.05, 2.0)
        c = rng.uniform(-0.2, 0.2, 3)
        a, b, d = rng.uniform(0.01, 0.3, 3)
        principal = np.diag([b * b + d * d, a * a + d * d, a * a + b * b]) * m / 12
        r = Rotation.from_euler("xyz", rng.uniform(-3, 3, 3)).as_matrix()
        i_c = r @ principal @ r.T
        i_o = i_c + m * (c @ c * np.eye(3) - np.outer(c, c))
        blocks.append([m, *(m * c), i_o[0, 0], i_o[1, 1], i_o[2, 2], i_o[0, 1], i_o[0, 2], i_o[1, 2]])
    joint_terms = rng.uniform(0.0, 1.0, 3 * robot.dof)
    return np.concatenate([np.ravel(blocks), joint_terms])
