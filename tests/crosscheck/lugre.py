#!/usr/bin/env python3
"""Independent SciPy integration of the 2-D LuGre friction model (docs/model.md section 8).

The model, integrated here with `scipy.integrate.solve_ivp` (Radau, an
implicit, L-stable Runge-Kutta method of order 5, with the analytic
Jacobian), with no code shared with the engine. State (10 numbers): stage
positions and velocities x_p,i, v_p,i, slider positions and velocities
x_s,i, v_s,i, and the bristles' mean deflection z_i, i in {x, y}. With
v_rel = v_p - v_s and s = |v_rel| (isotropic):

    g(s)        = f_c + (f_s - f_c) exp(-(s / v_S)^2)       Stribeck curve
    dz/dt       = v_rel - sigma0 s z / g(s)
    f           = sigma0 z + sigma1 dz/dt + sigma2 v_rel    friction on the slider
    m_p,i a_p,i = F_i(t) - c_i v_p,i - k_i x_p,i - f_i     the stage feels -f
    m_s a_s,i   = f_i + L_i                                 L: load on the slider
    F_i(t)      = gain_i V_i w(f_i t + phase_i; d_i)        docs/model.md section 2

w is the sawtooth of docs/model.md section 2: frac(u) / d while frac(u) < d (the
slow rise), (1 - frac(u)) / (1 - d) after it; d = 1 is a ramp with an
instantaneous drop. An axis with V_i = 0 is undriven (no corners). At t = 0
everything is at rest at zero displacement, z = 0, and the load comes on.
sigma1 defaults to sqrt(sigma0 m_s) (the instance's own sigma0 and m_s).

The right-hand side is continuous (Lipschitz) but not smooth: the drive
has corners (and a jump at d = 1) and |v_rel| a kink at 0. The integration
restarts at every drive corner and every scene period end k T (T = 1 / the
lowest driven frequency, docs/model.md section 4), inside which the drive is
affine in time; nothing else is located (there are no modes). The absolute
tolerances are scaled per component: rtol times X for positions
(X = max_i (|gain_i V_i| + f_s + |L|) / k_i, the stage's static excursion),
X sqrt(k_i / m_p,i) for velocities (the stage's ringing speed) and
f_s / sigma0 for z (the presliding deflection at breakaway). The analytic
Jacobian takes d|v_rel|/dv_rel = 0 at v_rel = 0 (a subgradient; it only
feeds Newton's iteration).

Measured quantity: the fixed window of docs/model.md section 4,
step_i = (x_s,i(cycles T) - x_s,i(settle T)) / ((cycles - settle) T f_i)
per the axis' own configured drive cycle (f_i even when the axis is
undriven).

Sub-commands:

* `reference`: docs/model.md section 8's seven converged reference cases (Table 1
  as printed, duty 0.98, phases 0, window 10 / 2, LuGre defaults sigma0 1e7,
  sigma1 = sqrt(sigma0 m_s), sigma2 0, v_S 1e-3) at rtol 1e-9 (`--rtol`,
  tighter allowed), each step within REF_BOUND_UM (2e-6 um) of the table, and
  the Karnopp limit (sigma0 1e10, v_S 1e-5, window 10 / 2: +0.612083 um) to the
  same bound. The bound is the table's rounding (5e-7 um) plus SciPy's own
  error at rtol 1e-9 (measured: 1e-8 um or less against LSODA at rtol 1e-12)
  with room. About 130 s of CPU (the 10/20 Hz case 30 s).
  Section 8's exact invariants are asserted too: the y step of a 1-DOF case
  is exactly 0, the 70.71/70.71 V steps are equal and the 100/50 V y step is
  half the x step, both within INVARIANT_UM (1e-8 um). `--extra` adds the
  Karnopp-limit table of section 8 (window 5 / 2) and the soft-bristle values
  (window 6 / 2), printed to 4 decimals, within 5.1e-5 um.
* `engine --pidm PATH`: `--instances` (10) seeded random LuGre instances,
  instance j from its own stream [seed, j] (so the count changes no
  instance), written as ONE points scene with `[mechanism] friction =
  "lugre"` and each point's `mechanism = { ... }`, run through `PATH run
  scene.toml --out file.h5 --backend cpu` (`--backend gpu` adds
  `--precision f64`; `--gpu-instances N` runs the f64 GPU on the first N
  too, held to the same SciPy integration), read back as crosscheck.py
  does, and integrated here at rtol 1e-10. The draws (draw(); the first eight force the features
  listed in FORCED so that every default run has them): sigma0
  log-uniform 1e5..1e10 N/m; sigma1 given (log-uniform 0.1..3 x
  sqrt(sigma0 m_s)) or derived (key omitted); sigma2 0 or uniform up to
  5 N s/m; v_S log-uniform 1e-5..1e-2 m/s; f_s 0.8..2 N, f_c 0.4..1 f_s or
  f_s = f_c; m_s 2e-3..2e-2 kg; equal stages (even j) or a stage drawn per
  axis (as crosscheck.py: resonance 1-4 kHz, Q 10-40, k 0.5-2 x 1e6 N/m,
  gain 0.5-1.5 x -0.6 N/V); 1-DOF (y voltage 0) or 2-DOF, |V| 30..150 V;
  f_x 10..40 Hz, f_y equal, within a factor 1.5, or twice f_x (2:1); duty
  0.5..1, some exactly 1; phases 0..1; a load of magnitude up to 0.8 f_c in
  any direction (the engine refuses |L| >= f_c). Window 10 / 2, or 4 / 1
  where a period is costly for Radau (sigma0 >= 1e8, or 2:1 in 2-DOF):
  about 240 s of CPU for the default 10, 1.5 to 3 minutes on 2 cores.
  Every instance must end with status 0 and every axis' step must satisfy
  |engine - scipy| <= 0.001 um + 0.1 % of |scipy| per own drive cycle:
  0.001 um is the project's accuracy bar at the default tolerance, and the
  relative part covers steps of tens of um per cycle (duty 1 with stiff
  bristles, loads), where the engine's relative tolerance leaves a few
  1e-3 um (measured: 2.8e-3 um on a 37.9 um step). SciPy's own error at
  rtol 1e-10 is about 1e-7 um (Radau at 1e-11 and LSODA at 1e-12 agree
  with it to that on the largest steps), far inside the bound.
  `--scipy-only` skips the engine (writes the scene under `--keep` if
  given) and prints SciPy's steps: the SciPy half on its own. `--method
  LSODA` (also for `reference`) integrates with LSODA instead, an
  independent check about 15 times faster.
* `radau-time [--case NAME]`: for the 1-DOF 100 V 10 Hz and the 2-DOF 100/50 V
  reference cases (or the named ones), the window step at Radau rtol 1e-3 ...
  1e-10 (atol scaled as above), single-threaded, with its error against the
  converged table and its CPU time (time.process_time); the loosest rtol whose
  step is within 0.001 um per cycle of the table (and every tighter one too)
  is reported with the CPU time of that one integration.
  Measured (one core of the build machine): rtol 1e-4 for both, 1.0 s and
  0.9 s of CPU, errors 1.3e-4 and 4.4e-4 um (1e-3 misses: 2.6e-3 and
  2.1e-3 um); rtol 1e-9 takes 13 s, 1e-10 22 s.

Usage: lugre.py reference [--rtol R] [--method M] [--extra] [--jobs N]
       lugre.py engine [--pidm PATH] [--instances N] [--seed S] [--backend cpu|gpu]
                       [--tolerance TOL] [--rtol R] [--method M] [--jobs N]
                       [--keep DIR] [--scipy-only] [-v]
       lugre.py radau-time [--case NAME]...

Exit status 1 when any assertion fails. Environment: PIDM_BIN = path of the
pidm binary when `--pidm` is not given (else `cargo run --release`).
"""

