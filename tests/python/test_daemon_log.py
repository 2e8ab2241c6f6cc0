"""The daemon's flight log as an analyst reads it: `arash.read_log` against the official MCAP
reader on a short run of `arash daemon` against `arash mock-motor`."""

import json
import os
import signal
import subprocess
import time

import numpy as np
import pytest

import arash
from support.paths import ARASH, loaded_host_config, mock_motor_args

mcap_reader = pytest.importorskip("mcap.reader")


@pytest.fixture(scope="module")
def daemon_logs(tmp_path_factory):
    if not ARASH.exists():
        pytest.skip(f"{ARASH} is not built")
    d = tmp_path_factory.mktemp("daemon")
    mock = subprocess.Popen(mock_motor_args(), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        pty = mock.stdout.readline().strip()
        daemon = subprocess.Popen([ARASH, "daemon", "--config", loaded_host_config(d), "--rt", "ignore", "--port", pty,
                                   "--socket", d / "s.sock", "--log-dir", d / "logs"], stderr=subprocess.DEVNULL)
        for _ in range(200):
            if (d / "s.sock").exists():
                break
            time.sleep(0.05)
        subprocess.run([ARASH, "ctl", "--socket", d / "s.sock", "enable"], check=True, capture_output=True)
        time.sleep(3.2)
        daemon.send_signal(signal.SIGTERM)
        assert daemon.wait(timeout=10) == 0
    finally:
        mock.kill()
        mock.wait()
    return sorted((d / "logs").glob("daemon-*.mcap"))


def official_json(path):
    out = {}
    with open(path, "rb") as f:
        for _, channel, message in mcap_reader.make_reader(f).iter_messages():
            if channel.message_encoding == "json":
                out.setdefault(channel.topic, []).append(message.data.decode())
    return out


def test_the_json_channels_read_like_the_official_reader(daemon_logs):
    assert len(daemon_logs) == 1
    log = arash.read_log(daemon_logs[0])
    assert not log["truncated"]
    ours = {topic: [text for _, text in messages] for topic, messages in log["json"].items()}
    assert ours == official_json(daemon_logs[0])
    events = [json.loads(e)["event"] for e in ours["/arash/event"]]
    assert "motors enabled" in events and "motors disabled" in events


def test_timing_histograms_count_every_cycle_of_their_second(daemon_logs):
    log = arash.read_log(daemon_logs[0])
    seconds = [json.loads(t) for _, t in log["json"]["/arash/timing"] if "period_error_us" in t]
    assert len(seconds) >= 3
    for s in seconds[1:]:  # the first second lacks cycle 0's period
        assert sum(s["period_error_us"]) == sum(s["exec_us"]) == 1000
        assert len(s["period_error_us"]) == len(s["bin_upper_edges_us"]) + 1
    # The cycles on /arash/cycle are consecutive: one message per cycle.
    assert np.all(np.diff(log["cycle"]) == 1)
    assert log["metadata"]["source"] == "arash-daemon"


def test_a_log_cut_by_kill_9_is_recovered_into_a_file_the_official_seeking_reader_opens(tmp_path):
    if not ARASH.exists():
        pytest.skip(f"{ARASH} is not built")
    mock = subprocess.Popen(mock_motor_args(), stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    sock = tmp_path / "s.sock"
    start = [ARASH, "daemon", "--config", loaded_host_config(tmp_path), "--rt", "ignore", "--port", None,
             "--socket", sock, "--log-dir", tmp_path / "logs"]

    def daemon(pty):
        args = [pty if a is None else a for a in start]
        d = subprocess.Popen(args, stderr=subprocess.DEVNULL)
        for _ in range(200):
            if sock.exists():
                return d
            time.sleep(0.05)
        raise AssertionError("no control socket")

    try:
        pty = mock.stdout.readline().strip()
        first = daemon(pty)
        time.sleep(2.5)
        first.send_signal(signal.SIGKILL)
        first.wait()
        os.remove(sock)
        second = daemon(pty)  # recovers the cut file at start-up
        second.send_signal(signal.SIGTERM)
        assert second.wait(timeout=10) == 0
    finally:
        mock.kill()
        mock.wait()
    recovered = sorted((tmp_path / "logs").glob("*.recovered.mcap"))
    assert len(recovered) == 1
    ours = arash.read_log(recovered[0])
    assert not ours["truncated"]
    with open(recovered[0], "rb") as f:
        reader = mcap_reader.make_reader(f)
        assert isinstance(reader, mcap_reader.SeekingReader)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        cycles = sum(1 for _, channel, _ in reader.iter_messages(topics=["/arash/cycle"]))
    assert cycles == len(ours["cycle"])
    # At most about one second lost of the 2.5 s the first daemon ran.
    assert cycles >= 1400, cycles


def test_the_uniform_grid_keeps_every_logged_measurement(daemon_logs):
    """`log["uniform"]` is what identify and diagnose take from a daemon log: a strictly uniform
    time grid, at least one sample per logged cycle, and wherever the grid meets a logged time the
    logged measurement itself (not a blend), so that encoder counts stay whole."""
    log = arash.read_log(daemon_logs[0])
    u = log["uniform"]
    t = log["t"]
    steps = np.diff(u["t"])
    assert np.all(steps > 0) and np.ptp(steps) < 1e-9 * steps.mean(), steps
    assert len(u["t"]) >= len(t) and u["q"].shape == (len(u["t"]), log["q"].shape[1])
    repeats = int(np.sum(np.diff(t) <= 0))
    assert u["repaired"] >= repeats
    h = np.median(steps)
    index = np.rint((t - u["t"][0]) / h).astype(int)
    on_grid = np.abs(t - (u["t"][0] + index * h)) < 1e-9 * h
    first = np.concatenate([[True], np.diff(t) > 0])  # a repeated time keeps its first sample
    kept = on_grid & first & (index < len(u["t"]))
    assert kept.sum() > 0.9 * len(t), (kept.sum(), len(t))
    np.testing.assert_array_equal(u["q"][index[kept]], log["q"][kept])
    np.testing.assert_array_equal(u["tau_meas"][index[kept]], log["tau_meas"][kept])
    if repeats == 0 and np.ptp(np.diff(t)) < 1e-6:
        np.testing.assert_array_equal(u["t"], t)


def test_every_cycle_carries_the_hand_force_observer(daemon_logs):
    """The observer runs on every cycle in every mode (disabled, then enabled here): its joint
    estimate and the instrument tip's force are in each cycle, as the official reader and the
    protobuf schema the file carries decode them."""
    mcap_protobuf = pytest.importorskip("mcap_protobuf.decoder")
    log = arash.read_log(daemon_logs[0])
    n = len(log["t"])
    assert log["tau_ext"].shape == (n, 3) and log["frame_force"].shape == (n, 3)
    assert np.all(np.isfinite(log["tau_ext"])) and np.abs(log["tau_ext"]).max() > 0
    with open(daemon_logs[0], "rb") as f:
        reader = mcap_reader.make_reader(f, decoder_factories=[mcap_protobuf.DecoderFactory()])
        cycles = [m for _, c, _, m in reader.iter_decoded_messages(topics=["/arash/cycle"])]
    np.testing.assert_array_equal(log["tau_ext"], [list(m.tau_ext) for m in cycles])
    np.testing.assert_array_equal(log["frame_force"], [list(m.frame_force) for m in cycles])
