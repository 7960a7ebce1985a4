//! Karnopp's friction law (docs/model.md section 3) on the CPU: `integrate/`
//! follows `shaders/karnopp/` file by file and function by function, and is
//! compiled twice, as the shader is, with the scalar `Real` of each
//! precision: [`double`] (f64, SI units: the reference every backend is
//! held to) and [`single`] (f32 in micrometres and milliseconds: the f32
//! shader's mirror). [`integrate`] is the f64 one. [`paper_rk4`] is the
//! paper's fixed-step RK4 of the same law, a baseline, not the reference.

pub mod double;
pub mod paper_rk4;
pub mod single;
pub mod units;

pub use double::integrate;