from __future__ import annotations

import os

# Single-threaded numerics (radau-time reports CPU time; parallelism comes
# from worker processes). Must precede numpy's import.
for _var in (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "BLIS_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    "NUMEXPR_NUM_THREADS",
):
    os.environ[_var] = "1"

import argparse
import itertools
import math
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# The engine's run and its file, read as the Karnopp cross-check reads them,
# and its draw of a stage (Table 1's stiffness and gain scaled, a resonance
# and a Q).
from crosscheck import draw_stage, run_engine
from scipy.integrate import solve_ivp

REPO = Path(__file__).resolve().parents[2]

SEED = 20240611
INSTANCES = 10
# The engine check: 1e-9 m (0.001 um) + 0.1 % of |scipy| per own drive cycle.
ENGINE_ABS_M = 1e-9
ENGINE_REL = 1e-3
ENGINE_RTOL = 1e-10
# The reference check against docs/model.md section 8's tables (um per own cycle).
REF_RTOL = 1e-9
REF_BOUND_UM = 2e-6
EXTRA_BOUND_UM = 5.1e-5  # tables printed to 4 decimals
INVARIANT_UM = 1e-8
# radau-time: within 0.001 um per own cycle of the converged table.
TIME_BOUND_UM = 1e-3
# solve_ivp methods offered by --method (Radau is the reference; LSODA, with
# the same Jacobian, is an independent check and about 15 times faster).
METHODS = ["Radau", "LSODA", "BDF"]
TIME_RTOLS = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]

# Stiff instances (sigma0 >= STIFF) get a shorter window in `engine` mode.
STIFF = 1e8
WINDOW = (10, 2)
STIFF_WINDOW = (4, 1)

# Table 1 as printed (docs/model.md section 5).
MP, MS, K, C, GAIN, FS, FC = 2.5e-3, 5.0e-3, 1.0e6, 3.2, -0.6, 1.2, 1.0


# ----------------------------------------------------------------------------
# Instances


@dataclass
class Instance:
    label: str
    voltage: list[float]
    frequency: list[float]
    duty: list[float]
    phase: list[float] = field(default_factory=lambda: [0.0, 0.0])
    slider_mass: float = MS
    static_friction: float = FS
    coulomb_friction: float = FC
    stage_mass: list[float] = field(default_factory=lambda: [MP, MP])
    stiffness: list[float] = field(default_factory=lambda: [K, K])
    damping: list[float] = field(default_factory=lambda: [C, C])
    gain: list[float] = field(default_factory=lambda: [GAIN, GAIN])
    # LuGre (docs/model.md section 8); bristle_damping None: sqrt(sigma0 m_s).
    bristle_stiffness: float = 1.0e7
    bristle_damping: float | None = None
    viscous_friction: float = 0.0
    stribeck_velocity: float = 1.0e-3
    load: list[float] = field(default_factory=lambda: [0.0, 0.0])
    cycles: int = 10
    settle: int = 2

    def driven(self, i: int) -> bool:
        return self.voltage[i] != 0.0

    def period(self) -> float:
        freqs = [self.frequency[i] for i in range(2) if self.driven(i)]
        return 1.0 / (min(freqs) if freqs else self.frequency[0])

    def sigma1(self) -> float:
        if self.bristle_damping is None:
            return math.sqrt(self.bristle_stiffness * self.slider_mass)
        return self.bristle_damping

    def name(self) -> str:
        return self.label.split()[0]


