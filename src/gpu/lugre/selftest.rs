//! A LuGre pipeline's self-test (ARCHITECTURE.md: no GPU pipeline
//! integrates an instance before its self-test batch agreed with the
//! CPU): on its first compile in a context, before any instance runs on
//! it, a small batch of windows runs on the device alone (no CPU tail)
//! and each run's steps are compared with the CPU's LuGre integrator.

use super::LugreGpu;
use crate::gpu::{GpuError, Precision};
use crate::laws::lugre::run_instance_until;
use crate::laws::{Law, Settings};
use crate::measurement::reduce;
use crate::model::{Instance, Measure, Shape, Table};

/// How far a self-test step may lie from the CPU's [m per own drive
/// cycle]: on a software adapter the shader's runs are the CPU's bit for
/// bit; on hardware its arithmetic (the prelude's division and square
/// root) moves the step control, measured at most 6.6e-6 um on the
/// waveform families (`tests/it/waveform.rs`) against a bound of 2e-5 um
/// at the default tolerance (`tests/it/gpu_lugre.rs`); five times that
/// bound, while a driver that computes wrong numbers is micrometres off.
pub const ALLOWANCE_M: f64 = 1e-10;

/// How far a backward pipeline's self-test backward travel may lie from
/// the CPU's [m per own drive cycle]: on hardware the step control moves
/// (as for [`ALLOWANCE_M`]) and with it where the cubic Hermite of each
/// step is read, which moves the backward travel more than the step: a
/// one-ulp change of the tolerance moves the CPU's own by up to 3.9e-10 m
/// on the self-test's waveform instance, and the hardware's variant on
/// lavapipe lies 4.2e-10 m from it there; five times the CPU's spread, two
/// thousandths of a micrometre, while a wrong variation is micrometres off.
pub const BACKWARD_ALLOWANCE_M: f64 = 2e-9;

/// The self-test's windows (2 periods, settling 1) at docs/model.md
/// section 8's interface: Table 1's stage against 20 Hz on y, and for a
/// waveform pipeline a slew-limited trapezoid on x against a table with a
/// jump on y, which its corners drive.
fn instances(waveform: bool) -> Vec<Instance> {
    let lugre = Law::from_name("lugre").expect("a law");
    let mut fig8 = Instance::TABLE1;
    fig8.axes[1].frequency = 20.0;
    (fig8.cycles, fig8.settle, fig8.measure) = (2, 1, Measure::Window);
    fig8.mechanism.friction = lugre.friction([1e7, f64::NAN, 0.0, 1e-3]);
    let mut out = vec![fig8];
    if waveform {
        let mut shaped = fig8;
        let x = &mut shaped.axes[0];
        (x.shape, x.rise, x.hold, x.fall, x.slew_rate) = (Shape::Trapezoid, 0.8, 0.1, 0.03, 2e4);
        let y = &mut shaped.axes[1];
        y.shape = Shape::Table(Table::intern(&[[0.1, -0.5], [0.6, 1.0], [0.6, 0.2]]));
        out.push(shaped);
    }
    out
}

/// Runs `gpu`'s self-test batch: an error naming the instance and axis
/// where the device's run fails, leaves a run to the CPU, or differs from
/// the CPU's steps by more than [`ALLOWANCE_M`], or a backward pipeline's
/// backward travel from the CPU's by more than [`BACKWARD_ALLOWANCE_M`],
/// the CPU's moved by `skew` [m per own
/// drive cycle; 0 but in the tests that the self-test can fail].
pub(super) fn self_test(gpu: &LugreGpu, skew: Skew) -> Result<(), GpuError> {
    let fail = |message: String| GpuError::SelfTest {
        precision: Precision::F64,
        adapter: gpu.ctx.describe(),
        message: format!("LuGre's {} pipeline: {message}", variant(gpu)),
    };
    // A backward pipeline is tested measuring the backward travel.
    let settings = Settings {
        backward: gpu.form.backward(),
        ..Settings::default()
    };
    let instances = instances(gpu.form.waveform());
    // Not the run's integration: its figures stay out of the profile.
    let (runs, report) = crate::profile::outside_integration(|| {
        gpu.followed_until(&instances, &settings, || false, &|_| {})
    })
    .map_err(|e| fail(e.to_string()))?;
    if !report.on_cpu.is_empty() {
        return Err(fail("the CPU finished a self-test run".into()));
    }
    for (k, (inst, (run, variation))) in instances.iter().zip(&runs).enumerate() {
        let cpu = run_instance_until(inst, &settings, || false).expect("never stopped");
        if let Some(v) = variation {
            let got = crate::measurement::reduce_variation(inst, run, v).0;
            let allowed = BACKWARD_ALLOWANCE_M;
            crate::gpu::context::backward_self_test(inst, &settings, got, (skew.backward, allowed))
                .map_err(|m| fail(format!("instance {k} {m}")))?;
        }
        let (got, want) = (reduce(inst, run), reduce(inst, &cpu));
        if got.status != want.status {
            return Err(fail(format!(
                "instance {k} ends with status {} where the CPU's ends with {}",
                got.status, want.status
            )));
        }
        for axis in 0..2 {
            let g = inst.measure_over(axis, got.travel[axis], got.span).1;
            let w = inst.measure_over(axis, want.travel[axis], want.span).1 + skew.step;
            let err = (g - w).abs();
            if err.is_nan() || err > ALLOWANCE_M {
                return Err(fail(format!(
                    "instance {k} axis {axis} steps {g:.6e} m where the CPU gives {w:.6e} m, \
                     {err:.2e} m apart, more than the {ALLOWANCE_M:.0e} m allowed"
                )));
            }
        }
    }
    Ok(())
}

/// What a self-test adds to the CPU's steps and backward travels [m per
/// own drive cycle]: zero but in the tests that it can fail.
#[derive(Clone, Copy, Debug, Default)]
pub struct Skew {
    pub step: f64,
    pub backward: f64,
}

/// The pipeline's name in a self-test's message.
fn variant(gpu: &LugreGpu) -> &'static str {
    match gpu.form {
        super::Form::Sawtooth => "sawtooth",
        super::Form::Waveform => "waveform",
        super::Form::Backward => "backward",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A waveform pipeline's self-test drives what only its corners can:
    /// a slew-limited trapezoid and a table with a jump.
    #[test]
    fn the_waveform_self_test_needs_the_corners() {
        let shaped = instances(true);
        assert_eq!((instances(false).len(), shaped.len()), (1, 2));
        assert!(!super::super::runner::drives_sawtooths(&shaped[1]));
        assert!(super::super::runner::drives_sawtooths(&shaped[0]));
    }
}
