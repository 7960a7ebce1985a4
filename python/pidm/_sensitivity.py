"""Sensitivity studies with the pidm binary: which inputs a quantity's spread across
units of a design comes from (pidm.sensitivity)."""

from __future__ import annotations

import json
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

from ._binary import find_binary
from ._design import _failure
from ._fit import _mtime, _note, _number
from ._run import (
    ProgressArg,
    Scene,
    _check_search,
    _scene_file,
    _watch,
)
from ._toml import _string, _value, dumps

#: The line pidm writes once the scene is read and a backend chosen.
_STARTED = "pidm: sensitivity of "

#: The columns of :attr:`SensitivityResult.indices`, and SENS.json's names for them.
_INDEX_COLUMNS = {"S1": "first", "S1_conf": "first_conf", "ST": "total", "ST_conf": "total_conf"}

#: The columns of :attr:`SensitivityResult.spread`.
_SPREAD_COLUMNS = ("mean", "sd", "q5", "q50", "q95", "noise")


class SensitivityWarning(UserWarning):
    """A study finished, but pidm warns about its numbers: an input's distribution
    truncated to the key's range, base rows dropped because a run of theirs failed
    (the indices are then conditioned on the rows kept), an output whose model
    noise is above 1 % of its variance, or an output without indices. The message
    is pidm's warnings."""


