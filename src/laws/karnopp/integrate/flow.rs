//! The closed-form motion over one step: propagators of the stage
//! oscillators, the flow (particular solution plus homogeneous part per
//! axis, and the slider), and its evaluation at any time inside the step.

use super::Real;
use super::coefficients::{Coefficients, Oscillator};
use super::constants::{
    MAX_SQUARINGS, ONE_SIXTH, ONE_THIRD, ONE_TWELFTH, TAYLOR_STAGE_CONVERGED, TAYLOR_STAGE_TERMS,
};
use super::precision::DEFLECTION;
use super::precision::only_f64;
use super::vec2::Vec2;

/// 1 / n as the shader's literal of it (`inverse_integer`): the f64
/// quotient, rounded once to the precision.
fn inverse_integer(n: u32) -> Real {
    (1.0 / n as f64) as Real
}

/// exp(A tau) = (1 + a0m1) I + a1 A per axis, for the oscillator matrix
/// A = [[0, 1], [-w2, -2 sigma]]. Keeping a0 - 1 rather than a0 makes short
/// steps exact at tau = 0 and free of cancellation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Propagator {
    pub a0m1: Vec2,
    pub a1: Vec2,
}

/// The propagator over zero time.
pub const IDENTITY: Propagator = Propagator {
    a0m1: Vec2::ZERO,
    a1: Vec2::ZERO,
};

/// The propagators at the sample points of a step: a quarter, half, three
/// quarters and all of it.
#[derive(Clone, Copy, Debug, Default)]
pub struct SamplePropagators {
    pub quarter: Propagator,
    pub half: Propagator,
    pub three_quarters: Propagator,
    pub full: Propagator,
}

/// The state at one instant of a step, with the derivatives event functions
/// need.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    pub x_p: Vec2,
    pub v_p: Vec2,
    pub a_p: Vec2,
    /// Stage jerk [m/s^3]: the homogeneous part's, which is the whole jerk
    /// because the particular solution is quadratic in time.
    pub j_p: Vec2,
    pub x_s: Vec2,
    pub v_s: Vec2,
    pub a_s: Vec2,
    /// v_p - v_s, from the start value and the changes since the start.
    pub v_rel: Vec2,
}

/// The motion of both axes over one step.
#[derive(Clone, Copy, Debug, Default)]
pub struct Flow {
    /// True in stick: the slider rides on the stage.
    pub stuck: bool,
    /// The mode's oscillator.
    pub osc: Oscillator,
    /// Damping and stiffness (the same in both modes).
    pub damping: Vec2,
    pub stiffness: Vec2,
    /// Step length the slider polynomial is scaled to [s], and its inverse.
    pub h: Real,
    pub inv_h: Real,
    /// Particular solution x(tau) = x0 + part1 tau + part2 tau^2 (its
    /// constant x0 enters only through y0).
    pub part1: Vec2,
    pub part2: Vec2,
    /// Homogeneous displacement and velocity at tau = 0.
    pub y0: Vec2,
    pub w0: Vec2,
    /// The state at tau = 0.
    pub x_p: Vec2,
    pub v_p: Vec2,
    pub x_s: Vec2,
    pub v_s: Vec2,
    pub v_rel: Vec2,
    /// The friction direction model's constant term (slip only).
    pub b0: Vec2,
    /// Slider acceleration polynomial in theta = tau / h (slip only).
    pub slider0: Vec2,
    pub slider1: Vec2,
    pub slider2: Vec2,
    /// Stage force polynomial g0 + g1 tau + g2 tau^2 [N, N/s, N/s^2].
    pub g0: Vec2,
    pub g1: Vec2,
    pub g2: Vec2,
    /// `DEFLECTION` (f32): g0 - drive force, g1 - drive slope, and the
    /// drive's static velocity slope / k; x_p and v_p are then the stage's
    /// deflection from the drive's static position F / k and its velocity
    /// relative to slope / k (see [`make_flow`]).
    pub g0_rel: Vec2,
    pub g1_rel: Vec2,
    pub ramp: Vec2,
    /// Per axis: the stage is evaluated by its Taylor series in tau rather
    /// than particular solution plus propagator (on short steps the
    /// particular solution of a steep force polynomial cancels badly).
    pub taylor: [bool; 2],
}

/// The friction direction model u(theta) = b0 + b1 theta + b2 theta^2 on
/// the slider over a step (theta = tau / h).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DirectionModel {
    pub b0: Vec2,
    pub b1: Vec2,
    pub b2: Vec2,
}

