//! The 2-D LuGre friction model (MODEL.md section 8, issue 40) on the CPU
//! in f64: the first part of the option, its integrator, held to MODEL.md's
//! converged reference values by the tests below. **Not wired into scenes
//! yet**: `mechanism.friction`, the shader variant, steady measurement and
//! the load search still run Karnopp only (issue 40 stays open).
//!
//! **The model.** The interface state z = (z_x, z_y) [m] is the bristles'
//! mean deflection. With v_rel = v_p - v_s and s = |v_rel|:
//!
//! ```text
//! g(s)  = f_c + (f_s - f_c) exp(-(s / v_S)^2)
//! dz/dt = v_rel - sigma0 s z / g(s)
//! f     = sigma0 z + sigma1 dz/dt + sigma2 v_rel      (on the slider)
//! m_p,i a_p,i = F_i(t) - c_i v_p,i - k_i x_p,i - f_i
//! m_s a_s,i   = f_i + L_i
//! ```
//!
//! **The integrator.** The right-hand side is continuous but stiff: the
//! bristles relax at sigma0 s / g(s) (3e5 /s at the defaults, 3e7 /s at
//! sigma0 = 1e9) and sigma1 damps v_rel at sigma1 (1/m_p + 1/m_s). An
//! explicit method's step would be bounded by those rates. Rodas4 (Hairer
//! and Wanner) is linearly implicit, L-stable and stiffly accurate, of
//! order 4 with an embedded order-3 solution that controls the steps; it
//! takes the exact Jacobian ([`Model::jacobian`]). The drive's corners and
//! the measurement's period ends are step boundaries, inside which the
//! drive is linear in time.
//!
//! **Where it stands** (`cargo run --release --example lugre_convergence`,
//! one core): against MODEL.md's converged window steps (1 s of motion),
//! within 0.0005 um at a tolerance of 1e-10 m (about 5,000 steps, 0.01
//! s), 0.00005 um at 1e-11 m and 4e-6 um at 1e-12 m (17,000 steps, 0.03
//! s), on the 1-DOF case and on 100 / 50 V (whose y step stays half of x).

use crate::model::{AXES, Instance};

/// The state: stage positions [m] and velocities [m/s], slider positions
/// and velocities, bristle deflections [m], and the time [s] (carried as a
/// state, so that the method sees the drive's time dependence).
const N: usize = 4 * AXES + AXES + 1;
const XP: usize = 0;
const VP: usize = 2;
const XS: usize = 4;
const VS: usize = 6;
const Z: usize = 8;
const T: usize = 10;
type State = [f64; N];

/// The LuGre parameters of MODEL.md section 8.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lugre {
    /// sigma0 [N/m]: 1e7 by default (a presliding deflection f_s / sigma0
    /// of 0.12 um at breakaway on Table 1; illustrative, not identified).
    pub bristle_stiffness: f64,
    /// sigma1 [N s/m]; `None`: sqrt(sigma0 m_s), a damping ratio of 0.5 of
    /// the slider on its bristles.
    pub bristle_damping: Option<f64>,
    /// sigma2 [N s/m]: 0 by default.
    pub viscous_friction: f64,
    /// v_S [m/s]: 1e-3 by default.
    pub stribeck_velocity: f64,
}

impl Default for Lugre {
    fn default() -> Self {
        Lugre {
            bristle_stiffness: 1e7,
            bristle_damping: None,
            viscous_friction: 0.0,
            stribeck_velocity: 1e-3,
        }
    }
}

/// What the right-hand side reads of one instance.
#[derive(Clone, Copy, Debug)]
struct Model {
    inst: Instance,
    sigma0: f64,
    sigma1: f64,
    sigma2: f64,
    v_s: f64,
}

impl Model {
    fn new(inst: &Instance, lugre: &Lugre) -> Model {
        let sigma0 = lugre.bristle_stiffness;
        let m_s = inst.mechanism.slider_mass;
        Model {
            inst: *inst,
            sigma0,
            sigma1: lugre.bristle_damping.unwrap_or((sigma0 * m_s).sqrt()),
            sigma2: lugre.viscous_friction,
            v_s: lugre.stribeck_velocity,
        }
    }

