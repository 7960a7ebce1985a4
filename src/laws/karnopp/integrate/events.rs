//! Mode-change events: their functions, the search for the first crossing
//! among a step's samples, and its location to near machine precision.
//!
//! Every event function is positive before its event and crosses to zero
//! or below at it. A step watches at most two: the primary one of its mode
//! (breakaway in stick, entering the band in slip, or slowing into it along
//! a fixed direction for a reversing slip trial, leaving it in band slip)
//! and, in band slip, the reversal of the relative velocity against the
//! held direction.

use super::Real;
use super::State;
use super::coefficients::Coefficients;
use super::constants::{
    EVENT_BREAKAWAY, EVENT_ENTER_BAND, EVENT_NOISE, FIRST_ROOT_CHECKS, ROOT_ITERATIONS,
};
use super::flow::{Flow, Sample, eval_at};
use super::precision::{TIME_EPSILON, TINY};
use super::vec2::{Vec2, dot, norm2};

/// Value and time derivative of an event function.
pub type EventValue = [Real; 2];

/// The first bracket of a crossing in step time: the function is positive
/// at `lo` and not positive at `hi`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    pub found: bool,
    pub lo: Real,
    pub hi: Real,
    /// The smallest positive value the function took at a dip between
    /// samples that did not cross (infinity where none was looked at): how
    /// close the step came to an event it did not have.
    pub closest: Real,
}

/// Fractions of a step at which every step is sampled.
pub const THETA: [Real; 5] = [0.0, 0.25, 0.5, 0.75, 1.0];

pub fn relative_velocity(s: &Sample) -> Vec2 {
    s.v_rel
}

pub fn relative_acceleration(s: &Sample) -> Vec2 {
    s.a_p - s.a_s
}

/// The primary event of a kind (breakaway, entering or leaving the band) at
/// a sample.
pub fn primary_event(c: &Coefficients, kind: u32, s: &Sample) -> EventValue {
    if kind == EVENT_BREAKAWAY {
        // f_need = m_s a_p - L = m_s (a_p - L / m_s) (docs/model.md section 7).
        let a = s.a_p - c.load_accel;
        let e = c.hold2 - c.ms2 * norm2(a);
        return [e, -c.two_ms2 * dot(a, s.j_p)];
    }
    let v = relative_velocity(s);
    let a = relative_acceleration(s);
    let e = norm2(v) - c.band2;
    let de = 2.0 * dot(v, a);
    if kind == EVENT_ENTER_BAND {
        [e, de]
    } else {
        [-e, -de]
    }
}

/// v_rel . u - a and its derivative, for the flow's constant friction
/// direction u.
pub fn approach_event(c: &Coefficients, flow: &Flow, s: &Sample) -> EventValue {
    [
        dot(relative_velocity(s), flow.b0) - c.band,
        dot(relative_acceleration(s), flow.b0),
    ]
}

/// The magnitude of the terms of the approach event.
pub fn approach_scale(c: &Coefficients, flow: &Flow, s: &Sample) -> Real {
    c.band + dot(s.v_p.abs() + s.v_s.abs(), flow.b0.abs())
}

/// v_rel . held and its derivative: the reversal event before its sign.
pub fn reversal_event(st: &State, s: &Sample) -> EventValue {
    [
        dot(relative_velocity(s), st.held),
        dot(relative_acceleration(s), st.held),
    ]
}

/// The magnitude of the terms the primary event function is the difference
/// of, for its rounding noise.
pub fn primary_scale(c: &Coefficients, kind: u32, s: &Sample) -> Real {
    if kind == EVENT_BREAKAWAY {
        // The stage acceleration is the small difference of the drive,
        // spring and damper forces, so its rounding is relative to those
        // forces, not to itself.
        // The load's acceleration is one more term of the difference.
        let forces = c.stiffness * s.x_p.abs() + c.damping * s.v_p.abs();
        let terms = s.a_p.abs() + 2.0 * forces * c.stick.inv_mass + c.load_accel.abs();
        return c.hold2 + dot(c.two_ms2 * (s.a_p - c.load_accel).abs(), terms);
    }
    // The relative velocity is a difference of two velocities that are
    // often far larger (a slider sliding with its stage), so its rounding
    // is relative to those, not to itself.
    let v = relative_velocity(s);
    c.band2 + dot(2.0 * v.abs(), s.v_p.abs() + s.v_s.abs())
}

/// The magnitude of the terms of the reversal event.
pub fn reversal_scale(st: &State, s: &Sample) -> Real {
    dot(s.v_p.abs() + s.v_s.abs(), st.held.abs())
}

