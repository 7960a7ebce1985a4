"""Shared helpers of the Python API tests.

They run the pidm binary named by PIDM_BINARY (tests/it/python.rs sets it to the
binary cargo built) and import the package from python/ of this checkout (also
in the Python processes they start). A missing optional package (tqdm, matplotlib) skips its test
on a developer's machine and fails it under CI=true.
"""

from __future__ import annotations

import importlib
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# The package of this checkout, before any installed copy.
sys.path.insert(0, str(ROOT / "python"))

#: A small 2 x 3 grid of voltages with baselines and one trajectory (milliseconds).
GRID = {
    "name": "grid",
    "axis": {
        "x": {"voltage": [50.0, 100.0]},
        "y": {"voltage": {"from": 0.0, "to": 80.0, "steps": 3}, "frequency": 20.0},
    },
    "simulation": {"measure": "window", "cycles": 3, "settle": 1},
    "output": {"baselines": True, "trajectories": [0]},
}

#: The same scene as a hand-written TOML file, as a CLI user writes it.
GRID_TOML = """\
name = "grid"
[axis.x]
voltage = [50.0, 100.0]
[axis.y]
voltage = { from = 0.0, to = 80.0, steps = 3 }
frequency = 20.0
[simulation]
measure = "window"
cycles = 3
settle = 1
[output]
baselines = true
trajectories = [0]
"""


def require(module: str):
    """Imports an optional module: skips without it, except under CI, where it fails."""
    try:
        return importlib.import_module(module)
    except ImportError:
        if os.environ.get("CI"):
            pytest.fail(f"{module} is not installed; CI must install tests/requirements.txt")
        pytest.skip(f"{module} is not installed (pip install -r tests/requirements.txt)")


def child_env(**extra: str) -> dict[str, str]:
    """The environment of a Python child process: this one's, with python/ of this
    checkout first on PYTHONPATH (as an absolute path: the child may run elsewhere)."""
    paths = [str(ROOT / "python")]
    if os.environ.get("PYTHONPATH"):
        paths.append(os.environ["PYTHONPATH"])
    return dict(os.environ, PYTHONPATH=os.pathsep.join(paths), **extra)


def interrupt_when_running(child: subprocess.Popen, pause: float = 0.0) -> tuple[str, str, float]:
    """Sends Ctrl-C (SIGINT) to `child` `pause` seconds after it prints "running",
    and returns its stdout, its stderr and the seconds it took to end after the
    signal. A child still there afterwards is killed."""
    try:
        ready, _, _ = select.select([child.stdout], [], [], 60.0)
        assert ready, "no progress within 60 s"
        assert child.stdout.readline().strip() == "running"
        time.sleep(pause)
        asked = time.monotonic()
        child.send_signal(signal.SIGINT)
        stdout, stderr = child.communicate(timeout=30)
        return stdout, stderr, time.monotonic() - asked
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()


@pytest.fixture(scope="session")
def binary() -> str:
    path = os.environ.get("PIDM_BINARY")
    if not path:
        pytest.fail(
            "PIDM_BINARY is not set: run these tests through `cargo test --test it python::`"
        )
    return path


@pytest.fixture
def cli_file(binary: str, tmp_path: Path) -> Path:
    """The grid scene run by the CLI on the CPU into a file."""
    scene = tmp_path / "grid.toml"
    scene.write_text(GRID_TOML)
    out = tmp_path / "cli.h5"
    subprocess.run(
        [binary, "run", str(scene), "--out", str(out), "--backend", "cpu"],
        check=True,
        capture_output=True,
    )
    return out
