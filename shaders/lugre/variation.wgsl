// Mirror of `laws::lugre::run`'s backward travel (issue 59; docs/model.md
// section 4): the slider's total variation over every accepted Rodas4
// step, on the cubic Hermite of the step's ends (`step_variation`, the
// trajectories' dense output), with the floor's `piece_variation` and
// `follow` from `shared/variation.wgsl`, whose `piece_point` and
// `variation_slot` this file defines. Only BACKWARD variants carry the
// two files (`pidm::gpu::lugre::source`); the others get empty twins of
// `follow_step` and `follow_period_end`. What they add never changes the
// state: a BACKWARD variant's steps are those of the variant without it,
// bit for bit.
//
// An instance's variation is the entry `variation_slot(held)` of the
// second half of `measures`. Beside what `shared/variation.wgsl` says its
// snapshots hold, `snaps[1].x_p` is the running total within the current
// period: the CPU's run adds the steps of a period to a local total and
// keeps it at the period's end (`continue_until`), so `snaps[0].x_p` is
// the total at the last period end, where the CPU tail continues a run.

fn variation_slot(slot: u32) -> u32 {
    return slot + arrayLength(&measures) / 2u;
}

// The step being followed: each axis' cubic Hermite of the slider's
// position, x(s) = xa + s (h va + s (c2 + s c3)) for s = t / h.
struct HermiteStep {
    xa: V2,
    va: V2,
    c2: V2,
    c3: V2,
    h: Real,
    inv_h: Real,
}

var<private> hermite: HermiteStep;

// The dense output's `point` on axis `axis`, `t` into the step (`t0` is
// 0: a LuGre step is one piece).
fn piece_point(t0: Real, t: Real, axis: u32) -> Point {
    let s = t * hermite.inv_h;
    var xa = hermite.xa.x;
    var va = hermite.va.x;
    var c2 = hermite.c2.x;
    var c3 = hermite.c3.x;
    if axis != 0u {
        xa = hermite.xa.y;
        va = hermite.va.y;
        c2 = hermite.c2.y;
        c3 = hermite.c3.y;
    }
    let h = hermite.h;
    let inv_h = hermite.inv_h;
    return Point(
        xa + s * (h * va + s * (c2 + s * c3)),
        va + s * (Real(2.0) * c2 + Real(3.0) * s * c3) * inv_h,
        (Real(2.0) * c2 + Real(6.0) * s * c3) * inv_h * inv_h,
    );
}

// `step_variation`: the slider's total variation per axis over the
// accepted step from `a` to `b` [m].
fn step_variation(a: Vector, b: Vector) -> V2 {
    let h = b[T] - a[T];
    let xa = V2(a[XS], a[XS + 1u]);
    let va = V2(a[VS], a[VS + 1u]);
    let xb = V2(b[XS], b[XS + 1u]);
    let vb = V2(b[VS], b[VS + 1u]);
    if h <= Real(0.0) {
        return abs(xb - xa);
    }
    hermite = HermiteStep(
        xa,
        va,
        Real(3.0) * (xb - xa) - h * (Real(2.0) * va + vb),
        Real(2.0) * (xa - xb) + h * (va + vb),
        h,
        quotient(Real(1.0), h),
    );
    var total = V2(0.0);
    for (var axis = 0u; axis < 2u; axis++) {
        // The ends are the integrator's own, with the Hermite's slopes.
        var start = piece_point(Real(0.0), Real(0.0), axis);
        var end = piece_point(Real(0.0), h, axis);
        start.x = select(xa.y, xa.x, axis == 0u);
        start.v = select(va.y, va.x, axis == 0u);
        end.x = select(xb.y, xb.x, axis == 0u);
        end.v = select(vb.y, vb.x, axis == 0u);
        let v = piece_variation(start, end, h, Real(0.0), axis, Real(-1.0));
        if axis == 0u {
            total.x = v;
        } else {
            total.y = v;
        }
    }
    return total;
}

// Adds the accepted step from `a` to `b` to the running total of the
// period.
fn follow_step(a: Vector, b: Vector) {
    let v = variation_slot(held);
    measures[v].snaps[1].x_p = measures[v].snaps[1].x_p + step_variation(a, b);
}

// The period's running total becomes the instance's total, as the CPU
// keeps it at a period end (before its measurement).
fn follow_commit() {
    let v = variation_slot(held);
    measures[v].snaps[0].x_p = measures[v].snaps[1].x_p;
}

// The measured periods begin: the total then (`settle_total`).
fn follow_settle() {
    let v = variation_slot(held);
    measures[v].snaps[0].v_p = measures[v].snaps[0].x_p;
}
