#!/usr/bin/env python3
"""Independent cross-check of the pidm engine against SciPy.

Seeded random 2-DOF instances are written as a points scene, run through
the engine (`pidm run`), and integrated again here, independently, with
`scipy.integrate.solve_ivp` (DOP853, tight tolerances) as a hybrid system:
every mode change is an event function, every drive corner and period end a
breakpoint where the integration restarts. The semantics are those of
MODEL.md with the engine's documented choices (src/cpu/integrate.rs):

* STICK: per axis one body, (m_p + m_s) a = P, P = F - c v - k x_p;
  f_need = m_s P / (m_p + m_s). Breaks when |f_need| > f_s (event
  f_s^2 - |f_need|^2, also checked at every breakpoint: duty 1 jumps).
* Breakaway -> BAND: relative velocity exactly 0, friction on the slider
  held along f_need / |f_need| (the stages are equal, so the engine's slip
  direction is f_need's).
* BAND and SLIP: m_p a_p = P - f_c u, m_s a_s = f_c u; u is the held vector
  in BAND and v_rel / |v_rel| in SLIP.
* BAND -> SLIP when |v_rel| rises to the band a; BAND also watches
  v_rel . u_held changing sign (a reversal) -> stick check.
* SLIP -> stick check when |v_rel| falls to a.
* Stick check: merge velocities per axis conserving momentum, compute f_need
  from the merged state; STICK if |f_need| <= f_s, else BAND along f_need.

solve_ivp finds an event only where its function changes sign between two
accepted steps. To catch a crossing hidden inside one step (a dip below
zero and back), every event function's derivative is also watched as a
non-terminal event at the function's local minima: a minimum below zero
before the reported event means a missed crossing, which is then located on
the dense output. The number of such recoveries is printed. A mode that
begins at an event starts with one watched function at its zero (v_rel = 0
in a fresh BAND, |v_rel| = a in a fresh SLIP); that function is watched as
g / (t - t0), signed at t0 by its slope, so a crossing in the first step is
seen and one that starts downward fires at once (the engine does the same
with its first sample).

Exits non-zero when any engine status is not 0 or any step differs from
SciPy's by more than 1e-9 m (0.001 um) per cycle. The engine is also run at
simulation.tolerance = 1e-8 (--tight) and that difference is shown, for
information: it separates the engine's accuracy knob from disagreements in
the model.

Usage: crosscheck.py [--instances N] [--seed S] [--keep DIR] [--tight TOL]
Environment: PIDM_BIN = path of the pidm binary (else `cargo run --release`).
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

SEED = 20240611
INSTANCES = 40
CYCLES = 3
SETTLE = 1
STIFFNESS = 1.0e6
GAIN = -0.6
BOUND_M = 1e-9  # 0.001 um per cycle

STICK, SLIP, BAND = "STICK", "SLIP", "BAND"

RTOL = 1e-12
ATOL = np.array([1e-15, 1e-15, 1e-12, 1e-12, 1e-15, 1e-15, 1e-12, 1e-12])
# State layout: x_p (x, y), v_p (x, y), x_s (x, y), v_s (x, y).

REPO = Path(__file__).resolve().parents[2]


# ----------------------------------------------------------------------------
# Instances


@dataclass
class Instance:
    label: str
    voltage: list[float]
    frequency: list[float]
    phase: list[float]
    duty: list[float]
    slider_mass: float
    static_friction: float
    coulomb_friction: float
    velocity_band: float
    stage_mass: float
    stiffness: float
    damping: float
    gain: float
    extra: dict = field(default_factory=dict)

    def driven(self, i: int) -> bool:
        return self.voltage[i] != 0.0

    def period(self) -> float:
        freqs = [self.frequency[i] for i in range(2) if self.driven(i)]
        return 1.0 / (min(freqs) if freqs else self.frequency[0])


def make_instances(n: int, seed: int) -> list[Instance]:
    rng = np.random.default_rng(seed)
    out = []

    def f(lo: float, hi: float) -> float:
        return float(rng.uniform(lo, hi))

    for j in range(n):
        voltage = [f(-150.0, 150.0), f(-150.0, 150.0)]
        frequency = [f(5.0, 30.0), f(5.0, 30.0)]
        phase = [f(0.0, 1.0), f(0.0, 1.0)]
        duty = [f(0.7, 1.0), f(0.7, 1.0)]
        slider_mass = f(2e-3, 2e-2)
        static_friction = f(0.8, 2.0)
        coulomb_friction = static_friction * f(0.4, 1.0)
        velocity_band = float(10.0 ** rng.uniform(-7.0, -5.0))
        resonance = f(1000.0, 4000.0)
        quality = f(10.0, 40.0)
        stage_mass = STIFFNESS / (2.0 * math.pi * resonance) ** 2
        damping = math.sqrt(STIFFNESS * stage_mass) / quality
        label = f"r{j}"
        # A few deliberate corner cases on top of the random draws.
        if j == 0:
            duty = [1.0, 1.0]
            label += " duty 1/1"
        elif j == 1:
            duty[0] = 1.0
            label += " duty 1/-"
        elif j == 2:
            duty[1] = 1.0
            label += " duty -/1"
        elif j == 3:
            voltage[1] = 0.0
            label += " y undriven"
        out.append(
            Instance(
                label,
                voltage,
                frequency,
                phase,
                duty,
                slider_mass,
                static_friction,
                coulomb_friction,
                velocity_band,
                stage_mass,
                STIFFNESS,
                damping,
                GAIN,
                {"resonance_hz": resonance, "quality": quality},
            )
        )
    return out


def scene_toml(instances: list[Instance], tolerance: float | None = None) -> str:
    lines = [
        'name = "crosscheck"',
        'description = "seeded random instances for the SciPy cross-check"',
        "",
        "[simulation]",
        f"cycles = {CYCLES}",
        f"settle = {SETTLE}",
    ]
    if tolerance is not None:
        lines.append(f"tolerance = {tolerance!r}")
    lines.append("")
    for inst in instances:
        lines.append("[[points]]")
        lines.append(f'label = "{inst.label}"')
        for key in ("slider_mass", "static_friction", "coulomb_friction", "velocity_band"):
            lines.append(f"mechanism.{key} = {getattr(inst, key)!r}")
        for i, name in enumerate("xy"):
            for key in ("stage_mass", "stiffness", "damping", "gain"):
                lines.append(f"axis.{name}.{key} = {getattr(inst, key)!r}")
            lines.append(f"axis.{name}.voltage = {inst.voltage[i]!r}")
            lines.append(f"axis.{name}.frequency = {inst.frequency[i]!r}")
            lines.append(f"axis.{name}.duty = {inst.duty[i]!r}")
            lines.append(f"axis.{name}.phase = {inst.phase[i]!r}")
        lines.append("")
    return "\n".join(lines)


# ----------------------------------------------------------------------------
# The engine


def run_engine(scene: Path, out: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    binary = os.environ.get("PIDM_BIN")
    if binary:
        cmd = [binary, "run", str(scene), "--out", str(out)]
    else:
        cmd = ["cargo", "run", "--release", "--quiet", "--", "run", str(scene), "--out", str(out)]
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    # Exit code 3 means some instance ended with a non-zero status: the maps
    # are still written, and the status check below reports it.
    if proc.returncode not in (0, 3) or not out.exists():
        sys.stderr.write(proc.stdout + proc.stderr)
        raise SystemExit(f"engine failed: {' '.join(cmd)} (exit {proc.returncode})")
    with h5py.File(out, "r") as h5:
        return (
            np.asarray(h5["/maps/step_x"][...], dtype=float),
            np.asarray(h5["/maps/step_y"][...], dtype=float),
            np.asarray(h5["/maps/status"][...], dtype=int),
        )


# ----------------------------------------------------------------------------
# The SciPy reference


def divided(g, dg, t0):
    """g / (t - t0), continued at t0 by the sign of the slope dg."""

    def h(t, y):
        if t == t0:
            return dg(t, y)
        return g(t, y) / (t - t0)

    return h


class Reference:
    """Hybrid-system integration of one instance with solve_ivp."""

    def __init__(self, inst: Instance):
        self.inst = inst
        self.mp = inst.stage_mass
        self.ms = inst.slider_mass
        self.k = inst.stiffness
        self.c = inst.damping
        self.fs = inst.static_friction
        self.fc = inst.coulomb_friction
        self.band = inst.velocity_band
        self.M = self.mp + self.ms
        self.amp = [inst.gain * inst.voltage[i] if inst.driven(i) else 0.0 for i in range(2)]
        # Fastest free oscillation per mode, for the largest step.
        w_slip = math.sqrt(self.k / self.mp) + self.c / self.mp
        w_stick = math.sqrt(self.k / self.M) + self.c / self.M
        self.max_step = {
            SLIP: 0.25 * 2 * math.pi / w_slip,
            BAND: 0.25 * 2 * math.pi / w_slip,
            STICK: 0.25 * 2 * math.pi / w_stick,
        }
        self.events = []  # (time, description)
        self.recovered = 0
        self.nfev = 0

    # -- drive ---------------------------------------------------------------

    def breakpoints(self, t_end: float, T: float) -> list[float]:
        pts = {k * T for k in range(CYCLES + 1)}
        for i in range(2):
            if not self.inst.driven(i):
                continue
            f, p, d = self.inst.frequency[i], self.inst.phase[i], self.inst.duty[i]
            n_max = int(math.ceil(f * t_end + p)) + 1
            for n in range(0, n_max + 1):
                for corner in (n, n + d) if d < 1.0 else (n,):
                    t = (corner - p) / f
                    if 0.0 < t < t_end:
                        pts.add(t)
        return sorted(pts)

    def segment_force(self, t0: float, t1: float) -> list[tuple[float, float]]:
        """Drive force of each axis on (t0, t1) as c0 + c1 t (affine there)."""
        out = []
        tm = 0.5 * (t0 + t1)
        for i in range(2):
            A = self.amp[i]
            if A == 0.0:
                out.append((0.0, 0.0))
                continue
            f, p, d = self.inst.frequency[i], self.inst.phase[i], self.inst.duty[i]
            u = p + f * tm
            n = math.floor(u)
            if u - n < d:  # rise: A (u - n) / d
                out.append((A * (p - n) / d, A * f / d))
            else:  # fall: A (n + 1 - u) / (1 - d)
                out.append((A * (n + 1 - p) / (1 - d), -A * f / (1 - d)))
        return out

    # -- mechanics -----------------------------------------------------------

    def f_need(self, t: float, y: np.ndarray, force) -> tuple[float, float]:
        """Static force stick needs, with the velocities merged."""
        out = []
        for i in range(2):
            v = (self.mp * y[2 + i] + self.ms * y[6 + i]) / self.M
            P = force[i][0] + force[i][1] * t - self.c * v - self.k * y[i]
            out.append(self.ms * P / self.M)
        return out[0], out[1]

    def merge(self, y: np.ndarray) -> np.ndarray:
        y = y.copy()
        for i in range(2):
            v = (self.mp * y[2 + i] + self.ms * y[6 + i]) / self.M
            y[2 + i] = v
            y[6 + i] = v
        return y

    def system(self, mode: str, force, held):
        """Right-hand side and events (terminal, with their minimum watchers)."""
        (c0x, c1x), (c0y, c1y) = force
        mp, ms, M, k, c, fc = self.mp, self.ms, self.M, self.k, self.c, self.fc
        fs2 = self.fs * self.fs
        ms2 = ms * ms
        a2 = self.band * self.band

        if mode == STICK:
            inv_m = 1.0 / M

            def rhs(t, y):
                xpx, xpy, vpx, vpy, _, _, vsx, vsy = y.tolist()
                ax = (c0x + c1x * t - c * vpx - k * xpx) * inv_m
                ay = (c0y + c1y * t - c * vpy - k * xpy) * inv_m
                return [vpx, vpy, ax, ay, vsx, vsy, ax, ay]

            def acc_jerk(t, y):
                xpx, xpy, vpx, vpy = y[:4].tolist()
                ax = (c0x + c1x * t - c * vpx - k * xpx) * inv_m
                ay = (c0y + c1y * t - c * vpy - k * xpy) * inv_m
                jx = (c1x - c * ax - k * vpx) * inv_m
                jy = (c1y - c * ay - k * vpy) * inv_m
                return ax, ay, jx, jy

            def breakaway(t, y):
                ax, ay, _, _ = acc_jerk(t, y)
                return fs2 - ms2 * (ax * ax + ay * ay)

            def breakaway_slope(t, y):
                ax, ay, jx, jy = acc_jerk(t, y)
                return -(ax * jx + ay * jy)

            return rhs, [("breakaway", breakaway, breakaway_slope, False)]

        def accel(t, y):
            """Stage and slider accelerations and v_rel, a_rel."""
            xpx, xpy, vpx, vpy, _, _, vsx, vsy = y.tolist()
            wx, wy = vpx - vsx, vpy - vsy
            if mode == SLIP:
                n = math.hypot(wx, wy)
                ux, uy = wx / n, wy / n
            else:
                ux, uy = held
            apx = (c0x + c1x * t - c * vpx - k * xpx - fc * ux) / mp
            apy = (c0y + c1y * t - c * vpy - k * xpy - fc * uy) / mp
            asx = fc * ux / ms
            asy = fc * uy / ms
            return (vpx, vpy, apx, apy, vsx, vsy, asx, asy), (wx, wy), (apx - asx, apy - asy)

        def rhs(t, y):
            return list(accel(t, y)[0])

        if mode == SLIP:

            def enter(t, y):
                _, (wx, wy), _ = accel(t, y)
                return wx * wx + wy * wy - a2

            def enter_slope(t, y):
                _, (wx, wy), (bx, by) = accel(t, y)
                return wx * bx + wy * by

            # Fresh slip starts where the band was left: |v_rel| = a.
            return rhs, [("enter band", enter, enter_slope, True)]

        hx, hy = held

        def leave(t, y):
            _, (wx, wy), _ = accel(t, y)
            return a2 - (wx * wx + wy * wy)

        def leave_slope(t, y):
            _, (wx, wy), (bx, by) = accel(t, y)
            return -(wx * bx + wy * by)

        def reversal(t, y):
            _, (wx, wy), _ = accel(t, y)
            return wx * hx + wy * hy

        def reversal_slope(t, y):
            _, _, (bx, by) = accel(t, y)
            return bx * hx + by * hy

        # A fresh band starts at v_rel = 0 exactly: the reversal function at 0.
        return rhs, [
            ("leave band", leave, leave_slope, False),
            ("reversal", reversal, reversal_slope, True),
        ]

    def integrate_piece(self, mode, force, held, t0, t1, y0, fresh):
        """Integrates one mode from t0 toward t1. Returns (t, y, event name or None).

        `fresh` is True right after the mode began at an event that put one of
        its watched functions at zero (v_rel = 0 in BAND, |v_rel| = a in SLIP).
        """
        rhs, raw = self.system(mode, force, held)
        watched = []
        for nm, g, dg, at_zero in raw:
            if at_zero and fresh:
                # A function that starts at its zero (up to the rounding of the
                # event that began this piece) is watched as g / (t - t0), whose
                # value at t0 is the sign of its slope: a crossing inside the
                # first step is then a sign change like any other, and a
                # function that starts downward fires at once.
                if dg(t0, y0) < 0.0:
                    return t0, y0, nm
                g = divided(g, dg, t0)
            watched.append((nm, g, dg))
        events = []
        for _, g, dg in watched:
            g.terminal = True
            g.direction = -1.0
            dg.terminal = False
            dg.direction = 1.0  # the slope rises through 0: a minimum of g
            events += [g, dg]
        kw = dict(method="DOP853", rtol=RTOL, atol=ATOL, max_step=self.max_step[mode])
        sol = solve_ivp(rhs, (t0, t1), y0, events=events, **kw)
        if sol.status < 0:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        self.nfev += sol.nfev
        t_end = sol.t[-1]
        y_end = sol.y[:, -1]
        name = None
        for j, (nm, g, _) in enumerate(watched):
            if len(sol.t_events[2 * j]):
                te = sol.t_events[2 * j][0]
                if name is None or te < t_end or (te == t_end):
                    name, t_end, y_end = nm, te, sol.y_events[2 * j][0]
        # A minimum below zero before the reported end is a crossing that fell
        # inside one step: locate it on the dense output and end there.
        missed = None
        for j, (nm, g, _) in enumerate(watched):
            for tm, ym in zip(sol.t_events[2 * j + 1], sol.y_events[2 * j + 1]):
                if tm < t_end and g(tm, ym) < 0.0 and (missed is None or tm < missed[1]):
                    missed = (j, tm)
                    break
        if missed is not None:
            j, tm = missed
            nm, g, _ = watched[j]
            # The same run again, now keeping the interpolants: the steps are
            # identical, so the minimum is found again in the same step.
            dense = solve_ivp(rhs, (t0, t1), y0, events=events, dense_output=True, **kw)
            k = min(int(np.searchsorted(dense.t, tm)) - 1, len(dense.sol.interpolants) - 1)
            step = dense.sol.interpolants[k]
            lo = dense.t[k]
            if not g(lo, step(lo)) > 0.0 or not g(tm, step(tm)) < 0.0:
                raise RuntimeError(f"could not bracket a crossing hidden in a step at t = {tm}")
            te = brentq(lambda s: g(s, step(s)), lo, tm, xtol=1e-18, rtol=4 * np.finfo(float).eps)
            self.recovered += 1
            return te, step(te), nm
        return t_end, np.array(y_end), name

    def start_slip(self, need):
        n = math.hypot(*need)
        return BAND, (need[0] / n, need[1] / n)

    def stick_check(self, t, y, force):
        y = self.merge(y)
        need = self.f_need(t, y, force)
        if math.hypot(*need) <= self.fs:
            return STICK, None, y
        mode, held = self.start_slip(need)
        return mode, held, y

    def run(self) -> tuple[float, float]:
        T = self.inst.period()
        t_end = CYCLES * T
        pts = self.breakpoints(t_end, T)
        y = np.zeros(8)
        mode, held = STICK, None
        fresh = False  # the mode began at an event, at this piece's start
        settle_xs = None
        for t0, t1 in zip(pts[:-1], pts[1:]):
            if abs(t0 - SETTLE * T) <= 0.0:
                settle_xs = y[4:6].copy()
            force = self.segment_force(t0, t1)
            if mode == STICK:
                need = self.f_need(t0, y, force)
                if math.hypot(*need) > self.fs:
                    mode, held = self.start_slip(need)
                    fresh = True
                    self.events.append((t0, "breakaway at corner"))
            t = t0
            stalled = 0
            while t < t1:
                t_new, y, name = self.integrate_piece(mode, force, held, t, t1, y, fresh)
                stalled = stalled + 1 if t_new <= t else 0
                if stalled > 64:
                    raise RuntimeError(f"event storm at t = {t}")
                t = t_new
                fresh = name is not None
                if name is None:
                    break
                self.events.append((t, f"{mode}: {name}"))
                if name == "breakaway":
                    mode, held = self.start_slip(self.f_need(t, y, force))
                elif name == "leave band":
                    mode, held = SLIP, None
                else:  # enter band, reversal
                    mode, held, y = self.stick_check(t, y, force)
                    self.events.append((t, f"-> {mode}"))
        if settle_xs is None:
            settle_xs = np.zeros(2)
        disp = y[4:6] - settle_xs
        vel = disp / ((CYCLES - SETTLE) * T)
        return vel[0] / self.inst.frequency[0], vel[1] / self.inst.frequency[1]


# ----------------------------------------------------------------------------


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--instances", type=int, default=INSTANCES)
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--keep", type=Path, help="write the scenes and HDF5 files here")
    ap.add_argument("--only", type=int, nargs="*", help="integrate only these instances")
    ap.add_argument(
        "--tight",
        type=float,
        default=1e-8,
        help="also run the engine at this simulation.tolerance and show its difference "
        "(information only, not checked; 0 to skip)",
    )
    args = ap.parse_args()
    if args.instances < 20:
        ap.error("at least 20 instances")
    started = time.time()
    instances = make_instances(args.instances, args.seed)
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        scene = work / "crosscheck.toml"
        scene.write_text(scene_toml(instances))
        t_engine = time.time()
        ex, ey, status = run_engine(scene, work / "crosscheck.h5")
        t_engine = time.time() - t_engine
        tight = None
        if args.tight > 0:
            scene = work / "crosscheck_tight.toml"
            scene.write_text(scene_toml(instances, args.tight))
            tight = run_engine(scene, work / "crosscheck_tight.h5")
    failures = checks = 0
    worst = worst_tight = 0.0
    t_scipy = 0.0
    print(
        f"{len(instances)} instances, seed {args.seed}, cycles {CYCLES}, settle {SETTLE}; "
        f"engine (default tolerance) {t_engine:.1f} s"
    )
    print("steps in um per own drive cycle; pass: engine status 0 and |engine - scipy| <= "
          f"{BOUND_M * 1e6:g} um")
    tight_head = f" {'tight diff':>10}" if tight else ""
    print(
        f"{'instance':<15} {'st':>2} {'axis':>4} {'engine':>14} {'scipy':>14} "
        f"{'diff':>10}{tight_head} {'events':>6} {'s':>5}"
    )
    for j, inst in enumerate(instances):
        if args.only is not None and j not in args.only:
            continue
        t0 = time.time()
        ref = Reference(inst)
        try:
            sx, sy = ref.run()
        except RuntimeError as err:
            print(f"{inst.label:<15} SciPy reference failed: {err}  FAIL")
            failures += 2
            checks += 2
            continue
        secs = time.time() - t0
        t_scipy += secs
        for i, (axis, e, s) in enumerate((("x", ex[j], sx), ("y", ey[j], sy))):
            diff = abs(e - s)
            bad = status[j] != 0 or not diff <= BOUND_M
            if status[j] == 0:
                worst = max(worst, diff)
            failures += bad
            checks += 1
            extra = ""
            if tight:
                d_tight = abs(tight[i][j] - s)
                if tight[2][j] == 0:
                    worst_tight = max(worst_tight, d_tight)
                extra = f" {d_tight * 1e6:>10.2e}" if tight[2][j] == 0 else f" {'status ' + str(tight[2][j]):>10}"
            print(
                f"{inst.label:<15} {status[j]:>2} {axis:>4} {e * 1e6:>14.6f} {s * 1e6:>14.6f} "
                f"{diff * 1e6:>10.2e}{extra} {len(ref.events):>6} {secs:>5.1f}"
                + ("  FAIL" if bad else "")
            )
        if ref.recovered:
            print(f"{'':<15} ({ref.recovered} crossing(s) inside a step recovered from the dense output)")
    if tight:
        print(f"max |engine at tolerance {args.tight:g} - scipy| = {worst_tight * 1e6:.3e} um (information)")
    print(
        f"max |engine - scipy| = {worst * 1e6:.3e} um (bound {BOUND_M * 1e6:g} um); "
        f"{failures} failure(s); scipy {t_scipy:.1f} s, total {time.time() - started:.1f} s"
    )
    print(f"crosscheck: {checks - failures} of {checks} checks passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
