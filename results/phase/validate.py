#!/usr/bin/env python3
"""The steady measurement of two-frequency points against long lattice
windows (issue 31, docs/steady.md): every point of a points scene (by
default results/phase/validation.toml) is measured as the scene says
(steady), and again over a fixed window of a lattice length: a whole
number of the drives' common period where their frequencies are decimals
with one up to 100,000 periods, else the largest continued-fraction
denominator of the faster drive's advance per period, at most --window
periods. A converged value must lie within 3 standard errors + 0.002 um of
the window's; the script prints every point and a summary (the periods in
total and their median, the statuses and kinds of motion, the misses).

Usage: python3 results/phase/validate.py [--bin target/release/pidm]
       [--scene results/phase/validation.toml] [--window 30000] [--jobs 2]
Needs h5py and numpy (tests/requirements.txt); Python 3.11 (tomllib).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import math
import subprocess
import tempfile
from fractions import Fraction
from pathlib import Path

import h5py
import numpy as np
import tomllib

ROOT = Path(__file__).resolve().parents[2]
KINDS = ["undetermined", "periodic", "quasi_periodic", "irregular"]


def as_decimal(f: float) -> Fraction | None:
    """f as n / 10^k, k <= 6, to 64 roundings (pidm's decimal_common_period)."""
    for k in range(7):
        scaled = f * 10**k
        n = round(scaled)
        if n >= 1 and abs(scaled - n) <= 64 * 2.220446049250313e-16 * scaled:
            return Fraction(n, 10**k)
    return None


def lattice(fx: float, fy: float, longest: int) -> int:
    lo, hi = min(fx, fy), max(fx, fy)
    a, b = as_decimal(lo), as_decimal(hi)
    if a is not None and b is not None:
        q = (b / a).denominator
        if q <= 100_000:
            return max(1, longest // q) * q
    rho = (hi / lo) % 1.0
    previous, current, rest = 0, 1, rho
    while rest > 1e-12:
        inverse = 1.0 / rest
        whole = math.floor(inverse)
        rest = inverse - whole
        following = whole * current + previous
        if following > longest:
            break
        previous, current = current, following
    return current


def points(scene: Path) -> tuple[dict, list[dict]]:
    with scene.open("rb") as f:
        doc = tomllib.load(f)
    return doc, doc["points"]


def axis(doc: dict, point: dict, name: str) -> dict:
    merged = dict(doc.get("axis", {}).get(name, {}))
    merged.update(point.get("axis", {}).get(name, {}))
    return merged


def toml_value(v) -> str:
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, str):
        return f'"{v}"'
    return repr(v)


def window(binary: str, doc: dict, point: dict, length: int, tmp: Path, k: int) -> np.ndarray:
    """The window's step per own drive cycle [um] of one point."""
    lines = [f'name = "window{k}"', "[simulation]", 'measure = "window"']
    lines += [f"cycles = {length + 2}", "settle = 2"]
    if "mechanism" in doc:
        lines += ["[mechanism]"] + [f"{k} = {toml_value(v)}" for k, v in doc["mechanism"].items()]
    for name in ("x", "y"):
        lines += [f"[axis.{name}]"] + [
            f"{key} = {toml_value(v)}" for key, v in axis(doc, point, name).items()
        ]
    if "mechanism" in point:
        lines += ["[mechanism]"] if "mechanism" not in doc else []
        lines += [f"{key} = {toml_value(v)}" for key, v in point["mechanism"].items()]
    scene = tmp / f"window{k}.toml"
    scene.write_text("\n".join(lines) + "\n")
    out = tmp / f"window{k}.h5"
    command = [binary, "run", str(scene), "--out", str(out), "--backend", "cpu"]
    subprocess.run(
        [*command, "--threads", "1", "--progress", "none"], check=True, capture_output=True
    )
    with h5py.File(out) as f:
        return np.array([f["maps/step_x"][()], f["maps/step_y"][()]]).ravel() * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bin", default=str(ROOT / "target" / "release" / "pidm"))
    parser.add_argument("--scene", default=str(ROOT / "results" / "phase" / "validation.toml"))
    parser.add_argument("--window", type=int, default=30_000)
    parser.add_argument("--jobs", type=int, default=2)
    args = parser.parse_args()
    scene = Path(args.scene)
    doc, pts = points(scene)
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        out = tmp / "steady.h5"
        subprocess.run(
            [
                args.bin,
                "run",
                str(scene),
                "--out",
                str(out),
                "--backend",
                "cpu",
                "--progress",
                "none",
            ],
            check=True,
            capture_output=True,
        )
        with h5py.File(out) as f:
            got = np.stack([f["maps/step_x"][...], f["maps/step_y"][...]], 1) * 1e6
            se = np.stack([f["maps/step_x_se"][...], f["maps/step_y_se"][...]], 1) * 1e6
            periods = f["maps/periods"][...]
            status = f["maps/status"][...]
            motion = f["maps/motion"][...]
        lengths = [
            lattice(axis(doc, p, "x")["frequency"], axis(doc, p, "y")["frequency"], args.window)
            for p in pts
        ]
        with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
            refs = list(
                pool.map(
                    lambda k: window(args.bin, doc, pts[k], lengths[k], tmp, k), range(len(pts))
                )
            )
    print(
        "| point | periods | status | motion | step x, y [um] | +- se [um] | window | "
        "reference [um] | within |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    misses = 0
    for k, p in enumerate(pts):
        err = np.abs(got[k] - refs[k])
        within = bool(np.all(err <= 3 * se[k] + 0.002))
        misses += not within
        print(
            f"| {p['label']} | {periods[k]} | {status[k]} | {KINDS[motion[k]]} | "
            f"{got[k][0]:+.4f}, {got[k][1]:+.4f} | {se[k][0]:.4f}, {se[k][1]:.4f} | "
            f"{lengths[k]} | {refs[k][0]:+.4f}, {refs[k][1]:+.4f} | {'yes' if within else 'NO'} |"
        )
    kinds = ", ".join(f"{int((motion == c).sum())} {n}" for c, n in enumerate(KINDS))
    print(
        f"\n{len(pts)} points: periods total {int(periods.sum())}, median "
        f"{np.median(periods):.0f}, mean {periods.mean():.0f}; status 0: "
        f"{int((status == 0).sum())}, not steady: {int((status == 6).sum())}; {kinds}; "
        f"outside 3 standard errors + 0.002 um of their window: {misses}"
    )


if __name__ == "__main__":
    main()
