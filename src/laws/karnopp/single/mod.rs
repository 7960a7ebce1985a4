//! The integrator in f32, in micrometres and milliseconds: the CPU mirror
//! of the f32 shader (`pidm::gpu::shader` with `Precision::F32`), the same
//! source as [`crate::laws::karnopp::double`] with the f32 formulation switched on.
//! Its coefficients are the f64 ones rounded once
//! (`integrate::Coefficients::of`), as the GPU packs them.

/// What `integrate/` computes in: the f32 shader's prelude
/// (`pidm::gpu::shader::prelude`).
pub mod precision {
    use crate::laws::floor::units::Units;

    /// The floor in this precision (`crate::laws::floor`).
    pub use crate::laws::floor::single as floor;

    /// The scalar type (the shader's `alias Real`).
    pub type Real = f32;
    /// The unit system: every quantity of the paper's mechanism is of order
    /// one, inside f32's range.
    pub const UNITS: Units = crate::laws::floor::single::precision::UNITS;
    /// Relative resolution of the two-part time within a period.
    pub const TIME_EPSILON: f64 = 1e-13;
    /// The smallest divisor kept away from zero.
    pub const TINY: Real = 1e-30;
    /// The time as two f32 parts (Knuth's two-sum).
    pub const COMPENSATED_TIME: bool = true;
    /// Period start phases from exact integer sums.
    pub const FIXED_PHASE: bool = true;
    /// Drive corners as two-part local times.
    pub const CORNER_CLOCK: bool = true;
    /// The stage state as its deflection from the drive's static motion.
    pub const DEFLECTION: bool = true;
    /// The approach's turn test allows for f32's rounding of v_rel.
    pub const APPROACH_NOISE: bool = true;
    /// A band graze stops the run for the f64 reference
    /// (`integrate::constants::GRAZE_MARGIN`).
    pub const GRAZE_GUARD: bool = true;

    /// Drops its items: they exist in f64 only (`double::precision`).
    macro_rules! only_f64 {
        ($($item:item)*) => {};
    }
    pub(crate) use only_f64;
}

// The same source as the other precision's, on purpose (the shader's
// `alias Real`): see `pidm::laws::karnopp`.
#[allow(clippy::duplicate_mod)]
#[path = "../integrate/mod.rs"]
#[allow(dead_code)]
pub mod integrate;
pub mod si;
