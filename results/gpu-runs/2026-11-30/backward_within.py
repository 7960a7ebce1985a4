"""Compares the backward maps of two result files (A the reference):
the largest difference of backward_x/y [m] and how many points differ by
more than 1e-12 m (1e-6 um), the ratios' by more than 1e-9, with the step maps' (--steps-only: the steps
alone, for two runs of one backend with and without the backward travel).

    python3 backward_within.py A.h5 B.h5 [--steps-only]
"""

import sys

import h5py
import numpy as np


def report(a, b, name):
    x, y = a["maps"][name][...], b["maps"][name][...]
    d = np.abs(x - y).ravel()
    unit, bar = ("", 1e-9) if "ratio" in name else (" m", 1e-12)
    over = int((d > bar).sum())
    print(f"{name}: largest {d.max():.3e}{unit}, over {bar:g}{unit} at {over} of {d.size}")


def main():
    names = ["step_x", "step_y"]
    if "--steps-only" not in sys.argv:
        names += ["backward_x", "backward_y", "backward_ratio_x", "backward_ratio_y"]
    with h5py.File(sys.argv[1], "r") as a, h5py.File(sys.argv[2], "r") as b:
        for name in names:
            report(a, b, name)
        same = np.array_equal(a["maps"]["status"][...], b["maps"]["status"][...])
        print(f"status: {'equal' if same else 'differs'}")


if __name__ == "__main__":
    main()
