"""Counts, per seed written by run.sh, the instances whose step on either
axis differs from the f64 CPU's by more than 0.005 um + 1 % of it (both
with status 0), for the nudged f64 run, the f32 shader and the f32 mirror,
and the integrations each f32 run handed to the CPU in f64.

    python3 results/graze/compare.py OUT_DIR SEED [SEED ...]
"""

import re
import sys
from pathlib import Path

# The same reading and counting as the tolerance study's.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from tolerance.compare import compare, load

RUNS = [
    ("nudged", "f64, parameters nudged by 6e-8"),
    ("f32", "f32 shader"),
    ("mirror", "f32 CPU mirror"),
]


def handed_over(log):
    try:
        with open(log) as f:
            text = f.read()
    except OSError:
        return 0
    m = re.search(r"(\d+) of the integrations ran on the CPU", text)
    return int(m.group(1)) if m else 0


def main():
    out, seeds = sys.argv[1], sys.argv[2:]
    totals = {run: [0, 0, 0, 0] for run, _ in RUNS}
    for seed in seeds:
        ref = load(f"{out}/cpu_{seed}.h5")
        for run, label in RUNS:
            over, failed = compare(ref, load(f"{out}/{run}_{seed}.h5"))
            t = totals[run]
            t[0] += len(over)
            t[1] += failed
            t[2] += len(ref[1])
            t[3] += handed_over(f"{out}/{run}_{seed}.log")
            if over or failed:
                listed = ", ".join(f"#{k} ({r:.1f}x)" for k, r in over)
                print(f"seed {seed}: {label}: over {listed or '-'}; failed only there: {failed}")
    print()
    for run, label in RUNS:
        over, failed, n, cpu = totals[run]
        handed = f", {cpu} integrations run on the CPU in f64" if run != "nudged" else ""
        print(f"{label}: {over} of {n} over, {failed} failed only there{handed}")


if __name__ == "__main__":
    main()
