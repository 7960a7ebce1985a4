"""examples/python_map.py runs and draws its picture."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from conftest import ROOT, child_env, require


def test_the_python_map_example_draws_a_png(tmp_path: Path) -> None:
    require("matplotlib")
    png = tmp_path / "map.png"
    example = ROOT / "examples" / "python_map.py"
    command = [sys.executable, str(example), "--steps", "5", "--max-cycles", "100"]
    command += ["--backend", "cpu", "--out", str(png)]
    done = subprocess.run(
        command, capture_output=True, text=True, cwd=tmp_path, env=child_env(), check=False
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "25 instances" in done.stdout
    assert png.stat().st_size > 1000
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
