// Mirror of src/cpu/lugre/model.rs: the LuGre right-hand side (MODEL.md
// section 8), its exact Jacobian, and the drive over one segment between
// corners, linear in time. f64 only. The prelude (`pidm::gpu::lugre`)
// defines Real, the state's layout (N, XP, VP, XS, VS, Z, T), the
// constants of `exp_nonpositive` and the helpers recip, div and root.
//
//   g(s)  = f_c + (f_s - f_c) exp(-(s / v_S)^2)
//   dz/dt = v_rel - sigma0 s z / g(s)
//   f     = sigma0 z + sigma1 dz/dt + sigma2 v_rel      (on the slider)
//   m_p,i a_p,i = F_i(t) - c_i v_p,i - k_i x_p,i - f_i
//   m_s a_s,i   = f_i + L_i

// The state: stage positions [m] and velocities [m/s], slider positions
// and velocities, bristle deflections [m], and the time within the scene
// period [s].
alias State = array<Real, N>;
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
}

// The instance the invocation integrates (Rust's `self`).
var<private> model: Model;

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

// exp(x) for x <= 0 (and NaN), from + - * and fma: x = k ln 2 + r with
// |r| <= ln 2 / 2 (Cody and Waite's two-part ln 2), a Taylor polynomial of
// degree EXP_DEGREE in r, then 2^k by halvings. Within 1e-15 of exp(x),
// relative, where exp(x) is a normal number. The prelude writes the
// polynomial (`exp_taylor`, Horner's scheme in fma) and the halvings
// (`exp_halvings`: the small powers first, so that only the last product
// may leave the normal range; 2^-1024 as two 2^-512) out as straight-line
// code: loops would count against llvmpipe's loop limit. Mirrored on the CPU by
// `pidm::gpu::lugre::exp_nonpositive`. Shader only (the CPU's model calls
// Rust's exp).
fn exp_nonpositive(x: Real) -> Real {
    if !(x >= EXP_MIN) {
        // Below EXP_MIN exp(x) rounds to 0; NaN stays NaN.
        return select(Real(0.0), x, x != x);
    }
    let k = floor(fma(x, EXP_INV_LN2, Real(0.5)));
    let r = fma(-k, EXP_LN2_LO, x - k * EXP_LN2_HI);
    return exp_halvings(exp_taylor(r), u32(-k));
}

// |(x, y)| as f64::hypot (within its rounding), scaled by a power of two
// where the squares would underflow or overflow. Shader only.
fn hypot(x: Real, y: Real) -> Real {
    let big = max(abs(x), abs(y));
    if big < HYPOT_SMALL {
        let a = x * HYPOT_UP;
        let b = y * HYPOT_UP;
        return root(a * a + b * b) * HYPOT_DOWN;
    }
    if big > HYPOT_LARGE {
        let a = x * HYPOT_DOWN;
        let b = y * HYPOT_DOWN;
        return root(a * a + b * b) * HYPOT_UP;
    }
    return root(x * x + y * y);
}

// Linear::at: the voltage at time t.
fn at(l: Linear, t: Real) -> Real {
    return l.a + l.b * t;
}

// dy/dt, with each axis' drive voltage linear in time.
fn rhs(y: State, drive: Drive) -> State {
    var yy = y;
    var dr = drive;
    var vr = array<Real, 2>(yy[VP] - yy[VS], yy[VP + 1u] - yy[VS + 1u]);
    let s = hypot(vr[0], vr[1]);
    let q = div(s, model.v_s);
    let g = model.coulomb_friction
        + (model.static_friction - model.coulomb_friction) * exp_nonpositive(-(q * q));
    var d: State;
    for (var i = 0u; i < 2u; i++) {
        let dz = vr[i] - div(model.sigma0 * s * yy[Z + i], g);
        let f = model.sigma0 * yy[Z + i] + model.sigma1 * dz + model.sigma2 * vr[i];
        let force = model.gain[i] * at(dr[i], yy[T]);
        d[XP + i] = yy[VP + i];
        d[VP + i] = div(
            force - model.damping[i] * yy[VP + i] - model.stiffness[i] * yy[XP + i] - f,
            model.stage_mass[i],
        );
        d[XS + i] = yy[VS + i];
        d[VS + i] = div(f + model.load[i], model.slider_mass);
        d[Z + i] = dz;
    }
    d[T] = Real(1.0);
    return d;
}

