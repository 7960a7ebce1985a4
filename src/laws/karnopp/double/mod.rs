//! The integrator in f64 and SI units: the reference, and the mirror of the
//! f64 shader (`pidm::gpu::shader` with `Precision::F64`).

/// What `integrate/` computes in: the f64 shader's prelude
/// (`pidm::gpu::shader::prelude`).
pub mod precision {
    use crate::laws::floor::units::Units;

    /// The floor in this precision (`crate::laws::floor`).
    pub use crate::laws::floor::double as floor;

    /// The scalar type (the shader's `alias Real`).
    pub type Real = f64;
    /// The unit system.
    pub const UNITS: Units = crate::laws::floor::double::precision::UNITS;
    /// Relative resolution of the time within a period.
    pub const TIME_EPSILON: f64 = f64::EPSILON;
    /// The smallest divisor kept away from zero.
    pub const TINY: Real = 1e-300;
    /// The f32 formulation's switches (see `single::precision`): all off,
    /// so each of their branches compiles to nothing here.
    pub const COMPENSATED_TIME: bool = false;
    pub const FIXED_PHASE: bool = false;
    pub const CORNER_CLOCK: bool = false;
    pub const DEFLECTION: bool = false;
    pub const APPROACH_NOISE: bool = false;
    pub const GRAZE_GUARD: bool = false;

    /// Keeps its items: they exist in f64 only (the coefficients are computed
    /// in f64, then rounded for f32).
    macro_rules! only_f64 {
        ($($item:item)*) => { $($item)* };
    }
    pub(crate) use only_f64;
}

// The same source as the other precision's, on purpose (the shader's
// `alias Real`): see `pidm::laws::karnopp`.
#[allow(clippy::duplicate_mod)]
#[path = "../integrate/mod.rs"]
pub mod integrate;
