"""The step maps of result files against a reference file: per file the
largest difference over both axes [um], its 99th and 90th percentile and
median, and how many instances are off by more than 1e-4 um and 1e-3 um.

    python3 results/lean/compare.py REFERENCE.h5 A.h5 [B.h5 ...]
"""

import sys

import h5py
import numpy as np


def steps(path):
    with h5py.File(path, "r") as f:
        return np.stack([f["maps/step_x"][...], f["maps/step_y"][...]]) * 1e6


def main():
    reference = steps(sys.argv[1])
    for path in sys.argv[2:]:
        d = np.abs(steps(path) - reference).max(axis=0).ravel()
        print(
            f"{path}: largest {d.max():.3g} um, p99 {np.percentile(d, 99):.3g}, "
            f"p90 {np.percentile(d, 90):.3g}, median {np.median(d):.3g}; "
            f"{int((d > 1e-4).sum())} over 1e-4 um, {int((d > 1e-3).sum())} over 1e-3 um"
        )


if __name__ == "__main__":
    main()