# ----------------------------------------------------------------------------
# The SciPy integration


def breakpoints(inst: Instance) -> list[float]:
    """Period ends k T and every drive corner in (0, cycles T), sorted.

    A corner within 1e-12 T of a period end (or of another corner) is merged
    into it: the period ends, where the window is read, are kept exact.
    """
    T = inst.period()
    t_end = inst.cycles * T
    ends = [k * T for k in range(inst.cycles + 1)]
    corners = []
    for i in range(2):
        if not inst.driven(i):
            continue
        f, p, d = inst.frequency[i], inst.phase[i], inst.duty[i]
        for n in range(math.floor(-p) - 1, math.ceil(f * t_end - p) + 2):
            for corner in (n, n + d) if d < 1.0 else (n,):
                t = (corner - p) / f
                if 0.0 < t < t_end:
                    corners.append(t)
    tiny = 1e-12 * T
    pts = sorted(ends)
    for t in sorted(corners):
        j = int(np.searchsorted(pts, t))
        near = [pts[m] for m in (j - 1, j) if 0 <= m < len(pts)]
        if all(abs(t - q) > tiny for q in near):
            pts.insert(j, t)
    return pts


def segment_force(inst: Instance, t0: float, t1: float) -> list[float]:
    """Drive force of each axis on (t0, t1) as c0 + c1 t: [c0x, c1x, c0y, c1y]."""
    out = []
    tm = 0.5 * (t0 + t1)
    for i in range(2):
        if not inst.driven(i):
            out += [0.0, 0.0]
            continue
        A = inst.gain[i] * inst.voltage[i]
        f, p, d = inst.frequency[i], inst.phase[i], inst.duty[i]
        u = p + f * tm
        n = math.floor(u)
        if u - n < d:  # rise: A frac(u) / d
            out += [A * (p - n) / d, A * f / d]
        else:  # fall: A (1 - frac(u)) / (1 - d)
            out += [A * (n + 1 - p) / (1 - d), -A * f / (1 - d)]
    return out


def system(inst: Instance, force: list[float]):
    """Right-hand side and its analytic Jacobian on one drive segment.

    State: x_p (x, y), v_p (x, y), x_s (x, y), v_s (x, y), z (x, y).
    """
    c0x, c1x, c0y, c1y = force
    mpx, mpy = inst.stage_mass
    kx, ky = inst.stiffness
    cx, cy = inst.damping
    Lx, Ly = inst.load
    ms, fc = inst.slider_mass, inst.coulomb_friction
    dfs = inst.static_friction - fc
    s0, s1, s2 = inst.bristle_stiffness, inst.sigma1(), inst.viscous_friction
    ivs2 = 1.0 / inst.stribeck_velocity**2

    def rhs(t, y):
        xpx, xpy, vpx, vpy, _, _, vsx, vsy, zx, zy = y.tolist()
        wx, wy = vpx - vsx, vpy - vsy
        s = math.hypot(wx, wy)
        r = s0 * s / (fc + dfs * math.exp(-s * s * ivs2))
        dzx, dzy = wx - r * zx, wy - r * zy
        fx = s0 * zx + s1 * dzx + s2 * wx
        fy = s0 * zy + s1 * dzy + s2 * wy
        return [
            vpx,
            vpy,
            (c0x + c1x * t - cx * vpx - kx * xpx - fx) / mpx,
            (c0y + c1y * t - cy * vpy - ky * xpy - fy) / mpy,
            vsx,
            vsy,
            (fx + Lx) / ms,
            (fy + Ly) / ms,
            dzx,
            dzy,
        ]

    eye = np.eye(2)
    inv_mp = np.array([[1.0 / mpx], [1.0 / mpy]])

    def jac(t, y):
        vpx, vpy, _, _, vsx, vsy, zx, zy = y[2:].tolist()
        wx, wy = vpx - vsx, vpy - vsy
        s = math.hypot(wx, wy)
        e = math.exp(-s * s * ivs2)
        g = fc + dfs * e
        h = s / g  # dz/dt = w - sigma0 h(s) z
        if s > 0.0:
            dg = -2.0 * s * ivs2 * dfs * e
            q = s0 * (g - s * dg) / (g * g)  # sigma0 h'(s)
            ux, uy = wx / s, wy / s
        else:
            q = ux = uy = 0.0
        # d(dz/dt)/dw and d(dz/dt)/dz; df/dw and df/dz.
        Dw = np.array([[1.0 - q * zx * ux, -q * zx * uy], [-q * zy * ux, 1.0 - q * zy * uy]])
        Dz = -s0 * h * eye
        Fw = s1 * Dw + s2 * eye
        Fz = s0 * eye + s1 * Dz
        J = np.zeros((10, 10))
        J[0, 2] = J[1, 3] = J[4, 6] = J[5, 7] = 1.0
        J[2, 0] = -kx / mpx
        J[3, 1] = -ky / mpy
        J[2:4, 2:4] = -Fw * inv_mp
        J[2, 2] -= cx / mpx
        J[3, 3] -= cy / mpy
        J[2:4, 6:8] = Fw * inv_mp
        J[2:4, 8:10] = -Fz * inv_mp
        J[6:8, 2:4] = Fw / ms
        J[6:8, 6:8] = -Fw / ms
        J[6:8, 8:10] = Fz / ms
        J[8:10, 2:4] = Dw
        J[8:10, 6:8] = -Dw
        J[8:10, 8:10] = Dz
        return J

    return rhs, jac


