//! Seeded random instances for tests, cross-checks and accuracy studies:
//! mechanism, drive and phase all varied within ranges where the model is
//! physical (f_c <= f_s). The generator is SplitMix64, so a seed gives the
//! same instances on every machine.

use crate::model::{AXES, Axis, Instance, Measure, Mechanism};

/// The one seeded generator of pidm (SplitMix64, `search::rng`).
pub use crate::search::rng::SplitMix64 as Rng;

/// One random 2-DOF instance: stage resonance 0.5-5 kHz and Q 5-60 per
/// axis, voltages within +-150 V, frequencies 5-40 Hz, duty 0.6-1, any
/// phase, slider 1-20 g, f_c <= f_s, band 1e-7-1e-5 m/s.
pub fn random_instance(rng: &mut Rng, cycles: u32, settle: u32) -> Instance {
    let mut axes = [Axis::TABLE1; AXES];
    for axis in &mut axes {
        let stiffness = rng.log_uniform(3e5, 3e6);
        let resonance = rng.log_uniform(500.0, 5000.0);
        let mass = Axis::mass_from_resonance(resonance, stiffness);
        let quality = rng.uniform(5.0, 60.0);
        *axis = Axis {
            stage_mass: mass,
            stiffness,
            damping: Axis::damping_from_quality(quality, stiffness, mass),
            gain: -0.6,
            voltage: rng.uniform(-150.0, 150.0),
            frequency: rng.uniform(5.0, 40.0),
            duty: rng.uniform(0.6, 1.0),
            phase: rng.unit(),
            ..Axis::TABLE1
        };
    }
    let static_friction = rng.uniform(0.5, 2.0);
    Instance {
        mechanism: Mechanism {
            slider_mass: rng.log_uniform(1e-3, 2e-2),
            static_friction,
            coulomb_friction: static_friction * rng.uniform(0.3, 1.0),
            velocity_band: rng.log_uniform(1e-7, 1e-5),
            friction: crate::model::Friction::default(),
            // Unloaded: the random instances of the studies and tests
            // predate the load, and stay what they were.
            load: [0.0; 2],
        },
        axes,
        cycles,
        settle,
        measure: Measure::Window,
    }
}

/// `count` random instances from `seed`.
pub fn random_instances(seed: u64, count: usize, cycles: u32, settle: u32) -> Vec<Instance> {
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| random_instance(&mut rng, cycles, settle))
        .collect()
}
