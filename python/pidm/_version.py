"""The package's version: the pidm crate's (Cargo.toml), one source for both."""

from __future__ import annotations

import importlib.metadata
import re
from pathlib import Path

#: The package directory this module was imported from.
PACKAGE_DIR = Path(__file__).resolve().parent


def installed_distribution() -> importlib.metadata.Distribution | None:
    """The installed distribution this package was imported from, or None when it runs
    from a source checkout (``PYTHONPATH=python``) whatever else is installed."""
    try:
        dist = importlib.metadata.distribution("pidm")
    except importlib.metadata.PackageNotFoundError:
        return None
    init = Path(str(dist.locate_file("pidm/__init__.py"))).resolve()
    return dist if init == PACKAGE_DIR / "__init__.py" else None


def package_version() -> str:
    """The installed distribution's version (maturin takes it from Cargo.toml), else
    that of the Cargo.toml beside a source checkout's ``python/``."""
    dist = installed_distribution()
    if dist is not None:
        return dist.version
    cargo = PACKAGE_DIR.parent.parent / "Cargo.toml"
    if cargo.is_file():
        package = cargo.read_text().split("[package]", 1)[-1].split("\n[", 1)[0]
        found = re.search(r'^version\s*=\s*"([^"]+)"', package, re.MULTILINE)
        if found:
            return found.group(1)
    return "unknown"
