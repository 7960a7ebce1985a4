"""Design studies with the pidm binary: which inputs a quantity's spread across units
of a design comes from (pidm.sensitivity), and the best values of a scene's free
keys for an objective under constraints, or the front between two objectives
(pidm.optimize)."""

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

from ._binary import describe_exit, error_text, find_binary
from ._errors import PidmError, SceneError
from ._fit import _mtime, _note, _number
from ._run import (
    ProgressArg,
    Scene,
    _check_backend,
    _check_threads,
    _scene_file,
    _watch,
)
from ._toml import _key, _string, _value, dumps

#: How pidm's error text starts when it refuses the scene before the study
#: starts: ``scene PATH`` (its TOML, ``[sensitivity]``, an input or an output),
#: or the scene file unreadable.
_REFUSALS = ("scene ", "cannot read scene file")

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
    _check_backend(backend)
    _check_threads(threads)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed={seed!r}: expected a whole number of at least 0")
    if out is not None and Path(out).suffix != ".json":
        raise ValueError(
            f"out={os.fspath(out)!r}: expected a .json file (SENS.png is written beside it)"
        )
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
                raise _failure(command, returncode, stderr)
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


def _failure(
    command: list[str], returncode: int, stderr: str, *, start: str = _STARTED
) -> PidmError:
    """The error for a failed ``pidm sensitivity`` (``pidm optimize`` with
    ``start=_OPT_STARTED``): SceneError when pidm refused the scene before the
    study started (before it wrote ``start``), PidmError otherwise."""
    message = error_text(stderr)
    started = any(line.startswith(start) for line in stderr.splitlines())
    if returncode == 1 and not started and message.startswith(_REFUSALS):
        return SceneError(message, stderr=stderr, returncode=1, command=command)
    if returncode != 1:
        message = f"{describe_exit(returncode)}: {message}"
    return PidmError(message, stderr=stderr, returncode=returncode, command=command)


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
    _check_backend(backend)
    _check_threads(threads)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed={seed!r}: expected a whole number of at least 0")
    if out is not None and Path(out).suffix != ".json":
        raise ValueError(
            f"out={os.fspath(out)!r}: expected a .json file (OPT.toml and OPT.png are "
            "written beside it)"
        )
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
