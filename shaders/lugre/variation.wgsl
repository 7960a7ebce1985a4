// Mirror of `laws::lugre::run`'s backward travel (issue 59; docs/model.md
// section 4): the slider's total variation over every accepted Rodas4
// step, on the cubic Hermite of the step's ends (`step_variation`, the
// trajectories' dense output), whose velocity zeros are a quadratic's
// roots, with the floor's `follow` from `shared/variation.wgsl`, whose
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

// `step_variation`: the slider's total variation per axis over the
// accepted step from `a` to `b` [m], over each axis' cubic Hermite of the
// ends (the trajectories' dense output), written out per axis: no loop
// for llvmpipe's limiter to count.
fn step_variation(a: Vector, b: Vector) -> V2 {
    let h = b[T] - a[T];
    let xa = V2(a[XS], a[XS + 1u]);
    let va = V2(a[VS], a[VS + 1u]);
    let xb = V2(b[XS], b[XS + 1u]);
    let vb = V2(b[VS], b[VS + 1u]);
    if h <= Real(0.0) {
        return abs(xb - xa);
    }
    return V2(
        cubic_variation(xa.x, va.x, xb.x, vb.x, h),
        cubic_variation(xa.y, va.y, xb.y, vb.y, h),
    );
}

// `cubic_variation`: the total variation of x(s) = xa + s (h va + s (c2
// + s c3)) over s in [0, 1], between the zeros of its slope.
fn cubic_variation(xa: Real, va: Real, xb: Real, vb: Real, h: Real) -> Real {
    let c2 = Real(3.0) * (xb - xa) - h * (Real(2.0) * va + vb);
    let c3 = Real(2.0) * (xa - xb) + h * (va + vb);
    let roots = quadratic_roots(Real(3.0) * c3, Real(2.0) * c2, h * va);
    var p1 = xa;
    if roots.x > Real(0.0) && roots.x < Real(1.0) {
        let s = roots.x;
        p1 = xa + s * (h * va + s * (c2 + s * c3));
    }
    var p2 = p1;
    if roots.y > Real(0.0) && roots.y < Real(1.0) {
        let s = roots.y;
        p2 = xa + s * (h * va + s * (c2 + s * c3));
    }
    return abs(p1 - xa) + abs(p2 - p1) + abs(xb - p2);
}

// `quadratic_roots`: the real roots of qa s^2 + qb s + qc, the smaller
// first, -1 for one that does not exist.
fn quadratic_roots(qa: Real, qb: Real, qc: Real) -> V2 {
    let disc = qb * qb - Real(4.0) * qa * qc;
    let real = disc >= Real(0.0);
    if !real {
        return V2(-1.0);
    }
    let sign = select(Real(1.0), Real(-1.0), qb < Real(0.0));
    let q = Real(-0.5) * (qb + sign * square_root(disc));
    var r1 = Real(-1.0);
    if qa != Real(0.0) {
        r1 = quotient(q, qa);
    }
    var r2 = Real(-1.0);
    if q != Real(0.0) {
        r2 = quotient(qc, q);
    }
    return V2(min(r1, r2), max(r1, r2));
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
