"""Simulates f32's check by the reference route at several shares from the
shader's unchecked maps (results/gpu.md, "The heaviest fifth"): a checked
run carries the CPU's f64 value exactly, so the misses left at a share are
the unchecked run's misses outside the heaviest share of the runs f32
finished itself with status 0 (ranked by f32's own steps, ties by index).
Runs f32 handed to the CPU (grazes, failures) equal the CPU's map exactly
and are not candidates.

    CHECKS=off MIRROR=0 bash results/check/run.sh OUT SEED ...
    python3 results/check/share.py OUT SEED ...
"""

import math
import sys
from pathlib import Path

import h5py
import numpy as np

# The same reading and counting as the tolerance study's.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from tolerance.compare import compare, load

SHARES = [0.0, 0.1, 0.15, 0.2, 0.25, 0.3]


def main():
    out, seeds = sys.argv[1], sys.argv[2:]
    left = {share: [] for share in SHARES}
    n = 0
    for seed in seeds:
        ref = load(f"{out}/cpu_{seed}.h5")
        run = load(f"{out}/off_{seed}.h5")
        with h5py.File(f"{out}/off_{seed}.h5", "r") as f:
            steps = f["maps/steps"][...].ravel()
        n += len(ref[1])
        over, _ = compare(ref, run)
        handed = np.all(ref[0] == run[0], axis=0) & (ref[1] == run[1])
        candidates = np.nonzero((run[1] == 0) & ~handed)[0]
        order = sorted(candidates, key=lambda k: (-int(steps[k]), int(k)))
        rank = {int(k): i for i, k in enumerate(order)}
        for share in SHARES:
            taken = math.ceil(len(candidates) * share)
            for k, r in over:
                if not (k in rank and rank[k] < taken):
                    where = (
                        f"{100 * rank[k] / len(candidates):.1f} %"
                        if k in rank
                        else "not a candidate"
                    )
                    left[share].append(f"{seed} #{k} ({r:.1f}x, {where})")
    for share in SHARES:
        print(f"share {share:.2f}: {len(left[share])} of {n} over: {', '.join(left[share])}")


if __name__ == "__main__":
    main()
