"""pidm.run, pidm.open, pidm.open_trajectory and pidm.check against the CLI."""

from __future__ import annotations

import warnings
from pathlib import Path

import h5py
import numpy as np
import pidm
import pytest
import xarray as xr
from conftest import GRID, GRID_TOML, require


def file_maps(path: Path) -> dict[str, np.ndarray]:
    """Every dataset under /maps and /baseline of a result file, read with h5py."""
    maps = {}
    with h5py.File(path, "r") as f:
        for group, prefix in (("maps", ""), ("baseline", "baseline_")):
            for name, dataset in f.get(group, {}).items():
                maps[prefix + name] = dataset[()]
    return maps


def assert_same_maps(ds: xr.Dataset, path: Path) -> None:
    """The Dataset holds every map of the file, bit for bit, and nothing else."""
    maps = file_maps(path)
    assert sorted(ds.data_vars) == sorted(maps)
    for name, values in maps.items():
        got = ds[name].values
        assert got.dtype == values.dtype, name
        assert got.shape == values.shape, name
        # Bit for bit: the same bytes, so NaN patterns and -0.0 count too.
        assert got.tobytes() == values.tobytes(), name


def test_run_of_a_dict_equals_the_cli_file_bit_for_bit(cli_file: Path, tmp_path: Path) -> None:
    ds = pidm.run(GRID, backend="cpu", progress=False)
    assert_same_maps(ds, cli_file)
    # The same through xarray's own reading of the CLI file.
    with xr.open_dataset(cli_file, engine="h5netcdf") as ref:
        for name in ref.data_vars:
            assert ds[name].values.tobytes() == ref[name].values.tobytes(), name
            assert ds[name].dims == ref[name].dims, name
        for name in ref.coords:
            assert ds[name].values.tobytes() == ref[name].values.tobytes(), name
    # A path and TOML text give the same maps.
    scene = tmp_path / "grid.toml"
    scene.write_text(GRID_TOML)
    assert_same_maps(pidm.run(scene, backend="cpu", progress=False), cli_file)
    assert_same_maps(pidm.run(str(scene), backend="cpu", progress=False), cli_file)
    assert_same_maps(pidm.run(GRID_TOML, backend="cpu", progress=False), cli_file)


def test_the_dataset_has_the_grid_the_units_and_the_run_facts(tmp_path: Path) -> None:
    out = tmp_path / "kept.h5"
    ds = pidm.run(GRID, backend="cpu", threads=1, out=out, progress=False)
    assert ds.step_x.dims == ("axis.x.voltage", "axis.y.voltage")
    assert dict(ds.sizes) == {"axis.x.voltage": 2, "axis.y.voltage": 3}
    assert ds["axis.x.voltage"].values.tolist() == [50.0, 100.0]
    assert ds["axis.y.voltage"].values.tolist() == [0.0, 40.0, 80.0]
    for axis in ("axis.x.voltage", "axis.y.voltage"):
        assert ds[axis].attrs["units"] == "V"
    for name in ("step_x", "step_y", "baseline_step_x", "baseline_step_y"):
        assert ds[name].attrs["units"] == "m", name
        assert ds[name].attrs["long_name"], name
        assert ds[name].dims == ds.step_x.dims
    assert ds.velocity_x.attrs["units"] == "m/s"
    assert (ds.status == 0).all()
    # A fixed window decides no kind of motion.
    assert (ds.motion == 0).all()
    for key in ("scene", "name", "pidm_version", "backend", "precision", "tolerance"):
        assert key in ds.attrs, key
    assert ds.attrs["name"] == "grid"
    assert ds.attrs["precision"] == "f64"
    assert ds.attrs["backend"].startswith("cpu")
    assert ds.attrs["wall_time_s"] >= 0.0
    assert "[axis.x]" in ds.attrs["scene"]
    # A given out keeps the file; the Dataset holds no handle on it: the file
    # opens for writing and can be removed while the Dataset is still read.
    assert out.exists()
    with h5py.File(out, "r+"):
        pass
    out.unlink()
    assert float(ds.step_x.sel({"axis.x.voltage": 100.0, "axis.y.voltage": 0.0})) > 0.0
    # pidm.open reads a CLI file the same way.
    assert_same_maps(pidm.open(pidm_run_file(tmp_path)), tmp_path / "again.h5")


