"""Counts, per pair of runs written by run.sh, the instances whose step on
either axis differs by more than 0.005 um + 1 % of the first run's step
(both with status 0), and those with status 0 in the first run only.

    python3 results/tolerance/compare.py OUT_DIR SEED [SEED ...]
"""

import sys

import h5py
import numpy as np

PAIRS = [
    ("cpu_1e-4", "cpu_1e-6", "CPU default (1e-4 rad) against CPU at 1e-6 rad"),
    ("cpu_1e-5", "cpu_1e-6", "CPU at 1e-5 rad against CPU at 1e-6 rad"),
    ("f32", "cpu_1e-4", "f32 (default tolerance) against CPU default"),
    ("f32", "cpu_1e-6", "f32 (default tolerance) against CPU at 1e-6 rad"),
    ("mirror", "cpu_1e-4", "f32 CPU mirror against CPU default"),
    ("mirror", "cpu_1e-6", "f32 CPU mirror against CPU at 1e-6 rad"),
    ("mirror", "f32", "f32 CPU mirror against f32 shader"),
]


def load(path):
    with h5py.File(path, "r") as f:
        steps = np.stack([f["maps/step_x"][...].ravel(), f["maps/step_y"][...].ravel()])
        return steps * 1e6, f["maps/status"][...].ravel()


def compare(ref, run):
    (a, sa), (b, sb) = ref, run
    ratio = np.max(np.abs(a - b) / (0.005 + 0.01 * np.abs(a)), axis=0)
    both = (sa == 0) & (sb == 0)
    over = np.nonzero(both & (ratio > 1))[0]
    return [(int(k), float(ratio[k])) for k in over], int(((sa == 0) & (sb != 0)).sum())


def main():
    out, seeds = sys.argv[1], sys.argv[2:]
    totals = {label: [0, 0, 0] for _, _, label in PAIRS}
    for seed in seeds:
        for run, ref, label in PAIRS:
            over, flagged = compare(load(f"{out}/{ref}_{seed}.h5"), load(f"{out}/{run}_{seed}.h5"))
            t = totals[label]
            t[0] += len(over)
            t[1] += flagged
            t[2] += 3000
            if over or flagged:
                listed = ", ".join(f"#{k} ({r:.1f}x)" for k, r in over)
                print(
                    f"seed {seed}: {label}: over {listed or '-'}; failed only in the run: {flagged}"
                )
    print()
    for label, (over, flagged, n) in totals.items():
        print(f"{label}: {over} of {n} over, {flagged} failed only in the run")


if __name__ == "__main__":
    main()
