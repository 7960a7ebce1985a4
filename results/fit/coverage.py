"""Coverage of `pidm fit`'s intervals and scaled errors over repeated noise
draws (issue 60, results/fit.md).

Recovery: for three synthetic sets made at a known truth with seeded noise,
the share of draws whose truth lies inside its 95 % profile interval:
- karnopp: examples/fit/karnopp (30 steps with their standard errors);
- lugre: examples/fit/lugre (12 steps with their standard errors);
- lab: the coupling truth at its 12 settings, 3 repeats each, x as steps in
  um, y as velocities in um/s, no error columns (the pooled repeats give
  them).
Honest errors: the karnopp set with its error column 3 times too small: the
share of draws where the p-value warns, and where each truth lies within 2
of the standard errors scaled by sqrt(reduced chi2).

    python3 results/fit/coverage.py [--draws 20] [--pidm target/release/pidm]

Draw d uses noise seed d (1..DRAWS), so a run is reproducible. Exits 1 when
a share falls below 17 of 20 (or, with fewer draws, when any draw misses).
"""

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

COUPLING = {
    "mechanism.static_friction": 1.2,
    "mechanism.coulomb_friction": 1.0,
    "axis.y.gain": -0.45,
}
KARNOPP = {
    "mechanism.static_friction": 1.2,
    "mechanism.coulomb_friction": 1.0,
    "axis.x.gain": -0.6,
}
#: The drive frequency of the coupling truth's y axis [Hz]: Table 1's.
Y_FREQUENCY = 10.0


def make_data(pidm: str, truth: str, rows: str, out: str, seed: int) -> None:
    """examples/fit/make_data.py: steps at the truth plus seeded noise."""
    subprocess.run(
        [sys.executable, "examples/fit/make_data.py", truth, rows, out]
        + ["--seed", str(seed), "--pidm", pidm],
        check=True,
        stdout=subprocess.DEVNULL,
    )


def fit(pidm: str, scene: str, data: str, out: str, intervals: bool = True) -> dict:
    """`pidm fit` on the CPU: FIT.json."""
    command = [pidm, "fit", scene, "--data", data, "--out", out, "--backend", "cpu"]
    command += ["--progress", "none"] + ([] if intervals else ["--no-intervals"])
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(out) as f:
        return json.load(f)


def rewrite(path: str, row) -> None:
    """Rewrites the CSV at `path` row by row through `row(dict) -> dict`."""
    with open(path, newline="") as f:
        rows = [row(r) for r in csv.DictReader(f)]
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def lab(r: dict) -> dict:
    """A coupling row as a lab writes it: um, um/s, no errors."""
    return {
        "axis.x.voltage": r["axis.x.voltage"],
        "axis.y.voltage": r["axis.y.voltage"],
        "step_x_um": f"{float(r['step_x']) * 1e6:.6f}",
        "velocity_y_um_s": f"{float(r['step_y']) * Y_FREQUENCY * 1e6:.6f}",
    }


def understated(r: dict) -> dict:
    """A karnopp row whose error column is 3 times too small."""
    return {**r, "step_x_se": f"{float(r['step_x_se']) / 3.0:.4e}"}


def inside95(json_: dict, truth: dict) -> dict:
    """Per key: whether the truth lies in its 95 % profile interval."""
    out = {}
    for key, value in truth.items():
        lo, hi = json_["parameters"][key]["interval95"]
        out[key] = (lo is None or lo <= value) and (hi is None or value <= hi)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=20)
    ap.add_argument("--pidm", default=os.environ.get("PIDM", "target/release/pidm"))
    args = ap.parse_args()
    pidm = os.path.abspath(args.pidm)
    ex = "examples/fit"
    sets = {
        "karnopp": (f"{ex}/karnopp_truth.toml", f"{ex}/karnopp_rows.csv", f"{ex}/karnopp.toml"),
        "lugre": (f"{ex}/lugre_truth.toml", f"{ex}/lugre_rows.csv", f"{ex}/lugre.toml"),
        "lab": (f"{ex}/coupling_truth.toml", None, f"{ex}/coupling.toml"),
    }
    truths = {"karnopp": KARNOPP, "lugre": {"mechanism.bristle_stiffness": 3.0e6}, "lab": COUPLING}
    counts = {name: dict.fromkeys(truths[name], 0) for name in sets}
    honest = {"warned": 0, **dict.fromkeys(KARNOPP, 0)}
    with tempfile.TemporaryDirectory() as tmp:
        repeated = os.path.join(tmp, "rows3.csv")
        with open(f"{ex}/coupling_rows.csv", newline="") as f:
            rows = list(csv.reader(f))
        with open(repeated, "w", newline="") as f:
            csv.writer(f).writerows([rows[0]] + [r for r in rows[1:] for _ in range(3)])
        for draw in range(1, args.draws + 1):
            for name, (truth, rows_csv, scene) in sets.items():
                data = os.path.join(tmp, f"{name}.csv")
                make_data(pidm, truth, rows_csv or repeated, data, draw)
                if name == "lab":
                    rewrite(data, lab)
                got = fit(pidm, scene, data, os.path.join(tmp, f"{name}.json"))
                for key, ok in inside95(got, truths[name]).items():
                    counts[name][key] += ok
            data = os.path.join(tmp, "honest.csv")
            make_data(pidm, sets["karnopp"][0], sets["karnopp"][1], data, draw)
            rewrite(data, understated)
            got = fit(pidm, sets["karnopp"][2], data, os.path.join(tmp, "h.json"), False)
            honest["warned"] += got["p_value"] is not None and got["p_value"] < 1e-3
            for key, value in KARNOPP.items():
                p = got["parameters"][key]
                scaled = p["se_scaled"] or p["se"]
                honest[key] += abs(p["value"] - value) <= 2.0 * scaled
            print(f"draw {draw}: {json.dumps(counts)} honest {json.dumps(honest)}", flush=True)
    need = args.draws if args.draws < 20 else 17 * args.draws // 20
    print(f"\n{args.draws} draws; a share passes at {need} or more")
    print("| set | key | truth inside its 95 % interval |")
    print("|---|---|---|")
    ok = True
    for name, keys in counts.items():
        for key, n in keys.items():
            print(f"| {name} | {key} | {n} of {args.draws} |")
            ok &= n >= need
    print("\n| understated errors (x 1/3) | draws |")
    print("|---|---|")
    for key, n in honest.items():
        what = "p < 0.001 warned" if key == "warned" else f"{key} within 2 scaled SEs"
        print(f"| {what} | {n} of {args.draws} |")
        ok &= n >= need
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
