//! Backends: the ways of integrating many instances, behind one trait the
//! sweep drives. The CPU path ([`CpuBackend`], rayon, f64) is the
//! reference; the GPU path ([`GpuBackend`]) runs the WGSL shader through
//! wgpu in f32 or f64. [`select`] turns the command line's choice into one,
//! `auto` by [`cost`]'s estimates and the GPU costs [`cost_book`] keeps;
//! `check` is the rule by which both f32 paths check their heaviest runs.

use anyhow::Result;

use crate::laws::Settings;
use crate::measurement::Outcome;
use crate::model::Instance;

pub mod cost;
pub mod cost_book;
pub mod cpu;
pub mod gpu;
pub mod probe;
pub mod select;

pub use crate::laws::Precision;
pub use cpu::CpuBackend;
pub use gpu::GpuBackend;
pub use select::{BackendChoice, Selected, Workload, select_backend};

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
