"""What each kind of measurement determines (docs/fit.md, results/fit.md):
synthetic data from Table 1 with the steady step (make_data.py, seed 1, 2 %
noise plus 0.01 um), fitted with static friction in [0.5, 3] N, Coulomb
friction in [0.3, 2] N and the gain in [-1, -0.2] N/V free. Prints one
Markdown row per data set: each key's value with its standard error, and
the fit's warnings in short.

    python3 results/fit/identify.py [--pidm target/release/pidm]
"""

import argparse
import csv
import os
import sys
import tempfile

from draws import make_data, run_fit

FREE = (
    'free = { "mechanism.static_friction" = [0.5, 3.0], '
    '"mechanism.coulomb_friction" = [0.3, 2.0], "axis.x.gain" = [-1.0, -0.2] }\n'
)
TRUTH = "[mechanism]\nstatic_friction = 1.2\ncoulomb_friction = 1.0\n[axis.x]\ngain = -0.6\n"
VOLTS = range(40, 221, 20)
SETS = {
    "one curve: 10 voltages at 50 Hz": (
        ["axis.x.voltage", "axis.x.frequency"],
        [[v, 50] for v in VOLTS],
    ),
    "two curves: 10 voltages at 10 and 200 Hz": (
        ["axis.x.voltage", "axis.x.frequency"],
        [[v, f] for v in VOLTS for f in (10, 200)],
    ),
    "loads: 7 loads from -0.6 to 0.6 N at 100 V, 50 Hz": (
        ["axis.x.voltage", "axis.x.frequency", "mechanism.load_x"],
        [[100, 50, load] for load in (-0.6, -0.4, -0.2, 0.0, 0.2, 0.4, 0.6)],
    ),
    "one point: 100 V, 50 Hz": (["axis.x.voltage", "axis.x.frequency"], [[100, 50]]),
}


def fit(header: list, rows: list, pidm: str, tmp: str) -> dict:
    """The fit of one data set: its FIT.json."""
    rows_csv, data, truth = (os.path.join(tmp, f) for f in ("rows.csv", "data.csv", "truth.toml"))
    with open(rows_csv, "w", newline="") as f:
        csv.writer(f).writerows([header] + rows)
    with open(truth, "w") as f:
        f.write(TRUTH)
    make_data(pidm, truth, rows_csv, data)
    scene = os.path.join(tmp, "fit_scene.toml")
    with open(scene, "w") as f:
        f.write("[fit]\n" + FREE)
    return run_fit(pidm, scene, data, os.path.join(tmp, "fit.json"))[0]


def short(warning: str) -> str:
    """A warning's first clause."""
    return warning.split(":")[0]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pidm", default="target/release/pidm")
    args = ap.parse_args()
    print(
        "| data | static friction [N] | Coulomb friction [N] | gain [N/V] | identifiable | warnings |"
    )
    print("|---|---|---|---|---|---|")
    for name, (header, rows) in SETS.items():
        with tempfile.TemporaryDirectory() as tmp:
            j = fit(header, rows, args.pidm, tmp)
        cells = []
        for key in j["order"]:
            p = j["parameters"][key]
            se = p["se"]
            cells.append(
                f"{p['value']:.4g} ± {se:.2g}" if se is not None else f"{p['value']:.4g} ± inf"
            )
        warnings = "; ".join(short(w) for w in j["warnings"]) or "none"
        print(f"| {name} | {' | '.join(cells)} | {j['identifiable']} | {warnings} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
