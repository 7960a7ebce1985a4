"""Judges the twins of a scene: CPU.h5 is the CPU's run of the scene, PLUS.h5
and MINUS.h5 the f32 runs of its two twins (nudge.py, sides +1 and -1). At
each threshold (a fraction of 0.005 um + 1 %), twins that differ by more go
to the CPU (their CPU value is taken), the others give their mean; prints
how many went to the CPU and which instances are still over the allowance.

    python3 results/twins/judge.py CPU.h5 PLUS.h5 MINUS.h5
"""

import sys

import h5py
import numpy as np


def load(path):
    with h5py.File(path, "r") as h:
        steps = np.stack([h["maps/step_x"][...].ravel(), h["maps/step_y"][...].ravel()])
        return steps * 1e6, h["maps/status"][...].ravel()


def allowance(x):
    return 0.005 + 0.01 * np.abs(x)


def main():
    (cpu, _), (a, sa), (b, sb) = (load(p) for p in sys.argv[1:4])
    apart = np.max(np.abs(a - b) / allowance(np.maximum(np.abs(a), np.abs(b))), axis=0)
    apart[sa != sb] = np.inf
    mean = 0.5 * (a + b)
    for threshold in (1, 0.5, 0.3, 0.2):
        to_cpu = apart > threshold
        result = np.where(to_cpu, cpu, mean)
        error = np.max(np.abs(result - cpu) / allowance(cpu), axis=0)
        over = np.nonzero(error > 1)[0].tolist()
        print(
            f"threshold {threshold}: to the CPU {int(to_cpu.sum())} "
            f"({to_cpu.mean() * 100:.2f} %), over {over}, worst {error.max():.3f}"
        )


if __name__ == "__main__":
    main()
