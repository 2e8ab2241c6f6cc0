"""The README's promises that can drift from the code: the Rust version it asks for is the one
Cargo.toml declares, and its Python example runs as written (on a simulated log in place of
``logs/run.mcap``)."""

import re
from pathlib import Path

import arash

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


def test_the_rust_version_is_cargo_tomls():
    declared = re.search(r'^rust-version = "([0-9.]+)"', (ROOT / "Cargo.toml").read_text(), re.M).group(1)
    asked = re.findall(r"Rust stable ≥ ([0-9.]+)", README)
    assert asked == [declared], f"README asks for Rust {asked}, Cargo.toml's rust-version is {declared}"


def test_the_python_example_runs(tmp_path):
    blocks = re.findall(r"```python\n(.*?)```", README, re.S)
    assert len(blocks) == 1, "README has one Python example"
    log = tmp_path / "run.mcap"
    arash.simulate(str(ROOT / "scenarios" / "nominal.toml"), {"kind": "paper-validation", "omega": 0.5},
                   controller="idc-cad", log=str(log), duration=30.0)
    example = blocks[0].replace('"logs/run.mcap"', repr(str(log)))
    assert example != blocks[0], "the example reads logs/run.mcap"
    scope = {}
    exec(compile(example, "README.md", "exec"), scope)
    assert scope["Y"].shape == (1000, 3, 89)
    assert scope["base"].p == 23
    assert scope["model"].settings["reasons"], "identification reports its choices"
    assert type(scope["found"]).__name__ == "Diagnosis"