    /// dy/dt, with each axis' drive voltage `volts(t)` linear in time.
    fn rhs(&self, y: &State, drive: &[Linear; AXES]) -> State {
        let m = &self.inst.mechanism;
        let vr = [y[VP] - y[VS], y[VP + 1] - y[VS + 1]];
        let s = vr[0].hypot(vr[1]);
        let g = m.coulomb_friction
            + (m.static_friction - m.coulomb_friction) * (-(s / self.v_s).powi(2)).exp();
        let mut d = [0.0; N];
        for i in 0..AXES {
            let a = &self.inst.axes[i];
            let dz = vr[i] - self.sigma0 * s * y[Z + i] / g;
            let f = self.sigma0 * y[Z + i] + self.sigma1 * dz + self.sigma2 * vr[i];
            let force = a.gain * drive[i].at(y[T]);
            d[XP + i] = y[VP + i];
            d[VP + i] =
                (force - a.damping * y[VP + i] - a.stiffness * y[XP + i] - f) / a.stage_mass;
            d[XS + i] = y[VS + i];
            d[VS + i] = (f + m.load[i]) / m.slider_mass;
            d[Z + i] = dz;
        }
        d[T] = 1.0;
        d
    }

    /// The Jacobian of [`Self::rhs`] (row: derivative, column: state). At
    /// v_rel = 0, where |v_rel| has no derivative, the bristle term's
    /// direction is dropped (its factor z h'(s) v_rel / s is bounded).
    fn jacobian(&self, y: &State, drive: &[Linear; AXES]) -> [[f64; N]; N] {
        let m = &self.inst.mechanism;
        let vr = [y[VP] - y[VS], y[VP + 1] - y[VS + 1]];
        let s = vr[0].hypot(vr[1]);
        let e = (-(s / self.v_s).powi(2)).exp();
        let g = m.coulomb_friction + (m.static_friction - m.coulomb_friction) * e;
        let dg = (m.static_friction - m.coulomb_friction) * e * (-2.0 * s / self.v_s.powi(2));
        let h = s / g;
        let dh = (g - s * dg) / (g * g);
        let mut jac = [[0.0; N]; N];
        for i in 0..AXES {
            // d(dz_i)/d(v_rel_j) and d(dz_i)/d(z_i); f_i's likewise.
            let ddz_dvr: [f64; AXES] = std::array::from_fn(|j| {
                let own = if i == j { 1.0 } else { 0.0 };
                let turn = if s > 0.0 { vr[j] / s } else { 0.0 };
                own - self.sigma0 * y[Z + i] * dh * turn
            });
            let ddz_dz = -self.sigma0 * h;
            let df_dvr: [f64; AXES] = std::array::from_fn(|j| {
                self.sigma1 * ddz_dvr[j] + if i == j { self.sigma2 } else { 0.0 }
            });
            let df_dz = self.sigma0 + self.sigma1 * ddz_dz;
            let a = &self.inst.axes[i];
            jac[XP + i][VP + i] = 1.0;
            jac[XS + i][VS + i] = 1.0;
            jac[VP + i][XP + i] = -a.stiffness / a.stage_mass;
            jac[VP + i][VP + i] = -a.damping / a.stage_mass;
            jac[VP + i][Z + i] = -df_dz / a.stage_mass;
            jac[VP + i][T] = a.gain * drive[i].b / a.stage_mass;
            jac[VS + i][Z + i] = df_dz / m.slider_mass;
            jac[Z + i][Z + i] = ddz_dz;
            for j in 0..AXES {
                jac[VP + i][VP + j] -= df_dvr[j] / a.stage_mass;
                jac[VP + i][VS + j] += df_dvr[j] / a.stage_mass;
                jac[VS + i][VP + j] += df_dvr[j] / m.slider_mass;
                jac[VS + i][VS + j] -= df_dvr[j] / m.slider_mass;
                jac[Z + i][VP + j] += ddz_dvr[j];
                jac[Z + i][VS + j] -= ddz_dvr[j];
            }
        }
        jac
    }
}

/// A drive voltage linear in time over a segment: `a + b t` [V].
#[derive(Clone, Copy, Debug)]
struct Linear {
    a: f64,
    b: f64,
}

impl Linear {
    fn at(&self, t: f64) -> f64 {
        self.a + self.b * t
    }
}

