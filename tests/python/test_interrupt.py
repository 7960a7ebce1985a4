"""Ctrl-C in Python stops the pidm child at once and leaves nothing behind."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from conftest import child_env, interrupt_when_running

# Runs one instance of ten million cycles (minutes of work) and says when the
# run has started. Python ignores SIGINT in a process started with it ignored
# (a background job): the script takes it back.
SCRIPT = """
import signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)
import pidm

out = None if sys.argv[1] == "-" else sys.argv[1]
scene = {"axis": {"x": {"voltage": 100.0}}, "simulation": {"measure": "window", "cycles": 10_000_000}}
try:
    pidm.run(scene, backend="cpu", out=out, progress=lambda record: print("running", flush=True))
except KeyboardInterrupt:
    print("KeyboardInterrupt", flush=True)
    sys.exit(0)
print("finished", flush=True)
sys.exit(1)
"""


def processes_naming(text: str) -> list[str]:
    """Command lines of the running processes that contain ``text``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if text in command and "pytest" not in command:
            found.append(f"{entry.name}: {command}")
    return found


@pytest.mark.parametrize("keep", [True, False], ids=["out", "no-out"])
def test_ctrl_c_raises_keyboard_interrupt_and_leaves_nothing(tmp_path: Path, keep: bool) -> None:
    script = tmp_path / "long.py"
    script.write_text(SCRIPT)
    temp = tmp_path / "tmp"
    temp.mkdir()
    out = tmp_path / "long.h5"
    env = child_env(TMPDIR=str(temp))
    child = subprocess.Popen(
        [sys.executable, str(script), str(out) if keep else "-"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
        text=True,
    )
    # Interrupted 0.3 s after the first progress record: pidm is running its sweep.
    stdout, stderr, waited = interrupt_when_running(child, pause=0.3)
    assert "KeyboardInterrupt" in stdout, stdout + stderr
    assert child.returncode == 0, stdout + stderr
    assert waited < 5.0, f"took {waited:.2f} s"
    assert processes_naming(str(tmp_path)) == []
    assert not out.exists()
    if keep:
        # pidm kept its checkpoint, as the CLI does.
        assert (tmp_path / ".long.h5.checkpoint").exists()
    else:
        assert list(temp.iterdir()) == []
