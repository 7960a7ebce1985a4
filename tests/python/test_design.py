"""pidm.sensitivity on a 1-DOF scene (x driven at 100 V, 10 Hz, y undriven) measured
over a window of 3 cycles after 1 to settle, so a study of a few hundred runs takes
milliseconds: its Sobol' indices against SALib's on the same runs, the scenes it
refuses, and the seed's determinism."""

from __future__ import annotations

import copy
import csv
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pidm
import pytest
from conftest import require

#: The study's inputs: one of each distribution, none of them cut by its key's range.
INPUTS = {
    "mechanism.static_friction": {"uniform": [1.08, 1.32]},
    "axis.x.stiffness": {"normal": {"mean": 1.0e6, "sd": 5.0e4}},
    "mechanism.slider_mass": {"lognormal": {"median": 5e-3, "factor": 1.05}},
}
KEYS = list(INPUTS)
SAMPLES = 32
SCENE = {
    "name": "sobol",
    "axis": {"y": {"voltage": 0}},
    "simulation": {"measure": "window", "cycles": 3, "settle": 1},
    "sensitivity": {"samples": SAMPLES, "outputs": ["step_x"], "inputs": INPUTS},
}
#: The same scene as a hand-written TOML file.
SCENE_TOML = """\
name = "sobol"
[axis.y]
voltage = 0
[simulation]
measure = "window"
cycles = 3
settle = 1
[sensitivity]
samples = 32
outputs = ["step_x"]
[sensitivity.inputs]
"mechanism.static_friction" = { uniform = [1.08, 1.32] }
"axis.x.stiffness" = { normal = { mean = 1.0e6, sd = 5.0e4 } }
"mechanism.slider_mass" = { lognormal = { median = 5e-3, factor = 1.05 } }
"""


def read_csv(path: Path) -> pd.DataFrame:
    """The samples' CSV as Python's csv module and float() read it: the values bit
    for bit, whatever pandas' own parser does."""
    with path.open(newline="") as file:
        header, *rows = list(csv.reader(file))
    columns = {name: [row[j] for row in rows] for j, name in enumerate(header)}
    return pd.DataFrame(
        {
            name: values
            if name == "matrix"
            else [int(v) for v in values]
            if name in ("row", "status")
            else [float(v) for v in values]
            for name, values in columns.items()
        }
    )


@pytest.fixture(autouse=True)
def _binary(binary: str) -> None:
    """Every test here runs the binary of PIDM_BINARY."""


