"""The SciPy reference of waveform.py: the drive a stage sees from a scene's
waveform keys (the polyline of its corners, and the slew-limited
follower's periodic orbit, found by bisection on its start), and
crosscheck.py's hybrid integration of the Karnopp model driven by it,
restarting at every corner, with the slider's total variation per axis
(located velocity zeros) for the backward travel. No pidm code.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np
from crosscheck import (
    ATOL,
    BAND,
    RTOL,
    SLIP,
    STICK,
    Instance,
    Reference,
    divided,
)
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

# SciPy's DOP853 tolerance (crosscheck.py's RTOL is 1e-12; see waveform.py's
# docstring).
SCIPY_RTOL = 1e-13

# ----------------------------------------------------------------------------
# Waveforms and the slew limit (docs/model.md section 2), from the scene keys


def polyline(shape: dict) -> tuple[list[float], list[float]]:
    """The waveform of `shape` (scene keys) as a closed polyline (U, L).

    U[0] <= U[1] <= ... <= U[-1] = U[0] + 1; w is linear between points,
    two points at one u are a jump (w there is the later level), and
    L[-1] != L[0] is a jump at the wrap.
    """
    kind = shape["waveform"]
    if kind == "sawtooth":
        d = shape["duty"]
        pts = [(0.0, 0.0), (1.0, 1.0)] if d == 1.0 else [(0.0, 0.0), (d, 1.0), (1.0, 0.0)]
    elif kind == "trapezoid":
        r, h, f = shape["rise"], shape["hold"], shape["fall"]
        raw = [(0.0, 0.0), (r, 1.0), (r + h, 1.0), (r + h + f, 0.0), (1.0, 0.0)]
        pts = [raw[0]]
        for p in raw[1:]:
            if p != pts[-1]:
                pts.append(p)
    elif kind == "table":
        pts = [(float(u), float(lv)) for u, lv in shape["table"]]
        pts.append((pts[0][0] + 1.0, pts[0][1]))
    else:
        raise ValueError(f"unknown waveform {kind!r}")
    U = [p[0] for p in pts]
    L = [p[1] for p in pts]
    if any(b < a for a, b in itertools.pairwise(U)) or U[-1] != U[0] + 1.0:
        raise ValueError(f"not a cycle: {pts}")
    return U, L


def follow(U, L, sigma: float, y0: float) -> tuple[list[float], list[float], bool]:
    """The slew-limited follower over one cycle from y(U[0]) = y0, exactly.

    Returns the follower's polyline (continuous, U[0] to U[0] + 1) and
    whether it met the waveform. On a segment of slope b the follower moves
    at +-sigma toward w until the gap closes (in closed form); on w it
    tracks w where |b| <= sigma and leaves it at sigma sign(b) where
    |b| > sigma. A jump of w takes the follower off it.
    """
    us, ys = [U[0]], [y0]
    y = y0
    on = False
    met = False
    for j in range(len(U) - 1):
        ua, ub, la, lb = U[j], U[j + 1], L[j], L[j + 1]
        if ub == ua:  # a jump
            if lb != y:
                on = False
            continue
        b = (lb - la) / (ub - ua)
        u = ua
        for _ in range(4):
            if on:
                if abs(b) <= sigma:
                    u, y = ub, lb
                else:
                    y += math.copysign(sigma, b) * (ub - u)
                    u, on = ub, False
                break
            w = la + b * (u - ua)
            gap = w - y
            if gap == 0.0:
                on = met = True
                continue
            s = sigma if gap > 0.0 else -sigma
            closing = s - b  # d(gap)/du = b - s
            if closing != 0.0 and (gap > 0.0) == (closing > 0.0):
                tau = gap / closing
                if u + tau < ub:
                    u += tau
                    y = la + b * (u - ua)
                    us.append(u)
                    ys.append(y)
                    on = met = True
                    continue
            y += s * (ub - u)
            u = ub
            break
        else:
            raise RuntimeError("follower: no progress on a segment")
        if u != us[-1]:
            us.append(u)
            ys.append(y)
    return us, ys, met


def slewed(U, L, sigma: float) -> tuple[list[float], list[float]]:
    """The follower's periodic orbit as a polyline: the root of Phi(y) - y."""
    if not math.isfinite(sigma):
        return list(U), list(L)

    def h(y0: float) -> float:
        return follow(U, L, sigma, y0)[1][-1] - y0

    lo, hi = min(L), max(L)
    if h(lo) < 0.0 or h(hi) > 0.0:
        raise RuntimeError("slew orbit: Phi maps [min w, max w] outside itself")
    while True:
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        if h(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    y = lo if abs(h(lo)) <= abs(h(hi)) else hi
    # Unique: Phi - id strictly falls through the root (slope -1 where the
    # follower tracks, 2 sigma / (sigma + |b|) - 1 per crossing otherwise).
    delta = 1e-6
    if not (h(y - delta) > 1e-3 * delta and h(y + delta) < -1e-3 * delta):
        raise RuntimeError("slew orbit is not unique (the follower never meets the waveform)")
    us, ys, _ = follow(U, L, sigma, y)
    if abs(ys[-1] - y) > 1e-12:
        raise RuntimeError(f"slew orbit does not close: {ys[-1] - y:.3e}")
    ys[-1] = y  # periodic: the orbit's end is its start
    return us, ys


def steepest(U, L) -> float:
    """The steepest finite flank of a polyline, in levels per cycle."""
    return max(
        (abs(lb - la) / (ub - ua) for ua, ub, la, lb in zip(U, U[1:], L, L[1:]) if ub > ua),
        default=0.0,
    )


# ----------------------------------------------------------------------------
# Instances


@dataclass
class WaveInstance(Instance):
    """crosscheck.py's instance with a waveform (scene keys) and a slew limit per axis."""

    shape: list[dict] = field(default_factory=list)
    slew_rate: list[float | None] = field(default_factory=lambda: [None, None])

    def sigma(self, i: int) -> float:
        """The slew limit in levels per cycle (inf: none)."""
        s = self.slew_rate[i]
        if s is None or not self.driven(i):
            return math.inf
        return s / (abs(self.voltage[i]) * self.frequency[i])

    def drive(self, i: int) -> tuple[list[float], list[float]]:
        """The polyline the stage sees: the waveform, slewed where limited."""
        U, L = polyline(self.shape[i])
        return slewed(U, L, self.sigma(i))


# ----------------------------------------------------------------------------
# The SciPy reference: crosscheck.py's with this drive and the travel


class WaveReference(Reference):
    """crosscheck.py's hybrid integration, driven by polylines.

    Also accumulates the slider's total variation per axis over the measured
    window (located velocity zeros; see `integrate_piece`).
    """

    def __init__(self, inst: WaveInstance, rtol: float = SCIPY_RTOL):
        super().__init__(inst)
        # crosscheck.py's tolerances, the absolute ones scaled with rtol.
        self.rtol = rtol
        self.atol = ATOL * (rtol / RTOL)
        self.drives = [inst.drive(i) if inst.driven(i) else None for i in range(2)]
        self.variation = [0.0, 0.0]
        self.travel_recovered = 0

    # -- drive ---------------------------------------------------------------

    def breakpoints(self, t_end: float, T: float) -> list[float]:
        periods = [k * T for k in range(self.inst.cycles + 1)]
        corners = set()
        for i in range(2):
            if self.drives[i] is None:
                continue
            U, _ = self.drives[i]
            f, p = self.inst.frequency[i], self.inst.phase[i]
            n_lo = math.floor(p - U[0]) - 1
            n_hi = math.ceil(f * t_end + p - U[0]) + 1
            for n in range(n_lo, n_hi + 1):
                for u in set(U[:-1]):
                    t = (n + u - p) / f
                    if 0.0 < t < t_end:
                        corners.add(t)
        # A corner within rounding of a period end is that period end (the
        # settle time must stay a breakpoint; nothing lies between).
        eps = 1e-13 * T
        kept = [t for t in corners if min(abs(t - s) for s in periods) > eps]
        return sorted(set(periods) | set(kept))

    def segment_force(self, t0: float, t1: float) -> list[tuple[float, float]]:
        """Drive force of each axis on (t0, t1) as c0 + c1 t (affine there)."""
        out = []
        tm = 0.5 * (t0 + t1)
        for i in range(2):
            A = self.amp[i]
            if A == 0.0 or self.drives[i] is None:
                out.append((0.0, 0.0))
                continue
            U, L = self.drives[i]
            f, p = self.inst.frequency[i], self.inst.phase[i]
            n = math.floor(p + f * tm - U[0])
            r = p + f * tm - n  # in [U[0], U[0] + 1)
            j = min(max(int(np.searchsorted(U, r, side="right")) - 1, 0), len(U) - 2)
            while U[j + 1] <= U[j]:  # never inside a jump (r < U[j + 1])
                j += 1
            s = (L[j + 1] - L[j]) / (U[j + 1] - U[j])
            # level(t) = L[j] + s (p + f t - n - U[j])
            out.append((A * (L[j] + s * (p - n - U[j])), A * s * f))
        return out

    # -- the travel ----------------------------------------------------------

    def travel_events(self, rhs):
        """Zeros of v_s,i and of a_s,i (extrema of v_s,i) of the driven axes."""
        events = []
        for i in range(2):
            if self.drives[i] is None:
                continue  # v_s,i is 0 throughout: no zeros to find

            def zero(t, y, i=i):
                return y[6 + i]

            def extremum(t, y, i=i):
                return rhs(t, y)[6 + i]

            for g in (zero, extremum):
                g.terminal = False
                g.direction = 0.0
                events.append((i, g))
        return events

    def add_travel(self, t0, y0, t_end, y_end, sol, travel, rhs, kw, t1, events):
        """Total variation of x_s over one piece [t0, t_end] into self.variation."""
        base = len(events) - len(travel)  # the travel events come last
        for i in range(2):
            if self.drives[i] is None:
                continue
            # The piece's points in time order: its ends, the zeros (sign 0)
            # and the extrema of v_s,i located by solve_ivp.
            pts = [(t0, np.asarray(y0), None), (t_end, np.asarray(y_end), None)]
            for k, (axis, g) in enumerate(travel):
                if axis != i:
                    continue
                is_zero = g.__name__ == "zero"
                for te, ye in zip(sol.t_events[base + k], sol.y_events[base + k]):
                    if t0 < te < t_end:
                        pts.append((te, ye, 0 if is_zero else None))
            pts.sort(key=lambda q: q[0])

            def sign(q, i=i):
                return q[2] if q[2] is not None else np.sign(q[1][6 + i])

            # Between neighbours v_s,i is monotone; a sign change with no
            # located zero is a pair hidden in one step: find it on the
            # dense output (the same steps again, with the interpolants).
            full = [pts[0]]
            dense = None
            for a, b in itertools.pairwise(pts):
                if sign(a) * sign(b) < 0:
                    if dense is None:
                        dense = solve_ivp(rhs, (t0, t1), y0, events=events, dense_output=True, **kw)
                    v = dense.sol

                    def velocity(s, v=v, i=i):
                        return v(s)[6 + i]

                    te = brentq(velocity, a[0], b[0], xtol=1e-18, rtol=4 * np.finfo(float).eps)
                    full.append((te, v(te), 0))
                    self.travel_recovered += 1
                full.append(b)
            self.variation[i] += sum(
                abs(b[1][4 + i] - a[1][4 + i]) for a, b in itertools.pairwise(full)
            )

    # -- crosscheck.py's piece, with the travel events -------------------------

    def integrate_piece(self, mode, force, held, t0, t1, y0, fresh, in_window=False):
        """crosscheck.py's `integrate_piece` (the same logic at self.rtol), plus the travel."""
        rhs, raw = self.system(mode, force, held)
        watched = []
        for nm, g, dg, at_zero in raw:
            if at_zero and fresh:
                if dg(t0, y0) < 0.0:
                    return t0, y0, nm
                g = divided(g, dg, t0)
            watched.append((nm, g, dg))
        events = []
        for _, g, dg in watched:
            g.terminal = True
            g.direction = -1.0
            dg.terminal = False
            dg.direction = 1.0
            events += [g, dg]
        travel = self.travel_events(rhs) if in_window else []
        events += [g for _, g in travel]
        kw = {
            "method": "DOP853",
            "rtol": self.rtol,
            "atol": self.atol,
            "max_step": self.max_step[mode],
        }
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
        missed = None
        for j, (nm, g, _) in enumerate(watched):
            for tm, ym in zip(sol.t_events[2 * j + 1], sol.y_events[2 * j + 1]):
                if tm < t_end and g(tm, ym) < 0.0 and (missed is None or tm < missed[1]):
                    missed = (j, tm)
                    break
        if missed is not None:
            j, tm = missed
            nm, g, _ = watched[j]
            dense = solve_ivp(rhs, (t0, t1), y0, events=events, dense_output=True, **kw)
            k = min(int(np.searchsorted(dense.t, tm)) - 1, len(dense.sol.interpolants) - 1)
            step = dense.sol.interpolants[k]
            lo = dense.t[k]
            if not g(lo, step(lo)) > 0.0 or not g(tm, step(tm)) < 0.0:
                raise RuntimeError(f"could not bracket a crossing hidden in a step at t = {tm}")
            te = brentq(lambda s: g(s, step(s)), lo, tm, xtol=1e-18, rtol=4 * np.finfo(float).eps)
            self.recovered += 1
            t_end, y_end, name = te, step(te), nm
        if mode == BAND and name != "leave band" and t_end > t0:
            hidden = self.hidden_excursion(rhs, watched, t0, t1, y0, t_end, events, kw)
            if hidden is not None:
                t_end, y_end, name = hidden
        if travel:
            self.add_travel(t0, y0, t_end, y_end, sol, travel, rhs, kw, t1, events)
        return t_end, np.array(y_end), name

    def hidden_excursion(self, rhs, watched, t0, t1, y0, t_end, events, kw):
        """A band left and re-entered inside one step of a BAND piece, or None.

        The minimum watcher above misses it when the piece ends in a
        reversal inside the same step: |v_rel| rises above a, falls back to
        0 and reverses, so the slope of a^2 - |v_rel|^2 changes sign twice
        and has the same sign at both step ends (seen with --seed 1, j0, at
        rtol 2.3e-14). Every step of the piece is scanned on its dense
        output (33 points of the interpolant bracket a crossing; brentq
        locates it); the first crossing ends the piece as "leave band".
        """
        g = next(g for nm, g, _ in watched if nm == "leave band")
        dense = solve_ivp(rhs, (t0, t1), y0, events=events, dense_output=True, **kw)
        for k, step in enumerate(dense.sol.interpolants):
            lo, hi = dense.t[k], min(dense.t[k + 1], t_end)
            if lo >= t_end:
                break
            ts = np.linspace(lo, hi, 33)
            vals = [g(s, step(s)) for s in ts]
            for a, b, ga, gb in zip(ts, ts[1:], vals, vals[1:]):
                if ga > 0.0 and gb < 0.0:
                    te = brentq(
                        lambda s, step=step: g(s, step(s)),
                        a,
                        b,
                        xtol=1e-18,
                        rtol=4 * np.finfo(float).eps,
                    )
                    self.recovered += 1
                    return te, step(te), "leave band"
        return None

    def run(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """crosscheck.py's `run` (the same logic) with the travel: (steps, backward travel)."""
        cycles, settle = self.inst.cycles, self.inst.settle
        T = self.inst.period()
        t_end = cycles * T
        pts = self.breakpoints(t_end, T)
        y = np.zeros(8)
        mode, held = STICK, None
        fresh = False
        settle_xs = None
        for t0, t1 in itertools.pairwise(pts):
            if t0 == settle * T:
                settle_xs = y[4:6].copy()
            in_window = settle_xs is not None
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
                t_new, y, name = self.integrate_piece(mode, force, held, t, t1, y, fresh, in_window)
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
            raise RuntimeError("the settle time is not a breakpoint")
        disp = y[4:6] - settle_xs
        window = (cycles - settle) * T
        own = [window * self.inst.frequency[i] for i in range(2)]
        steps = (disp[0] / own[0], disp[1] / own[1])
        backward = tuple(0.5 * (self.variation[i] - abs(disp[i])) / own[i] for i in range(2))
        return steps, backward


@dataclass
class Integrated:
    step: tuple[float, float]
    backward: tuple[float, float]
    events: int
    recovered: int
    travel_recovered: int
    seconds: float
    error: str | None


def integrate(inst: WaveInstance, rtol: float = SCIPY_RTOL) -> Integrated:
    """One instance's SciPy reference (run in a worker process)."""
    started = time.time()
    try:
        ref = WaveReference(inst, rtol)
        (step, backward), error = ref.run(), None
        extra = (len(ref.events), ref.recovered, ref.travel_recovered)
    except RuntimeError as err:
        step, backward, error = (math.nan, math.nan), (math.nan, math.nan), str(err)
        extra = (0, 0, 0)
    return Integrated(step, backward, *extra, time.time() - started, error)