def pidm_run_file(tmp_path: Path) -> Path:
    out = tmp_path / "again.h5"
    pidm.run(GRID, backend="cpu", out=out, progress=False)
    return out


def test_the_backward_maps_come_back_labelled() -> None:
    scene = {
        "name": "backward",
        "axis": {"x": {"duty": [0.9, 0.98]}, "y": {"voltage": 0.0}},
        "output": {"backward": True},
    }
    ds = pidm.run(scene, progress=False)
    assert "cpu" in ds.attrs["backend"]
    for axis in ("x", "y"):
        for name, units in (
            (f"backward_{axis}", "m"),
            (f"backward_{axis}_se", "m"),
            (f"backward_ratio_{axis}", "1"),
            (f"backward_ratio_{axis}_se", "1"),
        ):
            assert ds[name].dims == ("axis.x.duty",), name
            assert ds[name].attrs["units"] == units, name
    # Table 1's slider rides the ramp back: tens of micrometres, most of its path.
    assert (ds.backward_x > 50e-6).all()
    assert (ds.backward_ratio_x > 0.9).all() and (ds.backward_ratio_x <= 1.0).all()
    assert (ds.backward_y == 0.0).all()
    with pytest.raises(pidm.PidmError, match="measured in f64 only"):
        pidm.run(scene, backend="cpu", precision="f32", progress=False)
    # The GPU measures it too (lavapipe in CI): the CPU's to 1e-6 um.
    gpu = pidm.run(scene, backend="gpu", progress=False)
    assert "gpu" in gpu.attrs["backend"]
    for axis in ("x", "y"):
        assert abs(gpu[f"backward_{axis}"] - ds[f"backward_{axis}"]).max() <= 1e-12


def test_out_none_leaves_no_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    temp = tmp_path / "tmp"
    temp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(temp))
    pidm.run(GRID, backend="cpu", progress=False)
    assert list(temp.iterdir()) == []


def test_a_bad_scene_raises_a_scene_error_naming_the_key() -> None:
    with pytest.raises(pidm.SceneError) as caught:
        pidm.run({"axis": {"x": {"voltag": 100.0}}}, progress=False)
    assert isinstance(caught.value, ValueError)
    assert "axis.x.voltag" in str(caught.value)
    assert "did you mean `voltage`" in str(caught.value)
    with pytest.raises(ValueError, match="axis.y.frequency"):
        pidm.run({"axis": {"y": {"frequency": -5.0}}}, progress=False)
    with pytest.raises(pidm.SceneError, match="axis.x.voltag"):
        pidm.check({"axis": {"x": {"voltag": 100.0}}})
    # Not TOML at all.
    with pytest.raises(pidm.SceneError):
        pidm.run("[axis.x\nvoltage = 1.0\n", progress=False)
    with pytest.raises(FileNotFoundError):
        pidm.run("no/such/scene.toml", progress=False)


def test_other_failures_raise_pidm_error_with_pidms_text(tmp_path: Path) -> None:
    # An output that is a folder: the scene is fine, the run is not.
    folder = tmp_path / "folder.h5"
    folder.mkdir()
    with pytest.raises(pidm.PidmError) as caught:
        pidm.run(GRID, backend="cpu", out=folder, progress=False)
    assert not isinstance(caught.value, pidm.SceneError)
    assert caught.value.returncode == 1
    assert str(folder) in str(caught.value)
    assert "pidm: error:" in caught.value.stderr
    # A flag pidm does not know is a usage error (exit status 2).
    with pytest.raises(pidm.PidmError) as caught:
        pidm.run(GRID, backend="cpu", progress=False, no_such_flag=True)
    assert caught.value.returncode == 2
    assert "--no-such-flag" in str(caught.value)
    with pytest.raises(ValueError, match="backend"):
        pidm.run(GRID, backend="tpu")


