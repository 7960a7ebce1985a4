// Mirror of the floor's `piece_variation` and what it calls
// (`laws::floor::variation`; issue 59, docs/model.md section 4, "Backward
// travel"): the total variation of one axis' slider over a piece of a
// step, its velocity zeros located on the law's dense output. A law whose
// BACKWARD variants carry this file (Karnopp's) defines what it reads in
// its own variation file: `piece_point(t0, t, axis)`, the law's dense
// output (`at` on the CPU).

// The slider on one axis at one instant [m, m/s, m/s^2] (`Point`).
struct Point {
    x: Real,
    v: Real,
    a: Real,
}

// One axis' path from `a` through the velocity
// zeros to `b`, each zero located in its bracket by one call of
// `locate_zero`; `guess` is the law's first guess of the one zero between
// ends of opposite signs [s after a] (negative: the Hermite's).
fn piece_variation(a: Point, b: Point, h: Real, t0: Real, axis: u32, guess: Real) -> Real {
    if monotone(a, b, h) {
        return abs(b.x - a.x);
    }
    // The brackets' ends: a to b, or a to the dip m and m to b.
    var mid = b;
    var t_mid = h;
    var zeros = 0u;
    if a.v * b.v < Real(0.0) {
        zeros = 1u;
    } else {
        let t = hermite_extremum(a, b, h);
        if t < Real(0.0) {
            return abs(b.x - a.x);
        }
        let m = piece_point(t0, t, axis);
        if !(m.v * a.v < Real(0.0) || (a.v == Real(0.0) && m.v * b.v < Real(0.0))) {
            return abs(b.x - a.x);
        }
        mid = m;
        t_mid = t;
        zeros = 2u;
    }
    var total = Real(0.0);
    var last = a;
    for (var k = 0u; k < zeros; k++) {
        var lo = a;
        var t_lo = Real(0.0);
        var hi = mid;
        var t_hi = t_mid;
        if k == 1u {
            lo = mid;
            t_lo = t_mid;
            hi = b;
            t_hi = h;
        }
        var first = guess;
        var share = GUESSED_SHARE;
        if zeros == 2u || !(guess > Real(0.0) && guess < h) {
            first = t_lo + hermite_root(lo, hi, t_hi - t_lo);
            share = HERMITE_GUESS;
        }
        let z = locate_zero(lo, t_lo, hi, t_hi, t0, axis, first, share);
        total = total + abs(z.x - last.x);
        last = z;
    }
    return total + abs(b.x - last.x);
}

// `hermite_cubic`: v(s) = c0 + c1 s + c2 s^2 + c3 s^3.
struct Cubic {
    c0: Real,
    c1: Real,
    c2: Real,
    c3: Real,
}

fn hermite_cubic(a: Point, b: Point, h: Real) -> Cubic {
    let m0 = a.a * h;
    let m1 = b.a * h;
    return Cubic(a.v, m0, Real(3.0) * (b.v - a.v) - Real(2.0) * m0 - m1, Real(2.0) * (a.v - b.v) + m0 + m1);
}

fn cubic_value(q: Cubic, s: Real) -> Real {
    return q.c0 + s * (q.c1 + s * (q.c2 + s * q.c3));
}

// `no_dip`: the velocity's Hermite cubic over `h` cannot dip through zero
// between ends that share a sign.
fn no_dip(a: Point, b: Point, h: Real) -> bool {
    let m0 = a.a * h;
    let m1 = b.a * h;
    return min(abs(a.v), abs(b.v)) * Real(27.0) > Real(4.0) * (abs(m0) + abs(m1));
}

// `monotone`: `piece_variation` is |b.x - a.x| from the ends alone.
fn monotone(a: Point, b: Point, h: Real) -> bool {
    let crosses = a.v * b.v < Real(0.0);
    return !crosses && h > Real(0.0) && no_dip(a, b, h);
}