@dataclass(frozen=True, repr=False, eq=False)
class SensitivityResult:
    """The outcome of :func:`sensitivity`: Sobol' indices and the spread of a
    scene's quantities over distributions of its keys.

    ``indices`` is a DataFrame indexed by ``("quantity", "key")`` (every output
    with every input, in SENS.json's order) with columns ``S1``, ``S1_conf``,
    ``ST``, ``ST_conf``; ``spread`` a DataFrame indexed by ``quantity`` with
    ``mean``, ``sd``, ``q5``, ``q50``, ``q95`` (in the quantity's units) and
    ``noise``. ``json`` is SENS.json as a dict; ``json_path`` and ``png_path``
    SENS.json's and SENS.png's paths (None when ``out`` was None: the files are
    gone). ``str(result)`` is pidm's table.
    """

    #: First-order (``S1``, Saltelli et al. 2010) and total (``ST``, Jansen
    #: 1999) Sobol' indices per output and input, with their bootstrap 95 %
    #: half-widths ``S1_conf`` and ``ST_conf`` (dimensionless). NaN for an output
    #: without indices (its ``indices_error`` in ``json`` and ``warnings`` says
    #: why) and where pidm wrote a non-finite value.
    indices: pd.DataFrame
    #: Per output over the A and B rows kept (2 N' independent units): ``mean``,
    #: ``sd`` (sample standard deviation), the 5, 50 and 95 % quantiles ``q5``,
    #: ``q50``, ``q95``, all in the output's units (``units``), and ``noise``: the
    #: model's mean squared standard error as a share of the output's variance
    #: (dimensionless; NaN where undefined). NaN throughout for an output
    #: without a spread (its ``spread_error`` in ``json``).
    spread: pd.DataFrame
    #: Every run of the study (``samples_out`` given), else None: one row per
    #: run in SALib's order (per base row A, AB_1 ... AB_k, B) with ``row`` (the
    #: base row), ``matrix`` (``"A"``, ``"AB_1"``, ..., ``"B"``), each input's
    #: value in its units, ``status`` (the run's status code, as pidm run's
    #: ``status`` map: 0 normal; <NA> where the scene's rules refused the
    #: candidate, ``refused`` in the CSV) and per output its value and
    #: ``<quantity>_se`` (NaN for a refused candidate).
    samples: pd.DataFrame | None
    #: Units per input key and per output quantity ("N", "m", "1", ...).
    units: dict[str, str]
    #: pidm's warnings about the numbers (also issued as SensitivityWarning).
    warnings: list[str]
    json: dict[str, Any]
    #: SENS.json, or None when ``out`` was None.
    json_path: Path | None
    #: SENS.png (bars of S1 and ST per input, a panel per output), or None when
    #: ``out`` was None.
    png_path: Path | None
    #: The samples' CSV (``samples_out``), or None.
    samples_path: Path | None

    @property
    def keys(self) -> list[str]:
        """The input keys, in SENS.json's order."""
        return [str(entry["key"]) for entry in self.json["inputs"]]

    @property
    def quantities(self) -> list[str]:
        """The outputs, as the scene wrote them (``step_x``, ``hypot(step_x,
        step_y)``, ...), in SENS.json's order."""
        return [str(entry["quantity"]) for entry in self.json["outputs"]]

    def to_xarray(self) -> xr.Dataset:
        """The indices and the spread as labelled arrays: ``S1``, ``S1_conf``, ``ST``
        and ``ST_conf`` (dimensionless) over ``("quantity", "key")`` and ``mean``,
        ``sd``, ``q5``, ``q50``, ``q95`` (each quantity in its own units, the
        ``quantity_units`` coordinate) and ``noise`` (dimensionless) over
        ``quantity``, in SENS.json's order; ``key_units`` gives each input's
        units."""
        ds = xr.merge([self.indices.to_xarray(), self.spread.to_xarray()])
        ds = ds.reindex(quantity=self.quantities, key=self.keys)
        for name in (*_INDEX_COLUMNS, "noise"):
            ds[name].attrs["units"] = "1"
        return ds.assign_coords(
            quantity_units=("quantity", [self.units.get(q, "") for q in self.quantities]),
            key_units=("key", [self.units.get(k, "") for k in self.keys]),
        ).assign_attrs(scene=str(self.json.get("scene", "")), seed=int(self.json.get("seed", 0)))

    def table(self) -> str:
        """Per output its units, spread and each input's S1 and ST with their 95 %
        half-widths (what ``pidm sensitivity`` prints)."""
        lines: list[str] = []
        width = max([len("input"), *(len(k) for k in self.keys)])
        for quantity in self.quantities:
            lines.append(f"{quantity} [{self.units[quantity]}]")
            s = self.spread.loc[quantity]
            lines.append(
                f"  mean {s['mean']:.6e}  sd {s['sd']:.3e}  5/50/95 % {s['q5']:.4e} / "
                f"{s['q50']:.4e} / {s['q95']:.4e}  noise {s['noise']:.2e}"
            )
            ix = self.indices.loc[quantity]
            lines.append(f"  {'input'.ljust(width)}  {'S1 ± 95 %':>16}  {'ST ± 95 %':>16}")
            for key in self.keys:
                r = ix.loc[key]
                lines.append(
                    f"  {key.ljust(width)}  {r['S1']:>7.3f} ± {r['S1_conf']:<6.3f}"
                    f"  {r['ST']:>7.3f} ± {r['ST_conf']:<6.3f}".rstrip()
                )
        raw = self.json
        lines.append(
            f"N = {raw['samples']} base rows ({raw['rows_used']} used), {raw['runs']} runs "
            f"({raw['runs_failed']} failed), seed {raw['seed']}"
        )
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def __repr__(self) -> str:
        return (
            f"<pidm.SensitivityResult of {len(self.quantities)} outputs and "
            f"{len(self.keys)} inputs>\n{self}"
        )


