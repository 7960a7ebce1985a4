//! The floor in f32, in the f32 shader's mirror's units (micrometres and
//! milliseconds for Karnopp's): the same sources as [`super::double`].

/// What the floor computes in.
pub mod precision {
    /// The scalar type (the shader's `alias Real`).
    pub type Real = f32;
    /// The unit system: micrometres and milliseconds, in which every
    /// quantity of the paper's mechanism is of order one.
    pub const UNITS: crate::laws::floor::units::Units =
        crate::laws::floor::units::Units::MICRO_MILLI;

    /// Drops its items: they exist in f64 only (`double::precision`).
    macro_rules! only_f64 {
        ($($item:item)*) => {};
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
#[allow(dead_code)]
pub mod gauge;
#[allow(clippy::duplicate_mod)]
#[path = "../measure.rs"]
#[allow(dead_code)]
pub mod measure;
#[allow(clippy::duplicate_mod)]
#[path = "../phase.rs"]
#[allow(dead_code)]
pub mod phase;
#[allow(clippy::duplicate_mod)]
#[path = "../setup.rs"]
#[allow(dead_code)]
pub mod setup;
#[allow(clippy::duplicate_mod)]
#[path = "../vec2.rs"]
#[allow(dead_code)]
pub mod vec2;