// The Jacobian of `rhs` (row: derivative, column: state). At v_rel = 0,
// where |v_rel| has no derivative, the bristle term's direction is
// dropped (its factor z h'(s) v_rel / s is bounded).
fn jacobian(y: State, drive: Drive) -> Matrix {
    var yy = y;
    var dr = drive;
    var vr = array<Real, 2>(yy[VP] - yy[VS], yy[VP + 1u] - yy[VS + 1u]);
    let s = hypot(vr[0], vr[1]);
    let q = div(s, model.v_s);
    let e = exp_nonpositive(-(q * q));
    let fs_fc = model.static_friction - model.coulomb_friction;
    let g = model.coulomb_friction + fs_fc * e;
    let dg = fs_fc * e * div(Real(-2.0) * s, model.v_s * model.v_s);
    let h = div(s, g);
    let dh = div(g - s * dg, g * g);
    var jac: Matrix;
    for (var i = 0u; i < 2u; i++) {
        // d(dz_i)/d(v_rel_j) and d(dz_i)/d(z_i); f_i's likewise.
        var ddz_dvr: array<Real, 2>;
        var df_dvr: array<Real, 2>;
        for (var j = 0u; j < 2u; j++) {
            let own = select(Real(0.0), Real(1.0), i == j);
            let turn = select(Real(0.0), div(vr[j], s), s > Real(0.0));
            ddz_dvr[j] = own - model.sigma0 * yy[Z + i] * dh * turn;
        }
        let ddz_dz = -model.sigma0 * h;
        for (var j = 0u; j < 2u; j++) {
            df_dvr[j] = model.sigma1 * ddz_dvr[j] + select(Real(0.0), model.sigma2, i == j);
        }
        let df_dz = model.sigma0 + model.sigma1 * ddz_dz;
        let mass = model.stage_mass[i];
        jac[XP + i][VP + i] = Real(1.0);
        jac[XS + i][VS + i] = Real(1.0);
        jac[VP + i][XP + i] = div(-model.stiffness[i], mass);
        jac[VP + i][VP + i] = div(-model.damping[i], mass);
        jac[VP + i][Z + i] = div(-df_dz, mass);
        jac[VP + i][T] = div(model.gain[i] * dr[i].b, mass);
        jac[VS + i][Z + i] = div(df_dz, model.slider_mass);
        jac[Z + i][Z + i] = ddz_dz;
        for (var j = 0u; j < 2u; j++) {
            jac[VP + i][VP + j] -= div(df_dvr[j], mass);
            jac[VP + i][VS + j] += div(df_dvr[j], mass);
            jac[VS + i][VP + j] += div(df_dvr[j], model.slider_mass);
            jac[VS + i][VS + j] -= div(df_dvr[j], model.slider_mass);
            jac[Z + i][VP + j] += ddz_dvr[j];
            jac[Z + i][VS + j] -= ddz_dvr[j];
        }
    }
    return jac;
}

// Axis `i`'s drive over a segment that contains `t_mid` [s] and no corner
// (MODEL.md section 2), linear in time.
fn drive_on(clock: Clock, i: u32, t_mid: Real) -> Linear {
    var start = clock.start;
    let v = model.voltage[i];
    if v == Real(0.0) {
        return Linear(Real(0.0), Real(0.0));
    }
    let u0 = start[i];
    let f = model.frequency[i];
    let duty = model.duty[i];
    let n = floor(u0 + f * t_mid);
    // u = u0 + f t; rise: (u - n) / d, fall: (n + 1 - u) / (1 - d).
    if u0 + f * t_mid - n < duty {
        let k = div(v, duty);
        return Linear(k * (u0 - n), k * f);
    }
    let k = div(v, Real(1.0) - duty);
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
    let duty = model.duty[i];
    var after = t;
    var at = t;
    for (var pass = 0u; pass < CORNER_RETRIES; pass++) {
        let u = u0 + f * after;
        let n = floor(u);
        let corner = select(n + Real(1.0), n + duty, u - n < duty);
        at = div(corner - u0, f);
        if at <= after + Real(1e-15) * (abs(after) + div(Real(1.0), f)) {
            after = at + div(Real(1e-12), f);
        } else {
            break;
        }
    }
    return at;
}
