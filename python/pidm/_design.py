"""What pidm.sensitivity (_sensitivity.py) and pidm.optimize (_optimize.py) share:
the error for a failed ``pidm sensitivity`` or ``pidm optimize``, SceneError when
pidm refused the scene before the study started."""

from __future__ import annotations

from ._binary import describe_exit, error_text
from ._errors import PidmError, SceneError

#: How pidm's error text starts when it refuses the scene before the study
#: starts: ``scene PATH`` (its TOML, its ``[sensitivity]`` or ``[optimize]``
#: table, an input, an output, a free key or a constraint), or the scene file
#: unreadable.
_REFUSALS = ("scene ", "cannot read scene file")


def _failure(command: list[str], returncode: int, stderr: str, *, start: str) -> PidmError:
    """The error for a failed ``pidm sensitivity`` or ``pidm optimize``:
    SceneError when pidm refused the scene before the study started (before it
    wrote ``start``, the line it writes once the scene is read and a backend
    chosen), PidmError otherwise."""
    message = error_text(stderr)
    started = any(line.startswith(start) for line in stderr.splitlines())
    if returncode == 1 and not started and message.startswith(_REFUSALS):
        return SceneError(message, stderr=stderr, returncode=1, command=command)
    if returncode != 1:
        message = f"{describe_exit(returncode)}: {message}"
    return PidmError(message, stderr=stderr, returncode=returncode, command=command)
