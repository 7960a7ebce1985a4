//! CPU mirrors of the WGSL shader stages: `integrate/` follows
//! `shaders/integrate/` file by file and function by function, and is
//! compiled twice, as the shader is, with the scalar `Real` of each
//! precision: [`double`] (f64, SI units: the reference every backend is
//! held to) and [`single`] (f32 in micrometres and milliseconds: the f32
//! shader's mirror). [`integrate`] is the f64 one.

pub mod double;
pub mod karnopp;
pub mod lugre;
pub mod settings;
pub mod single;
pub mod units;

pub use double::integrate;

use crate::model::Instance;

/// Integrates one instance in f64 with its friction law's integrator
/// (`integrate` for Karnopp's, `lugre` for LuGre's) to the end, or until
/// `stop` says so (then `None`). Every caller that integrates an instance
/// of any scene goes through here.
pub fn run_until(
    inst: &Instance,
    settings: &integrate::Settings,
    stop: impl Fn() -> bool,
) -> Option<integrate::Run> {
    if inst.mechanism.lugre().is_some() {
        lugre::run_instance_until(inst, settings, stop)
    } else {
        integrate::run_instance_until(inst, settings, stop)
    }
}