/// Finds the first crossing of an event function among the values `ev` at
/// the five samples of a step of length h (`scale` sizes the rounding
/// noise at the start). Returns the bracket in step time.
pub fn find_crossing(
    c: &Coefficients,
    st: &State,
    kind: u32,
    sign: Real,
    ev: &[EventValue; 5],
    scale: Real,
    flow: &Flow,
    h: Real,
) -> Crossing {
    let mut prev = [sign * ev[0][0], sign * ev[0][1]];
    // A function already past its event when the step starts fires at once;
    // one at it, within the rounding noise of its evaluation, is armed for
    // the first interval. The noise margin keeps a decision taken at the
    // root of the previous event (the function is then zero up to
    // rounding) from depending on the last bit, which differs between
    // backends that fuse multiply-adds differently.
    let noise = EVENT_NOISE as Real * Real::EPSILON * scale;
    if prev[0] < -noise {
        return Crossing {
            found: true,
            lo: 0.0,
            hi: 0.0,
            closest: Real::INFINITY,
        };
    }
    let mut closest = Real::INFINITY;
    for j in 0..4 {
        let next = [sign * ev[j + 1][0], sign * ev[j + 1][1]];
        let lo = THETA[j] * h;
        let hi = THETA[j + 1] * h;
        let armed = prev[0] > 0.0 || j == 0;
        if armed && next[0] <= 0.0 && (prev[0] > 0.0 || next[0] < 0.0) {
            return Crossing {
                found: true,
                lo,
                hi,
                closest,
            };
        }
        if prev[0] > 0.0 && next[0] > 0.0 && prev[1] < 0.0 && next[1] > 0.0 {
            // A dip between samples: locate the minimum of the Hermite cubic
            // through both ends and test the true function there.
            let tau = hermite_minimum(prev, next, hi - lo);
            let e = event_at(c, st, kind, sign, flow, lo + tau)[0];
            if e <= 0.0 {
                return Crossing {
                    found: true,
                    lo,
                    hi: lo + tau,
                    closest,
                };
            }
            closest = closest.min(e);
        }
        prev = next;
    }
    Crossing {
        found: false,
        lo: 0.0,
        hi: 0.0,
        closest,
    }
}

/// An event function (with its sign applied) at tau inside the step.
pub fn event_at(
    c: &Coefficients,
    st: &State,
    kind: u32,
    sign: Real,
    flow: &Flow,
    tau: Real,
) -> EventValue {
    let s = eval_at(flow, tau);
    let ev = if kind == super::constants::EVENT_REVERSAL {
        reversal_event(st, &s)
    } else if kind == super::constants::EVENT_APPROACH {
        approach_event(c, flow, &s)
    } else {
        primary_event(c, kind, &s)
    };
    [sign * ev[0], sign * ev[1]]
}

/// Position of the minimum of the cubic Hermite interpolant of (value,
/// slope) pairs at 0 and len, given a negative slope at 0 and a positive one
/// at len.
pub fn hermite_minimum(a: EventValue, b: EventValue, len: Real) -> Real {
    // p(s) = a + a' s + c2 s^2 + c3 s^3 on [0, len].
    let d = (b[0] - a[0]) / len;
    let c2 = (3.0 * d - 2.0 * a[1] - b[1]) / len;
    let c3 = (a[1] + b[1] - 2.0 * d) / (len * len);
    // p'(s) = a' + 2 c2 s + 3 c3 s^2 = 0; the root where p' goes from - to +.
    let qa = 3.0 * c3;
    let qb = 2.0 * c2;
    let qc = a[1];
    let s = if qa.abs() < TINY || (qa * len).abs() < 1e-12 * qb.abs() {
        -qc / qb
    } else {
        let disc = (qb * qb - 4.0 * qa * qc).max(0.0).sqrt();
        // Stable quadratic roots; pick the one in (0, len) with p'' > 0.
        let signum = if qb >= 0.0 { 1.0 } else { -1.0 };
        let r = -0.5 * (qb + signum * disc);
        let r1 = r / qa;
        let r2 = if r != 0.0 { qc / r } else { r1 };
        let good = |s: Real| s > 0.0 && s < len && (qb + 2.0 * qa * s) > 0.0;
        if good(r1) {
            r1
        } else if good(r2) {
            r2
        } else {
            0.5 * len
        }
    };
    s.clamp(0.0, len)
}

/// Locates an event in (lo, hi) by bisection-guarded Newton iteration and
/// returns the step time just past its first crossing there.
pub fn locate(
    c: &Coefficients,
    st: &State,
    kind: u32,
    sign: Real,
    flow: &Flow,
    lo_in: Real,
    hi_in: Real,
) -> Real {
    let mut lo = lo_in;
    let mut hi = hi_in;
    // In f64 the second term never wins (hi <= period and TIME_EPSILON is
    // f64's epsilon); in f32 it stops the bisection at the resolution of
    // tau.
    let resolution = (4.0 * TIME_EPSILON as Real * c.period).max(4.0 * Real::EPSILON * hi);
    let mut tau = 0.5 * (lo + hi);
    let mut checks = 0;
    for _ in 0..ROOT_ITERATIONS {
        // A bracket may hold three crossings (a band left, re-entered and
        // left again inside it: results/events.md), and Newton's steps
        // settle on any: a crossing found is the first only where the
        // function is still positive halfway to it, else the search goes
        // on before that point.
        let check = hi - lo <= resolution;
        if check {
            if checks == FIRST_ROOT_CHECKS {
                break;
            }
            checks += 1;
            tau = 0.5 * (lo_in + hi);
        }
        let [e, de] = event_at(c, st, kind, sign, flow, tau);
        if check {
            if e > 0.0 {
                break;
            }
            lo = lo_in;
        }
        if e > 0.0 {
            lo = tau;
        } else {
            hi = tau;
        }
        let newton = tau - e / de;
        tau = if newton > lo && newton < hi && de != 0.0 {
            newton
        } else {
            0.5 * (lo + hi)
        };
        // Keep Newton from creeping toward one end of the bracket.
        let margin = 1e-3 * (hi - lo);
        if tau - lo < margin || hi - tau < margin {
            tau = tau.clamp(lo + margin, hi - margin);
        }
    }
    hi
}