def test_the_indices_are_salibs_on_the_same_runs(tmp_path: Path) -> None:
    sobol = require("SALib.analyze.sobol")
    samples_csv = tmp_path / "samples.csv"
    records: list[dict] = []
    result = pidm.sensitivity(
        SCENE,
        out=tmp_path / "sens.json",
        samples_out=samples_csv,
        backend="cpu",
        progress=records.append,
    )
    k = len(KEYS)
    runs = SAMPLES * (k + 2)
    raw = result.json
    assert raw["samples"] == SAMPLES and raw["runs"] == runs
    assert raw["runs_failed"] == 0 and raw["rows_dropped"] == 0 and raw["rows_used"] == SAMPLES
    assert [i["key"] for i in raw["inputs"]] == KEYS == result.keys
    assert result.quantities == ["step_x"]
    assert result.units == {
        "mechanism.static_friction": "N",
        "axis.x.stiffness": "N/m",
        "mechanism.slider_mass": "kg",
        "step_x": "m",
    }
    assert result.warnings == []
    assert result.json_path == tmp_path / "sens.json" and result.json_path.is_file()
    assert result.png_path == tmp_path / "sens.png" and result.png_path.is_file()
    assert result.samples_path == samples_csv
    assert records and records[-1]["done"] == records[-1]["total"] == runs

    # The CSV in SALib's row order: per base row A, AB_1 ... AB_k, B, where AB_i
    # is A with column i from B.
    frame = read_csv(samples_csv)
    assert list(frame.columns) == ["row", "matrix", *KEYS, "status", "step_x", "step_x_se"]
    assert len(frame) == runs
    matrices = ["A", *(f"AB_{i}" for i in range(1, k + 1)), "B"]
    assert frame["matrix"].tolist() == matrices * SAMPLES
    assert frame["row"].tolist() == [r for r in range(SAMPLES) for _ in matrices]
    values = frame[KEYS].to_numpy().reshape(SAMPLES, k + 2, k)
    a, b = values[:, 0], values[:, -1]
    for i in range(k):
        expected = a.copy()
        expected[:, i] = b[:, i]
        assert np.array_equal(values[:, 1 + i], expected), KEYS[i]
    assert (frame["status"] == 0).all()
    assert frame["step_x"].std() > 0.0
    assert list(result.samples.columns) == list(frame.columns)
    for column in frame.columns:
        assert result.samples[column].tolist() == frame[column].tolist(), column

    # SALib's estimators on the same outputs give the same indices.
    problem = {"num_vars": k, "names": KEYS, "bounds": [[0.0, 1.0]] * k}
    salib = sobol.analyze(problem, frame["step_x"].to_numpy(), calc_second_order=False, seed=7)
    ours = result.json["outputs"][0]
    for i, key in enumerate(KEYS):
        assert abs(salib["S1"][i] - ours["first"][i]) <= 1e-9, key
        assert abs(salib["ST"][i] - ours["total"][i]) <= 1e-9, key
        row = result.indices.loc[("step_x", key)]
        assert row["S1"] == ours["first"][i] and row["ST"] == ours["total"][i]
        assert row["S1_conf"] == ours["first_conf"][i] and row["ST_conf"] == ours["total_conf"][i]
        assert row["S1_conf"] > 0.0 and row["ST_conf"] > 0.0
    assert list(result.indices.columns) == ["S1", "S1_conf", "ST", "ST_conf"]
    assert result.indices.index.names == ["quantity", "key"]
    assert result.indices.index.get_level_values("key").tolist() == KEYS
    # The same as labelled arrays, in the inputs' order, with units.
    ds = result.to_xarray()
    assert ds["key"].values.tolist() == KEYS and ds["quantity_units"].values.tolist() == ["m"]
    assert ds["ST"].sel(quantity="step_x").values.tolist() == ours["total"]
    assert ds["S1"].attrs["units"] == "1"
    assert float(ds["mean"].sel(quantity="step_x")) == result.spread.loc["step_x", "mean"]

    # The spread is over the A and B rows: 2 N independent units.
    units = frame[frame["matrix"].isin(["A", "B"])]["step_x"].to_numpy()
    spread = result.spread.loc["step_x"]
    assert list(result.spread.columns) == ["mean", "sd", "q5", "q50", "q95", "noise"]
    assert spread["mean"] == pytest.approx(units.mean(), rel=1e-12, abs=1e-20)
    assert spread["sd"] == pytest.approx(units.std(ddof=1), rel=1e-12)
    assert spread["q5"] == pytest.approx(np.quantile(units, 0.05), rel=1e-12, abs=1e-20)
    assert spread["q50"] == pytest.approx(np.quantile(units, 0.5), rel=1e-12, abs=1e-20)
    assert spread["q95"] == pytest.approx(np.quantile(units, 0.95), rel=1e-12, abs=1e-20)
    assert spread["noise"] >= 0.0
    assert "step_x" in str(result) and all(key in str(result) for key in KEYS)


def refused(change: str) -> dict:
    """SCENE with one change that pidm refuses."""
    scene = copy.deepcopy(SCENE)
    section = scene["sensitivity"]
    if change == "samples":
        section["samples"] = 1
    elif change == "integer key":
        section["inputs"]["simulation.cycles"] = {"uniform": [2, 4]}
    elif change == "no such output":
        section["outputs"] = ["step_z"]
    elif change == "backward off":
        section["outputs"] = ["step_x", "backward_ratio_x"]
    return scene


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ("samples", "sensitivity.samples"),
        ("integer key", "simulation.cycles"),
        ("no such output", "step_z"),
        ("backward off", "backward_ratio_x"),
    ],
)
def test_a_refused_scene_raises_a_scene_error_naming_the_key(
    change: str, named: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    temp = tmp_path / "tmp"
    temp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(temp))
    out = tmp_path / "sens.json"
    samples_csv = tmp_path / "samples.csv"
    with pytest.raises(pidm.SceneError, match=named.replace(".", r"\.")) as caught:
        pidm.sensitivity(
            refused(change), out=out, samples_out=samples_csv, backend="cpu", progress=False
        )
    assert isinstance(caught.value, ValueError)
    assert caught.value.returncode == 1
    if change == "backward off":
        assert "[output] backward = true" in str(caught.value)
    # Nothing is written, and the temporary folder is gone.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tmp"]
    assert list(temp.iterdir()) == []


