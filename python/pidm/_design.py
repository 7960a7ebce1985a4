"""What pidm.sensitivity (_sensitivity.py) and pidm.optimize (_optimize.py) share:
the error for a failed ``pidm sensitivity`` or ``pidm optimize``, SceneError when
pidm refused the scene before the study started."""

from __future__ import annotations

from ._binary import classify_failure
from ._errors import PidmError

#: How pidm's error text starts when it refuses the scene before the study
#: starts: ``scene PATH`` (its TOML, its ``[sensitivity]`` or ``[optimize]``
#: table, an input, an output, a free key or a constraint), or the scene file
#: unreadable.
_REFUSALS = ("scene ", "cannot read scene file")


def _failure(command: list[str], returncode: int, stderr: str, *, start: str) -> PidmError:
    """The error for a failed ``pidm sensitivity`` or ``pidm optimize``
    (``classify_failure``: ``start`` is the line pidm writes once the scene is
    read and a backend chosen)."""
    return classify_failure(command, returncode, stderr, start=start, refusals=_REFUSALS)
