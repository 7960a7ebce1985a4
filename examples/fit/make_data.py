"""Makes a synthetic "measured" data set for `pidm fit`: the steps pidm
computes at known parameters, plus Gaussian noise of a known standard error.

    python3 examples/fit/make_data.py TRUTH.toml ROWS.csv OUT.csv \
        [--seed 1] [--relative 0.02] [--floor 1e-8] [--pidm target/release/pidm]

TRUTH.toml is a scene without grids (the true parameters); ROWS.csv has a
header of scene keys (axis.x.voltage, ...) and one row per measured
instance, and may name the axes measured in a column `measure` ("x", "y" or
"xy", default "x"). OUT.csv gets the keys, step_x/step_y [m per own drive
cycle] and step_x_se/step_y_se [m]: se = relative * |step| + floor.
"""

import argparse
import csv
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np

#: The steady measurement's tolerance of the truth [m per cycle]: the
#: integrator's own error, far under any noise a data set is given, so that
#: the truth's own measurement error does not bias the data.
TRUTH_TOLERANCE = 1e-10


def point_scene(truth: str, rows: list[dict]) -> str:
    """The truth scene, measured at TRUTH_TOLERANCE where it is steady, with
    one [[points]] table per row."""
    text = truth.rstrip() + "\n"
    if 'measure = "window"' not in text:
        line = f"step_tolerance = {TRUTH_TOLERANCE!r}\n"
        if "[simulation]\n" in text:
            text = text.replace("[simulation]\n", "[simulation]\n" + line, 1)
        else:
            text += "\n[simulation]\n" + line
    for row in rows:
        text += "\n[[points]]\n"
        for key, value in row.items():
            if key != "measure" and value != "":
                text += f"{key} = {float(value)!r}\n"
    return text


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("truth")
    ap.add_argument("rows")
    ap.add_argument("out")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--relative", type=float, default=0.02)
    ap.add_argument("--floor", type=float, default=1e-8)
    ap.add_argument("--pidm", default=os.environ.get("PIDM", "target/release/pidm"))
    args = ap.parse_args()
    with open(args.rows, newline="") as f:
        rows = list(csv.DictReader(f))
    with open(args.truth) as f:
        truth = f.read()
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, "truth.toml")
        with open(scene, "w") as f:
            f.write(point_scene(truth, rows))
        out = os.path.join(tmp, "truth.h5")
        subprocess.run(
            [args.pidm, "run", scene, "--backend", "cpu", "--out", out],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        with h5py.File(out, "r") as h5:
            steps = {a: h5[f"maps/step_{a}"][:] for a in "xy"}
            status = h5["maps/status"][:]
    if np.any(status != 0):
        sys.exit(f"some truth instances did not finish normally: {status}")
    rng = np.random.default_rng(args.seed)
    keys = [k for k in rows[0] if k != "measure"]
    with open(args.out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(keys + ["step_x", "step_x_se", "step_y", "step_y_se"])
        for i, row in enumerate(rows):
            measure = row.get("measure") or "x"
            cells = [row[k] for k in keys]
            for a in "xy":
                if a in measure:
                    se = args.relative * abs(steps[a][i]) + args.floor
                    cells += [f"{steps[a][i] + rng.normal(0.0, se):.6e}", f"{se:.3e}"]
                else:
                    cells += ["", ""]
            w.writerow(cells)
    return 0


if __name__ == "__main__":
    sys.exit(main())