/// The exponential of the oscillator matrix over `tau`, per axis: Taylor
/// series after halving the time until its norm is at most 1/2, then
/// repeated squaring.
pub fn propagator(osc: &Oscillator, tau: Real) -> Propagator {
    let mut scale = osc.rate * tau;
    let mut t = Vec2::splat(tau);
    let mut squarings = [0u32; 2];
    for _ in 0..MAX_SQUARINGS {
        let more = [scale.x > 0.5, scale.y > 0.5];
        if !more[0] && !more[1] {
            break;
        }
        scale = Vec2::select(scale, scale * 0.5, more);
        t = Vec2::select(t, t * 0.5, more);
        squarings[0] += more[0] as u32;
        squarings[1] += more[1] as u32;
    }
    let mut prop = taylor_propagator(osc, t);
    let most = squarings[0].max(squarings[1]);
    for k in 0..most {
        let squared = compose(osc, prop, prop);
        let more = [k < squarings[0], k < squarings[1]];
        prop = Propagator {
            a0m1: Vec2::select(prop.a0m1, squared.a0m1, more),
            a1: Vec2::select(prop.a1, squared.a1, more),
        };
    }
    prop
}

/// The Taylor series of exp(A t) for |A t| <= 1/2, per axis: term n is
/// t^n / n! A^n = p I + q A, with A^2 = -w2 I - 2 sigma A. The shader
/// unrolls the 14 terms ([`super::constants::TAYLOR_TERMS`]) with the same
/// constant factors 1 / n.
fn taylor_propagator(osc: &Oscillator, t: Vec2) -> Propagator {
    let mut p = Vec2::splat(1.0);
    let mut q = Vec2::ZERO;
    let mut a0m1 = Vec2::ZERO;
    let mut a1 = Vec2::ZERO;
    for n in 1..=super::constants::TAYLOR_TERMS {
        let f = t * inverse_integer(n);
        let next_p = -osc.w2 * q * f;
        let next_q = (p - 2.0 * osc.sigma * q) * f;
        p = next_p;
        q = next_q;
        a0m1 = a0m1 + p;
        a1 = a1 + q;
    }
    Propagator { a0m1, a1 }
}

/// The product of two propagators of the same oscillator.
pub fn compose(osc: &Oscillator, a: Propagator, b: Propagator) -> Propagator {
    // (1 + a) (1 + b) - 1 = a + b + a b for the identity parts.
    let ab = a.a1 * b.a1;
    Propagator {
        a0m1: a.a0m1 + b.a0m1 + a.a0m1 * b.a0m1 - osc.w2 * ab,
        a1: a.a1 + b.a1 + a.a0m1 * b.a1 + a.a1 * b.a0m1 - 2.0 * osc.sigma * ab,
    }
}

/// The propagators at the four sample points of a step of length h after
/// its start.
pub fn sample_propagators(flow: &Flow, h: Real) -> SamplePropagators {
    let osc = &flow.osc;
    let quarter = propagator(osc, 0.25 * h);
    let half = compose(osc, quarter, quarter);
    SamplePropagators {
        quarter,
        half,
        three_quarters: compose(osc, half, quarter),
        full: compose(osc, half, half),
    }
}

