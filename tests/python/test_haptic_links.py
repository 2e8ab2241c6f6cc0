"""The daemon's haptic mode (docs/haptics.md) through both motor links: the same simulated rig,
the demo's (a wiring disturbance and Stribeck friction the model lacks), with a trainee's grasp
(`[hand.grasp]`), behind `arash mock-motor` (arash's serial protocol) and behind simulated
CiA 402 drives (`arash.cia402_sim`, CANopen). The daemon runs in lockstep with the rig, so the
host's timing is out of the comparison.

What the hand felt is the simulated rig's truth, which each simulator writes beside the run
(`--truth`, the same columns on both), never the daemon's log: the hand's force along a slow
path in free space (transparency), and a press into the stiffest depth wall the mode accepts
(the wall's energy, at the true state, from `arash.render_fixtures`). Two serial runs measure
the run-to-run spread; the CANopen run must agree within it."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("can", reason="python-can is needed for the drive simulator (requirements-dev.txt)")
pytest.importorskip("canopen", reason="canopen is needed for the drive simulator (requirements-dev.txt)")

import arash  # noqa: E402
from arash.cia402_sim import rig_simulator  # noqa: E402
from support.paths import ARASH  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
# The instrument at rest in the eye, as in the demo's chapter (crates/arash-cli/src/cli/demo/haptic.rs).
START = [0.1, 0.3, 0.015]
# The hand takes hold this long after the motors are enabled (the rig's own clock), once the
# daemon has brought the instrument to START; the mode is entered just after, and the hand's
# force is judged from WINDOW_S on (the path's amplitude ramps in over its first period).
HOLD_AT_S = 6.0
ENTER_AFTER_S = 0.2
WINDOW_S = (HOLD_AT_S + 3.0, HOLD_AT_S + 15.0)

TRANSPARENCY = f"""
[hand]
frame = "insertion_carriage"

[hand.grasp]
at_s = {HOLD_AT_S}
amplitude_m = [0.0, 0.004, 0.003]
period_s = [5.0, 7.0, 6.0]
"""

PRESS = f"""
[hand]
frame = "instrument_tip"

[hand.grasp]
at_s = {HOLD_AT_S}

[[hand.grasp.press]]
at_s = {HOLD_AT_S + 1.0}
duration_s = 4.0
depth_m = 0.006
"""
PRESS_END_S = HOLD_AT_S + 6.0
DEEPEST_S = HOLD_AT_S + 3.0


def scenario(d: Path, hand: str) -> Path:
    path = d / "scenario.toml"
    path.write_text((REPO / "scenarios" / "demo.toml").read_text() + hand)
    return path


def truth_time(path: Path) -> float:
    """The rig's time at the last complete row of a truth file being written."""
    try:
        with open(path, "rb") as f:
            f.seek(0, 2)
            f.seek(max(0, f.tell() - 4096))
            lines = f.read().split(b"\n")
    except FileNotFoundError:
        return -1.0
    for line in reversed(lines[:-1]):
        try:
            return float(line.split(b",")[0])
        except ValueError:
            continue
    return -1.0


def read_truth(path: Path) -> dict[str, np.ndarray]:
    table = np.genfromtxt(path, delimiter=",", names=True)
    n = 3
    return {"t": table["t"],
            "q": np.column_stack([table[f"q{k}"] for k in range(1, n + 1)]),
            "qd": np.column_stack([table[f"qd{k}"] for k in range(1, n + 1)]),
            "hand": np.column_stack([table["hand_x"], table["hand_y"], table["hand_z"]])}