def atol_for(inst: Instance, rtol: float) -> np.ndarray:
    """Absolute tolerances: rtol times each component's natural scale."""
    load = math.hypot(*inst.load)
    X = max(
        (abs(inst.gain[i] * inst.voltage[i]) + inst.static_friction + load) / inst.stiffness[i]
        for i in range(2)
    )
    V = X * max(math.sqrt(inst.stiffness[i] / inst.stage_mass[i]) for i in range(2))
    Z = inst.static_friction / inst.bristle_stiffness
    return rtol * np.array([X, X, V, V, X, X, V, V, Z, Z])


@dataclass
class Integrated:
    """One integration: the window step [m per own cycle] and its cost."""

    step: tuple[float, float]
    steps: int
    nfev: int
    njev: int
    cpu: float
    error: str | None = None


def window_step(inst: Instance, rtol: float, method: str = "Radau") -> Integrated:
    """The fixed-window step of one instance, integrated with solve_ivp."""
    started = time.process_time()
    atol = atol_for(inst, rtol)
    T = inst.period()
    y = np.zeros(10)
    settle_xs = None
    steps = nfev = njev = 0
    pts = breakpoints(inst)
    try:
        for t0, t1 in itertools.pairwise(pts):
            if t0 == inst.settle * T:
                settle_xs = y[4:6].copy()
            rhs, jac = system(inst, segment_force(inst, t0, t1))
            kw = {"jac": jac} if method in ("Radau", "BDF", "LSODA") else {}
            sol = solve_ivp(rhs, (t0, t1), y, method=method, rtol=rtol, atol=atol, **kw)
            if sol.status != 0:
                raise RuntimeError(f"solve_ivp failed at t = {t0}: {sol.message}")
            steps += len(sol.t) - 1
            nfev += sol.nfev
            njev += sol.njev
            y = sol.y[:, -1]
        if settle_xs is None:
            raise RuntimeError("the settle time is not a breakpoint")
        if not np.all(np.isfinite(y)):
            raise RuntimeError("the state is not finite")
    except (RuntimeError, ValueError, np.linalg.LinAlgError) as err:
        return Integrated((math.nan, math.nan), steps, nfev, njev, 0.0, str(err))
    disp = y[4:6] - settle_xs
    span = (inst.cycles - inst.settle) * T
    step = (disp[0] / (span * inst.frequency[0]), disp[1] / (span * inst.frequency[1]))
    return Integrated(step, steps, nfev, njev, time.process_time() - started)


def integrate(job: tuple[Instance, float, str]) -> Integrated:
    """window_step for a worker process."""
    inst, rtol, method = job
    return window_step(inst, rtol, method)


def run_pool(jobs: list[tuple[Instance, float, str]], workers: int) -> list[Integrated]:
    if workers <= 1:
        return [integrate(job) for job in jobs]
    # Longest jobs first keeps both cores busy to the end.
    order = sorted(range(len(jobs)), key=lambda j: -jobs[j][0].cycles)
    with ProcessPoolExecutor(max_workers=workers) as pool:
        done = dict(zip(order, pool.map(integrate, [jobs[j] for j in order])))
    return [done[j] for j in range(len(jobs))]


# ----------------------------------------------------------------------------
# reference


def table1(label: str, volts, freqs=(10.0, 10.0), **lugre) -> Instance:
    return Instance(label, list(volts), list(freqs), [0.98, 0.98], **lugre)


# docs/model.md section 8: (instance, step_x, step_y) in um per own cycle; step_y
# None: a 1-DOF case, whose y step must be exactly 0.
REFERENCE = [
    (table1("1dof-100V-10Hz", (100.0, 0.0)), 1.285861, None),
    (table1("1dof-50V-10Hz", (50.0, 0.0)), 0.597945, None),
    (table1("1dof-100V-20Hz", (100.0, 0.0), (20.0, 20.0)), -1.800513, None),
    (table1("2dof-70.71V", (70.71, 70.71)), 0.909263, 0.909263),
    (table1("2dof-100-100V", (100.0, 100.0)), -0.310590, -0.310590),
    (table1("2dof-100-50V", (100.0, 50.0)), 0.765918, 0.382959),
    (table1("2dof-10-20Hz", (100.0, 100.0), (10.0, 20.0)), 2.575309, -1.296651),
    (
        table1("karnopp-limit", (100.0, 0.0), bristle_stiffness=1e10, stribeck_velocity=1e-5),
        0.612083,
        None,
    ),
]


def extra_cases() -> list[tuple[Instance, float, None]]:
    """docs/model.md section 8's Karnopp-limit table (window 5 / 2) and soft bristles."""
    out = []
    table = {
        (1e7, 1e-3): 1.2859,
        (1e7, 1e-5): 1.2624,
        (1e8, 1e-3): 0.7346,
        (1e8, 1e-5): 0.7332,
        (1e9, 1e-3): 0.6455,
        (1e9, 1e-5): 0.6257,
    }
    for (s0, vs), want in table.items():
        inst = table1(
            f"limit-{s0:.0e}-{vs:.0e}",
            (100.0, 0.0),
            bristle_stiffness=s0,
            stribeck_velocity=vs,
        )
        inst.cycles, inst.settle = 5, 2
        out.append((inst, want, None))
    # The soft cases state sigma1 explicitly (15 and 50 N s/m), which is not
    # sqrt(sigma0 m_s) (22.4 and 70.7): the printed values need the stated ones.
    for s0, s1, want in ((1e5, 15.0, -0.0424), (1e6, 50.0, -0.3024)):
        inst = table1(f"soft-{s0:.0e}", (100.0, 0.0), bristle_stiffness=s0, bristle_damping=s1)
        inst.cycles, inst.settle = 6, 2
        out.append((inst, want, None))
    return out


