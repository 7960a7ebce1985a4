// Mirror of `laws::lugre::model`: the LuGre right-hand side (docs/model.md
// section 8), its exact Jacobian, and the drive over one segment between
// corners, linear in time. f64 only. The prelude (`pidm::gpu::lugre`)
// defines Real, the state's layout (N, XP, VP, XS, VS, Z, T), the
// constants of the shader-only functions, and `quotient` and
// `square_root`: f64 division and square root, WGSL's own on llvmpipe
// (IEEE's, as the CPU's), the Karnopp prelude's `div` and `root` (from
// inverseSqrt and fma) on hardware.
//
//   g(s)  = f_c + (f_s - f_c) exp(-(s / v_S)^2)
//   dz/dt = v_rel - sigma0 s z / g(s)
//   f     = sigma0 z + sigma1 dz/dt + sigma2 v_rel      (on the slider)
//   m_p,i a_p,i = F_i(t) - c_i v_p,i - k_i x_p,i - f_i
//   m_s a_s,i   = f_i + L_i

// The state: stage positions [m] and velocities [m/s], slider positions
// and velocities, bristle deflections [m], and the time within the scene
// period [s] (Rust's `State`; WGSL's `State` is the measurement's,
// measure.wgsl).
alias Vector = array<Real, N>;
alias Matrix = array<array<Real, N>, N>;

// What the right-hand side reads of one instance (Rust's `Model`, with the
// drive's parameters and the error control's weights): one per instance,
// `pidm::gpu::lugre::Params`.
struct Model {
    gain: array<Real, 2>,
    damping: array<Real, 2>,
    stiffness: array<Real, 2>,
    stage_mass: array<Real, 2>,
    voltage: array<Real, 2>,
    frequency: array<Real, 2>,
    duty: array<Real, 2>,
    load: array<Real, 2>,
    slider_mass: Real,
    coulomb_friction: Real,
    static_friction: Real,
    sigma0: Real,
    sigma1: Real,
    sigma2: Real,
    v_s: Real,
    // The scene period [s].
    period: Real,
    // The error control's weights (`run::error_scale`): scale[T] is
    // infinite and never read.
    scale: array<Real, N>,
    // 1 (`keep`).
    one: Real,
    // Each axis' drive cycles per scene period and phase [cycles]: the
    // clock of period p is cycles p + phase (`Clock::of`).
    cycles: array<Real, 2>,
    phase: array<Real, 2>,
    // The recurrence test's tolerances (infinite: not compared) and its
    // common period (0: no test), read where used (measure.wgsl).
    repeat: array<Real, N>,
    common_period: u32,
    // Each axis' corners in `corners` (WAVEFORM variants: corners.wgsl).
    corner_first: array<u32, 2>,
    corner_count: array<u32, 2>,
    _pad: u32,
}

// The instance the invocation integrates (Rust's `self`) is `model`: a
// private copy on llvmpipe (hold_registers.wgsl); on hardware the host
// writes `models[held]` for it, read where used (`pidm::gpu::lugre`'s
// `read_where_used`).

// A drive voltage linear in time over a segment: `a + b t` [V], t the time
// within the scene period [s].
struct Linear {
    a: Real,
    b: Real,
}

alias Drive = array<Linear, 2>;

// Each axis' drive phase at the start of a scene period [cycles]
// (`Clock::of`, computed on the host).
struct Clock {
    start: array<Real, 2>,
}

// A number in two parts, hi + lo (`two_sum`, `two_prod`).
struct Pair {
    hi: Real,
    lo: Real,
}

// 1, from the instance's parameters (`Model::one`): see `keep`.
var<private> opaque_one: Real;

// x itself, as a product with a 1 the driver's compiler cannot see: it
// keeps the compiler from rewriting the two-part sums' algebra (Mesa's NIR
// folds c - (c - x) to x and (a + b) - a to b wherever it may reassociate,
// which leaves nothing of their rounding errors). The CPU's mirrors
// multiply by 1.0 alike.
fn keep(x: Real) -> Real {
    return x * opaque_one;
}

// a + b = s + e exactly (Knuth's two-sum). Mirror: `pidm::gpu::lugre::two_sum`.
fn two_sum(a: Real, b: Real) -> Pair {
    let s = keep(a + b);
    let bb = keep(s - a);
    return Pair(s, keep(a - keep(s - bb)) + keep(b - bb));
}