/// Axis `i`'s drive over a segment that contains `t_mid` and no corner
/// (MODEL.md section 2), linear in time.
fn drive_on(inst: &Instance, i: usize, t_mid: f64) -> Linear {
    let a = &inst.axes[i];
    if a.voltage == 0.0 {
        return Linear { a: 0.0, b: 0.0 };
    }
    let u = a.frequency * t_mid + a.phase;
    let n = u.floor();
    let v = a.voltage;
    // u = f t + phase; rise: (u - n) / d, fall: (n + 1 - u) / (1 - d).
    if u - n < a.duty {
        let k = v / a.duty;
        Linear {
            a: k * (a.phase - n),
            b: k * a.frequency,
        }
    } else {
        let k = v / (1.0 - a.duty);
        Linear {
            a: k * (n + 1.0 - a.phase),
            b: -k * a.frequency,
        }
    }
}

/// The first drive corner of axis `i` after `t` [s] (infinity undriven).
fn next_corner(inst: &Instance, i: usize, t: f64) -> f64 {
    let a = &inst.axes[i];
    if a.voltage == 0.0 {
        return f64::INFINITY;
    }
    let u = a.frequency * t + a.phase;
    let n = u.floor();
    let corner = if u - n < a.duty { n + a.duty } else { n + 1.0 };
    let at = (corner - a.phase) / a.frequency;
    // A corner rounded onto t: the next one.
    if at <= t * (1.0 + 1e-15) {
        next_corner(inst, i, at + 1e-12 / a.frequency)
    } else {
        at
    }
}

/// How the integration is held: each step's local error, weighted, is at
/// most 1 with positions and deflections to `tolerance` [m] and
/// velocities to `tolerance` times the stage's angular resonance [m/s].
#[derive(Clone, Copy, Debug)]
pub struct Accuracy {
    pub tolerance: f64,
}

/// Integrates `inst` from rest over [0, `t_end`] and returns the slider's
/// positions at each of `at` (ascending, within [0, t_end]) [m], and the
/// steps taken.
pub fn slider_positions(
    inst: &Instance,
    lugre: &Lugre,
    accuracy: Accuracy,
    at: &[f64],
) -> (Vec<[f64; AXES]>, u64) {
    let model = Model::new(inst, lugre);
    let omega = inst
        .axes
        .iter()
        .map(|a| (a.stiffness / a.stage_mass).sqrt())
        .fold(0.0, f64::max);
    let mut scale = [accuracy.tolerance; N];
    for i in 0..AXES {
        scale[VP + i] = accuracy.tolerance * omega;
        scale[VS + i] = accuracy.tolerance * omega;
    }
    scale[T] = f64::INFINITY;
    let mut y = [0.0; N];
    let mut h = 1e-7;
    let mut steps = 0;
    let mut out = Vec::with_capacity(at.len());
    for &stop in at {
        while y[T] < stop {
            let corner = (0..AXES)
                .map(|i| next_corner(inst, i, y[T]))
                .fold(stop, f64::min);
            let mid = 0.5 * (y[T] + corner);
            let drive = [drive_on(inst, 0, mid), drive_on(inst, 1, mid)];
            steps += segment(&model, &drive, &scale, &mut y, corner, &mut h);
        }
        out.push([y[XS], y[XS + 1]]);
    }
    (out, steps)
}

/// Rodas4's coefficients (Hairer and Wanner, "Solving Ordinary Differential
/// Equations II", section IV.7; the values of their RODAS code): gamma,
/// the stages' a_ij (stage i starts from y + sum_j a_ij k_j; stage 6 from
/// stage 5's start + k5) and C_ij (stage i's right-hand side adds sum_j
/// C_ij k_j / h). The method is stiffly accurate: y_n+1 is stage 6's
/// start + k6, and k6 is the embedded third-order solution's difference.
const GAMMA: f64 = 0.25;
const A: [[f64; 4]; 4] = [
    [1.544, 0.0, 0.0, 0.0],
    [0.9466785280815826, 0.2557011698983284, 0.0, 0.0],
    [
        3.314825187068521,
        2.896124015972201,
        0.9986419139977817,
        0.0,
    ],
    [
        1.221224509226641,
        6.019134481288629,
        12.53708332932087,
        -0.687886036105895,
    ],
];
const C: [[f64; 5]; 5] = [
    [-5.6688, 0.0, 0.0, 0.0, 0.0],
    [-2.430093356833875, -0.2063599157091915, 0.0, 0.0, 0.0],
    [
        -0.1073529058151375,
        -9.594562251023355,
        -20.47028614809616,
        0.0,
        0.0,
    ],
    [
        7.496443313967647,
        -10.24680431464352,
        -33.99990352819905,
        11.7089089320616,
        0.0,
    ],
    [
        8.083246795921522,
        -7.981132988064893,
        -31.52159432874371,
        16.31930543123136,
        -6.058818238834054,
    ],
];

