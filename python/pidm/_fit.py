"""Calibrating a scene to measured steps with the pidm binary: pidm.fit."""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from ._binary import classify_failure, find_binary
from ._errors import PidmError
from ._run import (
    ProgressArg,
    Scene,
    _check_search,
    _scene_file,
    _Shower,
    _watch,
)

#: What ``data=`` takes: None (the scene's ``[fit] data``), a path to a CSV, or a
#: pandas DataFrame of the same columns.
Data = str | os.PathLike | pd.DataFrame | None

#: How pidm's error text starts when it refuses the scene or the data (before
#: the fit starts): ``scene PATH`` (its TOML, ``[fit]``, a free key), ``data
#: file PATH`` (a column, a cell), ``no data file`` (neither ``[fit] data`` nor
#: ``--data``), or the scene file unreadable.
_REFUSALS = ("scene ", "data file ", "no data file", "cannot read scene file")

#: The line pidm writes once the scene and data are read and a backend chosen.
_STARTED = "pidm: fitting "

#: The measured and model columns of ``rows``, in this order after the keys.
_STEP_COLUMNS = tuple(
    f"{kind}step_{axis}{se}" for axis in ("x", "y") for kind in ("", "model_") for se in ("", "_se")
) + ("residual_x", "residual_y")

#: Below this p-value pidm warns that the data's standard errors are too small for
#: the misfit (docs/fit.md), and so does :func:`fit`.
P_WARN = 1e-3


class FitWarning(UserWarning):
    """A fit finished, but its answer is limited: the data do not determine every
    free key (``identifiable`` is False), or its p-value is below 0.001 (the data's
    standard errors are too small for the misfit). The message is pidm's warnings."""


@dataclass(frozen=True, repr=False, eq=False)
class FitResult:
    """The outcome of :func:`fit`: a scene's free keys calibrated to measured steps.

    ``values`` and ``se`` are pandas Series indexed by key (in FIT.json's
    ``order``), ``correlation`` an xarray DataArray over ``("key", "other_key")``,
    ``rows`` a DataFrame of every data row with the model's steps beside the
    measured ones (``line`` is the row's line in the CSV). ``scene`` is the
    fitted scene's TOML (FIT.toml), ``json`` FIT.json as a dict, ``path``
    FIT.json's path (None when ``out`` was None: the files are gone).
    ``str(result)`` is the table of values with their standard errors.
    """

    #: Fitted value per key, in the key's units.
    values: pd.Series
    #: Standard error per key, in the key's units.
    se: pd.Series
    #: The search bounds per key: (lower, upper).
    bounds: dict[str, tuple[float, float]]
    #: Units per key ("N", "N/V", ...).
    units: dict[str, str]
    #: The correlations of the fitted values (symmetric, 1 on the diagonal).
    correlation: xr.DataArray
    #: The weighted sum of squared residuals at the fitted values.
    chi2: float
    #: Degrees of freedom: measured values less free keys.
    dof: int
    #: ``chi2 / dof``.
    reduced_chi2: float
    #: The chance of a chi2 this large on ``dof`` degrees of freedom where every
    #: measured axis has the data's standard errors; None where a scale came from
    #: the residuals, or ``dof`` <= 0.
    p_value: float | None
    #: ``"given"`` (the data's standard errors as they are) or ``"scaled"`` (by
    #: sqrt(reduced chi2)): which ones ``se`` holds (``[fit] errors``).
    errors: str
    #: The standard errors scaled by sqrt(reduced chi2) where the p-value warns or
    #: ``errors`` is ``"scaled"``; else None.
    se_scaled: pd.Series | None
    #: The covariance of the fitted values in their units, over ``("key",
    #: "other_key")``, scaled as ``se`` is.
    covariance: xr.DataArray
    #: The profile-likelihood intervals by key: ``lo68``, ``hi68``, ``lo95``,
    #: ``hi95`` in the key's units (NaN where a side is open: the misfit never
    #: rises enough inside the bounds); None with ``intervals=False``.
    intervals: pd.DataFrame | None
    #: Whether the data pin down every free key (else see ``warnings``).
    identifiable: bool
    warnings: list[str]
    notes: list[str]
    #: "converged", or why the search ended otherwise.
    status: str
    #: Candidate parameter sets evaluated.
    evaluations: int
    rows: pd.DataFrame
    scene: str
    json: dict[str, Any]
    path: Path | None

    @property
    def keys(self) -> list[str]:
        """The free keys, in FIT.json's ``order``."""
        return list(self.values.index)

    @property
    def residuals(self) -> pd.DataFrame:
        """Each data row's normalized residual per axis, ``(model - data) / se``
        (NaN where the row measures no step on that axis), indexed by ``line``."""
        columns = [c for c in ("residual_x", "residual_y") if c in self.rows.columns]
        return self.rows.set_index("line")[columns]

    def table(self) -> str:
        """Key, value, standard error, the error in % of the value, and units."""
        header = ("key", "value", "se", "se %", "units")
        lines = [header]
        for key in self.keys:
            value, se = float(self.values[key]), float(self.se[key])
            percent = 100.0 * se / abs(value) if value != 0.0 else math.inf
            lines.append((key, f"{value:.7g}", f"{se:.5g}", f"{percent:.2f}", self.units[key]))
        widths = [max(len(line[k]) for line in lines) for k in range(4)]
        return "\n".join(
            (
                line[0].ljust(widths[0])
                + "".join(f"  {line[k].rjust(widths[k])}" for k in range(1, 4))
                + f"  {line[4]}"
            ).rstrip()
            for line in lines
        )

    def __str__(self) -> str:
        text = self.table()
        text += (
            f"\nchi2 {self.chi2:.5g} on {self.dof} degrees of freedom"
            + ("" if self.p_value is None else f" (p = {self.p_value:.3g})")
            + "; "
            f"{self.evaluations} candidates evaluated; {self.status}"
        )
        if not self.identifiable:
            text += "\nnot identifiable: the data do not pin down every free key"
        text += "".join(f"\nwarning: {w}" for w in self.warnings)
        return text

    def __repr__(self) -> str:
        return f"<pidm.FitResult of {len(self.keys)} keys>\n{self}"