// x = hi + lo with hi of at most 26 significant bits (Veltkamp).
fn split(x: Real) -> Pair {
    let c = keep(SPLITTER * x);
    let hi = keep(c - keep(c - x));
    return Pair(hi, x - hi);
}

// a b = p + e exactly (Dekker's two-product): without fma, which llvmpipe
// computes as a rounded product and a sum.
fn two_prod(a: Real, b: Real) -> Pair {
    let p = keep(a * b);
    let sa = split(a);
    let sb = split(b);
    return Pair(p, ((keep(sa.hi * sb.hi) - p) + sa.hi * sb.lo + sa.lo * sb.hi) + sa.lo * sb.lo);
}

// exp(x) for x <= 0 (NaN stays NaN) from + - * alone: x = k ln 2 + r with
// |r| <= ln 2 / 2 (Cody and Waite's two-part ln 2, r's rounding kept),
// exp(r) = (1 + r) + (r^2 / 2 + r^3 P(r)) with 1 + r and r^2 in two parts
// and one final rounding, then 2^k by exact halvings. Within one unit in
// the last place, and glibc's exp but in about one argument in a hundred. The prelude writes
// P (`exp_tail`) and the halvings (`exp_halvings`: the small powers first,
// so that only the last product may leave the normal range; 2^-1024 as two
// 2^-512) out as straight-line code. Shader only (the CPU's model calls
// Rust's exp); mirrored by `pidm::gpu::lugre::exp_nonpositive`.
fn exp_nonpositive(x: Real) -> Real {
    if !(x >= EXP_MIN) {
        // Below EXP_MIN exp(x) rounds to 0; NaN stays NaN.
        return select(Real(0.0), x, x != x);
    }
    let k = floor(x * EXP_INV_LN2 + Real(0.5));
    let rh = keep(x - k * EXP_LN2_HI);
    let kl = keep(k * EXP_LN2_LO);
    let r = keep(rh - kl);
    let r_lo = keep(rh - r) - kl;
    let r2 = two_prod(r, r);
    let tail = exp_tail(r) * r2.hi * r;
    let one_r = two_sum(Real(1.0), r);
    let small = Real(0.5) * r2.hi + ((Real(0.5) * r2.lo + tail) + r_lo * one_r.hi);
    let e = one_r.hi + (one_r.lo + small);
    return exp_halvings(e, u32(-k));
}

// |(x, y)|: glibc's hypot (its kernel without fma), which Rust's
// f64::hypot calls on the CPU: the same bits. Shader only; mirrored by
// `pidm::gpu::lugre::hypot`.
fn hypot(x: Real, y: Real) -> Real {
    if !is_finite(x) || !is_finite(y) {
        if abs(x) > INFINITY || abs(y) > INFINITY {
            return abs(x) + abs(y);
        }
        return x + y;
    }
    let ax = max(abs(x), abs(y));
    let ay = min(abs(x), abs(y));
    if ax > HYPOT_LARGE {
        if ay <= ax * HYPOT_EPS {
            return ax + ay;
        }
        return hypot_kernel(ax * HYPOT_SCALE, ay * HYPOT_SCALE) * HYPOT_UNSCALE;
    }
    if ay < HYPOT_TINY {
        if ax >= ay * HYPOT_INV_EPS {
            return ax + ay;
        }
        return hypot_kernel(ax * HYPOT_UNSCALE, ay * HYPOT_UNSCALE) * HYPOT_SCALE;
    }
    if ay <= ax * HYPOT_EPS {
        return ax + ay;
    }
    return hypot_kernel(ax, ay);
}

// glibc's hypot kernel for ax >= ay: the square root of the sum of
// squares, corrected once.
fn hypot_kernel(ax: Real, ay: Real) -> Real {
    let h = square_root(ax * ax + ay * ay);
    var t1: Real;
    var t2: Real;
    if h <= Real(2.0) * ay {
        let delta = h - ay;
        t1 = ax * (Real(2.0) * delta - ax);
        t2 = (delta - Real(2.0) * (ax - ay)) * delta;
    } else {
        let delta = h - ax;
        t1 = Real(2.0) * delta * (ax - Real(2.0) * ay);
        t2 = (Real(4.0) * delta - ay) * ay + delta * delta;
    }
    return h - quotient(t1 + t2, Real(2.0) * h);
}