def test_the_same_seed_gives_the_same_study(tmp_path: Path) -> None:
    scene = tmp_path / "sobol.toml"
    scene.write_text(SCENE_TOML)
    studies = {}
    for name, seed in (("first", 5), ("again", 5), ("other", 6)):
        studies[name] = pidm.sensitivity(
            scene,
            out=tmp_path / f"{name}.json",
            samples_out=tmp_path / f"{name}.csv",
            seed=seed,
            backend="cpu",
            progress=False,
        )

    def without_time(name: str) -> dict:
        raw = json.loads((tmp_path / f"{name}.json").read_text())
        assert isinstance(raw.pop("wall_time_s"), float)
        return raw

    first, again, other = (without_time(n) for n in ("first", "again", "other"))
    assert first == again
    assert first["seed"] == 5 and other["seed"] == 6
    assert (tmp_path / "first.csv").read_bytes() == (tmp_path / "again.csv").read_bytes()
    pd.testing.assert_frame_equal(studies["first"].indices, studies["again"].indices)
    # Another seed draws another sample: other indices.
    for column in ("S1", "ST"):
        ours, theirs = studies["first"].indices[column], studies["other"].indices[column]
        assert all(math.isfinite(v) for v in [*ours, *theirs])
        assert not np.allclose(ours.to_numpy(), theirs.to_numpy(), rtol=1e-6, atol=0.0)
    # A dict of the same scene gives the same indices as its file.
    from_dict = pidm.sensitivity(SCENE, seed=5, backend="cpu", progress=False)
    pd.testing.assert_frame_equal(from_dict.indices, studies["first"].indices)
    assert from_dict.json_path is None and from_dict.png_path is None
    assert from_dict.samples is None


# pidm.optimize on a 1-DOF scene (x driven, y undriven): its steady runs take
# about a millisecond each, so a search of a few hundred runs takes milliseconds.

#: The free keys: the drive's voltage [V] and frequency [Hz], in this order.
FREE = {"axis.x.voltage": [50.0, 150.0], "axis.x.frequency": [5.0, 40.0]}
OPT_BUDGET = 420
OPT_SCENE = {
    "axis": {"y": {"voltage": 0}},
    "output": {"backward": True},
    "optimize": {
        "maximize": "velocity_x",
        "free": FREE,
        "subject_to": ["backward_ratio_x <= 0.8"],
        "budget": OPT_BUDGET,
    },
}
#: The same scene as a hand-written TOML file.
OPT_TOML = """\
[axis.y]
voltage = 0
[output]
backward = true
[optimize]
maximize = "velocity_x"
free = { "axis.x.voltage" = [50, 150], "axis.x.frequency" = [5, 40] }
subject_to = ["backward_ratio_x <= 0.8"]
budget = 420
"""


def front_scene(budget: int = OPT_BUDGET) -> dict:
    """OPT_SCENE as a front: velocity_x up against backward_ratio_x down, no
    constraint."""
    scene = copy.deepcopy(OPT_SCENE)
    section = scene["optimize"]
    del section["subject_to"]
    section["minimize"] = "backward_ratio_x"
    section["budget"] = budget
    return scene