def fit(
    scene: Scene,
    data: Data = None,
    *,
    out: str | os.PathLike[str] | None = None,
    backend: str = "auto",
    seed: int = 1,
    threads: int | None = None,
    progress: ProgressArg | None = None,
    intervals: bool = True,
) -> FitResult:
    """Calibrates a fit scene's free keys to measured steps (``pidm fit``).

    Parameters
    ----------
    scene
        A fit scene: a scene with a ``[fit]`` table naming its data and its free
        keys with their bounds, e.g. ``free = { "mechanism.static_friction" = [0.5,
        3.0] }`` (docs/fit.md). A path to its file, its TOML text, or a dict
        shaped like the TOML. Text and dicts are written to a temporary folder,
        so their ``[fit] data`` must be an absolute path, or ``data`` given.
    data
        None: the scene's ``[fit] data`` (relative to the scene file). A path to
        a CSV (``,``, ``;`` or tab separated; ``#`` comments skipped), or a
        pandas DataFrame with the same columns: scene keys (``axis.x.voltage``,
        ...) and per axis one measured column naming its unit, ``step_x_um``,
        ``step_x_nm``, ``step_x`` [m per own drive cycle], or a velocity
        ``velocity_x_um_s``, ``velocity_x_m_s``, with its optional error
        ``step_x_se_um``, ``velocity_x_se_um_s``, ... (docs/fit.md). NaN in a
        measured column is "not measured"; NaN in a key column is refused
        (SceneError naming its line, the frame's row number + 2). Rows with
        equal keys are repeats: without error columns, each setting is fitted
        as its mean with errors from the pooled spread. A DataFrame's named
        index levels are written as columns too.
    out
        FIT.json; FIT.toml and FIT.png are written beside it and kept. None fits
        into a temporary folder that is removed once the result is read.
    backend
        ``"auto"``, ``"cpu"`` or ``"gpu"`` as for :func:`pidm.run`; a fit runs in
        f64.
    seed
        Seed of the global search: the same seed gives the same fit.
    threads
        Worker threads of the CPU path [default: every core].
    progress
        None or True shows a tqdm bar (candidates evaluated, the stage and the
        best chi2) when tqdm is installed; False shows nothing; a function is
        called with every progress record: a dict with ``stage`` (``"global"``,
        ``"local"``, ``"errors"`` or ``"intervals"``), ``batch``, ``evaluations`` and
        ``best_chi2`` (None before a finite one).
    intervals
        Walk the profile-likelihood intervals (68 % and 95 % per free key, about
        as many candidates again as the fit); False skips them (``--no-intervals``).

    Returns
    -------
    FitResult

    Raises
    ------
    SceneError
        pidm refuses the scene or the data (a ValueError; the message is pidm's
        and names the key, the column or the line).
    ValueError
        Arguments this function refuses, e.g. a scene given as text whose
        ``[fit] data`` is relative and no ``data``.
    FileNotFoundError
        No scene or data file at a given path.
    PidmError
        Any other failure, with pidm's error text.
    KeyboardInterrupt
        On Ctrl-C pidm is stopped (SIGINT, then SIGKILL after a grace); a given
        ``out`` then holds the best point so far (``"status": "interrupted"``)
        when pidm wrote it in time; the interrupt is raised again.
    """
    _check_search(backend, threads, seed, out, "FIT.toml and FIT.png are")
    if isinstance(data, (str, os.PathLike)) and not Path(data).is_file():
        raise FileNotFoundError(f"no data file {os.fspath(data)}")
    binary = find_binary()
    workdir = Path(tempfile.mkdtemp(prefix="pidm-"))
    try:
        with _scene_file(scene, workdir) as scene_path:
            if Path(scene_path).parent == workdir and data is None:
                _require_absolute_data(Path(scene_path).read_text(encoding="utf-8"))
            result = workdir / "fit.json" if out is None else Path(out).absolute()
            before = _mtime(result)
            command = [binary, "fit", scene_path, "--out", os.fspath(result)]
            command += ["--backend", backend, "--seed", str(int(seed))]
            if threads is not None:
                command += ["--threads", str(int(threads))]
            if not intervals:
                command += ["--no-intervals"]
            if data is not None:
                command += ["--data", _data_file(data, workdir)]
            command += ["--progress", "none" if progress is False else "jsonl"]
            try:
                returncode, stderr = _watch(
                    command,
                    True if progress is None else progress,
                    is_record=_is_fit_record,
                    shower=_FitShower,
                )
            except KeyboardInterrupt as interrupt:
                if out is not None and _mtime(result) != before:
                    _note(interrupt, f"pidm: the best point so far is in {result}")
                raise
            if returncode != 0:
                raise _failure(command, returncode, stderr)
            found = _read(result, keep=out is not None)
            _warn(found)
            return found
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


