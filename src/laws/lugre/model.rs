//! The LuGre right-hand side (docs/model.md section 8), its exact Jacobian, and
//! the drive over one segment between corners, linear in time.
//!
//! ```text
//! g(s)  = f_c + (f_s - f_c) exp(-(s / v_S)^2)
//! dz/dt = v_rel - sigma0 s z / g(s)
//! f     = sigma0 z + sigma1 dz/dt + sigma2 v_rel      (on the slider)
//! m_p,i a_p,i = F_i(t) - c_i v_p,i - k_i x_p,i - f_i
//! m_s a_s,i   = f_i + L_i
//! ```

use super::libm::{exp_nonpositive, hypot};
use crate::laws::floor::drive::Corners;
use crate::model::{AXES, Instance, Lugre};

/// The state: stage positions [m] and velocities [m/s], slider positions
/// and velocities, bristle deflections [m], and the time within the scene
/// period [s] (carried as a state, so that the method sees the drive's time
/// dependence).
pub(crate) const N: usize = 4 * AXES + AXES + 1;
pub(crate) const XP: usize = 0;
pub(crate) const VP: usize = 2;
pub(crate) const XS: usize = 4;
pub(crate) const VS: usize = 6;
pub(crate) const Z: usize = 8;
pub(crate) const T: usize = 10;
pub(crate) type State = [f64; N];

/// What the right-hand side reads of one instance.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Model {
    pub(crate) inst: Instance,
    pub(crate) sigma0: f64,
    pub(crate) sigma1: f64,
    pub(crate) sigma2: f64,
    pub(crate) v_s: f64,
}

impl Model {
    pub(crate) fn new(inst: &Instance, lugre: &Lugre) -> Model {
        Model {
            inst: *inst,
            sigma0: lugre.bristle_stiffness,
            sigma1: lugre.damping(inst.mechanism.slider_mass),
            sigma2: lugre.viscous_friction,
            v_s: lugre.stribeck_velocity,
        }
    }

    /// dy/dt, with each axis' drive voltage linear in time.
    pub(crate) fn rhs(&self, y: &State, drive: &[Linear; AXES]) -> State {
        let m = &self.inst.mechanism;
        let vr = [y[VP] - y[VS], y[VP + 1] - y[VS + 1]];
        let s = hypot(vr[0], vr[1]);
        let g = m.coulomb_friction
            + (m.static_friction - m.coulomb_friction) * exp_nonpositive(-(s / self.v_s).powi(2));
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
    pub(crate) fn jacobian(&self, y: &State, drive: &[Linear; AXES]) -> [[f64; N]; N] {
        let m = &self.inst.mechanism;
        let vr = [y[VP] - y[VS], y[VP + 1] - y[VS + 1]];
        let s = hypot(vr[0], vr[1]);
        let e = exp_nonpositive(-(s / self.v_s).powi(2));
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

/// A drive voltage linear in time over a segment: `a + b t` [V], t the
/// time within the scene period [s].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Linear {
    pub(crate) a: f64,
    pub(crate) b: f64,
}

impl Linear {
    pub(crate) fn at(&self, t: f64) -> f64 {
        self.a + self.b * t
    }
}

/// Each axis' drive phase at the start of a scene period [cycles]: the
/// time origin of [`drive_on`] and [`next_corner`], so that their times stay
/// within one period (no cancellation after thousands of periods).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Clock {
    pub(crate) start: [f64; AXES],
}

impl Clock {
    /// The clock of scene period `period` (counted from 0): the cycles
    /// per period times `period`, plus the phase (the GPU's lanes compute
    /// it so at their period starts, `shaders/lugre/measure.wgsl`).
    pub(crate) fn of(inst: &Instance, period: u32) -> Clock {
        let per = Clock::cycles_per_period(inst);
        Clock {
            start: std::array::from_fn(|i| per[i] * period as f64 + inst.axes[i].phase),
        }
    }

    /// Each axis' drive cycles per scene period, whole where it is within
    /// rounding of a whole number (the slowest axis: 1).
    pub(crate) fn cycles_per_period(inst: &Instance) -> [f64; AXES] {
        let t = inst.period();
        std::array::from_fn(|i| {
            let per = inst.axes[i].frequency * t;
            if (per - per.round()).abs() <= 1e-12 * per {
                per.round()
            } else {
                per
            }
        })
    }

    /// Axis `i`'s drive over a segment that contains `t_mid` [s] and no
    /// corner (docs/model.md section 2), linear in time; `corners` are the
    /// axis' (`floor::drive::axis_corners`). A piece is written from its
    /// corner at level 0 where it has one (the sawtooth's rise from its
    /// start, its fall from its end: the same bits as before corners).
    pub(crate) fn drive_on(
        &self,
        inst: &Instance,
        corners: &Corners,
        i: usize,
        t_mid: f64,
    ) -> Linear {
        let a = &inst.axes[i];
        if a.voltage == 0.0 {
            return Linear { a: 0.0, b: 0.0 };
        }
        let u0 = self.start[i];
        let n = (u0 + a.frequency * t_mid).floor();
        let v = a.voltage;
        let (from, to) = corners.piece_at(u0 + a.frequency * t_mid - n);
        // The voltage per cycle on the piece; u = u0 + f t.
        let k = v * (to[1] - from[1]) / (to[0] - from[0]);
        if to[1] == 0.0 {
            // v (L_to - k / v (n + u_to - u)), L_to = 0.
            Linear {
                a: -k * (n + to[0] - u0),
                b: k * a.frequency,
            }
        } else {
            let at = k * (u0 - n - from[0]);
            Linear {
                a: if from[1] == 0.0 { at } else { v * from[1] + at },
                b: k * a.frequency,
            }
        }
    }

    /// The first drive corner of axis `i` after `t` [s] (infinity
    /// undriven); `corners` as [`Clock::drive_on`]'s.
    pub(crate) fn next_corner(&self, inst: &Instance, corners: &Corners, i: usize, t: f64) -> f64 {
        let a = &inst.axes[i];
        if a.voltage == 0.0 {
            return f64::INFINITY;
        }
        let u0 = self.start[i];
        let u = u0 + a.frequency * t;
        let n = u.floor();
        let corner = n + corners.piece_at(u - n).1[0];
        let at = (corner - u0) / a.frequency;
        // A corner rounded onto t: the next one.
        if at <= t + 1e-15 * (t.abs() + 1.0 / a.frequency) {
            self.next_corner(inst, corners, i, at + 1e-12 / a.frequency)
        } else {
            at
        }
    }
}