def cmd_reference(args) -> int:
    started = time.time()
    cases = [(inst, x, y, REF_BOUND_UM) for inst, x, y in REFERENCE]
    if args.extra:
        cases += [(inst, x, y, EXTRA_BOUND_UM) for inst, x, y in extra_cases()]
    results = run_pool([(inst, args.rtol, args.method) for inst, *_ in cases], args.jobs)
    print(
        f"docs/model.md section 8 references: SciPy {args.method} rtol {args.rtol:g}, "
        "analytic Jacobian, "
        "atol scaled per component, restarted at every drive corner and period end"
    )
    print("steps in um per own drive cycle")
    print(
        f"{'case':<22} {'win':>5} {'axis':>4} {'scipy':>12} {'table':>10} {'diff':>9} "
        f"{'bound':>7} {'steps':>7} {'cpu s':>6}"
    )
    failures = []
    got = {}
    for (inst, want_x, want_y, bound), res in zip(cases, results):
        if res.error:
            failures.append(f"{inst.label}: {res.error}")
            print(f"{inst.label:<22} failed: {res.error}  FAIL")
            continue
        sx, sy = (s * 1e6 for s in res.step)
        got[inst.label] = (sx, sy)
        rows = [("x", sx, want_x), ("y", sy, want_y if want_y is not None else 0.0)]
        for i, (axis, s, want) in enumerate(rows):
            diff = abs(s - want)
            if axis == "y" and want_y is None:
                ok = sy == 0.0  # an undriven, unloaded axis stays exactly at 0
                shown_bound = "exact"
            else:
                ok = diff <= bound
                shown_bound = f"{bound:.0e}"
            mark = "" if ok else "  FAIL"
            if not ok:
                failures.append(f"{inst.label} {axis}: {s:+.9f} um, table {want:+.6f} um")
            first = i == 0
            print(
                f"{inst.label if first else '':<22} "
                f"{f'{inst.cycles}/{inst.settle}' if first else '':>5} {axis:>4} "
                f"{s:>+12.8f} {want:>+10.6f} {diff:>9.2e} {shown_bound:>7} "
                f"{res.steps if first else '':>7} {f'{res.cpu:.1f}' if first else '':>6}{mark}"
            )
    # Section 8's exact invariants (to the integration's rounding).
    for label, (a, b), what in (
        ("2dof-70.71V", (0, 1), "step_x = step_y"),
        ("2dof-100-50V", (0, 2), "step_x = 2 step_y"),
    ):
        if label not in got:
            continue
        sx, sy = got[label]
        dev = abs(sx - sy) if b == 1 else abs(sx - 2.0 * sy)
        ok = dev <= INVARIANT_UM
        print(
            f"invariant {label}: {what} within {dev:.2e} um "
            f"(bound {INVARIANT_UM:g}){'' if ok else '  FAIL'}"
        )
        if not ok:
            failures.append(f"{label}: {what} off by {dev:.2e} um")
    for failure in failures:
        print(f"FAIL: {failure}")
    cpu = sum(r.cpu for r in results)
    print(
        f"reference: {len(failures)} failure(s); scipy {cpu:.1f} s CPU in {args.jobs} "
        f"process(es), {time.time() - started:.1f} s wall"
    )
    return 1 if failures else 0


# ----------------------------------------------------------------------------
# engine: random instances, the scene, the engine run


# Forced features of the first instances (on top of their random draws), so
# that every default run covers them; later instances draw them at random.
FORCED = [
    {"dof": 1, "duty1": "x", "damping": "derived", "load": False, "fs_eq_fc": False},
    {
        "dof": 2,
        "ratio": True,
        "duty1": "y",
        "equal": False,
        "damping": "given",
        "viscous": True,
        "fs_eq_fc": False,
    },
    {"dof": 2, "fs_eq_fc": True, "equal": True, "load": True, "ratio": False},
    {"dof": 1, "load": True, "equal": False, "fs_eq_fc": False},
    {
        "dof": 2,
        "sigma0": (9.5, 10.0),
        "damping": "derived",
        "equal": False,
        "ratio": False,
        "fs_eq_fc": False,
    },
    {"dof": 2, "sigma0": (5.0, 6.0), "load": True, "damping": "given", "equal": True},
    {"dof": 2, "ratio": True, "load": True, "viscous": True, "duty1": "xy", "fs_eq_fc": False},
    {"dof": 1, "sigma0": (8.5, 9.0), "damping": "given", "fs_eq_fc": True, "equal": False},
]


