"""Compares two steady maps value by value against issue 39's rule: each step
within 3 combined standard errors + 0.002 um of the other's. Prints how many
values are within, the worst ones, and how the two files' replicas, periods,
motions and statuses compare.

    python3 results/replicas/within.py CPU.h5 GPU.h5
"""

import sys

import h5py
import numpy as np


def load(path):
    with h5py.File(path, "r") as f:
        m = f["maps"]
        return {k: m[k][...].ravel() for k in m}


def main():
    a, b = load(sys.argv[1]), load(sys.argv[2])
    within, rows = 0, []
    for axis in ("x", "y"):
        step_a, step_b = a[f"step_{axis}"] * 1e6, b[f"step_{axis}"] * 1e6
        se = np.hypot(a[f"step_{axis}_se"], b[f"step_{axis}_se"]) * 1e6
        allowed = 3 * se + 0.002
        apart = np.abs(step_a - step_b)
        within += int((apart <= allowed).sum())
        for i in np.flatnonzero(~(apart <= allowed)):
            rows.append((axis, i, step_a[i], step_b[i], apart[i], allowed[i]))
    total = 2 * a["step_x"].size
    print(f"within 3 SE + 0.002 um: {within} of {total}")
    for axis, i, sa, sb, d, allow in rows:
        print(f"  {axis} #{i}: {sa:.5f} against {sb:.5f} um, {d:.4f} apart, allowed {allow:.4f}")
    for key in ("status", "motion", "replicas", "periods"):
        same = int((a[key] == b[key]).sum())
        print(
            f"{key}: equal at {same} of {a[key].size}; B's sum {int(b[key].sum())}, A's {int(a[key].sum())}"
        )
    print(f"B's longest chain {int(b['periods'].max())} periods, A's {int(a['periods'].max())}")


if __name__ == "__main__":
    main()
