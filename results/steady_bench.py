#!/usr/bin/env python3
"""Steady measurement against the paper's fixed window (issue 18), whole
processes on one CPU thread:

1. sweeps/coupling.toml (61 x 61 + baselines, equal frequencies) measured
   steady (its default) and as a window of 10 periods, 2 settling: wall
   times (median of --runs alternating runs) and the largest difference of
   any step or baseline step;
2. the periods each instance of sweeps/frequency.toml and sweeps/beats.toml
   integrated, as a histogram, with how each stopped.

Usage: python3 results/steady_bench.py [--runs 7] [--bin target/release/pidm]
Needs h5py and numpy (tests/requirements.txt).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def run(binary: str, scene: Path, out: Path) -> float:
    command = [binary, "run", str(scene), "--threads", "1", "--backend", "cpu", "--out", str(out)]
    started = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    return time.perf_counter() - started


def steps(path: Path) -> np.ndarray:
    with h5py.File(path) as f:
        names = ["maps/step_x", "maps/step_y", "baseline/step_x", "baseline/step_y"]
        return np.stack([f[n][...].ravel() for n in names])


def histogram(binary: str, scene: str, tmp: Path) -> None:
    out = tmp / f"{scene}.h5"
    wall = run(binary, ROOT / "sweeps" / f"{scene}.toml", out)
    with h5py.File(out) as f:
        periods = f["maps/periods"][...].ravel()
        lag = f["maps/period_lag"][...].ravel()
        status = f["maps/status"][...].ravel()
        se = np.maximum(f["maps/step_x_se"][...], f["maps/step_y_se"][...]).ravel()
    edges = [0, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20001]
    counts, _ = np.histogram(periods, bins=edges)
    print(f"\n### sweeps/{scene}.toml: {periods.size} instances, {wall:.2f} s on one thread\n")
    print(
        f"periodic {int((lag > 0).sum())}, converged {int(((lag == 0) & (status == 0)).sum())}, "
        f"not steady {int((status == 6).sum())}; periods mean {periods.mean():.0f}, "
        f"median {np.median(periods):.0f}, most {periods.max()}; largest standard error "
        f"{se.max() * 1e6:.4f} um\n"
    )
    print("| periods | instances |\n|---|---|")
    for lo, hi, n in zip(edges[:-1], edges[1:], counts):
        if n:
            print(f"| {lo}-{hi - 1} | {n} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--bin", default=str(ROOT / "target" / "release" / "pidm"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        window = tmp / "coupling_window.toml"
        text = (ROOT / "sweeps" / "coupling.toml").read_text()
        window.write_text(text + '\n[simulation]\nmeasure = "window"\ncycles = 10\nsettle = 2\n')
        times = {"steady": [], "window": []}
        for _ in range(args.runs):
            times["steady"].append(run(args.bin, ROOT / "sweeps" / "coupling.toml", tmp / "s.h5"))
            times["window"].append(run(args.bin, window, tmp / "w.h5"))
        diff = np.abs(steps(tmp / "s.h5") - steps(tmp / "w.h5")).max() * 1e6
        s, w = (statistics.median(times[k]) for k in ("steady", "window"))
        ratios = [b / a for a, b in zip(times["steady"], times["window"])]
        print("### sweeps/coupling.toml, one thread, whole process\n")
        print("| measure | median wall [s] | min | max |\n|---|---|---|---|")
        for k in ("steady", "window"):
            print(
                f"| {k} | {statistics.median(times[k]):.3f} | {min(times[k]):.3f} | "
                f"{max(times[k]):.3f} |"
            )
        print(
            f"\nwindow / steady: {w / s:.2f} (pairwise {min(ratios):.2f}-{max(ratios):.2f}); "
            f"largest difference of any step or baseline step {diff:.2e} um"
        )
        for scene in ("frequency", "beats"):
            histogram(args.bin, scene, tmp)


if __name__ == "__main__":
    main()