def draw(seed: int, j: int) -> Instance:
    """Instance j, from its own random stream (independent of the count).

    Every random number is drawn, in the same order, whatever is forced.
    """
    rng = np.random.default_rng([seed, j])

    def f(lo: float, hi: float) -> float:
        return float(rng.uniform(lo, hi))

    def chance(p: float) -> bool:
        return bool(rng.uniform() < p)

    forced = FORCED[j] if j < len(FORCED) else {}
    voltage = [f(-150.0, 150.0), f(-150.0, 150.0)]
    for i in range(2):  # not too weak a drive: most instances slip
        if abs(voltage[i]) < 30.0:
            voltage[i] = math.copysign(30.0, voltage[i])
    # y within a factor 1.5 of x (the cost of a period grows with the number
    # of drive corners in it), or equal, or (forced below) twice x.
    frequency = [f(10.0, 40.0), 0.0]
    frequency[1] = frequency[0] * (1.0 if chance(0.3) else 1.5 ** f(-1.0, 1.0))
    phase = [f(0.0, 1.0), f(0.0, 1.0)]
    duty = [f(0.5, 1.0), f(0.5, 1.0)]
    slider_mass = f(2e-3, 2e-2)
    static_friction = f(0.8, 2.0)
    coulomb_friction = static_friction * f(0.4, 1.0)
    equal = j % 2 == 0
    x = draw_stage(f)
    y = draw_stage(f)
    log_sigma0 = f(5.0, 10.0)
    damping_given = chance(0.5)
    damping_factor = 10.0 ** f(-1.0, math.log10(3.0))  # 0.1 to 3 x sqrt(sigma0 m_s)
    viscous = f(0.0, 5.0) if chance(0.5) else 0.0
    stribeck = 10.0 ** f(-5.0, -2.0)
    dof = 1 if chance(0.3) else 2
    ratio = chance(0.2)
    fs_eq_fc = chance(0.2)
    duty1 = ["", "", "", "x", "y"][int(rng.integers(5))]
    has_load = chance(0.5)
    load_size = f(0.0, 0.8)
    load_angle = f(0.0, 2.0 * math.pi)
    forced_viscous = f(0.5, 5.0)
    # The forced features.
    equal = forced.get("equal", equal)
    dof = forced.get("dof", dof)
    ratio = forced.get("ratio", ratio)
    fs_eq_fc = forced.get("fs_eq_fc", fs_eq_fc)
    duty1 = forced.get("duty1", duty1)
    has_load = forced.get("load", has_load)
    if "damping" in forced:
        damping_given = forced["damping"] == "given"
    if forced.get("viscous") and viscous == 0.0:
        viscous = forced_viscous
    if "sigma0" in forced:
        lo, hi = forced["sigma0"]
        log_sigma0 = lo + (hi - lo) * (log_sigma0 - 5.0) / 5.0
    sigma0 = 10.0**log_sigma0
    tags = []
    if dof == 1:
        voltage[1] = 0.0
        tags.append("1dof")
    if ratio:
        frequency[1] = 2.0 * frequency[0]
        if dof == 2:
            tags.append("2:1")
    if fs_eq_fc:
        coulomb_friction = static_friction
        tags.append("fs=fc")
    for axis in duty1:
        duty["xy".index(axis)] = 1.0
    if duty1:
        tags.append(f"duty1 {duty1}")
    load = [0.0, 0.0]
    if has_load:
        # |L| < f_c (the engine refuses more): up to 0.8 f_c, on both axes.
        size = load_size * coulomb_friction
        load = [size * math.cos(load_angle), size * math.sin(load_angle)]
        tags.append("load")
    if equal:
        y = x
    else:
        tags.append("mp")
    # The window: 10 / 2, or 4 / 1 where a period is costly for Radau at
    # rtol 1e-10 (stiff bristles, or y at twice x: twice the corners).
    costly = sigma0 >= STIFF or (dof == 2 and ratio)
    cycles, settle = STIFF_WINDOW if costly else WINDOW
    sigma1 = damping_factor * math.sqrt(sigma0 * slider_mass) if damping_given else None
    return Instance(
        " ".join([f"e{j}", *tags]),
        voltage,
        frequency,
        duty,
        phase,
        slider_mass,
        static_friction,
        coulomb_friction,
        [x[0], y[0]],
        [x[1], y[1]],
        [x[2], y[2]],
        [x[3], y[3]],
        bristle_stiffness=sigma0,
        bristle_damping=sigma1,
        viscous_friction=viscous,
        stribeck_velocity=stribeck,
        load=load,
        cycles=cycles,
        settle=settle,
    )


def make_instances(count: int, seed: int) -> list[Instance]:
    return [draw(seed, j) for j in range(count)]


def scene_toml(instances: list[Instance], tolerance: float | None = None) -> str:
    lines = [
        'name = "lugre_crosscheck"',
        'description = "seeded random LuGre instances for the SciPy cross-check"',
        "",
        "[mechanism]",
        'friction = "lugre"',
        "",
        "[simulation]",
        'measure = "window"',
        f"cycles = {WINDOW[0]}",
        f"settle = {WINDOW[1]}",
    ]
    if tolerance is not None:
        lines.append(f"tolerance = {tolerance!r}")
    lines.append("")
    for inst in instances:
        mech = [
            ("slider_mass", inst.slider_mass),
            ("static_friction", inst.static_friction),
            ("coulomb_friction", inst.coulomb_friction),
            ("bristle_stiffness", inst.bristle_stiffness),
        ]
        if inst.bristle_damping is not None:  # omitted: derived by the engine
            mech.append(("bristle_damping", inst.bristle_damping))
        mech += [
            ("viscous_friction", inst.viscous_friction),
            ("stribeck_velocity", inst.stribeck_velocity),
            ("load_x", inst.load[0]),
            ("load_y", inst.load[1]),
        ]
        lines.append("[[points]]")
        lines.append(f'label = "{inst.label}"')
        lines.append(f"simulation.cycles = {inst.cycles}")
        lines.append(f"simulation.settle = {inst.settle}")
        lines.append("mechanism = { " + ", ".join(f"{k} = {v!r}" for k, v in mech) + " }")
        for i, axis in enumerate("xy"):
            for key in ("stage_mass", "stiffness", "damping", "gain"):
                lines.append(f"axis.{axis}.{key} = {getattr(inst, key)[i]!r}")
            lines.append(f"axis.{axis}.voltage = {inst.voltage[i]!r}")
            lines.append(f"axis.{axis}.frequency = {inst.frequency[i]!r}")
            lines.append(f"axis.{axis}.duty = {inst.duty[i]!r}")
            lines.append(f"axis.{axis}.phase = {inst.phase[i]!r}")
        lines.append("")
    return "\n".join(lines)


