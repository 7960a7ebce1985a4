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
//! explicit method's step would be bounded by those rates. ROS2 (Verwer,
//! Spee, Blom and Hundsdorfer 1999, "A second-order Rosenbrock method
//! applied to photochemical dispersion problems", SIAM J. Sci. Comput. 20)
//! is linearly implicit and L-stable, and of order 2 with any matrix in
//! place of the Jacobian (a W-method), so a finite-difference Jacobian
//! costs no order. Its steps are controlled on an embedded first-order
//! solution; the drive's corners and the measurement's period ends are
//! step boundaries, inside which the drive is linear in time.
//!
//! **Where the prototype stands** (`cargo run --release --example
//! lugre_convergence`, one core): on MODEL.md's 1-DOF case the error falls
//! about tenfold per decade of tolerance (+0.35, +0.040, -0.0034, -0.00038
//! um at 1e-10 .. 1e-13 m) while the steps grow only from 1.9 to 6.8
//! million for 1 s of motion (2.7-7.9 s): the steps are held by the stage's
//! and the bristles' ringing (3.2 and about 7 kHz), which a second-order
//! method resolves at great cost. On 100 / 50 V, y stays half of x only to
//! about 1e-3 relative at 1e-12 m, where the reference keeps it to 1e-9
//! um. Both point to a higher-order Rosenbrock method (Rodas-type, as
//! DiffEqGPU's kernels use) with this module's model, Jacobian, drive
//! segments and solver kept; that is issue 40's next step.

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

/// ROS2 steps from `y` to time `end` (an exact boundary); `h` carries the
/// step size from segment to segment. Returns the steps taken.
fn segment(
    model: &Model,
    drive: &[Linear; AXES],
    scale: &State,
    y: &mut State,
    end: f64,
    h: &mut f64,
) -> u64 {
    const GAMMA: f64 = 1.0 + std::f64::consts::FRAC_1_SQRT_2;
    let mut steps = 0;
    while y[T] < end {
        let last = y[T] + *h >= end * (1.0 - 1e-15);
        let step = if last { end - y[T] } else { *h };
        let f0 = model.rhs(y, drive);
        let w = w_matrix(model, drive, y, GAMMA * step);
        let k1 = w.solve(f0);
        let mut y1 = *y;
        for j in 0..N {
            y1[j] += step * k1[j];
        }
        let f1 = model.rhs(&y1, drive);
        let mut rhs2 = [0.0; N];
        for j in 0..N {
            rhs2[j] = f1[j] - 2.0 * k1[j];
        }
        let k2 = w.solve(rhs2);
        let mut err: f64 = 0.0;
        let mut next = *y;
        for j in 0..N {
            next[j] += step * (1.5 * k1[j] + 0.5 * k2[j]);
            let e = 0.5 * step * (k1[j] + k2[j]);
            err = err.max((e / scale[j]).abs());
        }
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
        // Order 1 estimate: the error scales with the step squared.
        let factor = (0.9 / err.max(1e-12).sqrt()).clamp(0.2, 4.0);
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

    fn solve(&self, mut b: State) -> State {
        for k in 0..N {
            b.swap(k, self.pivot[k]);
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

    /// The 1-DOF case of MODEL.md section 8's converged values (+1.285861
    /// um at 100 V, 10 Hz): ROS2 converges to it at first order in the
    /// tolerance (examples/lugre_convergence.rs), 0.0004 um off at 1e-13 m.
    #[test]
    fn the_defaults_approach_model_md_reference_step() {
        let inst = case([100.0, 0.0], [10.0, 10.0]);
        let (got, _) = window_step(&inst, &Lugre::default(), Accuracy { tolerance: 1e-13 });
        let um = got[0] * 1e6;
        assert!((um - 1.285861).abs() <= 1e-3, "{um} um");
        assert_eq!(got[1], 0.0);
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