def test_without_a_binary_the_error_says_how_to_build_one(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("PIDM_BINARY", str(tmp_path / "missing"))
    with pytest.raises(pidm.PidmError, match="cargo build --release"):
        pidm.run(GRID)
    monkeypatch.delenv("PIDM_BINARY")
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(pidm.PidmError, match="PIDM_BINARY=target/release/pidm"):
        pidm.check(GRID)


def test_progress_records_count_up_to_the_total() -> None:
    records = []
    pidm.run(GRID, backend="cpu", progress=records.append)
    assert len(records) >= 2
    for record in records:
        assert set(record) >= {"done", "total", "elapsed_s", "eta_s", "instances_per_s"}
        assert record["total"] == 6
    assert records[0]["done"] == 0
    assert records[0]["eta_s"] is None
    assert [r["done"] for r in records] == sorted(r["done"] for r in records)
    assert records[-1]["done"] == 6
    assert records[-1]["eta_s"] == 0.0


def test_progress_shows_a_tqdm_bar(capfd: pytest.CaptureFixture[str]) -> None:
    require("tqdm")
    pidm.run(GRID, backend="cpu")
    err = capfd.readouterr().err
    assert "pidm" in err and "6/6" in err, err
    pidm.run(GRID, backend="cpu", progress=False)
    assert capfd.readouterr().err == ""


def test_check_reports_the_grid_and_the_cost() -> None:
    report = pidm.check(GRID)
    assert report["instances"] == 6
    assert report["shape"] == [2, 3]
    assert [a["key"] for a in report["axes"]] == ["axis.x.voltage", "axis.y.voltage"]
    assert report["axes"][1]["units"] == "V"
    assert report["baselines"] is True
    assert report["trajectories"] == 1
    assert report["estimate_s"] > 0.0
    assert report["simulated_s"] > 0.0


def test_open_trajectory_reads_the_stored_motion(cli_file: Path) -> None:
    t = pidm.open_trajectory(cli_file, 0)
    assert t.stage_x.dims == ("time",)
    assert t.time.attrs["units"] == "s"
    assert t.slider_x.attrs["units"] == "m"
    assert t.voltage_x.attrs["units"] == "V"
    assert t.attrs["index"] == 0
    with h5py.File(cli_file, "r") as f:
        group = f["trajectories/0"]
        for name in ("time", "stage_x", "stage_y", "slider_x", "slider_y", "voltage_x"):
            assert t[name].values.tobytes() == group[name][()].tobytes(), name
        base = f["trajectories/0/baseline_x"]
        b = pidm.open_trajectory(cli_file, 0, baseline="x")
        assert b.slider.values.tobytes() == base["slider"][()].tobytes()
        assert b.attrs["measured_cycles"] == base.attrs["measured_cycles"]
    assert pidm.trajectory_names(cli_file) == [t.attrs["point"]]
    with pytest.raises(KeyError):
        pidm.open_trajectory(cli_file, 1)


def test_a_points_scene_has_labels() -> None:
    scene = {
        "simulation": {"measure": "window", "cycles": 3, "settle": 1},
        "points": [
            {"label": "slow", "axis": {"x": {"voltage": 60.0}}},
            {"label": "fast", "axis.x.voltage": 120.0, "axis.y.voltage": 50.0},
        ],
    }
    ds = pidm.run(scene, backend="cpu", progress=False)
    assert ds.step_x.dims == ("point",)
    assert ds.label.values.tolist() == ["slow", "fast"]
    assert ds.attrs["name"] == "scene"


def test_dict_scenes_keep_their_key_order_and_numpy_values() -> None:
    scene = {
        "axis": {
            "y": {"voltage": np.array([0.0, 60.0])},
            "x": {"voltage": np.linspace(40.0, 120.0, 3)},
        },
        "simulation": {"measure": "window", "cycles": np.int64(3), "settle": 1},
    }
    ds = pidm.run(scene, backend="cpu", progress=False)
    # axis.y first: the grid's axes follow the dict's order.
    assert ds.step_x.dims == ("axis.y.voltage", "axis.x.voltage")
    assert ds["axis.x.voltage"].values.tolist() == [40.0, 80.0, 120.0]
    text = pidm.scene_toml({"a": {"b": 0.1 + 0.2, "c": 'q"\n'}})
    assert "b = 0.30000000000000004" in text
    assert 'c = "q\\"\\n"' in text


def test_tied_keys_and_a_frequency_ratio_make_a_map_over_the_ratio() -> None:
    scene = {
        "axis": {
            "x": {"voltage": [60.0, 120.0]},
            "y": {
                "voltage": {"same_as": "axis.x.voltage"},
                "frequency_ratio": {"from": 1.0, "to": 2.0, "steps": 3},
            },
        },
        "simulation": {"measure": "window", "cycles": 4, "settle": 1},
    }
    ds = pidm.run(scene, backend="cpu", progress=False)
    assert ds.step_x.dims == ("axis.x.voltage", "axis.y.frequency_ratio")
    assert ds["axis.y.frequency_ratio"].values.tolist() == [1.0, 1.5, 2.0]
    assert ds["axis.y.frequency_ratio"].attrs["units"] == "1"
    # At a ratio of 1 the two axes are the same drive: equal steps.
    same = ds.sel({"axis.y.frequency_ratio": 1.0})
    assert same.step_x.values.tolist() == same.step_y.values.tolist()
    assert (same.step_y != 0).all()
    with pytest.raises(pidm.SceneError, match="axis.x.frequency_ratio"):
        pidm.run({"axis": {"x": {"frequency_ratio": 2.0}}}, backend="cpu", progress=False)


def test_failed_instances_warn_and_keep_their_status() -> None:
    # A step budget far too small: every instance ends with status 1.
    scene = {
        "simulation": {"measure": "window", "cycles": 3, "settle": 1, "max_steps_per_period": 2}
    }
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        ds = pidm.run(scene, backend="cpu", progress=False)
    assert any(issubclass(w.category, pidm.RunWarning) for w in seen)
    assert int(ds.status) == 1


def test_a_binary_of_another_version_is_refused(tmp_path: Path, monkeypatch) -> None:
    """A pidm binary whose --version is not the package's is refused, naming both."""
    fake = tmp_path / "pidm"
    fake.write_text("#!/bin/sh\necho 'pidm 9.9.9'\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PIDM_BINARY", str(fake))
    with pytest.raises(pidm.PidmError) as refused:
        pidm.run({"name": "v"}, backend="cpu", progress=False)
    said = str(refused.value)
    assert "9.9.9" in said and pidm.__version__ in said, said


def test_a_refined_map_reads_like_a_uniform_one_with_its_inferred_mask(tmp_path: Path) -> None:
    scene = {
        "name": "refined",
        "axis": {
            "x": {"voltage": {"from": -150.0, "to": 150.0, "steps": 9}},
            "y": {"voltage": {"from": -150.0, "to": 150.0, "steps": 9}},
        },
        "simulation": {"measure": "window", "cycles": 3, "settle": 1},
        "refine": {"levels": 2},
    }
    out = tmp_path / "refined.h5"
    ds = pidm.run(scene, backend="cpu", out=out, progress=False)
    assert dict(ds.sizes) == {"axis.x.voltage": 33, "axis.y.voltage": 33}
    assert ds.inferred.dtype == np.uint8
    assert ds.inferred.dims == ds.step_x.dims
    with h5py.File(out, "r") as f:
        index = f["refine/index"][()]
    # The integrated points are those the mask leaves at 0.
    assert np.array_equal(np.flatnonzero(ds.inferred.values.ravel() == 0), index)
    assert 81 <= index.size < 33 * 33
    assert_same_maps(pidm.open(out), out)


def test_a_steady_map_has_its_kinds_of_motion_with_their_flags(tmp_path: Path) -> None:
    # 10 Hz against 14 Hz repeats (lag 5); against 10 sqrt(3) Hz the
    # phase-resolved estimate converges (quasi-periodic).
    scene = {
        "name": "kinds",
        "axis": {
            "x": {"voltage": [60.0, 100.0], "frequency": 10.0},
            "y": {"voltage": 100.0, "frequency": [14.0, 10.0 * 3.0**0.5]},
        },
        "simulation": {"step_tolerance": 3e-8, "max_cycles": 5000},
    }
    out = tmp_path / "kinds.h5"
    ds = pidm.run(scene, backend="cpu", out=out, progress=False)
    motion = ds.motion
    assert motion.dtype == np.uint8
    assert motion.dims == ds.step_x.dims
    assert motion.attrs["units"] == "1"
    assert "kind of motion" in motion.attrs["long_name"]
    flag_values = motion.attrs["flag_values"]
    assert isinstance(flag_values, np.ndarray) and flag_values.dtype == np.uint8
    assert flag_values.tolist() == [0, 1, 2, 3, 4]
    assert motion.attrs["flag_meanings"] == (
        "undetermined periodic quasi_periodic irregular multistable"
    )
    codes = dict(zip(motion.attrs["flag_meanings"].split(), flag_values.tolist(), strict=True))
    assert motion.values.tolist() == [[codes["periodic"], codes["quasi_periodic"]]] * 2
    # The periodic instances are those with a lag.
    assert ((motion == codes["periodic"]) == (ds.period_lag > 0)).all()
    # pidm.open and xarray's own reading agree, attributes included.
    assert_same_maps(pidm.open(out), out)
    with xr.open_dataset(out, engine="h5netcdf") as ref:
        assert ref.motion.dtype == np.uint8
        assert ref.motion.values.tobytes() == motion.values.tobytes()
        assert ref.motion.attrs["flag_meanings"] == motion.attrs["flag_meanings"]
        assert ref.motion.attrs["flag_values"].tolist() == [0, 1, 2, 3, 4]


def test_a_stall_map_reads_with_its_units_and_the_grid(tmp_path: Path) -> None:
    # docs/model.md section 7: Table 1 at 10 Hz, 100 V on x, stalls at -0.0379 N
    # with y at 0 V and at +0.0792 N with y at 100 V (an independent
    # reference); f_c = 0.2 N never stalls (stall status 8, map 0).
    scene = {
        "name": "stall",
        "mechanism": {"coulomb_friction": [0.2, 1.0]},
        "axis": {"y": {"voltage": [0.0, 100.0]}},
        "simulation": {"measure": "window"},
        "stall": {"axis": "x"},
    }
    out = tmp_path / "stall.h5"
    ds = pidm.run(scene, backend="cpu", out=out, progress=False)
    load = ds.stall_load_x
    assert load.dims == ds.step_x.dims == ("mechanism.coulomb_friction", "axis.y.voltage")
    assert load.attrs["units"] == "N"
    assert "zero crossing nearest zero load" in load.attrs["long_name"]
    assert ds.stall_status_x.dtype == np.uint32
    found = load.sel({"mechanism.coulomb_friction": 1.0}).values
    assert np.allclose(found, [-0.0379, 0.0792], atol=1.5e-4)
    assert ds.stall_status_x.sel({"mechanism.coulomb_friction": 1.0}).values.tolist() == [0, 0]
    weak = ds.sel({"mechanism.coulomb_friction": 0.2})
    assert (weak.stall_status_x.values == 8).any()
    assert (weak.stall_load_x.values[weak.stall_status_x.values == 8] == 0.0).all()
    for name in ("stall_step_near_x", "stall_step_far_x", "stall_waves_x"):
        assert ds[name].dims == load.dims, name
    assert_same_maps(pidm.open(out), out)


def test_a_lugre_map_says_which_friction_ran(tmp_path: Path) -> None:
    # docs/model.md section 8: LuGre at its defaults, 1-DOF 100 V at 10 Hz over
    # the paper's window, +1.285861 um; a map over the bristle stiffness
    # whose attributes name the law and instance 0's values.
    scene = {
        "name": "lugre",
        "mechanism": {"friction": "lugre", "bristle_stiffness": [1e7, 1e9]},
        "axis": {"y": {"voltage": 0.0}},
        "simulation": {"measure": "window"},
    }
    out = tmp_path / "lugre.h5"
    ds = pidm.run(scene, backend="cpu", out=out, progress=False)
    assert ds.attrs["friction"] == "lugre"
    assert "bristle_stiffness 10000000 N/m" in ds.attrs["friction_parameters"]
    assert "derived" in ds.attrs["friction_parameters"]
    assert ds.step_x.dims == ("mechanism.bristle_stiffness",)
    assert ds["mechanism.bristle_stiffness"].attrs["units"] == "N/m"
    step = ds.step_x.sel({"mechanism.bristle_stiffness": 1e7}).item() * 1e6
    assert abs(step - 1.285861) <= 1e-4
    assert pidm.open(out).attrs["friction"] == "lugre"
    karnopp = pidm.run({"axis": {"y": {"voltage": 0.0}}}, backend="cpu", progress=False)
    assert karnopp.attrs["friction"] == "karnopp"
    assert "friction_parameters" not in karnopp.attrs


def test_a_key_of_the_other_friction_law_is_refused() -> None:
    with pytest.raises(pidm.SceneError, match="mechanism.velocity_band applies to"):
        pidm.run(
            {"mechanism": {"friction": "lugre", "velocity_band": 1e-6}},
            backend="cpu",
            progress=False,
        )