def describe(inst: Instance) -> str:
    s1 = "derived" if inst.bristle_damping is None else f"{inst.bristle_damping:.3g}"
    ratio = inst.sigma1() / math.sqrt(inst.bristle_stiffness * inst.slider_mass)
    return (
        f"sigma0 {inst.bristle_stiffness:.2e}, sigma1 {s1} (x{ratio:.2f}), "
        f"sigma2 {inst.viscous_friction:.2f}, v_S {inst.stribeck_velocity:.1e}, "
        f"f_s {inst.static_friction:.3f} f_c {inst.coulomb_friction:.3f}, "
        f"L ({inst.load[0]:+.3f}, {inst.load[1]:+.3f}), "
        f"V ({inst.voltage[0]:+.1f}, {inst.voltage[1]:+.1f}), "
        f"f ({inst.frequency[0]:.2f}, {inst.frequency[1]:.2f}), "
        f"d ({inst.duty[0]:.3f}, {inst.duty[1]:.3f})"
    )


def cmd_engine(args) -> int:
    if args.instances < 1:
        raise SystemExit("--instances must be at least 1")
    if not 0 <= args.gpu_instances <= args.instances:
        raise SystemExit("--gpu-instances must lie between 0 and --instances")
    binary = args.pidm or os.environ.get("PIDM_BIN")
    started = time.time()
    instances = make_instances(args.instances, args.seed)
    # The engines to check, each on the first `count` instances: --backend
    # on all, and with --gpu-instances the f64 GPU on the first few too,
    # against the one SciPy integration of them all.
    runs = [(args.backend, len(instances))]
    if args.gpu_instances and args.backend == "cpu":
        runs.append(("gpu", args.gpu_instances))
    engines = []
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        for backend, count in runs if not args.scipy_only else []:
            scene = work / f"lugre_crosscheck_{backend}.toml"
            scene.write_text(scene_toml(instances[:count], args.tolerance))
            precision = "f64" if backend == "gpu" else None
            out = work / f"lugre_crosscheck_{backend}.h5"
            engines.append((count, run_engine(scene, out, backend, precision, binary)))
    failures = []
    for count, engine in engines:
        failures.extend(engine.problems)
        if len(engine.step_x) != count:
            failures.append(
                f"{engine.backend}: the file has {len(engine.step_x)} points, not {count}"
            )
    engines = [(count, e) for count, e in engines if len(e.step_x) == count]
    print(
        f"{len(instances)} LuGre instances, seed {args.seed}; engines: "
        + (
            ", ".join(
                f"{e.backend} ({e.precision}) on {count}, {e.seconds:.1f} s" for count, e in engines
            )
            or "not run (--scipy-only)"
        )
    )
    print(
        f"steps in um per own drive cycle; SciPy {args.method} rtol {args.rtol:g}; "
        "pass: status 0 and "
        f"|engine - scipy| <= {ENGINE_ABS_M * 1e6:g} um + {ENGINE_REL * 100:g} % of |scipy|"
    )
    wall = time.time()
    refs = run_pool([(inst, args.rtol, args.method) for inst in instances], args.jobs)
    wall = time.time() - wall
    for j, (inst, ref) in enumerate(zip(instances, refs)):
        if ref.error:
            failures.append(f"{inst.label}: SciPy failed: {ref.error}")
    for count, engine in engines or [(len(instances), None)]:
        failures.extend(compare_engine(engine, instances[:count], refs, args.verbose))
    for failure in failures:
        print(f"FAIL: {failure}")
    cpu = sum(r.cpu for r in refs)
    print(
        f"lugre engine: {len(failures)} failure(s); scipy {cpu:.1f} s CPU in {args.jobs} "
        f"process(es), {wall:.1f} s wall; total {time.time() - started:.1f} s"
    )
    return 1 if failures else 0


def compare_engine(engine, instances, refs, verbose) -> list[str]:
    """One engine's steps (or none: SciPy's alone) against the references of
    its instances: a table, the largest difference in bounds, the failures."""
    failures = []
    print(f"-- {f'{engine.backend} ({engine.precision})' if engine else 'SciPy alone'}")
    print(
        f"{'instance':<26} {'win':>5} {'st':>2} {'axis':>4} {'engine':>12} {'scipy':>12} "
        f"{'diff':>9} {'bound':>9} {'steps':>7} {'cpu s':>6}"
    )
    worst, worst_at = 0.0, ""
    for j, (inst, ref) in enumerate(zip(instances, refs)):
        if ref.error:
            print(f"{inst.label:<26} SciPy failed: {ref.error}  FAIL")
            continue
        for i, axis in enumerate("xy"):
            s = ref.step[i]
            bound = ENGINE_ABS_M + ENGINE_REL * abs(s)
            mark, e_txt, d_txt, st = "", "", "", ""
            if engine:
                e = (engine.step_x, engine.step_y)[i][j]
                diff = abs(e - s)
                st = int(engine.status[j])
                e_txt, d_txt = f"{e * 1e6:>+12.6f}", f"{diff * 1e6:>9.2e}"
                bad = []
                if st != 0:
                    bad.append(f"status {st}")
                elif not diff <= bound:
                    bad.append(f"diff {diff * 1e6:.2e} um > {bound * 1e6:.2e} um")
                elif diff / bound > worst:
                    worst, worst_at = diff / bound, f"{inst.name()} {axis}"
                if bad:
                    mark = "  FAIL (" + ", ".join(bad) + ")"
                    failures.append(f"{engine.backend}: {inst.label} {axis}: " + ", ".join(bad))
            first = i == 0
            print(
                f"{inst.label if first else '':<26} "
                f"{f'{inst.cycles}/{inst.settle}' if first else '':>5} {st:>2} {axis:>4} "
                f"{e_txt:>12} {s * 1e6:>+12.6f} {d_txt:>9} {bound * 1e6:>9.2e} "
                f"{ref.steps if first else '':>7} {f'{ref.cpu:.1f}' if first else '':>6}{mark}"
            )
        if verbose:
            print(f"{'':<26} {describe(inst)}")
    if engine:
        print(f"largest |engine - scipy| / bound = {worst:.3f} ({worst_at or 'none'})")
    return failures


