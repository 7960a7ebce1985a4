"""Reading pidm result files into xarray Datasets held in memory."""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import h5py
import numpy as np
import xarray as xr

#: Groups whose datasets are maps shaped like the grid, and the prefix of their
#: variable names (the names the file's netCDF view gives them too).
MAP_GROUPS: tuple[tuple[str, str], ...] = (("maps", ""), ("baseline", "baseline_"))

# HDF5 dimension-scale and netCDF bookkeeping: not attributes of the data.
_BOOKKEEPING = {"CLASS", "NAME", "REFERENCE_LIST", "DIMENSION_LIST", "coordinates"}

PathLike = str | os.PathLike


def _attr(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray) and value.dtype.kind in "SO":
        return [_attr(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        return value.item()
    return value


def _attrs(obj: Any) -> dict[str, Any]:
    return {
        k: _attr(v)
        for k, v in obj.attrs.items()
        if k not in _BOOKKEEPING and not k.startswith("_Netcdf4") and not k.startswith("_NC")
    }


def _values(dataset: h5py.Dataset) -> np.ndarray:
    if h5py.check_string_dtype(dataset.dtype) is not None or dataset.dtype.kind == "S":
        return np.array([_attr(v) for v in dataset[()].ravel()], dtype=object).reshape(
            dataset.shape
        )
    return dataset[()]


def _dims(dataset: h5py.Dataset, fallback: str) -> list[str]:
    """The dimension names of a dataset: its attached dimension scales' names."""
    names = []
    for k, dim in enumerate(dataset.dims):
        scales = list(dim.values())
        if scales:
            names.append(scales[0].name.rsplit("/", 1)[-1])
        elif dataset.ndim == 1:
            names.append(fallback)
        else:
            names.append(f"{fallback}_{k}")
    return names


def open(path: PathLike) -> xr.Dataset:
    """Reads a pidm result file into an xarray Dataset held in memory (no file stays open).

    - dimensions and coordinates: the grid axes (``axis.x.voltage`` [V], ...), each
      with its ``units`` attribute, in grid order; a points scene has the dimension
      ``point`` with a ``label`` coordinate; a shard file's maps run over
      ``instance``, the flat scene index of each of its instances;
    - data variables: every dataset the file has under ``/maps`` (``step_x``,
      ``step_y`` [m per own drive cycle], ``velocity_x``, ``velocity_y`` [m/s],
      ``status``, ``steps``, ``replicas`` (the replicas whose merged estimate
      the values are, or the pieces of a cycle split whose joined travel
      they are: 1 for a run of its own), ...) and under ``/baseline`` with the prefix
      ``baseline_`` (``baseline_step_x`` [m per own drive cycle], ...), each with
      its ``units`` and ``long_name``;
    - ``motion`` (uint8, units 1): the kind of motion the steady measurement found,
      with the CF attributes ``flag_values`` (the codes, a uint8 array) and
      ``flag_meanings`` (their names, space separated, in code order):
      0 ``undetermined`` (a fixed window, "not steady", a failed run or an
      inferred point of a refined map), 1 ``periodic`` (the state repeated),
      2 ``quasi_periodic`` (the increments are a smooth function of the faster
      drive's phase), 3 ``irregular`` (only the batch means converged),
      4 ``multistable`` (replicas from other phases settled on other attractors:
      the instance's own run is kept); absent from files written before it
      existed. ``ds.motion == 1`` selects the
      periodic instances; ``dict(zip(ds.motion.attrs["flag_meanings"].split(),
      ds.motion.attrs["flag_values"]))`` names the codes;
    - with ``[output] backward = true`` (docs/model.md section 4): ``backward_x``
      [m per own drive cycle], the slider's travel against its step,
      ``backward_ratio_x`` (1), its share of the path, and their standard errors
      ``backward_x_se`` and ``backward_ratio_x_se`` (``_y`` for axis y);
    - for a scene with ``[stall]`` (docs/model.md section 7): ``stall_load_x`` [N],
      the load along x at which the x step stops (0 unless ``stall_status_x`` is 0
      or 6; status 8: no stall load below the kinetic friction), the steps at the
      bracket's ends ``stall_step_near_x`` and ``stall_step_far_x`` [m per own
      drive cycle] and the integrations ``stall_waves_x`` (``_y`` for axis y);
    - attributes: the file's root attributes: ``scene`` (the TOML text), ``name``,
      ``pidm_version``, ``backend``, ``precision``, ``tolerance`` [rad],
      ``wall_time_s`` [s, every part of the run], ``wall_time_parts_s`` [s, each
      part: the runs of a resumed run, the shards of a merged one], ``variant``, ...

    Trajectories are read by :func:`open_trajectory`.
    """
    with h5py.File(path, "r") as f:
        if "maps" not in f:
            raise ValueError(f"{os.fspath(path)} is no pidm result file: it has no /maps group")
        coords: dict[str, Any] = {}
        for key, axis in f.get("axes", {}).items():
            coords[key] = xr.Variable((key,), _values(axis), _attrs(axis))
        fallback = "instance" if "shard" in f else "index"
        if "shard/instance" in f:
            instance = f["shard/instance"]
            coords["instance"] = xr.Variable(("instance",), instance[()], _attrs(instance))
        data: dict[str, xr.Variable] = {}
        grid: tuple[tuple[int, ...], list[str]] | None = None
        for group, prefix in MAP_GROUPS:
            if group not in f:
                continue
            for name, dataset in f[group].items():
                if not isinstance(dataset, h5py.Dataset):
                    continue
                dims = _dims(dataset, fallback)
                if grid is None:
                    grid = (dataset.shape, dims)
                elif dataset.shape[: len(grid[0])] == grid[0] and dims[: len(grid[1])] != grid[1]:
                    # Shaped like the grid without scales attached: the grid's dims.
                    extra = [f"{prefix}{name}_{k}" for k in range(len(grid[0]), dataset.ndim)]
                    dims = list(grid[1]) + extra
                data[prefix + name] = xr.Variable(dims, _values(dataset), _attrs(dataset))
        if "labels" in f and grid is not None:
            labels = f["labels"]
            coords["label"] = xr.Variable(_dims(labels, "point"), _values(labels), _attrs(labels))
        attrs = _attrs(f)
    return xr.Dataset(data, coords=coords, attrs=attrs)


def trajectory_names(path: PathLike) -> list[str]:
    """The trajectories a result file holds, as their ``point`` names, in order (the
    index in this list is ``k`` of :func:`open_trajectory`)."""
    with h5py.File(path, "r") as f:
        group = f.get("trajectories")
        if group is None:
            return []
        keys = sorted(group.keys(), key=lambda k: (len(k), k))
        return [_attr(group[k].attrs.get("point", k)) for k in keys]


def open_trajectory(path: PathLike, k: int | str = 0, *, baseline: str | None = None) -> xr.Dataset:
    """Reads stored trajectory ``k`` of a result file (``/trajectories/<k>``) into an
    xarray Dataset held in memory.

    ``k`` is the trajectory's position in ``[output] trajectories`` (0, 1, ...), or
    the ``label`` of a points scene's point. The Dataset has the dimension and
    coordinate ``time`` [s from the start of the run, settle included] and the data
    variables ``stage_x``, ``stage_y``, ``slider_x``, ``slider_y`` [m] and
    ``voltage_x``, ``voltage_y`` [V]; its attributes name the instance (``point``,
    ``label``, ``index``) and give its drive (``voltage_x`` [V], ``frequency_x``
    [Hz], ``duty_x``, ``phase_x`` [cycles], ``drive_x``, the waveform and slew limit
    in words, the same for y), ``period_s``,
    ``settle_s``, ``duration_s`` [s] and ``status``.

    ``baseline="x"`` or ``"y"`` reads the 1-DOF run of that axis instead (scenes
    with baselines): ``stage``, ``slider`` [m] and ``voltage`` [V] along that axis
    over its own ``time``, with ``measured_cycles``.
    """
    with h5py.File(path, "r") as f:
        group = f.get("trajectories")
        if group is None:
            raise KeyError(f"{os.fspath(path)} holds no trajectories")
        names = sorted(group.keys(), key=lambda n: (len(n), n))
        if isinstance(k, str):
            found = [n for n in names if _attr(group[n].attrs.get("label", "")) == k]
            if not found:
                labels = [_attr(group[n].attrs.get("label", "")) for n in names]
                raise KeyError(f"no trajectory labelled {k!r}; the labels are {labels}")
            run = group[found[0]]
        else:
            if not 0 <= int(k) < len(names):
                raise KeyError(f"no trajectory {k}: the file holds {len(names)}")
            run = group[str(int(k))]
        if baseline is not None:
            sub = f"baseline_{baseline}"
            if sub not in run:
                raise KeyError(
                    f"trajectory {k} has no 1-DOF run {sub!r} (a scene without baselines)"
                )
            run = run[sub]
        return _series(run)


def _series(group: h5py.Group) -> xr.Dataset:
    time = group["time"]
    coords = {"time": xr.Variable(("time",), time[()], _attrs(time))}
    data = {}
    for name, dataset in group.items():
        if name == "time" or not isinstance(dataset, h5py.Dataset):
            continue
        if dataset.shape[:1] == time.shape:
            dims: Sequence[str] = ["time"] + [f"{name}_{j}" for j in range(1, dataset.ndim)]
        else:
            dims = [f"{name}_{j}" for j in range(dataset.ndim)]
        data[name] = xr.Variable(dims, _values(dataset), _attrs(dataset))
    return xr.Dataset(data, coords=coords, attrs=_attrs(group))