/// Sets up the closed-form motion from the current state: in stick
/// (`stuck`) under the drive force and the load with the slider riding on
/// the stage, in slip under the drive force less f_c times the direction
/// model with the slider accelerated by f_c / m_s times it plus L / m_s. `h` scales the
/// direction model (ignored in stick).
pub fn make_flow(
    c: &Coefficients,
    stuck: bool,
    x_p: Vec2,
    v_p: Vec2,
    x_s: Vec2,
    v_s: Vec2,
    v_rel: Vec2,
    force: Vec2,
    slope: Vec2,
    dir: &DirectionModel,
    h: Real,
    inv_h: Real,
) -> Flow {
    // The load (docs/model.md section 7) is a constant force: in stick it acts
    // on stage and slider as one body, in slip on the slider alone; either
    // way only the particular solution moves.
    let (osc, g0_rel, g1_rel, g2) = if stuck {
        (c.stick, Vec2::ZERO - c.neg_load, Vec2::ZERO, Vec2::ZERO)
    } else {
        (
            c.slip,
            -c.coulomb * dir.b0,
            -c.coulomb * dir.b1 * inv_h,
            -c.coulomb * dir.b2 * (inv_h * inv_h),
        )
    };
    let (g0, g1) = if stuck {
        (force - c.neg_load, slope)
    } else {
        (force + g0_rel, slope + g1_rel)
    };
    // Polynomial particular solution of m x'' + c x' + k x = g.
    let x2 = g2 * c.inv_stiffness;
    let x1 = (g1 - 2.0 * c.damping * x2) * c.inv_stiffness;
    let x0 = (g0 - c.damping * x1 - 2.0 * osc.mass * x2) * c.inv_stiffness;
    let turning = [
        dir.b1.x != 0.0 || dir.b2.x != 0.0,
        dir.b1.y != 0.0 || dir.b2.y != 0.0,
    ];
    let short = [osc.rate.x * h <= 1.0, osc.rate.y * h <= 1.0];
    let (mut part1, mut y0, mut w0) = (x1, x_p - x0, v_p - x1);
    if DEFLECTION {
        // x_p and v_p are deflections (x_p - F / k, v_p - slope / k): the
        // homogeneous part's start is their sum with the small offsets of
        // the particular solution from the drive's static motion, with no
        // difference of two large positions (f32 would know it only to
        // 6e-8 of the stage's position).
        part1 = (g1_rel - 2.0 * c.damping * x2) * c.inv_stiffness;
        y0 = x_p + (c.damping * x1 + 2.0 * osc.mass * x2 - g0_rel) * c.inv_stiffness;
        w0 = v_p + (2.0 * c.damping * x2 - g1_rel) * c.inv_stiffness;
    }
    Flow {
        stuck,
        osc,
        damping: c.damping,
        stiffness: c.stiffness,
        h,
        inv_h,
        part1,
        part2: x2,
        y0,
        w0,
        x_p,
        v_p,
        x_s,
        v_s,
        v_rel,
        b0: dir.b0,
        slider0: c.fc_over_ms * dir.b0 - c.neg_load_accel,
        slider1: c.fc_over_ms * dir.b1,
        slider2: c.fc_over_ms * dir.b2,
        g0,
        g1,
        g2,
        g0_rel,
        g1_rel,
        ramp: slope * c.inv_stiffness,
        taylor: [
            !stuck && turning[0] && short[0],
            !stuck && turning[1] && short[1],
        ],
    }
}

/// Stage (x, change of v since the start, a, jerk) at tau with the
/// propagator for tau.
fn eval_stage(f: &Flow, prop: Propagator, tau: Real) -> (Vec2, Vec2, Vec2, Vec2) {
    let o = &f.osc;
    // Changes of the homogeneous part since tau = 0, then the state as the
    // start value plus changes, so tau = 0 reproduces the start exactly.
    let dy = prop.a0m1 * f.y0 + prop.a1 * f.w0;
    let dw = prop.a0m1 * f.w0 + prop.a1 * (-o.w2 * f.y0 - 2.0 * o.sigma * f.w0);
    let y = f.y0 + dy;
    let w = f.w0 + dw;
    let a_h = -o.w2 * y - 2.0 * o.sigma * w;
    let j_h = -o.w2 * w - 2.0 * o.sigma * a_h;
    let x = f.x_p + (f.part1 + f.part2 * tau) * tau + dy;
    let dv = 2.0 * f.part2 * tau + dw;
    let a = 2.0 * f.part2 + a_h;
    (x, dv, a, j_h)
}

/// Stage (x, change of v, a, jerk) at tau by the Taylor series of the exact solution,
/// with derivatives from m x'' = g - c x' - k x. Valid and accurate to
/// rounding for rate * tau <= 1. Each axis stops adding terms once the
/// bound on its next term is negligible.
fn eval_stage_taylor(f: &Flow, tau: Real) -> (Vec2, Vec2, Vec2, Vec2) {
    let o = &f.osc;
    // Sliding window of derivatives d[n..n+3].
    let mut d0 = f.x_p;
    let mut d1 = f.v_p;
    let mut d2 = (f.g0 - f.damping * d1 - f.stiffness * d0) * o.inv_mass;
    let mut d3 = (f.g1 - f.damping * d2 - f.stiffness * d1) * o.inv_mass;
    if DEFLECTION {
        // The same derivatives from the deflections (F - k x_p = -k d).
        d2 = (f.g0_rel - f.damping * (d1 + f.ramp) - f.stiffness * d0) * o.inv_mass;
        d3 = (f.g1_rel - f.damping * d2 - f.stiffness * d1) * o.inv_mass;
    }
    let mut t = 1.0;
    // The n-th term is bounded by (rate tau)^n / n! times the state's scale.
    let rate_tau = o.rate * tau;
    let mut bound = Vec2::splat(1.0);
    let (mut x, mut v, mut a, mut j) = (Vec2::ZERO, Vec2::ZERO, Vec2::ZERO, Vec2::ZERO);
    for n in 0..TAYLOR_STAGE_TERMS {
        let live = [
            n < 3 || bound.x >= TAYLOR_STAGE_CONVERGED as Real,
            n < 3 || bound.y >= TAYLOR_STAGE_CONVERGED as Real,
        ];
        if !live[0] && !live[1] {
            break;
        }
        let inv_n1 = inverse_integer(n + 1);
        bound = Vec2::select(bound, bound * rate_tau * inv_n1, live);
        x = Vec2::select(x, x + d0 * t, live);
        // The velocity's change leaves out its start value (n = 0).
        if n > 0 {
            v = Vec2::select(v, v + d1 * t, live);
        }
        a = Vec2::select(a, a + d2 * t, live);
        j = Vec2::select(j, j + d3 * t, live);
        // g^(n+2)(0): 2 g2 for n = 0, zero after.
        let g = if n == 0 { 2.0 * f.g2 } else { Vec2::ZERO };
        let d4 = (g - f.damping * d3 - f.stiffness * d2) * o.inv_mass;
        d0 = d1;
        d1 = d2;
        d2 = d3;
        d3 = d4;
        t *= tau * inv_n1;
    }
    (x, v, a, j)
}