# ----------------------------------------------------------------------------
# radau-time


def cmd_radau_time(args) -> int:
    by_name = {inst.label: (inst, x, y) for inst, x, y in REFERENCE}
    names = args.case or ["1dof-100V-10Hz", "2dof-100-50V"]
    unknown = [n for n in names if n not in by_name]
    if unknown:
        raise SystemExit(f"--case: unknown {', '.join(unknown)}; known: {', '.join(by_name)}")
    print(
        "Radau (analytic Jacobian, atol = rtol x component scale), single-threaded, "
        f"window {WINDOW[0]} / {WINDOW[1]}; pass: every axis within {TIME_BOUND_UM:g} um "
        "per own cycle of docs/model.md section 8's converged value"
    )
    print(
        f"{'case':<16} {'rtol':>7} {'step_x':>11} {'step_y':>11} {'max err':>9} "
        f"{'steps':>7} {'cpu s':>7}"
    )
    summary = []
    failed = False
    for case in names:
        inst, want_x, want_y = by_name[case]
        want = (want_x, want_y if want_y is not None else 0.0)
        rows = []
        for rtol in TIME_RTOLS:
            res = window_step(inst, rtol)
            if res.error:
                err = math.inf
                print(f"{case:<16} {rtol:>7.0e} failed: {res.error}")
            else:
                s = [v * 1e6 for v in res.step]
                err = max(abs(s[0] - want[0]), abs(s[1] - want[1]))
                print(
                    f"{case:<16} {rtol:>7.0e} {s[0]:>+11.6f} {s[1]:>+11.6f} {err:>9.2e} "
                    f"{res.steps:>7} {res.cpu:>7.2f}"
                )
            rows.append((rtol, err, res))
        # The loosest rtol that passes with every tighter one passing too.
        pick = None
        for rtol, err, res in reversed(rows):
            if not err <= TIME_BOUND_UM:
                break
            pick = (rtol, err, res)
        loosest_any = next(((r, e) for r, e, _ in rows if e <= TIME_BOUND_UM), None)
        summary.append((case, pick, loosest_any))
        failed |= pick is None
    print()
    print(f"{'case':<16} {'loosest rtol':>12} {'error um':>9} {'steps':>7} {'cpu s':>7}")
    for case, pick, loosest_any in summary:
        if pick is None:
            print(f"{case:<16} none passes")
            continue
        rtol, err, res = pick
        note = ""
        if loosest_any and loosest_any[0] > rtol:
            note = f"  ({loosest_any[0]:.0e} passes too, but not every rtol between)"
        print(f"{case:<16} {rtol:>12.0e} {err:>9.2e} {res.steps:>7} {res.cpu:>7.2f}{note}")
    return 1 if failed else 0


# ----------------------------------------------------------------------------


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    jobs = os.cpu_count() or 1

    p = sub.add_parser("reference", help="docs/model.md section 8's converged reference values")
    p.add_argument("--rtol", type=float, default=REF_RTOL, help="Radau rtol (at most 1e-9)")
    p.add_argument("--jobs", type=int, default=jobs, help="integrations in parallel")
    p.add_argument("--method", choices=METHODS, default="Radau", help="solve_ivp method")
    p.add_argument(
        "--extra",
        action="store_true",
        help="also the Karnopp-limit table and the soft-bristle values (4 decimals)",
    )

    p = sub.add_parser("engine", help="random LuGre instances: the engine against SciPy")
    p.add_argument("--pidm", help="the pidm binary (else $PIDM_BIN, else cargo run --release)")
    p.add_argument("--instances", type=int, default=INSTANCES)
    p.add_argument("--seed", type=int, default=SEED)
    p.add_argument("--backend", choices=["cpu", "gpu"], default="cpu")
    p.add_argument(
        "--gpu-instances",
        type=int,
        default=0,
        help="with --backend cpu: also the f64 GPU on the first N instances, "
        "against the same SciPy integration",
    )
    p.add_argument("--tolerance", type=float, help="simulation.tolerance for the engine")
    p.add_argument("--rtol", type=float, default=ENGINE_RTOL, help="SciPy's Radau rtol")
    p.add_argument("--jobs", type=int, default=jobs, help="SciPy integrations in parallel")
    p.add_argument("--method", choices=METHODS, default="Radau", help="solve_ivp method")
    p.add_argument("--keep", type=Path, help="write the scene and the HDF5 file here")
    p.add_argument("--scipy-only", action="store_true", help="skip the engine")
    p.add_argument("--verbose", "-v", action="store_true", help="print each instance's parameters")

    p = sub.add_parser("radau-time", help="loosest Radau rtol within 0.001 um, and its CPU time")
    p.add_argument(
        "--case",
        action="append",
        help="a reference case by name (repeatable); default 1dof-100V-10Hz and 2dof-100-50V",
    )

    args = ap.parse_args()
    if args.command == "reference":
        if args.rtol > REF_RTOL:
            ap.error(f"--rtol must be {REF_RTOL:g} or tighter")
        return cmd_reference(args)
    if args.command == "engine":
        return cmd_engine(args)
    return cmd_radau_time(args)


if __name__ == "__main__":
    sys.exit(main())