def sensitivity(
    scene: Scene,
    *,
    out: str | os.PathLike[str] | None = None,
    samples_out: str | os.PathLike[str] | None = None,
    backend: str = "auto",
    seed: int = 1,
    threads: int | None = None,
    progress: ProgressArg | None = None,
) -> SensitivityResult:
    """Sobol' indices and the spread of a scene's quantities over distributions of
    its keys (``pidm sensitivity``).

    Parameters
    ----------
    scene
        A sensitivity scene: a scene with a ``[sensitivity]`` table of ``samples``
        (N base rows; the study runs N (k + 2) instances for k inputs), ``outputs``
        (quantities: ``step_x``, ``step_y`` [m per own drive cycle],
        ``velocity_x``, ``velocity_y`` [m/s], ``backward_x``, ``backward_ratio_x``,
        ... (those need ``[output] backward = true``), ``abs(q)``, ``hypot(a,
        b)``) and ``inputs``, a distribution per scene key in the key's units,
        e.g. ``{"mechanism.static_friction": {"uniform": [1.08, 1.32]},
        "axis.x.duty": {"normal": {"mean": 0.98, "sd": 0.005}},
        "mechanism.slider_mass": {"lognormal": {"median": 5e-3, "factor":
        1.05}}}`` (docs/design.md); each is truncated to the key's valid range. A
        path to its file, its TOML text, or a dict shaped like the TOML (its
        inputs keep the dict's order, which is the sample's column order). Text
        and dicts are written to a temporary folder, which SENS.json's ``scene``
        then names.
    out
        SENS.json; SENS.png is written beside it, and both are kept. None runs the
        study into a temporary folder that is removed once the result is read.
    samples_out
        Also write every run's inputs, status and outputs to this CSV (SALib's row
        order) and read it into ``samples``. None writes none (``samples`` is
        None).
    backend
        ``"auto"``, ``"cpu"`` or ``"gpu"`` as for :func:`pidm.run`; a study runs in
        f64.
    seed
        Seed of the sample and of the bootstrap of the confidence half-widths: the
        same seed gives the same SENS.json (but its ``wall_time_s``).
    threads
        Worker threads of the CPU path [default: every core].
    progress
        None or True shows a tqdm bar (runs done of N (k + 2)) when tqdm is
        installed; False shows nothing; a function is called with every progress
        record: a dict with ``done``, ``total`` (runs), ``elapsed_s`` [s],
        ``eta_s`` [s, None before the first run finished] and
        ``instances_per_s``.

    Returns
    -------
    SensitivityResult

    Raises
    ------
    SceneError
        pidm refuses the scene (a ValueError; the message is pidm's and names the
        key: an unknown input key or one that takes no distribution, a
        distribution it cannot use, an output the scene does not produce,
        ``samples`` outside 2 to 2^20). Nothing is written then.
    ValueError
        Arguments this function refuses: ``out`` not a .json file, ``samples_out``
        the same file as SENS.json or SENS.png, a bad ``backend``, ``seed`` or
        ``threads``.
    FileNotFoundError
        No scene file at a given path.
    PidmError
        Any other failure, with pidm's error text.
    KeyboardInterrupt
        On Ctrl-C pidm is stopped (SIGINT, then SIGKILL after a grace); a study
        so stopped writes nothing, and the interrupt is raised again.
    """
    _check_search(backend, threads, seed, out, "SENS.png is")
    binary = find_binary()
    workdir = Path(tempfile.mkdtemp(prefix="pidm-"))
    try:
        result = workdir / "sens.json" if out is None else Path(out).absolute()
        csv = None if samples_out is None else Path(samples_out).absolute()
        if csv is not None and csv in (result, result.with_suffix(".png")):
            raise ValueError(
                f"samples_out={os.fspath(samples_out)!r}: it would overwrite SENS.json or SENS.png"
            )
        with _scene_file(_quoted_inputs(scene), workdir) as scene_path:
            before = _mtime(result)
            command = [binary, "sensitivity", scene_path, "--out", os.fspath(result)]
            if csv is not None:
                command += ["--samples-out", os.fspath(csv)]
            command += ["--backend", backend, "--seed", str(int(seed))]
            if threads is not None:
                command += ["--threads", str(int(threads))]
            command += ["--progress", "none" if progress is False else "jsonl"]
            try:
                returncode, stderr = _watch(command, True if progress is None else progress)
            except KeyboardInterrupt as interrupt:
                if out is not None and _mtime(result) != before:
                    _note(interrupt, f"pidm: the study had finished; it is in {result}")
                raise
            if returncode != 0:
                raise _failure(command, returncode, stderr, start=_STARTED)
            found = _read(result, csv, keep=out is not None)
            if found.warnings:
                warnings.warn(
                    "pidm sensitivity: " + "; ".join(found.warnings),
                    SensitivityWarning,
                    stacklevel=2,
                )
            return found
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


