"""Compares two result files map by map: whether each `/maps/*` array is
equal bit for bit, and for the step maps the largest difference [um], how
many points differ by more than 1e-9 um on either axis, and how many (with
status 0 in both) by more than f32's 0.005 um + 1 % of A's step, with the
number of points whose status differs.

    python3 results/compare_maps.py A.h5 B.h5
"""

import sys

import h5py
import numpy as np


def main():
    with h5py.File(sys.argv[1], "r") as a, h5py.File(sys.argv[2], "r") as b:
        for name in sorted(a["maps"]):
            x, y = a["maps"][name][...], b["maps"][name][...]
            same = np.array_equal(x, y, equal_nan=x.dtype.kind == "f")
            print(f"{name}: {'bit for bit' if same else 'differs'}")
        steps = [
            np.abs(a["maps"][k][...] - b["maps"][k][...]).ravel() * 1e6
            for k in ("step_x", "step_y")
        ]
        worst = np.maximum(*steps)
        print(
            f"steps: largest difference {worst.max():.3e} um, "
            f"{int((worst > 1e-9).sum())} points over 1e-9 um"
        )
        sa, sb = (f["maps/status"][...].ravel() for f in (a, b))
        ok = (sa == 0) & (sb == 0)
        ratio = np.maximum(
            *[
                d / (0.005 + 0.01 * np.abs(a["maps"][k][...].ravel() * 1e6))
                for d, k in zip(steps, ("step_x", "step_y"))
            ]
        )
        print(
            f"over 0.005 um + 1 % of A: {int((ok & (ratio > 1)).sum())} "
            f"(worst {ratio[ok].max() if ok.any() else 0:.3f} of it); "
            f"status differs: {int((sa != sb).sum())}"
        )


if __name__ == "__main__":
    main()
