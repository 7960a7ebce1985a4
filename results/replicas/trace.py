"""Window estimates of one axis from `examples/period_trace.rs`'s output:
the phase-resolved trapezoid (the increments sorted by the faster drive's
phase at each period start) and the plain mean, over windows of the given
lengths started at the given periods, and the largest gap of each window's
phases times its length (its bunching, docs/steady.md).

    cargo run --release --example period_trace -- FX FY N > trace.txt
    python3 results/replicas/trace.py trace.txt FX FY AXIS START,... LENGTH,...

AXIS is x or y; steps are per own drive cycle [um].
"""

import sys

import numpy as np


def main():
    path, fx, fy, axis = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), sys.argv[4]
    starts = [int(s) for s in sys.argv[5].split(",")]
    lengths = [int(s) for s in sys.argv[6].split(",")]
    data = np.loadtxt(path)
    position = data[:, 1 if axis == "x" else 2] * 1e6
    slow = min(fx, fy)
    own = (fx if axis == "x" else fy) / slow  # own cycles per scene period
    rho = (max(fx, fy) / slow) % 1.0
    increments = np.diff(position) / own
    print("start length trapezoid plain bunching")
    for start in starts:
        for length in lengths:
            if start + length > len(increments):
                continue
            k = np.arange(start, start + length)
            phase = (k * rho) % 1.0
            order = np.argsort(phase)
            p, v = phase[order], increments[k][order]
            p2, v2 = np.r_[p, p[0] + 1.0], np.r_[v, v[0]]
            trapezoid = np.sum(np.diff(p2) * (v2[1:] + v2[:-1]) / 2.0)
            bunching = np.max(np.diff(p2)) * length
            print(f"{start} {length} {trapezoid:.5f} {v.mean():.5f} {bunching:.1f}")


if __name__ == "__main__":
    main()