def _require_absolute_data(text: str) -> None:
    """A scene given as text (or a dict) is written to a temporary folder: its
    ``[fit] data``, when relative, would name a file there. Raises ValueError
    then; leaves a scene that does not parse to pidm's own message."""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        try:
            import tomli as tomllib  # type: ignore[no-redef]
        except ImportError:
            return
    try:
        table = tomllib.loads(text)
    except ValueError:
        return
    section = table.get("fit")
    if not isinstance(section, dict):
        return  # not a fit scene: pidm says so
    named = section.get("data")
    if not isinstance(named, str) or not named:
        raise ValueError(
            "the scene, given as TOML text or a dict, has no [fit] data: pass data= "
            "(a CSV path or a pandas DataFrame of the measured steps)"
        )
    if not Path(named).is_absolute():
        raise ValueError(
            f"the scene, given as TOML text or a dict, names [fit] data = {named!r}, a "
            "relative path with no scene file to be relative to: pass data= (a CSV path "
            "or a pandas DataFrame), make the path absolute, or give the scene as a file"
        )


def _data_file(data: Data, workdir: Path) -> str:
    """``--data``'s argument: a given path made absolute, a DataFrame written to
    ``workdir/data.csv`` (empty cells for NaN)."""
    if isinstance(data, pd.DataFrame):
        frame = data
        if any(name is not None for name in frame.index.names):
            frame = frame.reset_index()
        path = workdir / "data.csv"
        frame.to_csv(path, index=False, na_rep="")
        return os.fspath(path)
    if isinstance(data, (str, os.PathLike)):
        return os.fspath(Path(data).expanduser().absolute())
    raise TypeError(f"data is a CSV path or a pandas DataFrame, not {type(data).__name__}")


def _mtime(path: Path) -> int | None:
    try:
        return path.stat().st_mtime_ns
    except OSError:
        return None


def _note(error: BaseException, note: str) -> None:
    if hasattr(error, "add_note"):
        error.add_note(note)


def _failure(command: list[str], returncode: int, stderr: str) -> PidmError:
    """The error for a failed ``pidm fit``: SceneError when pidm refused the
    scene or the data before fitting, PidmError otherwise. The message tells
    which (``pidm check``, which ``pidm.run`` asks, takes no ``--data``)."""
    return classify_failure(command, returncode, stderr, start=_STARTED, refusals=_REFUSALS)


