"""The type stubs are right: `mypy.stubtest` checks them against the compiled module, and a small
typed analysis passes `mypy --strict` against them. A stub that names a wrong type (numpy.typing
has no `Array`) or misses a parameter fails here."""

import pathlib
import subprocess
import sys

import pytest

pytest.importorskip("mypy", reason="mypy is not installed (requirements-dev.txt installs it)")

HERE = pathlib.Path(__file__).parent


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, cwd=HERE)


def test_the_stubs_match_the_compiled_module():
    result = run("mypy.stubtest", "arash")
    assert result.returncode == 0, result.stdout + result.stderr


def test_a_typed_analysis_passes_mypy_strict():
    result = run("mypy", "--strict", "--no-incremental", str(HERE / "typed" / "example.py"))
    assert result.returncode == 0, result.stdout + result.stderr


def test_a_wrong_call_fails_mypy_strict(tmp_path):
    """The check can fail: a misspelt option and a wrong type are errors."""
    bad = tmp_path / "bad.py"
    bad.write_text(
        "import arash\n"
        "robot = arash.Robot.arash_asist()\n"
        "arash.diagnose(robot, [0.0], [[0.0]], [[0.0]], cutoff='20')\n"
        "arash.identify(robot, [0.0], [[0.0]], [[0.0]], perods=4)\n"
    )
    result = run("mypy", "--strict", "--no-incremental", str(bad))
    assert result.returncode != 0
    assert "perods" in result.stdout and "cutoff" in result.stdout, result.stdout