/// Evaluates the flow at tau, given the propagator for tau.
pub fn eval_flow(flow: &Flow, prop: Propagator, tau: Real) -> Sample {
    // Each form only where an axis needs it (both where the axes differ).
    let mut stage = (Vec2::ZERO, Vec2::ZERO, Vec2::ZERO, Vec2::ZERO);
    if !(flow.taylor[0] && flow.taylor[1]) {
        stage = eval_stage(flow, prop, tau);
    }
    let (mut x, mut dv, mut a, mut j) = stage;
    if flow.taylor[0] || flow.taylor[1] {
        let (tx, tdv, ta, tj) = eval_stage_taylor(flow, tau);
        x = Vec2::select(x, tx, flow.taylor);
        dv = Vec2::select(dv, tdv, flow.taylor);
        a = Vec2::select(a, ta, flow.taylor);
        j = Vec2::select(j, tj, flow.taylor);
    }
    let v = flow.v_p + dv;
    if flow.stuck {
        let (x_s, v_s) = if DEFLECTION {
            (flow.x_s + ((x - flow.x_p) + flow.ramp * tau), v + flow.ramp)
        } else {
            (flow.x_s + (x - flow.x_p), v)
        };
        Sample {
            x_p: x,
            v_p: v,
            a_p: a,
            j_p: j,
            x_s,
            v_s,
            a_s: a,
            v_rel: Vec2::ZERO,
        }
    } else {
        let th = tau * flow.inv_h;
        let h = flow.h;
        let (c0, c1, c2) = (flow.slider0, flow.slider1, flow.slider2);
        let dv_s = (h * th) * (c0 + (c1 * 0.5 + c2 * (ONE_THIRD as Real * th)) * th);
        Sample {
            x_p: x,
            v_p: v,
            a_p: a,
            j_p: j,
            x_s: flow.x_s
                + flow.v_s * tau
                + (h * h * th * th)
                    * (c0 * 0.5 + (c1 * ONE_SIXTH as Real + c2 * (ONE_TWELFTH as Real * th)) * th),
            v_s: flow.v_s + dv_s,
            a_s: c0 + (c1 + c2 * th) * th,
            v_rel: flow.v_rel + (dv - dv_s),
        }
    }
}

/// Evaluates the flow at any tau inside its step (dense output).
pub fn eval_at(flow: &Flow, tau: Real) -> Sample {
    eval_flow(flow, propagator(&flow.osc, tau), tau)
}

only_f64! {
#[cfg(test)]
mod tests {
    use super::*;
    use crate::laws::karnopp::integrate::Settings;
    use crate::model::Instance;

    /// The propagator against the closed-form exponential of an
    /// underdamped oscillator: x(t) = e^(-sigma t) (cos wd t + sigma / wd sin
    /// wd t) for x(0) = 1, v(0) = 0.
    #[test]
    fn propagator_matches_the_damped_oscillator() {
        let c = Coefficients::new(&Instance::TABLE1, &Settings::default(), Real::EPSILON);
        let osc = c.slip;
        let (sigma, w2) = (osc.sigma.x, osc.w2.x);
        let wd = (w2 - sigma * sigma).sqrt();
        for tau in [0.0, 1e-9, 1e-6, 3e-5, 1e-4, 1e-3, 0.05] {
            let p = propagator(&osc, tau);
            // Applied to (1, 0), exp(A t) = a0 I + a1 A gives a0 as the
            // first component.
            let exact = (-sigma * tau).exp() * ((wd * tau).cos() + sigma / wd * (wd * tau).sin());
            let got = 1.0 + p.a0m1.x;
            assert!(
                (got - exact).abs() <= 1e-13,
                "tau {tau}: {got} against {exact}"
            );
            assert_eq!(p.a0m1.x, p.a0m1.y, "identical axes, tau {tau}");
        }
    }
}
}