/// One Rodas4 step of size `h` from `y`: the new state and the local
/// error estimate (k6). The stages solve (I / (gamma h) - J) k = rhs, that
/// is gamma h (I - gamma h J)^-1 rhs.
fn rodas4(model: &Model, drive: &[Linear; AXES], y: &State, h: f64) -> (State, State) {
    let w = w_matrix(model, drive, y, GAMMA * h);
    let mut k = [[0.0; N]; 6];
    let mut start = *y;
    for i in 0..6 {
        if (1..5).contains(&i) {
            start = *y;
            for (j, kj) in k.iter().enumerate().take(i) {
                for n in 0..N {
                    start[n] += A[i - 1][j] * kj[n];
                }
            }
        } else if i == 5 {
            for n in 0..N {
                start[n] += k[4][n];
            }
        }
        let mut rhs = model.rhs(&start, drive);
        if i > 0 {
            for (j, kj) in k.iter().enumerate().take(i) {
                for n in 0..N {
                    rhs[n] += C[i - 1][j] * kj[n] / h;
                }
            }
        }
        let solved = w.solve(rhs);
        k[i] = solved.map(|x| GAMMA * h * x);
    }
    let mut next = start;
    for n in 0..N {
        next[n] += k[5][n];
    }
    (next, k[5])
}

/// Rodas4 steps from `y` to time `end` (an exact boundary); `h` carries the
/// step size from segment to segment. Returns the steps taken.
fn segment(
    model: &Model,
    drive: &[Linear; AXES],
    scale: &State,
    y: &mut State,
    end: f64,
    h: &mut f64,
) -> u64 {
    let mut steps = 0;
    let mut rejected = false;
    while y[T] < end {
        let last = y[T] + *h >= end * (1.0 - 1e-15);
        let step = if last { end - y[T] } else { *h };
        let (next, e) = rodas4(model, drive, y, step);
        let err = (0..N).fold(0.0_f64, |m, n| m.max((e[n] / scale[n]).abs()));
        if !err.is_finite() {
            *h = step * 0.1;
            continue;
        }
        if err <= 1.0 {
            *y = next;
            if last {
                y[T] = end;
            }
            steps += 1;
        }
        // A third-order estimate: the error scales with the step's fourth
        // power.
        // No growth right after a rejection (Hairer and Wanner's rule):
        // the error jumps where |v_rel| turns through 0, and growing at
        // once there rejects the next step again.
        let most = if rejected { 1.0 } else { 4.0 };
        let factor = (0.9 / err.max(1e-16).powf(0.25)).clamp(0.2, most);
        rejected = err > 1.0;
        if !(last && err <= 1.0) {
            *h = step * factor;
        }
    }
    steps
}

/// I - gamma h J with the exact Jacobian J of [`Model::rhs`], LU-factored.
fn w_matrix(model: &Model, drive: &[Linear; AXES], y: &State, gh: f64) -> Lu {
    let j = model.jacobian(y, drive);
    let mut a = [[0.0; N]; N];
    for (i, row) in a.iter_mut().enumerate() {
        for (k, x) in row.iter_mut().enumerate() {
            *x = -gh * j[i][k];
        }
        row[i] += 1.0;
    }
    Lu::factor(a)
}

/// An LU factorisation with partial pivoting of an N x N matrix.
struct Lu {
    a: [[f64; N]; N],
    pivot: [usize; N],
}

impl Lu {
    fn factor(mut a: [[f64; N]; N]) -> Lu {
        let mut pivot = [0; N];
        for k in 0..N {
            let p = (k..N)
                .max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))
                .unwrap_or(k);
            a.swap(k, p);
            pivot[k] = p;
            let (top, rest) = a.split_at_mut(k + 1);
            let row = &top[k];
            for below in rest.iter_mut() {
                let l = below[k] / row[k];
                below[k] = l;
                for (x, r) in below[k + 1..].iter_mut().zip(&row[k + 1..]) {
                    *x -= l * r;
                }
            }
        }
        Lu { a, pivot }
    }

    /// Solves A x = b. The factorisation swapped whole rows, multipliers
    /// included (as LAPACK's getrf), so every swap applies to `b` before
    /// the forward substitution, not between its columns.
    fn solve(&self, mut b: State) -> State {
        for k in 0..N {
            b.swap(k, self.pivot[k]);
        }
        for k in 0..N {
            for i in k + 1..N {
                b[i] -= self.a[i][k] * b[k];
            }
        }
        for k in (0..N).rev() {
            for j in k + 1..N {
                b[k] -= self.a[k][j] * b[j];
            }
            b[k] /= self.a[k][k];
        }
        b
    }
}

