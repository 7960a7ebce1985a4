//! Backends: the ways of integrating many instances, behind one trait the
//! sweep drives. The CPU path ([`CpuBackend`], rayon, f64) is the
//! reference; the GPU path ([`GpuBackend`]) runs the WGSL shader through
//! wgpu in f32 or f64. [`select`] turns the command line's choice into one,
//! `auto` by [`cost`]'s estimates and the GPU costs [`cost_book`] keeps;
//! [`check`] is the rule by which both f32 paths check their heaviest runs.

use std::fmt;

use anyhow::Result;

use crate::laws::karnopp::integrate::Settings;
use crate::measurement::Outcome;
use crate::model::Instance;

pub mod check;
pub mod cost;
pub mod cost_book;
pub mod cpu;
pub mod gpu;
pub mod select;

pub use cpu::CpuBackend;
pub use gpu::GpuBackend;
pub use select::{BackendChoice, Selected, Workload, select_backend};

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

/// Whether `status` says the integration failed (step budget, non-finite
/// state, step underflow, event storm), as opposed to finishing or to a
/// steady measurement's verdict. In f32 such a failure is f32's own far
/// more often than the instance's (a velocity band below what f32 resolves
/// next to the stage speeds ends in step underflow: 279 of `stress.toml`'s
/// 432 instances with a 1e-9 m/s band).
pub fn is_integrator_failure(status: u32) -> bool {
    use crate::laws::karnopp::integrate::{
        STATUS_EVENT_STORM, STATUS_NON_FINITE, STATUS_STEP_BUDGET, STATUS_STEP_UNDERFLOW,
    };
    matches!(
        status,
        STATUS_STEP_BUDGET | STATUS_NON_FINITE | STATUS_STEP_UNDERFLOW | STATUS_EVENT_STORM
    )
}

/// Whether an f32 integration that ended with `status` is integrated again
/// on the CPU in f64, by every f32 path (the shader's batches and the CPU
/// mirror's backend alike): a failure ([`is_integrator_failure`]), or a
/// band graze, where f32 stopped because the step depends on a decision
/// that the direction tolerance, not f32, leaves open
/// (`cpu::integrate::constants::GRAZE_MARGIN`). The instance then carries
/// the f64 reference's value, or its status where that fails too, and is
/// counted as run on the CPU.
pub fn f32_needs_f64(status: u32) -> bool {
    is_integrator_failure(status)
        || status == crate::laws::karnopp::integrate::constants::STATUS_GRAZE
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
    /// The part of [`Backend::run`]'s work on `instances` that can be done
    /// ahead, on the sweep's driver thread while the chunk before them
    /// integrates: the GPU packs their coefficients. Nothing by default.
    fn stage(&self, _instances: &[Instance], _settings: &Settings) -> Staged {
        Staged::default()
    }
    /// [`Backend::run`] with what [`Backend::stage`] made of the same
    /// instances and settings.
    fn run_staged(
        &self,
        instances: &[Instance],
        settings: &Settings,
        _staged: Staged,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Outcome>> {
        self.run(instances, settings, done)
    }
}

/// What [`Backend::stage`] did ahead for a chunk: on the GPU its packed
/// coefficients.
#[derive(Default)]
pub struct Staged(pub(crate) Option<crate::gpu::Packed>);
