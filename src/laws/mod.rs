//! The friction laws, each a folder of the same shape: its CPU integrator
//! (the f64 reference, and the mirror its shader follows function for
//! function), its mirror tests beside it; the shader files are in
//! `shaders/<law>/` and the device side in `crate::gpu::<law>`.
//!
//! * [`karnopp`]: Karnopp's stick-slip law (docs/model.md section 3), with
//!   events located exactly; compiled in both precisions.
//! * [`lugre`]: the LuGre bristle model (docs/model.md section 8), Rodas4
//!   in f64.
//!
//! A third law is one more folder here (and in `shaders/`) and one more arm
//! in [`run_until`] and `crate::backend::gpu`'s choice of device integrator.
//! [`settings`] are what every law's integrator takes.

pub mod karnopp;
pub mod lugre;
pub mod settings;

use crate::model::Instance;
use karnopp::{integrate, single};
use std::fmt;

/// Integrates one instance in f64 with its friction law's integrator
/// ([`karnopp`] or [`lugre`]) to the end, or until
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

/// Floating-point precision of an integration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, clap::ValueEnum)]
pub enum Precision {
    F32,
    F64,
}

impl Precision {
    /// "f32" or "f64", as result files and messages write it.
    pub fn as_str(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }
}

impl fmt::Display for Precision {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}
