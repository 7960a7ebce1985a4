"""pidm.fit against the shipped example fits: examples/fit/coupling.toml (both
axes driven, 12 rows: static 1.2 N, Coulomb 1.0 N, y gain -0.45 N/V) for the
recoveries, which the integration tests also run at full size for the Karnopp
set, and examples/fit/karnopp.toml (static 1.2 N, Coulomb 1.0 N, gain -0.6 N/V)
for the rest; synthetic steps with 2 % noise."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pidm
import pytest
from conftest import ROOT, child_env, interrupt_when_running, require

SCENE = ROOT / "examples" / "fit" / "karnopp.toml"
STEPS = ROOT / "examples" / "fit" / "karnopp_steps.csv"
TRUTH = {
    "mechanism.static_friction": 1.2,
    "mechanism.coulomb_friction": 1.0,
    "axis.x.gain": -0.6,
}
FREE = {
    "mechanism.static_friction": [0.5, 3.0],
    "mechanism.coulomb_friction": [0.3, 2.0],
    "axis.x.gain": [-1.0, -0.2],
}
#: The example scene as text, its [fit] without `data`.
TEXT = SCENE.read_text().replace('data = "karnopp_steps.csv"\n', "")
#: The coupling example: a fit of both axes' steps.
COUPLING = ROOT / "examples" / "fit" / "coupling.toml"
COUPLING_STEPS = ROOT / "examples" / "fit" / "coupling_steps.csv"
COUPLING_TRUTH = {
    "mechanism.static_friction": 1.2,
    "mechanism.coulomb_friction": 1.0,
    "axis.y.gain": -0.45,
}
COUPLING_TEXT = COUPLING.read_text().replace('data = "coupling_steps.csv"\n', "")


def assert_recovers_the_truth(fit: pidm.FitResult, truths: dict[str, float]) -> None:
    assert fit.keys == list(truths)
    assert fit.status == "converged"
    assert fit.identifiable
    for key, truth in truths.items():
        assert abs(fit.values[key] - truth) < 3.0 * fit.se[key], (key, fit.values[key], fit.se[key])
        assert 0.0 < fit.se[key] < 0.1 * abs(fit.values[key]), key
    corr = fit.correlation
    assert corr.dims == ("key", "other_key")
    assert corr["key"].values.tolist() == fit.keys
    assert corr["other_key"].values.tolist() == fit.keys
    assert np.allclose(corr.values, corr.values.T)
    assert np.allclose(np.diag(corr.values), 1.0)
    assert "static_friction" in fit.scene
    assert "[fit]" not in fit.scene


def test_a_fit_of_the_example_file_recovers_the_truth(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    temp = tmp_path / "tmp"
    temp.mkdir()
    monkeypatch.setattr("tempfile.tempdir", str(temp))
    fit = pidm.fit(COUPLING, backend="cpu", progress=False)
    assert_recovers_the_truth(fit, COUPLING_TRUTH)
    assert fit.values.name == "value" and fit.se.name == "se"
    assert fit.bounds == {
        "mechanism.static_friction": (0.5, 3.0),
        "mechanism.coulomb_friction": (0.3, 2.0),
        "axis.y.gain": (-1.0, -0.2),
    }
    assert fit.units == {
        "mechanism.static_friction": "N",
        "mechanism.coulomb_friction": "N",
        "axis.y.gain": "N/V",
    }
    assert fit.dof == 24 - 3
    assert fit.chi2 == pytest.approx(fit.reduced_chi2 * fit.dof)
    assert fit.evaluations > 0
    assert fit.json["order"] == fit.keys
    # Every data row, with the model's step beside the measured one.
    assert len(fit.rows) == 12
    assert fit.rows["line"].tolist() == list(range(2, 14))
    measured = pd.read_csv(COUPLING_STEPS)
    for axis in "xy":
        assert np.array_equal(fit.rows[f"step_{axis}"].values, measured[f"step_{axis}"].values)
        assert fit.rows[f"model_step_{axis}"].notna().all()
    # The table names every key with its value; nothing is left behind.
    text = str(fit)
    assert text.splitlines()[0].split() == ["key", "value", "se", "se", "%", "units"]
    assert all(key in text for key in COUPLING_TRUTH)
    assert fit.path is None
    assert list(temp.iterdir()) == []


def test_a_text_scene_with_a_dataframe_and_progress_records() -> None:
    steps = pd.read_csv(COUPLING_STEPS)
    # Three rows without step y: NaN in the frame, written as empty cells.
    steps.loc[steps.index[::4], ["step_y", "step_y_se"]] = np.nan
    records: list[dict] = []
    fit = pidm.fit(COUPLING_TEXT, steps, backend="cpu", progress=records.append)
    assert_recovers_the_truth(fit, COUPLING_TRUTH)
    assert len(fit.rows) == 12
    assert fit.rows["step_y"].isna().sum() == 3
    assert fit.dof == 24 - 3 - 3
    assert records, "no progress records"
    assert {r["stage"] for r in records} <= {"global", "local", "errors", "intervals"}
    assert records[0]["stage"] == "global"
    evaluations = [r["evaluations"] for r in records]
    assert evaluations == sorted(evaluations)
    assert evaluations[-1] == fit.evaluations
    # Without data, relative `data` in text has no folder to resolve against.
    with pytest.raises(ValueError, match="data="):
        pidm.fit(TEXT, backend="cpu", progress=False)
    with pytest.raises(ValueError, match="relative"):
        pidm.fit(TEXT.replace("[fit]\n", '[fit]\ndata = "steps.csv"\n'), progress=False)


def test_a_bad_dataframe_raises_a_scene_error_naming_the_column() -> None:
    steps = pd.read_csv(STEPS).rename(columns={"axis.x.voltage": "axis.x.volts"})
    with pytest.raises(pidm.SceneError) as caught:
        pidm.fit(TEXT, steps, backend="cpu", progress=False)
    assert isinstance(caught.value, ValueError)
    assert caught.value.returncode == 1
    assert "axis.x.volts" in str(caught.value)
    # A free key that is no scene key: pidm's message names it.
    bad = TEXT.replace("mechanism.static_friction", "mechanism.static_frictio")
    with pytest.raises(pidm.SceneError, match="mechanism.static_frictio"):
        pidm.fit(bad, STEPS, backend="cpu", progress=False)
    # NaN in a key column (an empty cell in the CSV written) is refused, not
    # the scene's value: pidm's message names the line and the column.
    steps = pd.read_csv(STEPS)
    steps.loc[steps.index[3], "axis.x.voltage"] = np.nan
    with pytest.raises(pidm.SceneError, match=r"line 5, column axis\.x\.voltage: empty"):
        pidm.fit(TEXT, steps, backend="cpu", progress=False)
    with pytest.raises(FileNotFoundError):
        pidm.fit(SCENE, STEPS.with_name("missing.csv"), progress=False)
    with pytest.raises(ValueError, match=".json"):
        pidm.fit(SCENE, out="fit.toml", progress=False)


def test_out_keeps_the_json_the_toml_and_the_png(tmp_path: Path) -> None:
    # A dict scene and a CSV path; 10 rows at 10 Hz fit in well under a second.
    data = tmp_path / "steps.csv"
    pd.read_csv(STEPS).iloc[::3].to_csv(data, index=False)
    out = tmp_path / "kept" / "karnopp.json"
    scene = {"name": "karnopp_dict", "fit": {"free": FREE}}
    fit = pidm.fit(scene, data, out=out, backend="cpu", seed=2, progress=False)
    assert fit.path == out
    for suffix in (".json", ".toml", ".png"):
        assert out.with_suffix(suffix).stat().st_size > 0, suffix
    assert json.loads(out.read_text()) == fit.json
    assert out.with_suffix(".toml").read_text() == fit.scene
    assert fit.json["seed"] == 2
    assert fit.keys == list(TRUTH)


def test_progress_shows_a_tqdm_bar(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    require("tqdm")
    data = tmp_path / "steps.csv"
    pd.read_csv(STEPS).iloc[::3].to_csv(data, index=False)
    pidm.fit(SCENE, data, backend="cpu")
    err = capfd.readouterr().err
    assert "pidm fit" in err and "best_chi2" in err and "candidate" in err, err


# Fits the example with a progress function that says when the fit runs.
# Python ignores SIGINT in a process started with it ignored: the script takes
# it back.
SCRIPT = """
import signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)
import pidm

