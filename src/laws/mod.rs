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
//! [`Law`] (`law.rs`) is the one place that names them; ARCHITECTURE.md
//! says what a third law touches. [`settings`] are what every law's
//! integrator takes.

pub mod floor;
pub mod karnopp;
pub mod law;
pub mod lugre;
pub mod observe;
pub mod settings;
pub mod status;

pub use floor::{Record, Run};
pub use law::{Law, Parameter};
pub use settings::{Replica, Replicas, Settings};

use crate::model::Instance;
use std::fmt;

/// Integrates one instance in f64 with its friction law's integrator
/// ([`Law::run_until`]) to the end, or until `stop` says so (then
/// `None`). Every caller that integrates an instance of any scene goes
/// through here.
pub fn run_until(inst: &Instance, settings: &Settings, stop: impl Fn() -> bool) -> Option<Run> {
    Law::run_until(inst, settings, stop)
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
