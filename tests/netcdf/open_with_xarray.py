"""Opens a pidm result file the way users do, with xarray (h5netcdf engine)
and h5py, and checks that the two agree: the dimensions are the scene's grid
axes with their coordinate values and units, the maps carry units and long
names, and every map value is the one stored under /maps or /baseline.

Usage: open_with_xarray.py FILE.h5 DIM=UNITS...  (the expected dimensions in
grid order). Exits non-zero with a message on the first mismatch.
"""

import sys

import h5py
import numpy as np
import xarray as xr


def main() -> None:
    path = sys.argv[1]
    expected = [arg.split("=", 1) for arg in sys.argv[2:]]
    ds = xr.open_dataset(path, engine="h5netcdf")
    with h5py.File(path, "r") as raw:
        dims = [name for name, _ in expected]
        for name, units in expected:
            coord = ds.coords[name]
            assert coord.dims == (name,), f"{name}: dims {coord.dims}"
            assert coord.attrs["units"] == units, f"{name}: units {coord.attrs}"
            np.testing.assert_array_equal(coord.values, raw["axes"][name][()])
        maps = [("maps", n) for n in raw["maps"]]
        maps += [("baseline", n) for n in raw.get("baseline", {})]
        for group, name in maps:
            var = ds[name if group == "maps" else f"baseline_{name}"]
            assert list(var.dims) == dims, f"{name}: dims {var.dims}, expected {dims}"
            assert var.attrs["units"] == raw[group][name].attrs["units"]
            assert var.attrs["long_name"], f"{name} has no long_name"
            stored = raw[group][name][()]
            assert var.values.dtype == stored.dtype, f"{name}: {var.values.dtype}"
            # Bit for bit: the same numbers through both readers.
            assert var.values.tobytes() == stored.tobytes(), f"{name} differs"
        step = ds["step_x"]
        assert step.attrs["units"] == "m"
        # Label-based selection works: the first coordinate value of every
        # dimension picks the first entry.
        first = step.sel({d: ds.coords[d].values[0] for d in dims})
        assert first.item() == raw["maps"]["step_x"][()].flat[0]
        groups = trajectory_groups(raw)
    for group in groups:
        check_trajectory(path, group)
    print(f"ok: {path} opens in xarray with dims {dims}")
    print(f"{len(groups)} trajectory groups open in xarray over time")


def trajectory_groups(raw: h5py.File) -> list[str]:
    """Every trajectory group of the file and its 1-DOF runs."""
    groups = []
    for k, run in raw.get("trajectories", {}).items():
        groups.append(f"trajectories/{k}")
        groups += [f"trajectories/{k}/{sub}" for sub in run if isinstance(run[sub], h5py.Group)]
    return groups


def check_trajectory(path: str, group: str) -> None:
    """A trajectory group opens in xarray as its own Dataset: `time` [s] is
    its dimension and coordinate, every series lies along it with its units,
    and the values are the stored ones."""
    ds = xr.open_dataset(path, engine="h5netcdf", group=group)
    with h5py.File(path, "r") as raw:
        stored = raw[group]
        assert list(ds.dims) == ["time"], f"{group}: dims {dict(ds.sizes)}"
        assert ds.coords["time"].attrs["units"] == "s", f"{group}: time units"
        series = [n for n in stored if isinstance(stored[n], h5py.Dataset) and n != "time"]
        assert series, f"{group} has no series"
        assert sorted(ds.data_vars) == sorted(series), f"{group}: {list(ds.data_vars)}"
        for name in series + ["time"]:
            var = ds[name]
            assert var.dims == ("time",), f"{group}/{name}: dims {var.dims}"
            assert var.attrs["units"] == stored[name].attrs["units"], f"{group}/{name}"
            assert var.values.tobytes() == stored[name][()].tobytes(), f"{group}/{name} differs"
        assert int(ds.attrs["status"]) == int(stored.attrs["status"])


if __name__ == "__main__":
    main()