def _quoted_inputs(scene: Scene) -> Scene:
    """A dict scene as TOML text whose ``[sensitivity.inputs]`` keys are quoted
    strings (``"mechanism.static_friction" = ...``); any other scene as it is.

    :func:`pidm.scene_toml` writes a key with dots as a dotted key, which TOML
    nests: ``{"mechanism.static_friction": ..., "axis.x.duty": ...,
    "mechanism.slider_mass": ...}`` would come back grouped by table
    (``mechanism`` first), and the inputs' order is the order of the sample's
    columns and of SENS.json's lists: the dict's own order must be kept."""
    if not isinstance(scene, Mapping):
        return scene
    section = scene.get("sensitivity")
    inputs = section.get("inputs") if isinstance(section, Mapping) else None
    if not isinstance(inputs, Mapping) or not inputs:
        return scene
    rest = {key: value for key, value in section.items() if key != "inputs"}
    text = dumps({**{k: v for k, v in scene.items() if k != "sensitivity"}, "sensitivity": rest})
    lines = ["", "[sensitivity.inputs]"]
    for key, value in inputs.items():
        if not isinstance(key, str):
            raise TypeError(f"scene keys must be strings, not {key!r}")
        lines.append(f"{_string(key)} = {_value(value, f'sensitivity.inputs.{key}')}")
    return text + "\n".join(lines) + "\n"


def _read(path: Path, csv: Path | None, *, keep: bool) -> SensitivityResult:
    """SensitivityResult of SENS.json at ``path`` and the samples' CSV ``csv``."""
    raw = json.loads(path.read_text(encoding="utf-8"))
    keys = [str(entry["key"]) for entry in raw["inputs"]]
    outputs = raw["outputs"]
    units = {str(entry["key"]): str(entry["units"]) for entry in raw["inputs"]}
    units.update({str(entry["quantity"]): str(entry["units"]) for entry in outputs})
    return SensitivityResult(
        indices=_indices(outputs, keys),
        spread=_spread(outputs),
        samples=None if csv is None else _samples(csv),
        units=units,
        warnings=[str(w) for w in raw.get("warnings", [])],
        json=raw,
        json_path=path if keep else None,
        png_path=path.with_suffix(".png") if keep else None,
        samples_path=csv,
    )


def _indices(outputs: list[dict[str, Any]], keys: list[str]) -> pd.DataFrame:
    """S1, S1_conf, ST, ST_conf per (quantity, key); NaN where an output has none."""
    index = pd.MultiIndex.from_product(
        [[str(entry["quantity"]) for entry in outputs], keys], names=["quantity", "key"]
    )
    columns: dict[str, list[float]] = {column: [] for column in _INDEX_COLUMNS}
    for entry in outputs:
        for column, name in _INDEX_COLUMNS.items():
            values = entry.get(name) or [None] * len(keys)
            columns[column] += [_number(v) for v in values]
    return pd.DataFrame(columns, index=index)


def _spread(outputs: list[dict[str, Any]]) -> pd.DataFrame:
    """mean, sd, q5, q50, q95 and noise per quantity; NaN where an output has none."""
    rows = []
    for entry in outputs:
        quantiles = entry.get("quantiles") or {}
        rows.append(
            [
                _number(entry.get("mean")),
                _number(entry.get("sd")),
                *(_number(quantiles.get(q)) for q in ("5", "50", "95")),
                _number(entry.get("noise")),
            ]
        )
    index = pd.Index([str(entry["quantity"]) for entry in outputs], name="quantity")
    return pd.DataFrame(rows, index=index, columns=list(_SPREAD_COLUMNS), dtype=float)


def _samples(csv: Path) -> pd.DataFrame:
    """The samples' CSV: ``row`` as integers, ``matrix`` as text, ``status`` as
    nullable integers (<NA> for ``refused``), every other column as floats bit
    for bit (read as text and converted by Python's ``float``, whatever the
    pandas version's own float parser)."""
    frame = pd.read_csv(csv, dtype=str, keep_default_na=False)
    for column in frame.columns:
        if column == "row":
            frame[column] = frame[column].astype(np.int64)
        elif column == "status":
            status = pd.to_numeric(frame[column], errors="coerce")  # refused: NaN
            frame[column] = status.astype("Int64")
        elif column != "matrix":
            frame[column] = np.array([float(v) for v in frame[column]], dtype=float)
    return frame