def _read(path: Path, *, keep: bool) -> FitResult:
    """FitResult of FIT.json at ``path`` and FIT.toml beside it."""
    raw = json.loads(path.read_text(encoding="utf-8"))
    scene = path.with_suffix(".toml").read_text(encoding="utf-8")
    order = list(raw["order"])
    parameters = raw["parameters"]
    index = pd.Index(order, name="key")
    values = pd.Series([_number(parameters[k]["value"]) for k in order], index, name="value")
    se = pd.Series([_number(parameters[k]["se"]) for k in order], index, name="se")
    covariance = xr.DataArray(
        np.array(
            [[_number(c) for c in row] for row in raw.get("covariance", [])], dtype=float
        ).reshape(len(order), len(order)),
        dims=("key", "other_key"),
        coords={"key": order, "other_key": order},
        name="covariance",
        attrs={"long_name": "covariance of the fitted values", "units": "keys' units squared"},
    )
    scaled = [parameters[k].get("se_scaled") for k in order]
    se_scaled = (
        None
        if all(v is None for v in scaled)
        else pd.Series([_number(v) for v in scaled], index, name="se_scaled")
    )
    correlation = xr.DataArray(
        np.array([[_number(c) for c in row] for row in raw["correlation"]], dtype=float).reshape(
            len(order), len(order)
        ),
        dims=("key", "other_key"),
        coords={"key": order, "other_key": order},
        name="correlation",
        attrs={"long_name": "correlation of the fitted values", "units": "1"},
    )
    return FitResult(
        values=values,
        se=se,
        bounds={k: tuple(float(b) for b in parameters[k]["bounds"]) for k in order},
        units={k: str(parameters[k]["units"]) for k in order},
        correlation=correlation,
        chi2=_number(raw["chi2"]),
        dof=int(raw["dof"]),
        reduced_chi2=_number(raw.get("reduced_chi2")),
        p_value=None if raw.get("p_value") is None else float(raw["p_value"]),
        errors=str(raw.get("errors", "given")),
        se_scaled=se_scaled,
        covariance=covariance,
        intervals=_intervals(order, parameters),
        identifiable=bool(raw["identifiable"]),
        warnings=list(raw.get("warnings", [])),
        notes=list(raw.get("notes", [])),
        status=str(raw["status"]),
        evaluations=int(raw["evaluations"]),
        rows=_rows(raw.get("rows", [])),
        scene=scene,
        json=raw,
        path=path if keep else None,
    )


def _intervals(order: list[str], parameters: Mapping[str, Any]) -> pd.DataFrame | None:
    """The profile intervals of FIT.json's parameters, or None where skipped."""
    if all(parameters[k].get("interval68") is None for k in order):
        return None
    columns: dict[str, list[float]] = {"lo68": [], "hi68": [], "lo95": [], "hi95": []}
    for key in order:
        for level in ("68", "95"):
            lo, hi = parameters[key].get(f"interval{level}") or (None, None)
            columns[f"lo{level}"].append(_number(lo))
            columns[f"hi{level}"].append(_number(hi))
    return pd.DataFrame(columns, index=pd.Index(order, name="key"))


def _warn(found: FitResult) -> None:
    """A :class:`FitWarning` where the fit is not identifiable or its p-value warns."""
    limited = not found.identifiable or (
        found.p_value is not None and found.p_value < P_WARN and found.errors == "given"
    )
    if limited:
        text = "; ".join(found.warnings) or "the data do not determine every free key"
        warnings.warn(f"pidm fit: {text}", FitWarning, stacklevel=3)


def _number(value: Any) -> float:
    """A JSON number; null (pidm's non-finite) as NaN."""
    return math.nan if value is None else float(value)


def _rows(rows: list[Mapping[str, Any]]) -> pd.DataFrame:
    """The data rows: ``line`` (and ``lines``, a pooled setting's lines, when
    repeats were pooled), the keys, then measured and model steps per axis (NaN
    where a row measures no step)."""
    frame = pd.DataFrame(rows)
    steps = [c for c in _STEP_COLUMNS if c in frame.columns]
    first = [c for c in ("line", "lines") if c in frame.columns]
    keys = [c for c in frame.columns if c not in steps and c not in first]
    return frame[first + keys + steps]


def _is_fit_record(record: Any) -> bool:
    """Whether a JSON line of stderr is a progress record of ``pidm fit``."""
    return isinstance(record, dict) and "stage" in record and "evaluations" in record


class _FitShower(_Shower):
    """A fit's tqdm bar: candidates evaluated (no total: the search ends when
    it converges), with the stage and the best chi2 so far."""

    def show(self, record: dict[str, Any]) -> None:
        if self.bar is None:
            self.bar = self.tqdm(total=None, unit=" candidates", desc="pidm fit")
        best = record.get("best_chi2")
        postfix = {
            "stage": record.get("stage"),
            "best_chi2": "-" if best is None else f"{best:.5g}",
        }
        self.bar.set_postfix(postfix, refresh=False)
        self.bar.update(int(record["evaluations"]) - self.bar.n)