def test_the_optimum_keeps_its_constraint_and_runs_again(tmp_path: Path) -> None:
    records: list[dict] = []
    out = tmp_path / "opt.json"
    result = pidm.optimize(OPT_SCENE, out=out, backend="cpu", progress=records.append)
    assert result.status.startswith("ok"), result.status
    assert result.on_cliff == (result.status == "ok, on a cliff")
    assert result.keys == list(FREE) == list(result.values)
    for key, (lo, hi) in FREE.items():
        assert lo <= result.values[key] <= hi, key
    assert 0 < result.runs <= OPT_BUDGET
    assert result.runs == result.json["runs"] and result.json["budget"] == OPT_BUDGET
    assert result.units == {"axis.x.voltage": "V", "axis.x.frequency": "Hz", "velocity_x": "m/s"}
    assert result.front is None and result.json["front"] is None
    assert result.json_path == out and out.is_file()
    assert result.toml_path == tmp_path / "opt.toml" and result.toml_path.is_file()
    assert result.png_path == tmp_path / "opt.png" and result.png_path.is_file()
    assert result.scene_text == result.toml_path.read_text()
    # The first record counts against the budget, the last the runs made.
    assert records[0]["total"] == OPT_BUDGET
    assert records[-1]["done"] == records[-1]["total"] == result.runs <= OPT_BUDGET

    # The constraint is kept, with its slack in the ratio's units (1).
    assert list(result.constraints.index) == ["backward_ratio_x <= 0.8"]
    constraint = result.constraints.loc["backward_ratio_x <= 0.8"]
    assert bool(constraint["kept"]) and constraint["slack"] >= 0.0
    assert list(result.constraints.columns) == [
        "kept",
        "slack",
        "slack_se",
        "margin_se",
        "margin",
        "margin_note",
    ]

    # The objective at the optimum is the best of the search's progress.
    value, se = result.objective
    assert value == result.json["optimum"]["objectives"][0]["value"] and se >= 0.0
    assert list(result.progress.columns) == ["runs", "best"]
    runs = result.progress["runs"].to_numpy()
    best = result.progress["best"].dropna().to_numpy()
    assert (np.diff(runs) > 0).all() and runs[-1] <= result.runs
    assert (np.diff(best) >= 0.0).all() and best[-1] == value
    text = str(result)
    assert text.startswith(f"status: {result.status}") and "axis.x.voltage" in text
    assert repr(result).startswith("<pidm.OptimizeResult")

    # OPT.toml is the scene at the optimum: running it measures the optimum again.
    voltage = result.values["axis.x.voltage"]
    assert f"voltage = {voltage!r}" in result.scene_text
    assert "[optimize]" not in result.scene_text
    for scene in (result.toml_path, result.scene_text):
        ds = pidm.run(scene, backend="cpu", progress=False)
        assert float(ds["velocity_x"]) == pytest.approx(value, rel=1e-12, abs=0.0)
        assert float(ds["backward_ratio_x"]) <= 0.8
        assert int(ds["status"]) == 0


def dominates(a: pd.Series, b: pd.Series, senses: dict[str, str]) -> bool:
    """Whether point a dominates point b: no worse in every objective, better in one."""
    better = {
        q: (a[q] > b[q]) if sense == "maximize" else (a[q] < b[q]) for q, sense in senses.items()
    }
    worse = {
        q: (a[q] < b[q]) if sense == "maximize" else (a[q] > b[q]) for q, sense in senses.items()
    }
    return not any(worse.values()) and any(better.values())


def test_a_front_is_its_non_dominated_points(tmp_path: Path) -> None:
    result = pidm.optimize(front_scene(), backend="cpu", progress=False)
    front = result.front
    assert isinstance(front, pd.DataFrame) and len(front) >= 5
    assert list(front.columns) == [
        *FREE,
        "velocity_x",
        "velocity_x_se",
        "backward_ratio_x",
        "backward_ratio_x_se",
        "status",
        "motion",
    ]
    assert len(front) == len(result.json["front"])
    assert (front["status"] == 0).all()
    for key, (lo, hi) in FREE.items():
        assert front[key].between(lo, hi).all(), key
    # Ordered by the second objective.
    assert front["backward_ratio_x"].is_monotonic_increasing
    senses = {"velocity_x": "maximize", "backward_ratio_x": "minimize"}
    rows = [row for _, row in front.iterrows()]
    for i, a in enumerate(rows):
        for j, b in enumerate(rows):
            assert i == j or not dominates(a, b, senses), (i, j)
    # A front has an optimum (the best first objective) but no constraints.
    assert result.constraints.empty and result.status.startswith("ok")
    assert result.objective[0] == front["velocity_x"].max()
    assert result.json_path is None and result.toml_path is None and result.png_path is None
    assert result.scene_text is not None and "[optimize]" not in result.scene_text
    # The front as labelled arrays over `point`, with units.
    ds = result.to_xarray()
    assert ds.sizes == {"point": len(front)}
    assert (ds["velocity_x"].values == front["velocity_x"].to_numpy()).all()
    assert ds["velocity_x"].attrs["units"] == "m/s" and ds["axis.x.voltage"].attrs["units"] == "V"
    assert "front: " in str(result)


