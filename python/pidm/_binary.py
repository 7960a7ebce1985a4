"""Finding the pidm binary and running it."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
from collections.abc import Sequence
from pathlib import Path

from ._errors import PidmError

#: The environment variable that names the binary to run.
BINARY_VARIABLE = "PIDM_BINARY"

HOW_TO_BUILD = (
    "build one from the pidm repository with `cargo build --release`, then set "
    "PIDM_BINARY=target/release/pidm (an absolute path, or one relative to the working "
    "directory) or put that pidm on PATH"
)


def find_binary() -> str:
    """The pidm binary to run: ``$PIDM_BINARY`` when set, else ``pidm`` on ``PATH``.

    Raises PidmError, saying how to build one, when there is none.
    """
    named = os.environ.get(BINARY_VARIABLE)
    if named:
        path = Path(named).expanduser()
        if path.is_file() and os.access(path, os.X_OK):
            return str(path.resolve())
        raise PidmError(f"{BINARY_VARIABLE}={named} is not an executable file; {HOW_TO_BUILD}")
    found = shutil.which("pidm")
    if found:
        return found
    raise PidmError(
        f"no pidm binary: {BINARY_VARIABLE} is not set and PATH has no pidm; {HOW_TO_BUILD}"
    )


def error_text(stderr: str) -> str:
    """pidm's error message from its stderr: the ``pidm: error:`` line and its causes,
    without the prefix; the whole text when there is no such line."""
    lines = stderr.splitlines()
    for k, line in enumerate(lines):
        if line.startswith("pidm: error: "):
            rest = [line[len("pidm: error: ") :]]
            rest += [x.strip() for x in lines[k + 1 :] if x.startswith("  caused by: ")]
            return "\n".join(rest)
    # clap's usage errors start with "error: ".
    for k, line in enumerate(lines):
        if line.startswith("error: "):
            return "\n".join(lines[k:]).strip()
    return stderr.strip() or "(pidm printed nothing)"


def describe_exit(returncode: int) -> str:
    """Words for an exit status that is not pidm's own: a signal that ended it."""
    if returncode < 0:
        try:
            name = signal.Signals(-returncode).name
        except ValueError:
            name = f"signal {-returncode}"
        return f"pidm was killed by {name}"
    if returncode in (130, 143):
        name = "SIGINT" if returncode == 130 else "SIGTERM"
        return f"pidm was stopped by {name} (exit status {returncode})"
    return f"pidm exited with status {returncode}"


def run_quiet(args: Sequence[str]) -> subprocess.CompletedProcess:
    """Runs a short pidm command to its end, capturing stdout and stderr as text."""
    return subprocess.run(
        list(args),
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        errors="replace",
        check=False,
    )