// Whether x is neither infinite nor NaN.
fn is_finite(x: Real) -> bool {
    return x == x && abs(x) <= INFINITY;
}

// Linear::at: the voltage at time t.
fn at(l: Linear, t: Real) -> Real {
    return l.a + l.b * t;
}

// dy/dt, with each axis' drive voltage linear in time. The CPU's loop
// over the axes is a call per axis with a literal index (`rhs_axis`), so
// that once the driver inlines it no array is indexed at run time (a
// private array indexed so lives in local memory on NVIDIA).
fn rhs(y: Vector, drive: Drive) -> Vector {
    let vr = array<Real, 2>(y[VP] - y[VS], y[VP + 1u] - y[VS + 1u]);
    let s = hypot(vr[0], vr[1]);
    let q = quotient(s, model.v_s);
    let g = model.coulomb_friction
        + (model.static_friction - model.coulomb_friction) * exp_nonpositive(-(q * q));
    var d: Vector;
    rhs_axis(&d, y, drive, vr, s, g, 0u);
    rhs_axis(&d, y, drive, vr, s, g, 1u);
    d[T] = Real(1.0);
    return d;
}

// Axis `i`'s rows of `rhs` (the body of the CPU's loop).
fn rhs_axis(
    d: ptr<function, Vector>,
    y: Vector,
    drive: Drive,
    vr: array<Real, 2>,
    s: Real,
    g: Real,
    i: u32,
) {
    let dz = vr[i] - quotient(model.sigma0 * s * y[Z + i], g);
    let f = model.sigma0 * y[Z + i] + model.sigma1 * dz + model.sigma2 * vr[i];
    let force = model.gain[i] * at(drive[i], y[T]);
    (*d)[XP + i] = y[VP + i];
    (*d)[VP + i] = quotient(
        force - model.damping[i] * y[VP + i] - model.stiffness[i] * y[XP + i] - f,
        model.stage_mass[i],
    );
    (*d)[XS + i] = y[VS + i];
    (*d)[VS + i] = quotient(f + model.load[i], model.slider_mass);
    (*d)[Z + i] = dz;
}

// What every entry of the Jacobian reads of the friction's state: the
// relative velocities, their norm s, and h = s / g(s) with its derivative.
struct Friction {
    vr: array<Real, 2>,
    s: Real,
    h: Real,
    dh: Real,
}

// The Jacobian of `rhs` (row: derivative, column: state). At v_rel = 0,
// where |v_rel| has no derivative, the bristle term's direction is
// dropped (its factor z h'(s) v_rel / s is bounded). The CPU's loops over
// the axes are calls with literal indices (`jacobian_axis`,
// `jacobian_pair`), as `rhs`'s.
fn jacobian(y: Vector, drive: Drive) -> Matrix {
    let vr = array<Real, 2>(y[VP] - y[VS], y[VP + 1u] - y[VS + 1u]);
    let s = hypot(vr[0], vr[1]);
    let q = quotient(s, model.v_s);
    let e = exp_nonpositive(-(q * q));
    let fs_fc = model.static_friction - model.coulomb_friction;
    let g = model.coulomb_friction + fs_fc * e;
    let dg = fs_fc * e * quotient(Real(-2.0) * s, model.v_s * model.v_s);
    let h = quotient(s, g);
    let dh = quotient(g - s * dg, g * g);
    let friction = Friction(vr, s, h, dh);
    var jac: Matrix;
    jacobian_axis(&jac, y, drive, friction, 0u);
    jacobian_axis(&jac, y, drive, friction, 1u);
    return jac;
}

// d(dz_i)/d(v_rel_j).
fn ddz_dvr(y: Vector, fr: Friction, i: u32, j: u32) -> Real {
    let own = select(Real(0.0), Real(1.0), i == j);
    let turn = select(Real(0.0), quotient(fr.vr[j], fr.s), fr.s > Real(0.0));
    return own - model.sigma0 * y[Z + i] * fr.dh * turn;
}

