"""Counts, per seed written by run.sh, the instances whose step on either
axis differs from the f64 CPU's by more than 0.005 um + 1 % of it (both
with status 0) for f32 with each setting of its check, with the
integration time and the integrations run on the CPU in f64 from each
run's summary.

    python3 results/check/compare.py OUT_DIR SEED [SEED ...]
"""

import re
import sys
from pathlib import Path

# The same reading and counting as the tolerance study's.
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from tolerance.compare import compare, load

RUNS = [
    ("off", "f32 shader, no check"),
    ("twins", "f32 shader, twins"),
    ("reference", "f32 shader, reference"),
    ("mirror", "f32 CPU mirror (reference)"),
]


def summary(log):
    """(integration seconds, integrations run on the CPU) from a run's log."""
    with open(log) as f:
        text = f.read()
    seconds = float(re.search(r"of which ([0-9.]+) s integrating", text).group(1))
    m = re.search(r"(\d+) of the integrations ran on the CPU", text)
    return seconds, int(m.group(1)) if m else 0


def main():
    out, seeds = sys.argv[1], sys.argv[2:]
    # The runs written for every seed (run.sh's CHECKS and MIRROR choose them).
    runs = [
        (r, label) for r, label in RUNS if all(Path(f"{out}/{r}_{s}.h5").exists() for s in seeds)
    ]
    totals = {run: [0, 0, 0, 0.0, 0] for run, _ in runs}
    for seed in seeds:
        ref = load(f"{out}/cpu_{seed}.h5")
        for run, label in runs:
            over, failed = compare(ref, load(f"{out}/{run}_{seed}.h5"))
            seconds, cpu = summary(f"{out}/{run}_{seed}.log")
            t = totals[run]
            t[0] += len(over)
            t[1] += failed
            t[2] += len(ref[1])
            t[3] += seconds
            t[4] += cpu
            if over or failed:
                listed = ", ".join(f"#{k} ({r:.1f}x)" for k, r in over)
                print(f"seed {seed}: {label}: over {listed or '-'}; failed only there: {failed}")
    print()
    for run, label in runs:
        over, failed, n, seconds, cpu = totals[run]
        print(
            f"{label}: {over} of {n} over, {failed} failed only there, "
            f"{cpu} integrations on the CPU in f64, {seconds:.1f} s integrating"
        )


if __name__ == "__main__":
    main()
