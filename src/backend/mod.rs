//! Backends: the ways of integrating many instances, behind one trait the
//! sweep drives. The CPU path ([`CpuBackend`], rayon, f64) is the
//! reference; the GPU path ([`GpuBackend`]) runs the WGSL shader through
//! wgpu in f32 or f64. [`select`] turns the command line's choice into one.

use std::fmt;

use anyhow::Result;

use crate::cpu::integrate::Settings;
use crate::measurement::Outcome;
use crate::model::Instance;

pub mod cpu;
pub mod gpu;
pub mod select;

pub use cpu::CpuBackend;
pub use gpu::GpuBackend;
pub use select::{BackendChoice, select_backend};

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

/// What a backend computes on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Hardware {
    /// CPU cores, through a rayon pool of this many threads.
    Cpu { threads: usize },
    /// A GPU adapter (a software one such as lavapipe included).
    Gpu,
}

/// A way of integrating many instances.
pub trait Backend: Sync {
    /// Names the hardware that ran, for the `backend` attribute.
    fn describe(&self) -> String;
    /// The floating-point precision it integrates in.
    fn precision(&self) -> Precision;
    /// A good number of instances per chunk.
    fn chunk_size(&self) -> usize;
    /// What it computes on.
    fn hardware(&self) -> Hardware;
    /// Integrates the instances; `done(n)` reports n more finished ones.
    fn run(
        &self,
        instances: &[Instance],
        settings: &Settings,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Outcome>>;
}
