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

/// The profile table's lines of the CPU integrator's iterations by kind
/// (both precisions' mirrors together), with the share of slip trials
/// rejected; empty where the CPU integrated nothing (LuGre's integrator
/// is not counted).
pub fn iteration_lines() -> String {
    use integrate::constants::{ITERATION_KINDS, KIND_NAMES, rejected_share};
    use std::sync::atomic::Ordering;
    let mut kinds = [0u64; ITERATION_KINDS];
    for (k, total) in kinds.iter_mut().enumerate() {
        *total = integrate::ITERATIONS[k].load(Ordering::Relaxed)
            + single::integrate::ITERATIONS[k].load(Ordering::Relaxed);
    }
    let all: u64 = kinds.iter().sum();
    if all == 0 {
        return String::new();
    }
    let by_kind: Vec<String> = KIND_NAMES
        .iter()
        .zip(kinds)
        .filter(|(_, n)| *n > 0)
        .map(|(name, n)| format!("{name} {:.1} %", 100.0 * n as f64 / all as f64))
        .collect();
    format!(
        "pidm: phase CPU integrator: {all} iterations; by kind: {}\n\
         pidm: phase   rejected trials: {:.1} % of slip trials (slip steps and rejected trials)\n",
        by_kind.join(", "),
        100.0 * rejected_share(&kinds)
    )
}