// Axis `i`'s rows of the Jacobian (the body of the CPU's loop over `i`).
fn jacobian_axis(jac: ptr<function, Matrix>, y: Vector, drive: Drive, fr: Friction, i: u32) {
    let ddz_dz = -model.sigma0 * fr.h;
    let df_dz = model.sigma0 + model.sigma1 * ddz_dz;
    let mass = model.stage_mass[i];
    (*jac)[XP + i][VP + i] = Real(1.0);
    (*jac)[XS + i][VS + i] = Real(1.0);
    (*jac)[VP + i][XP + i] = quotient(-model.stiffness[i], mass);
    (*jac)[VP + i][VP + i] = quotient(-model.damping[i], mass);
    (*jac)[VP + i][Z + i] = quotient(-df_dz, mass);
    (*jac)[VP + i][T] = quotient(model.gain[i] * drive[i].b, mass);
    (*jac)[VS + i][Z + i] = quotient(df_dz, model.slider_mass);
    (*jac)[Z + i][Z + i] = ddz_dz;
    jacobian_pair(jac, y, fr, i, 0u);
    jacobian_pair(jac, y, fr, i, 1u);
}

// The entries of row axis `i` and column axis `j` that the velocities
// couple (the body of the CPU's inner loop over `j`).
fn jacobian_pair(jac: ptr<function, Matrix>, y: Vector, fr: Friction, i: u32, j: u32) {
    let ddz = ddz_dvr(y, fr, i, j);
    let df_dvr = model.sigma1 * ddz + select(Real(0.0), model.sigma2, i == j);
    let mass = model.stage_mass[i];
    (*jac)[VP + i][VP + j] -= quotient(df_dvr, mass);
    (*jac)[VP + i][VS + j] += quotient(df_dvr, mass);
    (*jac)[VS + i][VP + j] += quotient(df_dvr, model.slider_mass);
    (*jac)[VS + i][VS + j] -= quotient(df_dvr, model.slider_mass);
    (*jac)[Z + i][VP + j] += ddz;
    (*jac)[Z + i][VS + j] -= ddz;
}

// Axis `i`'s drive over a segment that contains `t_mid` [s] and no corner
// (docs/model.md section 2), linear in time: a sawtooth's, or in a
// WAVEFORM variant any waveform's (corners.wgsl).
fn drive_on(clock: Clock, i: u32, t_mid: Real) -> Linear {
    var start = clock.start;
    let v = model.voltage[i];
    if v == Real(0.0) {
        return Linear(Real(0.0), Real(0.0));
    }
    let u0 = start[i];
    let f = model.frequency[i];
    let n = floor(u0 + f * t_mid);
    if WAVEFORM {
        return piece_drive(i, v, u0, n, f, u0 + f * t_mid - n);
    }
    let duty = model.duty[i];
    // u = u0 + f t; rise: (u - n) / d, fall: (n + 1 - u) / (1 - d).
    if u0 + f * t_mid - n < duty {
        let k = quotient(v, duty);
        return Linear(k * (u0 - n), k * f);
    }
    let k = quotient(v, Real(1.0) - duty);
    return Linear(k * (n + Real(1.0) - u0), -k * f);
}

// The first drive corner of axis `i` after `t` [s] (INFINITY undriven).
// The CPU's recursion (a corner rounded onto t: the next one) is a loop
// here, of at most CORNER_RETRIES passes.
fn next_corner(clock: Clock, i: u32, t: Real) -> Real {
    var start = clock.start;
    if model.voltage[i] == Real(0.0) {
        return INFINITY;
    }
    let u0 = start[i];
    let f = model.frequency[i];
    var after = t;
    var at = t;
    for (var retry = 0u; retry < CORNER_RETRIES; retry++) {
        let u = u0 + f * after;
        let n = floor(u);
        let corner = n + cycle_corner(i, u - n);
        at = quotient(corner - u0, f);
        if at <= after + Real(1e-15) * (abs(after) + quotient(Real(1.0), f)) {
            after = at + quotient(Real(1e-12), f);
        } else {
            break;
        }
    }
    return at;
}

// The end of the piece of axis `i`'s cycle that holds phase `p` in [0, 1)
// [cycles] (`Corners::piece_at`'s end): the sawtooth's duty or 1, or in a
// WAVEFORM variant its corners' (corners.wgsl).
fn cycle_corner(i: u32, p: Real) -> Real {
    if WAVEFORM {
        return piece_end(i, p);
    }
    let duty = model.duty[i];
    return select(Real(1.0), duty, p < duty);
}
