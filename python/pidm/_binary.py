"""Finding the pidm binary and running it."""

from __future__ import annotations

import functools
import os
import shutil
import signal
import subprocess
from collections.abc import Sequence
from pathlib import Path

from ._errors import PidmError, SceneError
from ._version import installed_distribution, package_version

#: The environment variable that names the binary to run.
BINARY_VARIABLE = "PIDM_BINARY"

HOW_TO_BUILD = (
    "install the package with `pip install ./python` from the pidm repository (it "
    "builds and installs the binary), or build one with `cargo build --release` and set "
    "PIDM_BINARY=target/release/pidm (an absolute path, or one relative to the working "
    "directory) or put that pidm on PATH"
)


def find_binary() -> str:
    """The pidm binary to run, checked against the package's version.

    In this order: ``$PIDM_BINARY`` when set (an override for a build of your own);
    else the binary installed with this package (``pip install ./python``); else
    ``pidm`` on ``PATH``. Raises PidmError, saying how to get one, when there is
    none, and naming both versions when the binary's is not the package's.
    """
    named = os.environ.get(BINARY_VARIABLE)
    if named:
        path = Path(named).expanduser()
        if not (path.is_file() and os.access(path, os.X_OK)):
            raise PidmError(f"{BINARY_VARIABLE}={named} is not an executable file; {HOW_TO_BUILD}")
        found = str(path.resolve())
    else:
        found = own_binary() or shutil.which("pidm")
    if not found:
        raise PidmError(
            "no pidm binary: the package was installed without one, "
            f"{BINARY_VARIABLE} is not set and PATH has no pidm; {HOW_TO_BUILD}"
        )
    check_version(found)
    return found


def own_binary() -> str | None:
    """The pidm executable installed with this package (maturin puts it among the
    environment's scripts), if the package was imported from an installation."""
    dist = installed_distribution()
    for file in (dist.files or []) if dist is not None else []:
        if file.name in ("pidm", "pidm.exe") and file.parent.name != "pidm":
            path = Path(str(dist.locate_file(file)))
            if path.is_file() and os.access(path, os.X_OK):
                return str(path.resolve())
    return None


def check_version(binary: str) -> None:
    """Raises PidmError naming both versions when ``binary --version`` is not this
    package's version (a binary of another build answers options and writes files
    this package may not read)."""
    theirs = binary_version(binary)
    ours = package_version()
    if theirs != ours:
        raise PidmError(
            f"the pidm binary {binary} is version {theirs}, the Python package pidm is "
            f"version {ours}; use a binary of the package's version ({HOW_TO_BUILD})"
        )


@functools.lru_cache(maxsize=8)
def binary_version(binary: str) -> str:
    """What ``binary --version`` says after ``pidm `` (asked once per binary path)."""
    done = run_quiet([binary, "--version"])
    words = done.stdout.split()
    if done.returncode != 0 or len(words) != 2 or words[0] != "pidm":
        said = (done.stdout + done.stderr).strip() or f"exit status {done.returncode}"
        raise PidmError(f"{binary} --version did not name a pidm version: {said}")
    return words[1]


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


def classify_failure(
    command: list[str], returncode: int, stderr: str, *, start: str, refusals: tuple[str, ...]
) -> PidmError:
    """The error for a failed pidm search (``fit``, ``sensitivity``, ``optimize``):
    SceneError when pidm refused its input before the search started (exit status
    1, the message starting with one of ``refusals``, and no line yet starting with
    ``start``, the one pidm writes once the input is read and a backend chosen);
    PidmError otherwise."""
    message = error_text(stderr)
    started = any(line.startswith(start) for line in stderr.splitlines())
    if returncode == 1 and not started and message.startswith(refusals):
        return SceneError(message, stderr=stderr, returncode=1, command=command)
    if returncode != 1:
        message = f"{describe_exit(returncode)}: {message}"
    return PidmError(message, stderr=stderr, returncode=returncode, command=command)


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
