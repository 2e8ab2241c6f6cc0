"""`pip install` on a plain machine (issue 20): the wheel maturin builds is self-contained (its
extension needs nothing outside the manylinux allow-list: no BLAS, no LAPACK), installs into a
fresh venv that holds only numpy, and identifies a small log there, physically consistent fit
included; the sdist carries everything it needs and builds and installs from its own contents;
and README's `pip install ./crates/arash-py` works as written.

These build the package (a release build in the workspace's target directory, reusing the
compiled dependencies of scripts/setup's build) and install numpy into fresh venvs from the
package registry or pip's cache.
"""

import os
import subprocess
import sys
import tarfile
import textwrap
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CRATE = ROOT / "crates" / "arash-py"
MATURIN = Path(sys.executable).with_name("maturin")

# PEP 599/600's manylinux allow-list (the libraries a manylinux wheel may assume), and the
# loader and vDSO that `ldd` also prints.
ALLOWED = {
    "libgcc_s.so.1", "libstdc++.so.6", "libm.so.6", "libdl.so.2", "librt.so.1", "libc.so.6", "libnsl.so.1",
    "libutil.so.1", "libpthread.so.0", "libresolv.so.2", "libX11.so.6", "libXext.so.6", "libXrender.so.1",
    "libICE.so.6", "libSM.so.6", "libGL.so.1", "libgobject-2.0.so.0", "libgthread-2.0.so.0", "libglib-2.0.so.0",
}

# A two-period Fourier log of the CAD model, made in the fresh venv with arash's own regressor
# (the point is that the installed package runs, not what it computes, which other tests check).
SMOKE = textwrap.dedent("""
    import numpy as np, arash
    robot = arash.Robot.arash_asist()
    t = np.arange(0, 20.0, 1e-3)
    w = 2 * np.pi / 10.0
    limits = np.array(robot.position_limits())
    centre, span = limits.mean(axis=1), np.diff(limits, axis=1)[:, 0]
    q = np.zeros((len(t), 3)); qd = np.zeros_like(q); qdd = np.zeros_like(q)
    for l in (1, 2, 3):
        for j in range(3):
            a = 0.12 * span[j] / l * np.array([1.0, 0.7, 0.5])[j]
            phase = 0.9 * l + 1.3 * j
            q[:, j] += a * np.sin(l * w * t + phase)
            qd[:, j] += a * l * w * np.cos(l * w * t + phase)
            qdd[:, j] -= a * (l * w) ** 2 * np.sin(l * w * t + phase)
    q += centre
    tau = np.einsum("nkp,p->nk", robot.regressor(q, qd, qdd), robot.cad_parameters())
    ols = arash.identify(robot, t, q, tau, periods=2)
    consistent = arash.identify(robot, t, q, tau, periods=2, method="consistent")
    assert min(ols.fp_percent) > 99 and min(consistent.fp_percent) > 99, (ols.fp_percent, consistent.fp_percent)
    print("installed arash", arash.__file__, "fits", list(np.round(consistent.fp_percent, 2)))
""")


def run(*args, **kwargs):
    result = subprocess.run([str(a) for a in args], capture_output=True, text=True, **kwargs)
    assert result.returncode == 0, f"{' '.join(map(str, args))} failed:\n{result.stdout}\n{result.stderr}"
    return result.stdout + result.stderr