def refused_search(change: str) -> dict:
    """OPT_SCENE with one change that pidm refuses."""
    scene = copy.deepcopy(OPT_SCENE)
    section = scene["optimize"]
    if change == "unknown quantity":
        section["maximize"] = "step_w"
    elif change == "bound outside the range":
        section["free"] = {"axis.x.voltage": [50, 150], "axis.x.duty": [0.5, 1.5]}
    elif change == "backward objective off":
        del scene["output"]
        del section["subject_to"]
        section["maximize"] = "backward_x"
    elif change == "backward constraint off":
        del scene["output"]
        section["subject_to"] = ["backward_x <= 1e-6"]
    return scene


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ("unknown quantity", r"`step_w` is no quantity"),
        ("bound outside the range", r"axis\.x\.duty.*1\.5 is outside the key's range"),
        ("backward objective off", r"backward_x.*\[output\] backward = true"),
        ("backward constraint off", r"backward_x.*\[output\] backward = true"),
    ],
)
def test_a_refused_search_raises_a_scene_error_naming_the_problem(
    change: str, named: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    temp = tmp_path / "tmp"
    temp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(temp))
    with pytest.raises(pidm.SceneError, match=named) as caught:
        pidm.optimize(
            refused_search(change), out=tmp_path / "opt.json", backend="cpu", progress=False
        )
    assert isinstance(caught.value, ValueError)
    assert caught.value.returncode == 1
    assert str(caught.value).startswith("scene ")
    # No OPT files, and the temporary folder is gone.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tmp"]
    assert list(temp.iterdir()) == []


def test_an_infeasible_search_warns_and_gives_the_least_violation() -> None:
    scene = copy.deepcopy(OPT_SCENE)
    scene["optimize"].update(subject_to=["step_x >= 1"], budget=150)
    scene["optimize"]["free"] = {"axis.x.voltage": [50.0, 150.0]}
    with pytest.warns(pidm.OptimizeWarning, match="infeasible"):
        result = pidm.optimize(scene, backend="cpu", progress=False)
    assert result.status.startswith("infeasible: ")
    assert not result.constraints.loc["step_x >= 1", "kept"]
    assert result.constraints.loc["step_x >= 1", "slack"] < 0.0
    assert 50.0 <= result.values["axis.x.voltage"] <= 150.0


def test_the_same_seed_gives_the_same_search(tmp_path: Path) -> None:
    scene = tmp_path / "opt.toml"
    scene.write_text(OPT_TOML)
    for name, seed in (("first", 5), ("again", 5), ("other", 6)):
        pidm.optimize(
            scene, out=tmp_path / f"{name}.json", seed=seed, backend="cpu", progress=False
        )

    def without_time(name: str) -> dict:
        raw = json.loads((tmp_path / f"{name}.json").read_text())
        assert isinstance(raw.pop("wall_time_s"), float)
        return raw

    first, again, other = (without_time(n) for n in ("first", "again", "other"))
    assert first == again
    assert (tmp_path / "first.toml").read_bytes() == (tmp_path / "again.toml").read_bytes()
    assert first["seed"] == 5 and other["seed"] == 6
    # Another seed searches other candidates.
    assert first["progress"] != other["progress"]
    assert first["optimum"]["values"] != other["optimum"]["values"]
    # The same scene as a dict searches the same candidates (its file is another).
    from_dict = pidm.optimize(OPT_SCENE, seed=5, backend="cpu", progress=False).json
    from_dict.pop("wall_time_s")
    assert from_dict.pop("scene") != first.pop("scene")
    assert from_dict == first


def test_a_dict_keeps_its_free_keys_order() -> None:
    # Written as dotted keys, TOML would group these by table (axis first).
    free = {
        "mechanism.static_friction": [1.0, 1.4],
        "axis.x.voltage": [50.0, 150.0],
        "mechanism.slider_mass": [4e-3, 6e-3],
    }
    scene = copy.deepcopy(OPT_SCENE)
    scene["optimize"].update(free=free, budget=180)
    del scene["optimize"]["subject_to"]
    result = pidm.optimize(scene, backend="cpu", progress=False)
    assert result.keys == list(free) == list(result.values)
    assert [f["units"] for f in result.json["free"]] == ["N", "V", "kg"]
