"""The exceptions of the pidm package."""

from __future__ import annotations

from collections.abc import Sequence


class PidmError(Exception):
    """A failure of the pidm binary, or no binary to run.

    The message is pidm's own error text; ``stderr`` holds everything the
    binary wrote on stderr (progress lines left out), ``returncode`` its exit
    status (None when it never ran) and ``command`` the command line.
    """

    def __init__(
        self,
        message: str,
        *,
        stderr: str = "",
        returncode: int | None = None,
        command: Sequence[str] | None = None,
    ) -> None:
        super().__init__(message)
        self.message = message
        self.stderr = stderr
        self.returncode = returncode
        self.command = list(command) if command is not None else None


class SceneError(PidmError, ValueError):
    """A scene pidm refuses; the message is pidm's and names the key, the value and
    what was expected (for example ``unknown key `axis.x.voltag` (did you mean
    `voltage`?)``). Also a ``ValueError``."""
