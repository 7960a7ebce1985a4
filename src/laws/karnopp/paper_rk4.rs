//! The paper's method, kept as a baseline for accuracy studies: the 2-D
//! Karnopp friction law (paper eqs. 4-5) integrated with classical RK4 at a
//! fixed step, without locating mode changes or drive corners.
//!
//! Inside the band |v_rel| <= a the friction is the force that keeps both
//! bodies together, f_need = m_s P / (m_p + m_s), clipped to f_s in
//! magnitude; outside it is f_c along v_rel. This is what a Simulink block
//! diagram with relay and saturation blocks computes. It converges slowly
//! and erratically: docs/model.md section 3 explains why.

use crate::laws::floor::drive::{Corners, axis_corners};
use crate::model::{AXES, Instance};

/// State: stage x, v and slider x, v per axis.
type KState = [[f64; 4]; AXES];

/// The drive force [N]: each axis' levels (`axis_corners`) at time `t`.
fn drive(inst: &Instance, drives: &[Corners; AXES], t: f64) -> [f64; AXES] {
    let mut f = [0.0; AXES];
    for (i, axis) in inst.axes.iter().enumerate() {
        if axis.is_driven() {
            let u = axis.frequency * t + axis.phase;
            f[i] = axis.gain * axis.voltage * drives[i].level(u);
        }
    }
    f
}

fn derivative(inst: &Instance, drives: &[Corners; AXES], t: f64, s: &KState) -> KState {
    let m = &inst.mechanism;
    let force = drive(inst, drives, t);
    let mut v_rel = [0.0; AXES];
    let mut p = [0.0; AXES];
    let mut need = [0.0; AXES];
    for i in 0..AXES {
        let axis = &inst.axes[i];
        v_rel[i] = s[i][1] - s[i][3];
        p[i] = force[i] - axis.damping * s[i][1] - axis.stiffness * s[i][0];
        need[i] = m.slider_mass * p[i] / (axis.stage_mass + m.slider_mass);
    }
    let speed = (v_rel[0] * v_rel[0] + v_rel[1] * v_rel[1]).sqrt();
    let mut friction = [0.0; AXES];
    if speed > m.velocity_band {
        for i in 0..AXES {
            friction[i] = m.coulomb_friction * v_rel[i] / speed;
        }
    } else {
        let n = (need[0] * need[0] + need[1] * need[1]).sqrt();
        let scale = if n > m.static_friction {
            m.static_friction / n
        } else {
            1.0
        };
        for i in 0..AXES {
            friction[i] = need[i] * scale;
        }
    }
    let mut d = [[0.0; 4]; AXES];
    for i in 0..AXES {
        let axis = &inst.axes[i];
        d[i] = [
            s[i][1],
            (p[i] - friction[i]) / axis.stage_mass,
            s[i][3],
            friction[i] / m.slider_mass,
        ];
    }
    d
}

fn axpy(s: &KState, k: &KState, h: f64) -> KState {
    let mut out = *s;
    for i in 0..AXES {
        for j in 0..4 {
            out[i][j] += h * k[i][j];
        }
    }
    out
}

/// Slider displacement over the measured periods [m] with fixed RK4 steps
/// of about `step` seconds (rounded so that whole periods are covered), and
/// the number of steps taken.
pub fn run_fixed_step(inst: &Instance, step: f64) -> ([f64; AXES], u64) {
    let drives = inst.axes.map(|a| axis_corners(&a));
    let period = inst.period();
    let per_period = (period / step).ceil().max(1.0) as u64;
    let h = period / per_period as f64;
    let mut s: KState = [[0.0; 4]; AXES];
    let mut settle = [0.0; AXES];
    let mut steps = 0;
    for n in 0..inst.cycles as u64 {
        if n == inst.settle as u64 {
            settle = [s[0][2], s[1][2]];
        }
        for k in 0..per_period {
            let t = n as f64 * period + k as f64 * h;
            let k1 = derivative(inst, &drives, t, &s);
            let k2 = derivative(inst, &drives, t + 0.5 * h, &axpy(&s, &k1, 0.5 * h));
            let k3 = derivative(inst, &drives, t + 0.5 * h, &axpy(&s, &k2, 0.5 * h));
            let k4 = derivative(inst, &drives, t + h, &axpy(&s, &k3, h));
            for i in 0..AXES {
                for j in 0..4 {
                    s[i][j] += h / 6.0 * (k1[i][j] + 2.0 * k2[i][j] + 2.0 * k3[i][j] + k4[i][j]);
                }
            }
            steps += 1;
        }
    }
    ([s[0][2] - settle[0], s[1][2] - settle[1]], steps)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// How far the fixed-step baseline at RK4 step `h` is from the
    /// event-locating integrator, in um per own drive cycle, on the 1-DOF
    /// 100 V case of Table 1 (4 cycles of which 2 settle).
    fn fixed_step_error_um(h: f64) -> f64 {
        let mut inst = Instance::TABLE1;
        inst.axes[1].voltage = 0.0;
        inst.cycles = 4;
        inst.settle = 2;
        // The window's travel (`measurement::window_displacement`) of the
        // event-locating reference.
        let run = crate::laws::karnopp::integrate::run_instance(&inst, &Default::default());
        assert_eq!(run.state.status, 0);
        let reference = (run.state.x_s - run.state.settle_x_s).to_array()[0];
        let (fixed, _) = run_fixed_step(&inst, h);
        let step = |d: f64| inst.measure(0, d).1 * 1e6;
        (step(fixed[0]) - step(reference)).abs()
    }

    #[test]
    fn the_fixed_step_baseline_is_far_off_at_the_papers_step_and_closer_when_refined() {
        // docs/model.md section 3: plain fixed-step RK4 at h = 1e-5 s is wrong by
        // micrometres per cycle on the paper's cases. Measured here: 21.7 um;
        // the bound leaves a factor of 4.
        let coarse = fixed_step_error_um(1e-5);
        assert!(coarse > 5.0, "at h = 1e-5 s the error is {coarse} um");
        // Ten times finer the error falls to 0.056 um, 390 times smaller
        // (the default integrator's error is about 1e-4 um, far below
        // both). The bound asks for a factor of 100.
        let refined = fixed_step_error_um(1e-6);
        assert!(
            refined < coarse / 100.0,
            "at h = 1e-6 s the error is {refined} um, at 1e-5 s {coarse} um"
        );
        // Refining does not converge it, though: the error goes on
        // scattering (with changing sign) at a few 0.01 um down to h = 1e-7
        // s, where it is still 0.0096 um. At 1e-6 s it stays above ten
        // times the project's 0.001 um bar (measured 0.056 um, so the bound
        // leaves a factor of 5).
        assert!(refined > 0.01, "at h = 1e-6 s the error is {refined} um");
    }
}
