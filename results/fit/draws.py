"""The reported standard errors of `pidm fit` against the spread of the
fitted values over repeated noise draws (results/fit.md).

For each shipped synthetic set (examples/fit/), draws DRAWS new noisy data
sets from the same truth (make_data.py, seeds 1..DRAWS), fits each on the
CPU, and prints per parameter: the truth, the mean fitted value, the
standard deviation of the fitted values over the draws, the median reported
standard error, their ratio, and the fraction of draws whose truth lies
within 3 reported standard errors; then the median wall time of a fit.

    python3 results/fit/draws.py [DRAWS] [--pidm target/release/pidm]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

SETS = {
    "karnopp": {
        "mechanism.static_friction": 1.2,
        "mechanism.coulomb_friction": 1.0,
        "axis.x.gain": -0.6,
    },
    "lugre": {"mechanism.bristle_stiffness": 3.0e6},
    "coupling": {
        "mechanism.static_friction": 1.2,
        "mechanism.coulomb_friction": 1.0,
        "axis.y.gain": -0.45,
    },
}


def make_data(pidm: str, truth: str, rows: str, out: str, seed: int = 1) -> None:
    """A synthetic data set: make_data.py on `truth` at `rows`, into `out`."""
    subprocess.run(
        [
            sys.executable,
            "examples/fit/make_data.py",
            truth,
            rows,
            out,
            "--seed",
            str(seed),
            "--pidm",
            pidm,
        ],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


def run_fit(pidm: str, scene: str, data: str, out: str) -> tuple[dict, float]:
    """`pidm fit` of `scene` to `data` on the CPU: FIT.json and the wall time."""
    started = time.perf_counter()
    subprocess.run(
        [
            pidm,
            "fit",
            scene,
            "--data",
            data,
            "--out",
            out,
            "--backend",
            "cpu",
            "--progress",
            "none",
        ],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    elapsed = time.perf_counter() - started
    with open(out) as f:
        return json.load(f), elapsed


def fit_draw(name: str, seed: int, pidm: str, tmp: str) -> tuple[dict, float]:
    """One noise draw of set `name`, fitted: FIT.json and the fit's wall time."""
    data = os.path.join(tmp, f"{name}_{seed}.csv")
    rows = f"examples/fit/{name}_rows.csv"
    make_data(pidm, f"examples/fit/{name}_truth.toml", rows, data, seed)
    out = os.path.join(tmp, f"{name}_{seed}.json")
    return run_fit(pidm, f"examples/fit/{name}.toml", data, out)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("draws", nargs="?", type=int, default=20)
    ap.add_argument("--pidm", default="target/release/pidm")
    args = ap.parse_args()
    print(
        "| set | key | truth | mean fit | sd over draws | median se | sd / se | truth within 3 se |"
    )
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, truth in SETS.items():
            fits, times = [], []
            for seed in range(1, args.draws + 1):
                fit, elapsed = fit_draw(name, seed, args.pidm, tmp)
                fits.append(fit)
                times.append(elapsed)
            flagged = sum(not f["identifiable"] for f in fits)
            for key, true_value in truth.items():
                # A standard error FIT.json writes as null is infinite: the
                # data did not determine the key in that draw.
                values = [f["parameters"][key]["value"] for f in fits]
                ses = [f["parameters"][key]["se"] or float("inf") for f in fits]
                sd = statistics.stdev(values)
                se = statistics.median(ses)
                inside = sum(abs(v - true_value) <= 3 * s for v, s in zip(values, ses))
                print(
                    f"| {name} | {key} | {true_value:.4g} | {statistics.mean(values):.5g} | "
                    f"{sd:.3g} | {se:.3g} | {sd / se:.2f} | {inside}/{len(fits)} |"
                )
            print(
                f"| {name} | median fit time; draws flagged not identifiable | | | | | "
                f"{statistics.median(times):.2f} s | {flagged}/{len(fits)} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
