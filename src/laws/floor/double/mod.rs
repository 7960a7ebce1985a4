//! The floor in f64 and SI units (the reference's).

/// What the floor computes in.
pub mod precision {
    /// The scalar type (the shader's `alias Real`).
    pub type Real = f64;
    /// The unit system: SI, as the reference's.
    pub const UNITS: crate::laws::floor::units::Units = crate::laws::floor::units::Units::SI;

    /// Keeps its items: they exist in f64 only.
    macro_rules! only_f64 {
        ($($item:item)*) => { $($item)* };
    }
    pub(crate) use only_f64;
}

pub use precision::Real;
pub use setup::Setup;
pub use vec2::Vec2;

// The same sources as the other precision's, on purpose (the shader's
// `alias Real`).
#[allow(clippy::duplicate_mod)]
#[path = "../gauge.rs"]
pub mod gauge;
#[allow(clippy::duplicate_mod)]
#[path = "../measure.rs"]
pub mod measure;
#[allow(clippy::duplicate_mod)]
#[path = "../phase.rs"]
pub mod phase;
#[allow(clippy::duplicate_mod)]
#[path = "../setup.rs"]
pub mod setup;
#[allow(clippy::duplicate_mod)]
#[path = "../vec2.rs"]
pub mod vec2;