/// The window step of MODEL.md section 4 under LuGre: each axis' slider
/// displacement from `settle` T to `cycles` T over the periods' own drive
/// cycles [m per own drive cycle], and the steps taken.
pub fn window_step(inst: &Instance, lugre: &Lugre, accuracy: Accuracy) -> ([f64; AXES], u64) {
    let period = inst.period();
    let times = [inst.settle as f64 * period, inst.cycles as f64 * period];
    let (x, steps) = slider_positions(inst, lugre, accuracy, &times);
    let span = (inst.cycles - inst.settle) as f64 * period;
    let step = std::array::from_fn(|i| (x[1][i] - x[0][i]) / (span * inst.axes[i].frequency));
    (step, steps)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Axis, Measure};

    /// MODEL.md section 6's cases (Table 1, duty 0.98, phases 0, window 10
    /// / 2) with voltages `v` [V] and frequencies `f` [Hz].
    fn case(v: [f64; 2], f: [f64; 2]) -> Instance {
        let mut inst = Instance::TABLE1;
        for i in 0..AXES {
            inst.axes[i] = Axis {
                voltage: v[i],
                frequency: f[i],
                ..Axis::TABLE1
            };
        }
        inst.cycles = 10;
        inst.settle = 2;
        inst.measure = Measure::Window;
        inst
    }

    /// Two of MODEL.md section 8's converged window steps at LuGre's
    /// defaults (SciPy Radau at rtol 1e-9, checked by LSODA): the 1-DOF
    /// case (100 V, 10 Hz) and 100 / 50 V, whose motion stays on the line
    /// (2, 1); within 2e-5 um at a tolerance of 1e-12 m (measured 2e-6).
    #[test]
    fn the_defaults_give_model_md_reference_steps() {
        let cases = [
            ([100.0, 0.0], [1.285861, 0.0]),
            ([100.0, 50.0], [0.765918, 0.382959]),
        ];
        for (volts, want) in cases {
            let inst = case(volts, [10.0, 10.0]);
            let accuracy = Accuracy { tolerance: 1e-12 };
            let (got, _) = window_step(&inst, &Lugre::default(), accuracy);
            for i in 0..AXES {
                let um = got[i] * 1e6;
                assert!((um - want[i]).abs() <= 2e-5, "{volts:?} axis {i}: {um} um");
            }
            assert!(
                (got[1] - 0.5 * volts[1] / 50.0 * got[0]).abs() <= 2e-11,
                "{got:?}"
            );
        }
    }

    /// The Jacobian against central differences of the right-hand side, in
    /// slip (2-D, loaded) and at rest.
    #[test]
    fn the_jacobian_is_the_right_hand_side_s() {
        let mut inst = case([100.0, 70.0], [10.0, 14.0]);
        inst.mechanism.load = [0.1, -0.2];
        let model = Model::new(&inst, &Lugre::default());
        let drive = [drive_on(&inst, 0, 0.03), drive_on(&inst, 1, 0.03)];
        let slip: State = [
            1e-6, -2e-6, 0.01, -0.02, 3e-6, 1e-6, -0.003, 0.001, 5e-8, -7e-8, 0.03,
        ];
        for y in [slip, [0.0; N]] {
            let jac = model.jacobian(&y, &drive);
            for k in 0..N {
                let delta = [
                    1e-9, 1e-9, 1e-7, 1e-7, 1e-9, 1e-9, 1e-7, 1e-7, 1e-12, 1e-12, 1e-7,
                ][k];
                let (mut up, mut down) = (y, y);
                up[k] += delta;
                down[k] -= delta;
                let (fu, fd) = (model.rhs(&up, &drive), model.rhs(&down, &drive));
                for i in 0..N {
                    let fd_ik = (fu[i] - fd[i]) / (2.0 * delta);
                    let scale = fd_ik.abs().max(jac[i][k].abs()).max(1e-6);
                    assert!(
                        (fd_ik - jac[i][k]).abs() <= 1e-4 * scale,
                        "d{i}/d{k}: {} against {fd_ik}",
                        jac[i][k]
                    );
                }
            }
        }
    }
}