try:
    pidm.fit(sys.argv[1], out=sys.argv[2], backend="cpu", threads=1,
             progress=lambda record: print("running", flush=True))
except KeyboardInterrupt as interrupt:
    print("KeyboardInterrupt", *getattr(interrupt, "__notes__", []), flush=True)
    sys.exit(0)
print("finished", flush=True)
sys.exit(1)
"""


def test_ctrl_c_stops_the_fit_and_keeps_the_best_point(tmp_path: Path) -> None:
    script = tmp_path / "fit.py"
    script.write_text(SCRIPT)
    out = tmp_path / "stopped.json"
    child = subprocess.Popen(
        [sys.executable, str(script), str(SCENE), str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=child_env(),
        text=True,
    )
    stdout, stderr, _ = interrupt_when_running(child)
    assert "KeyboardInterrupt" in stdout, stdout + stderr
    assert child.returncode == 0, stdout + stderr
    if out.exists():
        # pidm wrote its best point within the grace: the note says where.
        assert str(out) in stdout
        assert json.loads(out.read_text())["status"] == "interrupted"
    # No pidm process of this fit is left.
    time.sleep(0.2)
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
            except OSError:
                continue
            assert str(out) not in command or "pytest" in command, command


def test_the_goodness_of_fit_the_covariance_and_the_residuals() -> None:
    fit = pidm.fit(SCENE, backend="cpu", progress=False)
    # The example's 2 % errors are given: a p-value, nothing scaled.
    assert fit.errors == "given"
    assert fit.p_value is not None and 0.001 < fit.p_value <= 1.0
    assert fit.se_scaled is None
    cov = fit.covariance
    assert cov.dims == ("key", "other_key")
    assert cov["key"].values.tolist() == fit.keys
    assert np.allclose(np.sqrt(np.diag(cov.values)), fit.se.values, rtol=1e-9)
    assert np.allclose(cov.values, cov.values.T)
    residuals = fit.residuals
    assert residuals.index.name == "line"
    assert len(residuals) == len(fit.rows)
    rows = fit.rows.set_index("line")
    expect = (rows["model_step_x"] - rows["step_x"]) / rows["step_x_se"]
    assert np.allclose(residuals["residual_x"].values, expect.values)
    assert np.isclose((residuals["residual_x"] ** 2).sum(), fit.chi2, rtol=1e-9)
    # The profile intervals bracket each value, the 95 % outside the 68 %.
    intervals = fit.intervals
    assert intervals is not None
    assert intervals.index.tolist() == fit.keys
    assert list(intervals.columns) == ["lo68", "hi68", "lo95", "hi95"]
    for key in fit.keys:
        lo68, hi68, lo95, hi95 = intervals.loc[key]
        assert lo95 < lo68 < fit.values[key] < hi68 < hi95, (key, intervals.loc[key])


def test_understated_errors_raise_a_fit_warning() -> None:
    steps = pd.read_csv(STEPS)
    steps["step_x_se"] /= 3.0
    with pytest.warns(pidm.FitWarning, match="too small for the misfit"):
        fit = pidm.fit(TEXT, steps, backend="cpu", progress=False, intervals=False)
    assert fit.intervals is None
    assert fit.p_value is not None and fit.p_value < 1e-3
    assert fit.se_scaled is not None
    assert (fit.se_scaled > fit.se).all()
