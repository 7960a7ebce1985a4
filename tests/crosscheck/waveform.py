#!/usr/bin/env python3
"""Independent cross-check of pidm's drive waveforms and slew limit against SciPy.

Issue 59 gave the drive other waveforms than the paper's sawtooth and an
amplifier slew limit (docs/model.md section 2, docs/scenes.md "Waveforms and
the amplifier's slew limit"). This script writes seeded instances of them
as one points scene, runs it through the engine on the CPU path (`pidm run
--backend cpu`; with `--backend gpu`, the f64 shader, which must run every
integration itself, as crosscheck.py's GPU check asks) and integrates every
instance again here with the hybrid solve_ivp integration of
crosscheck.py, imported from it: the Karnopp model's modes, events, slip
direction and stick check are crosscheck.py's `Reference`, subclassed; its
`integrate_piece` and `run` are copied here with the same logic, plus the
travel events below and SciPy's tolerance (SCIPY_RTOL). What is new here
is the drive, built from the scene's keys with no engine code:

* The waveform w(u), u in cycles, as a closed polyline over one cycle:
  points (U_0, L_0) ... (U_m, L_m) with U_m = U_0 + 1, U not decreasing,
  linear between points, periodic; two points at one u are a jump and w
  there is the level after it; L_m != L_0 is a jump at the wrap.
  - sawtooth of duty d: (0, 0), (d, 1), (1, 0); d = 1: (0, 0), (1, 1)
    (the drop at the wrap), which is also the table [[0, 1], [0, 0]];
  - trapezoid (rise r, hold h, fall f): (0, 0), (r, 1), (r + h, 1),
    (r + h + f, 0), (1, 0), repeated points dropped; a fraction of 0 is a
    jump, r + h + f = 1 leaves no dwell;
  - table [[u_k, l_k]]: the entries, then (u_0 + 1, l_0).
* The slew limit S [V/s]: the follower y(u) moves toward w(u) at most at
  sigma = S / (|V| f) levels per cycle, and tracks w where |w'| <= sigma
  once it has met it. Its one-cycle map Phi (follow one cycle from
  y(U_0) = y0, exactly, segment by segment: the meeting points are
  solved in closed form) is non-decreasing with slope at most 1, and
  Phi(min w) >= min w, Phi(max w) <= max w, so the periodic orbit is a root
  of Phi(y) - y on [min w, max w], found here by bisection to the last bit.
  A root is unique when the follower meets the waveform or crosses a
  finite flank in a cycle; the script checks that it is (it refuses an
  instance whose orbit is not unique). The orbit is again a polyline,
  without jumps: its corners are the meeting and leaving points and the
  waveform's corners.
* The drive force F_i(t) = gain_i V_i y_i(f_i t + phase_i) is affine
  between consecutive corners; every corner of every driven axis is a
  breakpoint where the integration restarts (and a stuck slider is checked
  for breakaway, as crosscheck.py does at duty-1 drops).

crosscheck.py's minimum watcher misses a band left and re-entered inside
one step of a BAND piece that then ends in a reversal within the same
step; every BAND piece not ended by "leave band" is therefore also
scanned on its dense output (`WaveReference.hidden_excursion`), and a
crossing found there counts among the recovered ones.

Also computed, and asserted with `--backward` (printed otherwise): the
**backward travel** per axis per own drive cycle over the
measured window, (total variation of x_s,i - |net displacement|) / 2 /
(own drive cycles in the window). The slider's velocity zeros are located
as non-terminal events of every piece of the integration, with the zeros
of its acceleration (the extrema of v_s,i) watched too, so a pair of zeros
hidden inside one step is found on the dense output (counted like
crosscheck.py's recovered crossings). Events that do not end a piece do
not change solve_ivp's steps, so the steps are the same with or without
this. `--backward` runs the default scene with `[output] backward = true`
and asserts it against /maps/backward_x and /maps/backward_y within
BACKWARD_BOUND_M.

The instances (each family from its own random stream [seed, 100 + k], so
a family's size changes no other family): mechanisms and stages drawn as
in crosscheck.py (`draw`: equal stages for even indices, a stage per axis
for odd ones, "mp" in the label), bands 1e-7 to 1e-5 m/s, |V| 60 to 150 V
(either sign; smaller drives mostly stick), window 3 / 1. Instance 0 of
every family (and 3 of t, j and b) has axis y undriven (1-DOF); the rest
are 2-DOF, both axes of the family's kind at their own frequencies:

* t: trapezoids with a hold and a dwell (rise 0.2-0.55, hold 0.05-0.3,
  fall 0.002-0.03);
* j: trapezoids with jumps, in turn: rise 0 (a jump up), fall 0 (a jump
  down), rise 0 and fall 0 (a square pulse), rise + hold + fall = 1 in
  256ths (no dwell; with fall 0 the drop is at the wrap);
* b: tables of 3 to 6 distinct u, one or two of them doubled (jumps; b2 x
  with a jump at u = 0), levels of both signs, the first entry mostly
  after u = 0 (the wrap segment crosses the cycle's start), some with a
  steep finite flank (0.002-0.01 of a cycle);
* s: slew-limited sawtooths: duty 0.9-0.995 with S = 0.3-0.9 times the
  fall's slope |V| f / (1 - d) (the follower tracks the rise); duty 1 (s1
  x, s4 x) with the drop slewed over 0.1-1 % of a cycle; s5 x duty 0.7
  with sigma below the rise's slope, so that the follower never meets the
  waveform but crosses it twice a cycle;
* p: slew-limited trapezoids: S = 0.3-0.9 times the steepest flank, or a
  jump (rise 0 or fall 0) slewed over 0.1-1 % of a cycle;
* w: slew-limited tables with a jump, a steep flank and levels of both
  signs: S = 0.3-0.9 times the steepest finite flank, or (odd j + i) only
  the jump limited (sigma above every finite flank, the jump over at most
  1 % of a cycle);
* l: 5 / 1 windows at a 2:1 frequency ratio (f_x = 2 f_y): a trapezoid on
  x and a table on y, one of them slewed at half its steepest flank.

A scene's axis y inherits axis x's `slew_rate`: the families give a
limited x a limited y, or an undriven one (where 0 V makes any limit none).

Two checks, both asserted (exit status 1 when either fails), as in
crosscheck.py:

* default: the engine at its default simulation.tolerance; every instance
  must end with status 0 and each step must be within BOUND_M (1e-9 m,
  0.001 um per own drive cycle) of SciPy's;
* tight: the engine at simulation.tolerance = `--tight` (1e-8) within
  TIGHT_BOUND_M (2e-7 um per own drive cycle; its comment gives the
  measurement). `--tight 0` skips it.

With `--verify`, the default scene runs a second time under `pidm run
--verify`, and the default check asks less of the engine's tolerance and
more of its labels: an instance that `--verify` flags unconverged (status
5) may be off by more than BOUND_M (its backward travel too, which its
step's error moves), an unflagged one may not (nothing silently wrong),
and a flag on an instance within BOUND_M / 10 of SciPy fails (a flag
that cannot tell converged from unconverged proves nothing). Unflagged
instances must keep the plain run's steps bit for bit.

SciPy runs DOP853 at rtol 1e-13 here (crosscheck.py: 1e-12; the absolute
tolerances scaled alike): at 1e-12 its own error on these instances
reaches 1.0e-7 um per cycle (j2 x, against rtol 2.2e-14, SciPy's
floor), which would dominate the tight check; at 1e-13 it is at most
9.6e-9 um, for about 20 % more time.

Usage: waveform.py [--pidm PATH] [--seed S] [--tight TOL] [--jobs N] [--rtol R]
                   [--keep DIR] [--only NAME...] [--backward] [--verify] [--verbose]
Environment: PIDM_BIN = path of the pidm binary when `--pidm` is not given
(else `cargo run --release`).
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

# The Karnopp model's SciPy integration (modes, events, slip direction,
# stick check), the engine's run and its file, and the draws of a
# mechanism and its stages: crosscheck.py's, unchanged.
from crosscheck import (
    Instance,
    draw,
    run_engine,
)
from waveform_reference import (
    SCIPY_RTOL,
    WaveInstance,
    integrate,
    polyline,
    steepest,
)

SEED = 20240611
CYCLES = 3
SETTLE = 1
LONG_CYCLES = 5
BANDS = (-7.0, -5.0)
# Instances per family (see the docstring).
FAMILIES = {"t": 6, "j": 6, "b": 6, "s": 6, "p": 5, "w": 4, "l": 2}
# The default check: 0.001 um per own drive cycle, the project's bar.
BOUND_M = 1e-9
# The tight check, at simulation.tolerance = 1e-8 (crosscheck.py's): the
# largest difference measured over the default instances (seed 20240611,
# SciPy at rtol 1e-13) is 1.98e-8 um (b1 y); SciPy's own error there is
# below 1.2e-10 um (rtol 1e-13 against 2.2e-14), and the engine at 1e-8
# is within 2.0e-8 um of SciPy at 2.2e-14 on every instance. The bound is
# 10 times the measurement. A slew orbit of the wrong frequency (sigma
# from the scene period instead of the axis' own frequency) moves s5 y,
# which has no slew limit of its own but shares the interface with s5 x,
# by 9.1e-5 um: only the tight check sees it.
# With --seed 7, w1 y was 3.2e-7 um off at every tolerance from 1e-8 to
# 1e-12, a band exit located at a later root of its bracket (fixed:
# results/events.md); it is now 2.8e-9 um off at 1e-8.
# At the default tolerance, --seed 4 has two instances past BOUND_M (j4 x
# 2.0e-3 um, b1 y 1.1e-3 um, on steps of 50-110 um; 1.2e-4 and 4.0e-5 um
# at tolerance 1e-5), --seed 6 one (j4 y 2.3e-3 um on 104.7 um, its
# backward travel 1.0e-3 um): `--seed 4 --verify` checks that `pidm run
# --verify` flags them (CI runs it; --seed 6 --verify --backward passes).
TIGHT_BOUND_M = 2e-13  # 2e-7 um per own drive cycle
TIGHT = 1e-8
# --backward: the bound on the backward travel per own drive cycle, the
# issue's. Measured with the default seed at the default tolerance: 5.1e-4
# um at worst (p3 x, where the step itself is 1.5e-4 um off), as the
# step's error moves the slider's path.
BACKWARD_BOUND_M = 1e-9

# Instances left out of the checks, by name, with the reason (printed).
EXCLUDED: dict[str, str] = {}

# /maps/status of an instance that `pidm run --verify` finds unconverged
# (docs/output.md; `STATUS_UNCONVERGED` in src/sweep/chunks.rs).
STATUS_UNCONVERGED = 5


def sawtooth(d: float) -> dict:
    return {"waveform": "sawtooth", "duty": d}


def trapezoid(r: float, h: float, f: float) -> dict:
    return {"waveform": "trapezoid", "rise": r, "hold": h, "fall": f}


def table(entries: list[tuple[float, float]]) -> dict:
    return {"waveform": "table", "table": [list(e) for e in entries]}


def draw_table(rng, jumps: int, first_at_zero: bool = False, steep: bool = False) -> dict:
    """3 to 6 distinct u with `jumps` of them doubled (jumps), levels of both signs.

    `first_at_zero` puts a jump at u = 0; `steep` adds an entry 0.002 to
    0.01 of a cycle after another one, at a level across 0 from it (a steep
    finite flank).
    """

    def level(lo: float, hi: float) -> float:
        return float(np.round(rng.uniform(lo, hi), 4))

    n = max(int(rng.integers(3, 7)), jumps + 1)
    us = {0.0} if first_at_zero else set()
    while len(us) < n:
        us.add(level(0.0, 0.95))
    us = sorted(us)
    rest = [k for k in range(len(us)) if not (first_at_zero and k == 0)]
    doubled = [int(k) for k in rng.choice(rest, size=jumps - first_at_zero, replace=False)]
    if first_at_zero:
        doubled.append(0)
    entries = []
    for k, u in enumerate(us):
        entries.append([u, level(-1.0, 1.0)])
        if k in doubled:
            a = entries[-1][1]
            b = level(0.3, 1.0) * (-1.0 if a > 0.0 else 1.0) + (0.0 if abs(a) < 0.7 else a)
            entries.append([u, float(np.clip(np.round(b, 4), -1.0, 1.0))])
    # At least one level well below 0 and one well above.
    entries[int(rng.integers(len(entries)))][1] = -level(0.5, 1.0)
    entries[int(rng.integers(len(entries)))][1] = level(0.5, 1.0)
    for a, b in itertools.pairwise(entries):
        if a[0] == b[0] and abs(a[1] - b[1]) < 0.3:  # keep every jump a jump
            b[1] = float(np.round(a[1] - math.copysign(0.6, a[1]), 4))
    if steep:
        k = int(rng.integers(len(entries)))
        u = float(np.round(entries[k][0] + rng.uniform(0.002, 0.01), 4))
        nxt = entries[k + 1][0] if k + 1 < len(entries) else 1.0
        if u < nxt and u < 1.0:
            lv = entries[k][1]
            entries.insert(k + 1, [u, -math.copysign(level(0.5, 1.0), lv)])
    return table([tuple(e) for e in entries])


def draw_trapezoid(rng, family: str, j: int) -> dict:
    """A trapezoid: with a hold and a dwell ("t") or with jumps ("j", by j)."""

    def f(lo, hi):
        return float(np.round(rng.uniform(lo, hi), 4))

    if family == "t":
        return trapezoid(f(0.2, 0.55), f(0.05, 0.3), f(0.002, 0.03))
    kind = j % 4
    if kind == 0:  # rise 0: a jump up
        return trapezoid(0.0, f(0.1, 0.4), f(0.003, 0.05))
    if kind == 1:  # fall 0: a jump down
        return trapezoid(f(0.3, 0.8), f(0.0, 0.1), 0.0)
    if kind == 2:  # a square pulse
        return trapezoid(0.0, f(0.2, 0.6), 0.0)
    # No dwell: exact 1/256ths summing to 1 (fall 0: the drop at the wrap).
    r = int(rng.integers(64, 192))
    h = int(rng.integers(1, 256 - r))
    fall = 256 - r - h if rng.uniform() < 0.5 else 0
    return trapezoid(r / 256, (256 - r - fall) / 256, fall / 256)


def make_instances(seed: int, families: dict[str, int]) -> list[WaveInstance]:
    """The families of the docstring, each from its own stream [seed, 100 + k]."""
    out = []
    for k, (fam, count) in enumerate(families.items()):
        rng = np.random.default_rng([seed, 100 + k])
        for j in range(count):
            base = draw(rng, f"{fam}{j}", BANDS, equal_stages=j % 2 == 0)
            inst = WaveInstance(**{key: getattr(base, key) for key in base.__dataclass_fields__})
            # 60 to 150 V (the sign drawn): smaller drives mostly stick.
            inst.voltage = [math.copysign(float(rng.uniform(60.0, 150.0)), v) for v in inst.voltage]
            one_dof = j == 0 or (j == 3 and fam in "tjb")
            shapes, slews, notes = [], [None, None], []
            for i in range(2):
                V, fr = abs(inst.voltage[i]), inst.frequency[i]
                if fam in "tj":
                    shapes.append(draw_trapezoid(rng, fam, j + i))
                elif fam == "b":
                    first = j == 2 and i == 0
                    shapes.append(draw_table(rng, 1 + (j + i) % 2, first, steep=(j + i) % 3 == 0))
                elif fam == "s":
                    if j in (1, 4) and i == 0:
                        # Duty 1: the drop slewed over 0.1 to 1 % of a cycle.
                        shapes.append(sawtooth(1.0))
                        slews[i] = V * fr / float(rng.uniform(0.001, 0.01))
                    elif j == 5 and i == 0:
                        # sigma below the rise's slope: the follower never meets
                        # the waveform, it crosses it twice a cycle.
                        shapes.append(sawtooth(0.7))
                        slews[i] = float(rng.uniform(0.3, 0.4)) * V * fr / 0.3
                    else:
                        d = float(np.round(rng.uniform(0.9, 0.995), 4))
                        shapes.append(sawtooth(d))
                        slews[i] = float(rng.uniform(0.3, 0.9)) * V * fr / (1.0 - d)
                elif fam == "p":
                    shp = draw_trapezoid(rng, "j" if (j + i) % 3 == 1 else "t", j + i)
                    shapes.append(shp)
                    U, L = polyline(shp)
                    if shp["rise"] == 0.0 or shp["fall"] == 0.0:
                        # A jump, slewed over 0.1 to 1 % of a cycle.
                        slews[i] = V * fr / float(rng.uniform(0.001, 0.01))
                    else:
                        slews[i] = float(rng.uniform(0.3, 0.9)) * V * fr * steepest(U, L)
                elif fam == "w":
                    shp = draw_table(rng, 1, steep=True)
                    shapes.append(shp)
                    U, L = polyline(shp)
                    if (j + i) % 2:
                        # Only the jumps limited: 1.1 to 2 times the steepest
                        # finite flank, the jump over at most 1 % of a cycle.
                        sigma = max(float(rng.uniform(1.1, 2.0)) * steepest(U, L), 200.0)
                    else:
                        sigma = float(rng.uniform(0.3, 0.9)) * steepest(U, L)
                    slews[i] = sigma * V * fr
                elif fam == "l":
                    shp = trapezoid(0.5, 0.1, 0.01) if i == 0 else draw_table(rng, 1, steep=True)
                    shapes.append(shp)
                    if i == j % 2:
                        U, L = polyline(shp)
                        slews[i] = 0.5 * V * fr * steepest(U, L)
            if fam == "l":
                inst.frequency[0] = 2.0 * inst.frequency[1]
                inst.cycles = LONG_CYCLES
                notes.append("2:1")
            if one_dof:
                inst.voltage[1] = 0.0
                notes.append("1-DOF")
            # A scene's axis y inherits axis x's slew_rate: the families give a
            # limited x a limited y (or an undriven one, where a limit is none).
            if slews[0] is not None and slews[1] is None and not one_dof:
                raise AssertionError(f"{fam}{j}: x slewed, y not")
            if one_dof:
                slews[1] = None
            inst.shape = shapes
            inst.slew_rate = slews
            inst.duty = [math.nan, math.nan]  # unused: the shape is the drive
            kinds = []
            for i in range(1 if one_dof else 2):
                kinds.append(shape_word(shapes[i]) + ("/S" if slews[i] else ""))
            inst.label = f"{fam}{j} " + " ".join(kinds + notes + (["mp"] if j % 2 else []))
            out.append(inst)
    return out


def shape_word(shape: dict) -> str:
    """The waveform in a word, for the label."""
    kind = shape["waveform"]
    if kind == "sawtooth":
        return f"saw{shape['duty']:g}"
    if kind == "trapezoid":
        r, h, f = shape["rise"], shape["hold"], shape["fall"]
        tags = [
            tag for tag, on in (("r0", r == 0.0), ("f0", f == 0.0), ("=1", r + h + f == 1.0)) if on
        ]
        return "trap" + ("(" + ",".join(tags) + ")" if tags else "")
    return f"tab{len(shape['table'])}"


def name(inst: Instance) -> str:
    return inst.label.split()[0]


def toml_value(v) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return repr(float(v))


def scene_toml(
    instances: list[WaveInstance], tolerance: float | None = None, backward: bool = False
) -> str:
    lines = [
        'name = "waveform crosscheck"',
        'description = "seeded waveform and slew-limit instances for the SciPy cross-check"',
        "",
        "[simulation]",
        'measure = "window"',
        f"cycles = {CYCLES}",
        f"settle = {SETTLE}",
    ]
    if tolerance is not None:
        lines.append(f"tolerance = {tolerance!r}")
    if backward:
        lines += ["", "[output]", "backward = true"]
    lines.append("")
    for inst in instances:
        lines.append("[[points]]")
        lines.append(f'label = "{inst.label}"')
        lines.append(f"simulation.cycles = {inst.cycles}")
        lines.append(f"simulation.settle = {inst.settle}")
        for key in ("slider_mass", "static_friction", "coulomb_friction", "velocity_band"):
            lines.append(f"mechanism.{key} = {getattr(inst, key)!r}")
        for i, axis in enumerate("xy"):
            for key in ("stage_mass", "stiffness", "damping", "gain"):
                lines.append(f"axis.{axis}.{key} = {getattr(inst, key)[i]!r}")
            lines.append(f"axis.{axis}.voltage = {inst.voltage[i]!r}")
            lines.append(f"axis.{axis}.frequency = {inst.frequency[i]!r}")
            lines.append(f"axis.{axis}.phase = {inst.phase[i]!r}")
            for key, value in inst.shape[i].items():
                lines.append(f"axis.{axis}.{key} = {toml_value(value)}")
            if inst.slew_rate[i] is not None:
                lines.append(f"axis.{axis}.slew_rate = {inst.slew_rate[i]!r}")
        lines.append("")
    return "\n".join(lines)


# ----------------------------------------------------------------------------
# The engine


@dataclass
class Engine:
    """One `pidm run` of the scene: its steps, statuses and (optional) travel."""

    step: tuple[np.ndarray, np.ndarray]
    status: np.ndarray
    backward: tuple[np.ndarray, np.ndarray] | None
    seconds: float
    backend: str
    problems: list[str]


def engine(
    scene: Path,
    out: Path,
    binary: str | None,
    backward: bool,
    backend: str = "cpu",
    extra: tuple[str, ...] = (),
) -> Engine:
    """`pidm run SCENE --backend BACKEND --out FILE [EXTRA]` (crosscheck.py's
    run_engine, f64 on the GPU), read back."""
    run = run_engine(scene, out, backend, "f64" if backend == "gpu" else None, binary, extra)
    problems = list(run.problems)
    travel = None
    if backward:
        with h5py.File(out, "r") as h5:
            missing = [k for k in ("/maps/backward_x", "/maps/backward_y") if k not in h5]
            if missing:
                problems.append(f"--backward: {out.name} has no {', '.join(missing)}")
            else:
                travel = tuple(
                    np.asarray(h5[k][...], dtype=float)
                    for k in ("/maps/backward_x", "/maps/backward_y")
                )
    return Engine((run.step_x, run.step_y), run.status, travel, run.seconds, run.backend, problems)


# ----------------------------------------------------------------------------


def describe(inst: WaveInstance) -> str:
    """The drive of each axis, for --verbose."""
    parts = []
    for i, axis in enumerate("xy"):
        if not inst.driven(i):
            parts.append(f"    {axis}: undriven")
            continue
        shape = ", ".join(f"{k} = {v}" for k, v in inst.shape[i].items())
        U, _ = inst.drive(i)
        slew = ""
        if inst.slew_rate[i] is not None:
            slew = f", slew_rate {inst.slew_rate[i]:.6g} V/s (sigma {inst.sigma(i):.4g}/cycle)"
        parts.append(
            f"    {axis}: {inst.voltage[i]:+.2f} V, {inst.frequency[i]:.3f} Hz, phase "
            f"{inst.phase[i]:.4f}, {shape}{slew}; {len(U) - 1} drive segments"
        )
    return "\n".join(parts)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pidm", help="the pidm binary (else $PIDM_BIN, else cargo run --release)")
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument(
        "--backend",
        choices=["cpu", "gpu"],
        default="cpu",
        help="the engine's backend (gpu: the f64 shader, which must run every instance itself)",
    )
    ap.add_argument("--keep", type=Path, help="write the scenes and HDF5 files here")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="only these instances (t0, s3, ...)")
    ap.add_argument(
        "--tight",
        type=float,
        default=TIGHT,
        help=f"also run the engine at this simulation.tolerance and check it against "
        f"the tight bound ({TIGHT_BOUND_M * 1e6:g} um, measured at {TIGHT:g}); 0 skips it",
    )
    ap.add_argument(
        "--jobs",
        type=int,
        default=os.cpu_count() or 1,
        help="SciPy integrations in parallel (default: one per core)",
    )
    ap.add_argument(
        "--backward",
        action="store_true",
        help="also assert the backward travel against /maps/backward_x and /maps/backward_y "
        f"(within {BACKWARD_BOUND_M * 1e6:g} um per own drive cycle)",
    )
    ap.add_argument(
        "--rtol",
        type=float,
        default=SCIPY_RTOL,
        help=f"SciPy's DOP853 rtol (default {SCIPY_RTOL:g}; the absolute tolerances scaled alike)",
    )
    ap.add_argument(
        "--verify",
        action="store_true",
        help="also run the default scene under `pidm run --verify`: instances it flags "
        "unconverged may miss the default bound, unflagged ones may not",
    )
    ap.add_argument("--verbose", "-v", action="store_true", help="print each instance's drive")
    args = ap.parse_args()
    binary = args.pidm or os.environ.get("PIDM_BIN")
    started = time.time()
    instances = make_instances(args.seed, FAMILIES)
    if args.only:
        unknown = set(args.only) - {name(inst) for inst in instances}
        if unknown:
            ap.error(f"--only: no instance named {', '.join(sorted(unknown))}")
        instances = [inst for inst in instances if name(inst) in args.only]
    runs: dict[str, Engine] = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for which, tolerance in (("default", None), ("tight", args.tight or None)):
            if which == "tight" and tolerance is None:
                continue
            travel = args.backward and which == "default"  # the default run's only
            scene = work / f"waveform_{which}.toml"
            scene.write_text(scene_toml(instances, tolerance, travel))
            runs[which] = engine(scene, work / f"waveform_{which}.h5", binary, travel, args.backend)
        if args.verify:
            runs["verified"] = engine(
                work / "waveform_default.toml",
                work / "waveform_verified.h5",
                binary,
                False,
                args.backend,
                ("--verify",),
            )
    eng, tight, verified = runs["default"], runs.get("tight"), runs.get("verified")
    failures = []
    for which, run in runs.items():
        failures += [f"{which}: {p}" for p in run.problems]
    counts = {}
    for inst in instances:
        counts[name(inst)[0]] = counts.get(name(inst)[0], 0) + 1
    print(
        f"{len(instances)} instances ("
        + ", ".join(f"{fam} {n}" for fam, n in counts.items())
        + (f"; only {' '.join(args.only)}" if args.only else "")
        + f"), seed {args.seed}; engine: {eng.backend}, {eng.seconds:.1f} s at the default "
        "tolerance" + (f", {tight.seconds:.1f} s at {args.tight:g}" if tight else "")
    )
    print(
        "steps and backward travel in um per own drive cycle; pass: engine status 0, "
        f"|engine - scipy| <= {BOUND_M * 1e6:g} um at the default tolerance"
        + (f" and <= {TIGHT_BOUND_M * 1e6:g} um at {args.tight:g}" if tight else " (tight skipped)")
        + (", or flagged unconverged by --verify" if verified else "")
        + (
            f"; backward within {BACKWARD_BOUND_M * 1e6:g} um"
            if args.backward
            else "; backward travel printed, not checked"
        )
    )
    lw = max([len(inst.label) for inst in instances] + [8])
    header = (
        f"{'instance':<{lw}} {'st':>2} {'axis':>4} {'engine':>12} {'scipy':>12} {'diff':>9} "
        f"{'tight':>9} {'backward':>10}"
    )
    if args.backward:
        header += f" {'bw diff':>9}"
    print(header + f" {'events':>6} {'s':>5}")
    wall_scipy = time.time()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        references = list(pool.map(integrate, instances, itertools.repeat(args.rtol)))
    wall_scipy = time.time() - wall_scipy
    worst = {"default": (0.0, ""), "tight": (0.0, ""), "backward": (0.0, "")}
    flags: dict[str, list[float]] = {}
    t_scipy = 0.0
    for j, (inst, ref) in enumerate(zip(instances, references)):
        excluded = EXCLUDED.get(name(inst))
        if args.verbose:
            print(describe(inst))
        if ref.error:
            print(f"{inst.label:<{lw}} SciPy reference failed: {ref.error}  FAIL")
            failures.append(f"{inst.label}: SciPy reference failed: {ref.error}")
            continue
        t_scipy += ref.seconds
        for i, axis in enumerate("xy"):
            s = ref.step[i]
            e = eng.step[i][j]
            checks = [("default", eng, e, s, BOUND_M)]
            if tight:
                checks.append(("tight", tight, tight.step[i][j], s, TIGHT_BOUND_M))
            cells, bad = {}, []
            flagged = verified is not None and verified.status[j] == STATUS_UNCONVERGED
            for which, run, value, want, bound in checks:
                diff = abs(value - want)
                cells[which] = diff
                if run.status[j] != 0:
                    bad.append(f"{which} status {run.status[j]}")
                elif which == "default" and flagged:
                    flags.setdefault(name(inst), []).append(diff)
                elif not diff <= bound:
                    bad.append(f"{which} {diff * 1e6:.2e} um")
                elif not excluded and diff > worst[which][0]:
                    worst[which] = (diff, f"{name(inst)} {axis}")
            bw = ref.backward[i]
            bw_cell = ""
            if args.backward and eng.backward is not None:
                diff = abs(eng.backward[i][j] - bw)
                bw_cell = f" {diff * 1e6:>9.2e}"
                if flagged:
                    pass  # its step's error moves its path: labelled with it
                elif not diff <= BACKWARD_BOUND_M:
                    bad.append(f"backward {diff * 1e6:.2e} um")
                elif not excluded and diff > worst["backward"][0]:
                    worst["backward"] = (diff, f"{name(inst)} {axis}")
            if verified is not None and not flagged:
                if verified.status[j] != 0:
                    bad.append(f"--verify status {verified.status[j]}")
                elif verified.step[i][j] != e:
                    bad.append(f"--verify moved the step by {abs(verified.step[i][j] - e):.2e} m")
            mark = "  flagged by --verify" if flagged else ""
            if excluded:
                mark = "  excluded"
            elif bad:
                mark = "  FAIL (" + ", ".join(bad) + ")"
                failures.append(f"{inst.label} {axis}: " + ", ".join(bad))
            first = i == 0
            print(
                f"{inst.label if first else '':<{lw}} {eng.status[j]:>2} {axis:>4} "
                f"{e * 1e6:>12.6f} {s * 1e6:>12.6f} {cells['default'] * 1e6:>9.2e} "
                f"{cells.get('tight', math.nan) * 1e6:>9.2e} {bw * 1e6:>10.4f}{bw_cell} "
                f"{ref.events if first else '':>6} {f'{ref.seconds:.1f}' if first else '':>5}"
                f"{mark}"
            )
        if ref.recovered or ref.travel_recovered:
            print(
                f"{'':<{lw}} ({ref.recovered} mode crossing(s), {ref.travel_recovered} velocity "
                "zero(s) inside a step recovered from the dense output)"
            )
    for label, reason in EXCLUDED.items():
        print(f"excluded {label}: {reason}")
    if verified is not None:
        for label, diffs in flags.items():
            largest = max(diffs)
            print(
                f"flagged unconverged by --verify: {label}, off by {largest * 1e6:.2e} um at "
                f"the default tolerance"
            )
            if not largest > BOUND_M / 10:
                failures.append(
                    f"{label}: --verify flags it though it is within "
                    f"{BOUND_M / 10 * 1e6:g} um of SciPy"
                )
        print(f"--verify flagged {len(flags)} of {len(instances)} instance(s)")
    for which, title in (
        ("default", "the default tolerance"),
        ("tight", f"tolerance {args.tight:g}"),
    ):
        if which == "tight" and not tight:
            continue
        bound = BOUND_M if which == "default" else TIGHT_BOUND_M
        print(
            f"max |engine - scipy| at {title} = {worst[which][0] * 1e6:.3e} um "
            f"({worst[which][1]}; bound {bound * 1e6:g} um)"
        )
    if args.backward:
        print(
            f"max |engine - scipy| of the backward travel = {worst['backward'][0] * 1e6:.3e} um "
            f"({worst['backward'][1]}; bound {BACKWARD_BOUND_M * 1e6:g} um)"
        )
    for failure in failures:
        print(f"FAIL: {failure}")
    print(
        f"waveform crosscheck: {len(failures)} failure(s); scipy {t_scipy:.1f} s in {args.jobs} "
        f"process(es), {wall_scipy:.1f} s wall; total {time.time() - started:.1f} s"
    )
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
