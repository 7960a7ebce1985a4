#!/usr/bin/env python3
"""Two drive frequencies (issue 31): whole processes on every core of the
CPU path, one binary or two side by side.

1. The frequency map of issue 31: sweeps/frequency.toml with both axes'
   frequencies `{ from = 5.1, to = 39.9, steps = 16 }` (a user's non-round
   grid, 256 instances, default steady settings): wall time, the periods
   integrated in total and as a histogram, the instances not steady, the
   kinds of motion;
2. sweeps/two_frequency.toml: periods, status and kind of motion per point.

With --baseline BIN the same runs are made with an earlier binary, in
turn with this one (--runs each), and both are printed; a binary without
/maps/motion shows no kinds.

Usage: python3 results/two_frequency_bench.py [--bin target/release/pidm]
       [--baseline OLD_BIN] [--runs 1]
Needs h5py and numpy (tests/requirements.txt).
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
KINDS = ["undetermined", "periodic", "quasi_periodic", "irregular"]
EDGES = [0, 10, 100, 300, 500, 700, 1000, 1500, 2000, 5000, 10001]


def frequency_map(tmp: Path) -> Path:
    """sweeps/frequency.toml on the non-round 16 x 16 grid of issue 31."""
    text = (ROOT / "sweeps" / "frequency.toml").read_text()
    text, n = re.subn(
        r"frequency = \{ from = 5\.0, to = 40\.0, steps = 36 \}",
        "frequency = { from = 5.1, to = 39.9, steps = 16 }",
        text,
    )
    assert n == 2, "sweeps/frequency.toml no longer has the two frequency ranges"
    text = text.replace('name = "frequency"', 'name = "frequency16"')
    path = tmp / "frequency16.toml"
    path.write_text(text)
    return path


def run(binary: str, scene: Path, out: Path) -> float:
    command = [binary, "run", str(scene), "--backend", "cpu", "--progress", "none"]
    started = time.perf_counter()
    subprocess.run([*command, "--out", str(out)], check=True, capture_output=True)
    return time.perf_counter() - started


def read(out: Path) -> dict[str, np.ndarray]:
    with h5py.File(out) as f:
        maps = {name: f["maps"][name][...].ravel() for name in f["maps"]}
        if "labels" in f:
            maps["labels"] = np.array([s.decode() for s in f["labels"][...]])
    return maps


def summary(label: str, walls: list[float], maps: dict[str, np.ndarray]) -> None:
    periods = maps["periods"]
    status = maps["status"]
    counts, _ = np.histogram(periods, bins=EDGES)
    wall = statistics.median(walls)
    print(f"\n#### {label}: median wall {wall:.1f} s of {len(walls)} runs (all {walls})\n")
    print(
        f"periods: total {int(periods.sum())}, mean {periods.mean():.0f}, median "
        f"{np.median(periods):.0f}, most {periods.max()}; not steady {int((status == 6).sum())} "
        f"of {periods.size}; largest standard error "
        f"{max(maps['step_x_se'].max(), maps['step_y_se'].max()) * 1e6:.4f} um"
    )
    if "motion" in maps:
        kinds = ", ".join(f"{int((maps['motion'] == k).sum())} {n}" for k, n in enumerate(KINDS))
        print(f"\nmotion: {kinds}")
    print("\n| periods | instances |\n|---|---|")
    for lo, hi, n in zip(EDGES[:-1], EDGES[1:], counts, strict=True):
        if n:
            print(f"| {lo}-{hi - 1} | {n} |")


def points(label: str, maps: dict[str, np.ndarray]) -> None:
    print(f"\n#### {label}\n")
    print("| point | periods | status | motion | step_x [um] | step_y [um] | se x, y [um] |")
    print("|---|---|---|---|---|---|---|")
    for k, name in enumerate(maps["labels"]):
        kind = KINDS[maps["motion"][k]] if "motion" in maps else "-"
        print(
            f"| {name} | {maps['periods'][k]} | {maps['status'][k]} | {kind} | "
            f"{maps['step_x'][k] * 1e6:+.4f} | {maps['step_y'][k] * 1e6:+.4f} | "
            f"{maps['step_x_se'][k] * 1e6:.4f}, {maps['step_y_se'][k] * 1e6:.4f} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin", default=str(ROOT / "target" / "release" / "pidm"))
    parser.add_argument("--baseline", help="an earlier pidm binary, run in turn with --bin")
    parser.add_argument("--runs", type=int, default=1)
    args = parser.parse_args()
    binaries = [("this binary", args.bin)]
    if args.baseline:
        binaries.insert(0, ("baseline", args.baseline))
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        scene = frequency_map(tmp)
        walls: dict[str, list[float]] = {label: [] for label, _ in binaries}
        for _ in range(args.runs):
            for label, binary in binaries:
                walls[label].append(run(binary, scene, tmp / f"{label}.h5"))
        print("### The frequency map of issue 31 (16 x 16, 5.1-39.9 Hz)")
        for label, _ in binaries:
            summary(label, walls[label], read(tmp / f"{label}.h5"))
        print("\n### sweeps/two_frequency.toml")
        for label, binary in binaries:
            out = tmp / f"points-{label}.h5"
            wall = run(binary, ROOT / "sweeps" / "two_frequency.toml", out)
            points(f"{label}: {wall:.1f} s", read(out))


if __name__ == "__main__":
    main()
