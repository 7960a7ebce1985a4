"""Optimization with the pidm binary: the best values of a scene's free keys for an
objective under constraints, or the front between two objectives (pidm.optimize)."""

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
from ._toml import _key, _string, _value, dumps

#: The line ``pidm optimize`` writes once the scene is read and a backend chosen.
_OPT_STARTED = "pidm: optimize: "

#: The columns of :attr:`OptimizeResult.constraints`, after its index ``constraint``.
_CONSTRAINT_COLUMNS = ("kept", "slack", "slack_se", "margin_se", "margin", "margin_note")


class OptimizeWarning(UserWarning):
    """A search finished, but its optimum is not a plain one: no run kept every
    constraint (status ``"infeasible: ..."``: the optimum is the least
    violation), no run finished (``"failed: ..."``: there is no optimum), or a
    probe at ±1 % of a key's range changed the run's status, kind of motion or a
    step's sign (``"ok, on a cliff"``). The message is pidm's status."""


@dataclass(frozen=True, repr=False, eq=False)
class OptimizeResult:
    """The outcome of :func:`optimize`: the best values of a scene's free keys for
    an objective under constraints, or the front between two objectives.

    ``values`` maps each free key (in the scene's order) to its value at the
    optimum in the key's units, ``objective`` is the first objective's
    ``(value, se)`` there in its units; both None when no run finished.
    ``constraints`` is a DataFrame of the constraints at the optimum, ``front``
    one of the front's points (None for one objective), ``progress`` one of the
    best feasible first objective after each batch. ``json`` is OPT.json as a
    dict; ``json_path``, ``toml_path`` and ``png_path`` OPT.json's, OPT.toml's
    and OPT.png's paths (None when ``out`` was None: the files are gone; also
    ``toml_path`` when there is no optimum). ``scene_text`` is OPT.toml's text,
    which :func:`pidm.run` runs to measure the optimum again. ``str(result)`` is
    pidm's table.
    """

    #: Each free key's value at the optimum, in the key's units ("V", "Hz",
    #: ...; ``units``), in the scene's order of ``free``; None when no run
    #: finished (status ``"failed: ..."``).
    values: dict[str, float] | None
    #: The first objective at the optimum: its value and the standard error of
    #: its measurement (0 for a window or a periodic motion), in the
    #: quantity's units; NaN where pidm wrote a non-finite value; None when no
    #: run finished.
    objective: tuple[float, float] | None
    #: One row per constraint at the optimum, indexed by ``constraint`` (as the
    #: scene wrote it, ``"backward_ratio_x <= 0.8"``): ``kept`` (bool),
    #: ``slack`` (how far inside the limit, in the constraint's units; negative
    #: where it is broken), ``slack_se`` (its standard error), ``margin_se``
    #: (the slack in standard errors, dimensionless) or, where the measurement
    #: has no SE, ``margin`` (the slack, absolute) with ``margin_note`` saying
    #: so; NaN (None for the note) where the other applies. Empty without
    #: constraints or an optimum.
    constraints: pd.DataFrame
    #: Two objectives: the non-dominated set of every steady, feasible run,
    #: ordered by the second objective: one row per point with each free key's
    #: value (in its units), each objective's value and ``<quantity>_se`` (in
    #: the quantity's units; a quantity that is both objectives is named
    #: ``"maximize <quantity>"`` and ``"minimize <quantity>"``), the run's
    #: ``status`` (0: steady) and ``motion`` (its kind of motion). None for
    #: one objective.
    front: pd.DataFrame | None
    #: The search's progress: ``runs`` made after each batch and ``best``, the
    #: best feasible first objective so far (in its units; NaN before a
    #: feasible run).
    progress: pd.DataFrame
    #: pidm's verdict: ``"ok"``, ``"ok, on a cliff"``, ``"infeasible: ..."`` (no
    #: run kept every constraint; the optimum is the least violation) or
    #: ``"failed: ..."`` (no run finished; no optimum).
    status: str
    #: Whether a probe at ±1 % of a key's range around the optimum changed its
    #: status, kind of motion or a step's sign (``json["optimum"]
    #: ["neighbourhood"]`` lists the changes).
    on_cliff: bool
    #: The runs the search made (at most the budget; it stops once converged).
    runs: int
    #: Units per free key and per objective quantity ("V", "Hz", "m/s", "1", ...).
    units: dict[str, str]
    json: dict[str, Any]
    #: OPT.json, or None when ``out`` was None.
    json_path: Path | None
    #: OPT.toml (the scene at the optimum), or None when ``out`` was None or
    #: there is no optimum.
    toml_path: Path | None
    #: OPT.png (the search's progress, then the front or the objective along
    #: each free key through the optimum), or None when ``out`` was None.
    png_path: Path | None
    #: OPT.toml's text, read before a temporary folder is removed.
    _scene_text: str | None

    @property
    def scene_text(self) -> str | None:
        """OPT.toml's text: the scene without ``[optimize]``, the free keys at the
        optimum (``pidm.run(result.scene_text)`` measures it again); None when
        there is no optimum."""
        return self._scene_text

    @property
    def keys(self) -> list[str]:
        """The free keys, in the scene's order (the search's coordinates)."""
        return [str(entry["key"]) for entry in self.json["free"]]

    @property
    def quantities(self) -> list[str]:
        """The objectives' quantities, as the scene wrote them."""
        return [str(entry["quantity"]) for entry in self.json["objectives"]]

    def to_xarray(self) -> xr.Dataset | None:
        """The front as labelled arrays over ``point`` (ordered by the second
        objective): each free key's value and each objective's value and SE, with
        their ``units`` attributes; None for one objective."""
        if self.front is None:
            return None
        ds = xr.Dataset.from_dataframe(self.front.reset_index(drop=True).rename_axis("point"))
        for name in ds.data_vars:
            base = str(name).removesuffix("_se")
            if base in self.units:
                ds[name].attrs["units"] = self.units[base]
        return ds.assign_attrs(
            scene=str(self.json.get("scene", "")), seed=int(self.json.get("seed", 0))
        )

    def table(self) -> str:
        """The status, the optimum's values, objectives and constraints' slacks,
        the cliffs found around it and the runs made (what ``pidm optimize``
        prints)."""
        raw = self.json
        lines = [f"status: {self.status}"]
        optimum = raw.get("optimum")
        if optimum is not None and self.values is not None:
            for key, value in self.values.items():
                lines.append(f"  {key} = {value:.6e} {self.units[key]}")
            for spec, found in zip(raw["objectives"], optimum["objectives"], strict=False):
                value, se = _number(found.get("value")), _number(found.get("se"))
                lines.append(
                    f"  {spec['sense']} {spec['quantity']} = {value:.6e} ± {se:.2e} {spec['units']}"
                )
            for name, row in self.constraints.iterrows():
                kept = "kept" if row["kept"] else "broken"
                lines.append(f"  {name}: slack {row['slack']:.4e} ({kept})")
            for probe in (optimum.get("neighbourhood") or {}).get("probes", []):
                if probe.get("changes"):
                    moved = probe["moved"]
                    sign = "+" if moved["direction"] > 0 else "-"
                    lines.append(
                        f"  cliff: {moved['key']} {sign}1 %: {', '.join(probe['changes'])}"
                    )
        if self.front is not None:
            lines.append(f"front: {len(self.front)} points")
        lines.append(f"runs: {self.runs} of a budget of {raw['budget']}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def __repr__(self) -> str:
        kind = "a front" if self.front is not None else "an optimum"
        return (
            f"<pidm.OptimizeResult: {kind} over {len(self.keys)} free keys, "
            f"{self.runs} runs>\n{self}"
        )


def optimize(
    scene: Scene,
    *,
    out: str | os.PathLike[str] | None = None,
    backend: str = "auto",
    seed: int = 1,
    threads: int | None = None,
    progress: ProgressArg | None = None,
) -> OptimizeResult:
    """The best values of a scene's free keys for an objective under constraints,
    or the front between two objectives (``pidm optimize``).

    Parameters
    ----------
    scene
        An optimize scene: a scene of one instance with an ``[optimize]`` table of
        ``maximize = "Q"`` and/or ``minimize = "Q"`` (both: a front), quantities
        as for :func:`sensitivity` (``step_x``, ``step_y`` [m per own drive
        cycle], ``velocity_x``, ``velocity_y`` [m/s], ``backward_x``,
        ``backward_ratio_x``, ... (those need ``[output] backward = true``),
        ``abs(q)``, ``hypot(a, b)``); ``free``, the keys to search with their
        bounds in the keys' units, e.g. ``{"axis.x.voltage": [50, 150],
        "axis.x.frequency": [5, 40]}`` (V, Hz; inside each key's valid range; a
        log scale where the bounds span a factor of 100); optionally
        ``subject_to``, constraints like ``["backward_ratio_x <= 0.8"]``, and
        ``budget``, the runs the search may make (default 210 per free key, 2000
        per key for a front; at least 60 per key) (docs/design.md). A path to
        its file, its TOML text, or a dict shaped like the TOML: its ``free``
        keys keep the dict's order, which is the search's coordinate order (and
        so what a seed reproduces). Text and dicts are written to a temporary
        folder, which OPT.json's ``scene`` then names.
    out
        OPT.json; OPT.toml (the scene at the optimum) and OPT.png are written
        beside it, and all are kept. None searches into a temporary folder that
        is removed once the result is read.
    backend
        ``"auto"``, ``"cpu"`` or ``"gpu"`` as for :func:`pidm.run`; a search runs
        in f64.
    seed
        Seed of the search: the same seed (and the same scene, its free keys in
        the same order) gives the same OPT.json (but its ``wall_time_s``).
    threads
        Worker threads of the CPU path [default: every core].
    progress
        None or True shows a tqdm bar (runs done of the budget; a search that
        converges early jumps to the end) when tqdm is installed; False shows
        nothing; a function is called with every progress record: a dict with
        ``done``, ``total`` (runs: the budget), ``elapsed_s`` [s], ``eta_s`` [s,
        None before the first batch finished] and ``instances_per_s``.

    Returns
    -------
    OptimizeResult

    Raises
    ------
    SceneError
        pidm refuses the scene (a ValueError; the message is pidm's and names the
        key: an objective or constraint quantity the scene does not produce, a
        ``backward_*`` quantity without ``[output] backward = true``, a free key
        that is not a real-valued instance key or whose bounds leave its valid
        range, a budget below 60 per free key, a scene of more than one
        instance). Nothing is written then.
    ValueError
        Arguments this function refuses: ``out`` not a .json file, a bad
        ``backend``, ``seed`` or ``threads``.
    FileNotFoundError
        No scene file at a given path.
    PidmError
        Any other failure, with pidm's error text.
    KeyboardInterrupt
        On Ctrl-C pidm is stopped (SIGINT, then SIGKILL after a grace); a search
        so stopped writes nothing, and the interrupt is raised again.

    Warns
    -----
    OptimizeWarning
        The status is not ``"ok"``: infeasible, failed, or on a cliff.
    """
    _check_search(backend, threads, seed, out, "OPT.toml and OPT.png are")
    binary = find_binary()
    workdir = Path(tempfile.mkdtemp(prefix="pidm-"))
    try:
        result = workdir / "opt.json" if out is None else Path(out).absolute()
        with _scene_file(_quoted_free(scene), workdir) as scene_path:
            before = _mtime(result)
            command = [binary, "optimize", scene_path, "--out", os.fspath(result)]
            command += ["--backend", backend, "--seed", str(int(seed))]
            if threads is not None:
                command += ["--threads", str(int(threads))]
            command += ["--progress", "none" if progress is False else "jsonl"]
            try:
                returncode, stderr = _watch(command, True if progress is None else progress)
            except KeyboardInterrupt as interrupt:
                if out is not None and _mtime(result) != before:
                    _note(interrupt, f"pidm: the search had finished; it is in {result}")
                raise
            if returncode != 0:
                raise _failure(command, returncode, stderr, start=_OPT_STARTED)
            found = _read_optimum(result, keep=out is not None)
            if found.status != "ok":
                warnings.warn(f"pidm optimize: {found.status}", OptimizeWarning, stacklevel=2)
            return found
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


def _quoted_free(scene: Scene) -> Scene:
    """A dict scene as TOML text whose ``[optimize]`` table is written whole, its
    ``free`` keys quoted strings (``free = { "axis.x.voltage" = [50, 150], ...
    }``); any other scene as it is.

    :func:`pidm.scene_toml` writes a key with dots as a dotted key, which TOML
    nests: ``{"mechanism.static_friction": ..., "axis.x.voltage": ...,
    "mechanism.slider_mass": ...}`` would come back grouped by table
    (``mechanism`` first), and the free keys' order is the search's coordinate
    order, on which a seed's search depends: the dict's own order must be
    kept. ``[optimize]`` stays one table (pidm refuses it split into
    ``[optimize.free]``)."""
    if not isinstance(scene, Mapping):
        return scene
    section = scene.get("optimize")
    if not isinstance(section, Mapping):
        return scene
    text = dumps({k: v for k, v in scene.items() if k != "optimize"})
    lines = ["", "[optimize]"]
    for key, value in section.items():
        if not isinstance(key, str):
            raise TypeError(f"scene keys must be strings, not {key!r}")
        if key == "free" and isinstance(value, Mapping):
            fields = []
            for name, bounds in value.items():
                if not isinstance(name, str):
                    raise TypeError(f"scene keys must be strings, not {name!r}")
                fields.append(f"{_string(name)} = {_value(bounds, f'optimize.free.{name}')}")
            lines.append("free = { " + ", ".join(fields) + " }" if fields else "free = {}")
        else:
            name = _string(key) if "." in key else _key(key)
            lines.append(f"{name} = {_value(value, f'optimize.{key}')}")
    return text.rstrip("\n") + "\n" + "\n".join(lines) + "\n"


def _read_optimum(path: Path, *, keep: bool) -> OptimizeResult:
    """OptimizeResult of OPT.json at ``path`` and OPT.toml beside it."""
    raw = json.loads(path.read_text(encoding="utf-8"))
    toml_path = path.with_suffix(".toml")
    scene_text = toml_path.read_text(encoding="utf-8") if toml_path.is_file() else None
    keys = [str(entry["key"]) for entry in raw["free"]]
    units = {str(entry["key"]): str(entry["units"]) for entry in raw["free"]}
    units.update({str(entry["quantity"]): str(entry["units"]) for entry in raw["objectives"]})
    optimum = raw.get("optimum")
    values = None
    objective = None
    if optimum is not None:
        values = {key: _number(optimum["values"].get(key)) for key in keys}
        first = optimum["objectives"][0]
        objective = (_number(first.get("value")), _number(first.get("se")))
    neighbourhood = (optimum or {}).get("neighbourhood") or {}
    status = str(raw["status"])
    front = raw.get("front")
    return OptimizeResult(
        values=values,
        objective=objective,
        constraints=_constraints((optimum or {}).get("constraints") or []),
        front=None if front is None else _front(front, keys, raw["objectives"]),
        progress=_progress(raw.get("progress") or []),
        status=status,
        on_cliff=bool(neighbourhood.get("cliff", False)) or status.startswith("ok, on a cliff"),
        runs=int(raw["runs"]),
        units=units,
        json=raw,
        json_path=path if keep else None,
        toml_path=toml_path if keep and scene_text is not None else None,
        png_path=path.with_suffix(".png") if keep else None,
        _scene_text=scene_text,
    )


def _constraints(entries: list[dict[str, Any]]) -> pd.DataFrame:
    """The optimum's constraints, indexed by their text."""
    index = pd.Index([str(entry["constraint"]) for entry in entries], name="constraint")
    columns: dict[str, list[Any]] = {
        "kept": [bool(entry["kept"]) for entry in entries],
        "slack": [_number(entry.get("slack")) for entry in entries],
        "slack_se": [_number(entry.get("slack_se")) for entry in entries],
        "margin_se": [_number(entry.get("margin_se")) for entry in entries],
        "margin": [_number(entry.get("margin")) for entry in entries],
        "margin_note": [entry.get("margin_note") for entry in entries],
    }
    frame = pd.DataFrame(columns, index=index)
    frame["kept"] = frame["kept"].astype(bool)
    for column in ("slack", "slack_se", "margin_se", "margin"):
        frame[column] = frame[column].astype(float)
    frame["margin_note"] = frame["margin_note"].astype(object)
    return frame[list(_CONSTRAINT_COLUMNS)]


def _objective_names(objectives: list[dict[str, Any]]) -> list[str]:
    """The front's column of each objective: its quantity, or ``"<sense>
    <quantity>"`` where both objectives are the same quantity."""
    quantities = [str(entry["quantity"]) for entry in objectives]
    if len(set(quantities)) == len(quantities):
        return quantities
    return [f"{entry['sense']} {entry['quantity']}" for entry in objectives]


def _front(
    points: list[dict[str, Any]], keys: list[str], objectives: list[dict[str, Any]]
) -> pd.DataFrame:
    """The front's points: the free keys, each objective's value and SE, status
    and motion."""
    names = _objective_names(objectives)
    columns: dict[str, list[Any]] = {key: [] for key in keys}
    for name in names:
        columns[name] = []
        columns[f"{name}_se"] = []
    columns["status"] = []
    columns["motion"] = []
    for point in points:
        for key in keys:
            columns[key].append(_number(point["values"].get(key)))
        for name, found in zip(names, point["objectives"], strict=True):
            columns[name].append(_number(found.get("value")))
            columns[f"{name}_se"].append(_number(found.get("se")))
        columns["status"].append(point.get("status"))
        columns["motion"].append(point.get("motion"))
    frame = pd.DataFrame(columns)
    for column in columns:
        if column not in ("status", "motion"):
            frame[column] = frame[column].astype(float)
    return frame


def _progress(entries: list[list[Any]]) -> pd.DataFrame:
    """``runs`` (integers) and ``best`` (NaN before a feasible run) per batch."""
    return pd.DataFrame(
        {
            "runs": np.array([int(runs) for runs, _ in entries], dtype=np.int64),
            "best": np.array([_number(best) for _, best in entries], dtype=float),
        }
    )