def haptic_run(d: Path, link: str, port: str, truth: Path, until_s: float, fixtures: Path | None = None):
    """The daemon on ``port``: enable, bring the instrument to START, enter the haptic mode
    (with ``fixtures``) just after the hand takes hold, and leave it for hold once the rig's
    clock reaches ``until_s``. Returns the daemon's status in the mode and after it."""
    sock = d / "s.sock"
    # As in test_canopen_link.py: the heartbeats are timed by the host's clock, not the lockstep.
    (d / "daemon.toml").write_text("[canopen]\nheartbeat_timeout_ms = 1000\nmaster_heartbeat_timeout_ms = 1000\n")
    hold = d / "start.json"
    hold.write_text(json.dumps({"format": "arash-trajectory/1", "kind": "hold", "q": START}))
    with open(d / "daemon.err", "w") as err:
        daemon = subprocess.Popen([ARASH, "daemon", "--rt", "ignore", "--pace", "lockstep", "--link", link,
                                   "--controller", "robust", "--port", port, "--socket", sock,
                                   "--log-dir", d / "logs", "--config", d / "daemon.toml"], stderr=err)
    ctl = [ARASH, "ctl", "--socket", sock]

    def call(*args):
        out = subprocess.run([*ctl, *map(str, args)], capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, f"ctl {args}: {out.stderr}" + (d / "daemon.err").read_text()
        return out.stdout

    def until(condition, seconds):
        deadline = time.monotonic() + seconds
        while not condition():
            assert daemon.poll() is None and time.monotonic() < deadline, (d / "daemon.err").read_text()
            time.sleep(0.02)

    try:
        until(sock.exists, 20)
        until(lambda: json.loads(subprocess.run([*ctl, "status"], capture_output=True, text=True).stdout)["telemetry"],
              60)
        call("enable")
        call("run", hold, "--duration", 1.0, "--wait")
        assert truth_time(truth) < HOLD_AT_S, "the approach to the start took longer than the hand waits"
        until(lambda: truth_time(truth) >= HOLD_AT_S + ENTER_AFTER_S, 60)
        call("haptic", *(["--fixtures", fixtures] if fixtures else []))
        during = json.loads(call("status"))
        until(lambda: truth_time(truth) >= until_s, 120)
        call("hold")
        after = json.loads(call("status"))
    finally:
        daemon.send_signal(signal.SIGTERM)
        daemon.wait(timeout=10)
    return during, after


def through(link: str, d: Path, hand: str, until_s: float, fixtures: Path | None = None):
    """One run on a fresh simulated rig (seed 1) behind ``link``: the truth and the statuses."""
    d.mkdir()
    rig = scenario(d, hand)
    truth = d / "truth.csv"
    if link == "serial":
        mock = subprocess.Popen([ARASH, "mock-motor", "--scenario", rig, "--seed", "1", "--truth", truth],
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            statuses = haptic_run(d, "serial", mock.stdout.readline().strip(), truth, until_s, fixtures)
        finally:
            mock.terminate()
            mock.wait()
    else:
        with open(truth, "w", encoding="utf-8") as out:
            sim = rig_simulator(str(rig), seed=1, truth=out)
            try:
                statuses = haptic_run(d, "canopen", sim.path, truth, until_s, fixtures)
            finally:
                sim.close()
    for status in statuses:
        assert not status["faults"], status
    assert statuses[0]["phase"] == "haptic" and statuses[1]["phase"] != "haptic", statuses
    return read_truth(truth)


def window_rms(truth):
    kept = (truth["t"] >= WINDOW_S[0]) & (truth["t"] <= WINDOW_S[1])
    assert kept.sum() > 0.9 * 1000 * (WINDOW_S[1] - WINDOW_S[0]), "the truth misses cycles of the window"
    return np.sqrt(np.mean(truth["hand"][kept] ** 2, axis=0))


def agree(canopen, serial, name):
    """The CANopen figure within twice the serial runs' spread, plus 10 % for the ‰ steps of the
    drives' torque target and where in the rig's noise each run starts."""
    serial = np.asarray(serial)
    reference, spread = serial.mean(axis=0), np.abs(serial[1] - serial[0])
    print(f"{name}: serial {serial.tolist()}, canopen {np.asarray(canopen).tolist()}")
    assert np.all(np.abs(canopen - reference) <= 2 * spread + 0.10 * np.abs(reference) + 1e-3), (name, canopen, serial)


def test_the_hand_feels_the_same_device_through_cia402_drives_as_through_the_serial_link(tmp_path):
    """Transparency: the trainee's hand at the carriage on the demo chapter's path (4 mm across
    at 7 s, 3 mm along at 6 s), the mode on the CAD model."""
    until_s = WINDOW_S[1] + 0.2
    serial = [window_rms(through("serial", tmp_path / f"serial-{i}", TRANSPARENCY, until_s)) for i in range(2)]
    canopen = window_rms(through("canopen", tmp_path / "canopen", TRANSPARENCY, until_s))
    # The hand moved the device: the path's own force at 135 N/m would be about half a newton
    # were the device held still; free in the mode, it is a fraction of that.
    assert np.linalg.norm(canopen) < 0.5, canopen
    agree(canopen, serial, "the hand's RMS force per base axis (N)")


def test_a_press_into_the_stiffest_wall_the_mode_accepts_renders_alike_through_both_links(tmp_path):
    """Rendering: a depth wall 2 mm deeper than the tip starts, at 0.999 of the passivity bound
    the daemon's own check gives on the CAD model, pressed by the hand's set-point 6 mm deeper
    and back over 4 s. At the true state the wall's energy never grows after the deepest
    set-point, through either link, and the depth and force reached agree."""
    robot = arash.Robot.arash_asist()
    depth = tip_depth(robot)
    wall = lambda k: f"[[wall]]\ndepth_m = {depth + 0.002}\nstiffness = {k}\ndamping = 0.0\n"  # noqa: E731
    bound = arash.fixture_bounds(robot, wall(1.0))["fixtures"]["wall[0]"]["stiffness_bound"]
    fixtures = tmp_path / "wall.toml"
    fixtures.write_text(wall(0.999 * bound))
    figures = {}
    for name in ["serial-0", "serial-1", "canopen"]:
        truth = through(name.split("-")[0], tmp_path / name, PRESS, PRESS_END_S, fixtures)
        rendered = arash.render_fixtures(robot, fixtures.read_text(), truth["q"], truth["qd"])
        energy, t = np.asarray(rendered["energy"]), truth["t"]
        at_deepest = energy[t <= DEEPEST_S].max()
        after = energy[t > DEEPEST_S].max()
        assert at_deepest > 0, f"{name}: the press never reached the wall"
        assert after <= 1.01 * at_deepest, f"{name}: the wall's energy grew after the press: {after} J > {at_deepest} J"
        force = np.linalg.norm(np.asarray(rendered["force"]), axis=1)
        figures[name] = np.array([np.sqrt(2 * at_deepest / (0.999 * bound)), force.max()])
    print(f"wall at {0.999 * bound:.0f} N/m: depth (m) and force (N) at the deepest", figures)
    agree(figures["canopen"], [figures["serial-0"], figures["serial-1"]], "the wall's depth (m) and peak force (N)")


def tip_depth(robot) -> float:
    """How deep the tip is at START: the depth at which a wall there starts to push."""
    lo, hi = -0.2, 0.2
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        text = f"[[wall]]\ndepth_m = {mid}\nstiffness = 1.0\ndamping = 0.0\n"
        pushing = arash.render_fixtures(robot, text, np.array([START]), np.zeros((1, 3)))["energy"][0] > 0
        lo, hi = (mid, hi) if pushing else (lo, mid)
    return 0.5 * (lo + hi)