def clean_env():
    """The environment without the test venv's and any library-path settings."""
    env = {k: v for k, v in os.environ.items() if k not in ("LD_LIBRARY_PATH", "PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = os.pathsep.join(p for p in env.get("PATH", "").split(os.pathsep) if ".venv" not in p)
    return env


def fresh_venv(path):
    run(sys.executable, "-m", "venv", path)
    python = path / "bin" / "python"
    import numpy

    run(python, "-m", "pip", "install", "--quiet", f"numpy=={numpy.__version__}", env=clean_env())
    return python


def needed_libraries(extension):
    """The shared libraries `ldd` resolves for `extension`, by name."""
    out = run("ldd", extension, env=clean_env())
    return {line.split()[0] for line in out.splitlines() if line.strip()}


def smoke_test(python, tmp_path):
    out = run(python, "-c", SMOKE, cwd=tmp_path, env=clean_env())  # outside the repository
    assert "installed arash" in out and str(ROOT) not in out.split("installed arash")[1].split()[0]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheels")
    log = run(MATURIN, "build", "--release", "--locked", "--auditwheel", "check", "-m", CRATE / "Cargo.toml",
              "--out", out, cwd=ROOT)
    wheels = list(out.glob("*.whl"))
    assert len(wheels) == 1, log
    return wheels[0]


def test_the_wheel_is_abi3_manylinux_and_self_contained(wheel, tmp_path):
    assert "abi3" in wheel.name and "manylinux_" in wheel.name, wheel.name
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        extensions = [n for n in names if n.startswith("arash/_arash") and n.endswith(".so")]
        assert len(extensions) == 1, names
        assert "arash/py.typed" in names and "arash/_arash.pyi" in names
        assert not any(".libs/" in n for n in names), "maturin bundled a library it should not need"
        archive.extract(extensions[0], tmp_path)
        metadata = archive.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
    needed = needed_libraries(tmp_path / extensions[0])
    loader = {n for n in needed if n.startswith(("linux-vdso", "ld-linux", "/lib"))}
    assert needed - loader <= ALLOWED, f"outside the manylinux allow-list: {needed - loader - ALLOWED}"
    assert not any("blas" in n or "lapack" in n for n in needed)
    for field in ("Name: arash", "Requires-Python: >=3.9", "Requires-Dist: numpy", "License-Expression: MIT OR Apache-2.0",
                  "Description-Content-Type: text/markdown", "Classifier: Typing :: Typed", "Provides-Extra: sim"):
        assert field in metadata, f"{field!r} missing from the wheel's METADATA:\n{metadata[:2000]}"
    extra = [line for line in metadata.splitlines() if line.startswith("Requires-Dist:") and "extra ==" in line]
    assert {line.split()[1].split(">")[0] for line in extra} == {"python-can", "canopen"}, extra


def test_the_wheel_installs_and_fits_in_a_fresh_venv_with_only_numpy(wheel, tmp_path):
    python = fresh_venv(tmp_path / "venv")
    run(python, "-m", "pip", "install", "--quiet", "--no-deps", wheel, env=clean_env())
    installed = run(python, "-m", "pip", "list", "--format=freeze", env=clean_env())
    assert {line.split("==")[0].lower() for line in installed.split()} <= {"numpy", "arash", "pip", "setuptools"}
    smoke_test(python, tmp_path)
    # The drive simulator is the `sim` extra's: without it, its import says how to get it.
    missing = subprocess.run([python, "-c", "import arash.cia402_sim"], capture_output=True, text=True,
                             env=clean_env(), cwd=tmp_path)
    assert missing.returncode != 0 and "pip install 'arash[sim]'" in missing.stderr, missing.stderr


def test_the_sdist_builds_and_installs_from_its_own_contents(tmp_path):
    run(MATURIN, "sdist", "-m", CRATE / "Cargo.toml", "--out", tmp_path / "dist", cwd=ROOT)
    (sdist,) = (tmp_path / "dist").glob("arash-*.tar.gz")
    with tarfile.open(sdist) as archive:
        names = archive.getnames()
    assert any(n.endswith("crates/arash-core/robots/arash_asist.urdf") for n in names), names
    assert any(n.endswith("Cargo.lock") for n in names) and any(n.endswith("pyproject.toml") for n in names)
    python = fresh_venv(tmp_path / "venv")
    # Built in pip's isolated environment from the sdist alone; the workspace's target directory,
    # where scripts/setup's build of the package is, only lends compiled registry crates (the
    # sdist's own crates are rebuilt from its sources: another path, another build).
    env = {**clean_env(), "CARGO_TARGET_DIR": str(ROOT / "target")}
    run(python, "-m", "pip", "install", "--quiet", sdist, env=env, cwd=tmp_path)
    smoke_test(python, tmp_path)


def test_pip_install_of_the_crate_directory_works_as_the_readme_says(tmp_path):
    """README's install line for analysts, `pip install ./crates/arash-py`, run as written from
    the repository root into a fresh venv."""
    python = fresh_venv(tmp_path / "venv")
    env = {**clean_env(), "CARGO_TARGET_DIR": str(ROOT / "target")}
    run(python, "-m", "pip", "install", "--quiet", "./crates/arash-py", env=env, cwd=ROOT)
    smoke_test(python, tmp_path)
