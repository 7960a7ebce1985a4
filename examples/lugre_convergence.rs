//! The LuGre integrator (`pidm::cpu::lugre`, Rodas4) against
//! MODEL.md section 8's converged window steps, as the tolerance falls:
//! the error [um], the steps and the run time of each, for the 1-DOF case
//! (100 V, 10 Hz; +1.285861 um) and the 2-DOF 100 / 50 V case (+0.765918 /
//! +0.382959 um), whose y step should be half its x step.
//!
//! ```text
//! cargo run --release --example lugre_convergence
//! ```
//! (about a minute on one core.)

use pidm::cpu::lugre::{Accuracy, Lugre, window_step};
use pidm::model::{Axis, Instance, Measure};

fn main() {
    let cases = [
        ([100.0, 0.0], [1.285861, 0.0]),
        ([100.0, 50.0], [0.765918, 0.382959]),
    ];
    for (volts, want) in cases {
        let mut inst = Instance::TABLE1;
        for (axis, v) in inst.axes.iter_mut().zip(volts) {
            *axis = Axis {
                voltage: v,
                frequency: 10.0,
                ..Axis::TABLE1
            };
        }
        inst.cycles = 10;
        inst.settle = 2;
        inst.measure = Measure::Window;
        for tolerance in [1e-10, 1e-11, 1e-12, 1e-13] {
            let started = std::time::Instant::now();
            let (step, steps) = window_step(&inst, &Lugre::default(), Accuracy { tolerance });
            let um = step.map(|s| s * 1e6);
            println!(
                "{volts:?} V, tolerance {tolerance:.0e} m: x {:+.6} um (error {:+.6}), y {:+.6} um (error {:+.6}), {steps} steps, {:.2} s",
                um[0],
                um[0] - want[0],
                um[1],
                um[1] - want[1],
                started.elapsed().as_secs_f64()
            );
        }
    }
}