// `hermite_extremum` [s into the piece], or -1 where it has none.
fn hermite_extremum(a: Point, b: Point, h: Real) -> Real {
    if h <= Real(0.0) {
        return Real(-1.0);
    }
    let q = hermite_cubic(a, b, h);
    let qa = Real(3.0) * q.c3;
    let qb = Real(2.0) * q.c2;
    let qc = q.c1;
    // The roots of v'(s), each with whether it exists (the CPU's NaN).
    var r0 = Real(0.0);
    var r1 = Real(0.0);
    var has = vec2<bool>(false);
    if abs(qa) <= Real(1e-14) * (abs(qb) + abs(qc)) {
        if qb != Real(0.0) {
            r0 = div(-qc, qb);
            has.x = true;
        }
    } else {
        let disc = qb * qb - Real(4.0) * qa * qc;
        if disc >= Real(0.0) {
            let qs = -Real(0.5) * (qb + select(Real(1.0), Real(-1.0), qb < Real(0.0)) * root(disc));
            r0 = div(qs, qa);
            has.x = true;
            if qs != Real(0.0) {
                r1 = div(qc, qs);
                has.y = true;
            }
        }
    }
    let sign = select(b.v, a.v, a.v != Real(0.0));
    if has.x && r0 > Real(0.0) && r0 < Real(1.0) && cubic_value(q, r0) * sign <= Real(0.0) {
        return r0 * h;
    }
    if has.y && r1 > Real(0.0) && r1 < Real(1.0) && cubic_value(q, r1) * sign <= Real(0.0) {
        return r1 * h;
    }
    return Real(-1.0);
}

// `hermite_root` [s after a].
fn hermite_root(a: Point, b: Point, h: Real) -> Real {
    let q = hermite_cubic(a, b, h);
    var s = div(a.v, a.v - b.v);
    for (var k = 0u; k < 4u; k++) {
        let v = cubic_value(q, s);
        let d = q.c1 + s * (Real(2.0) * q.c2 + Real(3.0) * s * q.c3);
        var next = s;
        if d != Real(0.0) {
            next = s - div(v, d);
        }
        if !(next > Real(0.0) && next < Real(1.0)) {
            break;
        }
        s = next;
    }
    return s * h;
}

// The velocity zero between `a` (at `ta` into the piece) and
// `b` (at `tb`), the motion evaluated in one place: evaluation 0 is at
// `first` (the Hermite's guess or the law's, whose one-evaluation
// shortcut takes a first step within `share` of the bracket), each later
// one a Newton or bisection step's.
fn locate_zero(a: Point, ta: Real, b: Point, tb: Real, t0: Real, axis: u32, first: Real, share: Real) -> Point {
    if a.v == Real(0.0) {
        return a;
    }
    if b.v == Real(0.0) {
        return b;
    }
    var lo = ta;
    var hi = tb;
    let rising = a.v > Real(0.0);
    var t = first;
    var p = a;
    var settled = false;
    // A bound the compiler cannot know (`control.zero` is 0), so that it
    // keeps the loop rolled: unrolled, its 41 evaluations of the motion
    // tripled llvmpipe's compile of the whole shader.
    let most = ZERO_ITERATIONS + control.zero;
    for (var k = 0u; k <= most; k++) {
        p = piece_point(t0, t, axis);
        if k == 0u && p.a != Real(0.0) {
            let dt = div(-p.v, p.a);
            if abs(dt) <= share * (tb - ta) && t + dt > ta && t + dt < tb {
                return Point(p.x + Real(0.5) * p.v * dt, Real(0.0), p.a);
            }
        }
        if settled || k == most || p.v == Real(0.0) {
            break;
        }
        if (p.v > Real(0.0)) == rising {
            lo = t;
        } else {
            hi = t;
        }
        var next = Real(0.5) * (lo + hi);
        if p.a != Real(0.0) {
            let newton = t - div(p.v, p.a);
            if newton > lo && newton < hi {
                next = newton;
            }
        }
        settled = abs(next - t) <= ZERO_TIME * (tb - ta);
        t = next;
    }
    return p;
}
