//! The 2-D LuGre friction model (docs/model.md section 8, `mechanism.friction =
//! "lugre"`) on the CPU in f64: the reference for LuGre scenes, which the
//! f64 shader of `crate::gpu::lugre` mirrors function for function.
//!
//! **The model** (`model`). The interface state z = (z_x, z_y) [m] is the
//! bristles' mean deflection; the right-hand side is continuous (no modes)
//! but stiff: the bristles relax at sigma0 s / g(s) (3e5 /s at the
//! defaults, 3e7 /s at sigma0 = 1e9) and sigma1 damps v_rel at
//! sigma1 (1/m_p + 1/m_s).
//!
//! **The integrator** (`rodas`). Rodas4 (Hairer and Wanner) is linearly
//! implicit, L-stable and stiffly accurate, of order 4 with an embedded
//! order-3 solution that controls the steps; it takes the exact Jacobian.
//! An explicit method's step would be bounded by the stiff rates, not by
//! accuracy. The drive's corners and the scene period's ends are step
//! boundaries, inside which the drive is linear in time.
//!
//! **The run** ([`run`]). Period by period, with every backend's steady
//! measurement on top (`measure::period_end`); the recurrence test compares
//! z as well. `simulation.tolerance` sets the local error per step
//! ([`run::LENGTH_PER_TOLERANCE`]).

pub mod libm;
mod model;
mod rodas;
pub mod run;

pub use run::{LENGTH_PER_TOLERANCE, run_instance_until};

#[cfg(test)]
mod tests {
    use super::model::{Clock, Model, N, State};
    use crate::model::{AXES, Axis, Friction, Instance, Lugre, Measure};

    /// docs/model.md section 6's cases (Table 1, duty 0.98, phases 0, window 10
    /// / 2) with voltages `v` [V] and frequencies `f` [Hz], under LuGre's
    /// defaults. (Their converged steps are held by tests/it/lugre.rs,
    /// through `measurement::reduce`, a layer above this one.)
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
        inst.mechanism.friction = Friction::Lugre(Lugre::DEFAULT);
        inst
    }

    /// The Jacobian against central differences of the right-hand side, in
    /// slip (2-D, loaded) and at rest.
    #[test]
    fn the_jacobian_is_the_right_hand_side_s() {
        let mut inst = case([100.0, 70.0], [10.0, 14.0]);
        inst.mechanism.load = [0.1, -0.2];
        let model = Model::new(&inst, &Lugre::DEFAULT);
        let clock = Clock::of(&inst, 3);
        let drives = inst
            .axes
            .map(|a| crate::laws::floor::drive::axis_corners(&a));
        let drive = [0, 1].map(|i| clock.drive_on(&inst, &drives[i], i, 0.03));
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
