//! The GPU backend: the WGSL shader in `shaders/karnopp/`, a
//! file-by-file mirror of [`crate::laws::status`], run through wgpu with
//! one invocation per instance.
//!
//! * [`GpuContext::new`] picks an adapter and opens a device; the work
//!   itself ([`execute_gpu_inner`]) takes any device, so tests and callers
//!   may pass their own.
//! * [`GpuContext::prepare`] compiles the pipeline of a precision and runs a
//!   self-test batch against the CPU before any instance is integrated: a
//!   driver that fails to compile the shader without saying so through
//!   wgpu (NVIDIA's "NVVM compilation failed" loses the device) or that
//!   computes wrong numbers is caught there, as a [`GpuError`], never a
//!   panic.
//! * A batch is integrated in time slices: every dispatch advances every
//!   instance by at most [`BatchOptions::slice_iterations`] iterations of
//!   `iterate`, the states stay in a storage buffer between dispatches, an
//!   atomic counts the instances still unfinished, and the host dispatches
//!   again until none is. No dispatch has to run an instance to its end,
//!   which desktop watchdogs would not allow.
//! * llvmpipe (lavapipe, and Mesa's GL on the CPU) ends every loop of an
//!   invocation once all its loops together have run 65,535 iterations,
//!   silently. Its pipelines check after each iteration whether that
//!   happened; if so the iteration is undone and the slice ends, and the
//!   next dispatch redoes it with a fresh budget. An iteration that cannot
//!   fit in one budget ends with [`STATUS_LOOP_LIMIT`], and the host
//!   integrates that instance on the CPU ([`GpuOutcome::cpu_fallback`]
//!   says so). Results do not depend on the slice length.
//! * Batches larger than the device's storage-binding, buffer or dispatch
//!   limits are split automatically (and dispatched in two dimensions when
//!   one is not enough).
//! * f32 runs everywhere; f64 where the adapter offers `SHADER_F64`. The f32
//!   shader computes in micrometres and milliseconds and keeps the time as
//!   a two-part number (see [`layout::Units`]). An f32 instance that fails
//!   or stops at a band graze is integrated again on the CPU in f64
//!   ([`f32_needs_f64`]; [`GpuOutcome::shader_status`] says which). The
//!   heaviest fifth of an f32 call's window runs is checked
//!   ([`crate::laws::floor::check`], [`BatchOptions::check`]): by twins at a
//!   looser tolerance on a hardware adapter (while the CPU integrates the
//!   failures and grazes), by the f64 reference on the CPU on a software
//!   one ([`GpuOutcome::checked`]).
//! * Compiled pipelines are kept in a [`wgpu::PipelineCache`] on disk where
//!   the adapter supports one (Vulkan), so a later run skips the driver's
//!   compile ([`cache`]).
//!
//! The files, one concern each: `adapters.rs` (discovery, ranking, what
//! `pidm info` reports), `context.rs` (the device, its health, the
//! pipelines and their self-test), `options.rs` (a batch's knobs),
//! `runner.rs` (a batch in time slices: buffers, dispatches, readback),
//! `staging.rs` (a sweep chunk's size, coefficients packed ahead),
//! `tail.rs` (what the CPU takes over), `readback.rs` (which accumulators
//! come back), `knobs.rs` and `cache.rs`; each law's device side is its
//! folder (`karnopp/`, `lugre/`: the same file names in the same roles).

mod adapters;
pub mod cache;
mod context;
mod groups;
pub mod isa;
pub mod karnopp;
mod knobs;
mod lanes;
pub mod layout;
pub mod lugre;
#[cfg(test)]
pub(crate) mod mirrors;
mod options;
pub mod prelude;
pub mod readback;
mod rounds;
mod runner;
mod slices;
pub mod spirv;
mod staging;
mod tail;
pub mod warps;

pub use adapters::{
    AdapterSummary, PrecisionCheck, check_adapters, list_adapters, private_runtime_dir,
};
pub use context::{BACKWARD_ALLOWANCE_M, GpuContext, Preparation, create_pipeline};
pub use options::{BatchOptions, CPU_TAIL_MIN_BATCH, CPU_TAIL_PER_THREAD, F32Check, tail_size};
pub use runner::{
    dispatch_size, execute_gpu_inner, run_batch, run_batch_packed, run_batch_with, workgroups,
};
pub use slices::engine_queue;
pub use staging::{Packed, batch_limit, chunk_instances, max_batch_instances, pack};
// The module's other items, for its files (`use super::*`).
use adapters::*;
use karnopp::runner::*;
use lanes::*;
use options::*;
use tail::*;

pub use karnopp::{footprint, shader};

// The twin of `crate::laws::Law` on the device side: what the commands and
// the backend ask of the laws' own lanes beside the engine's variants
// (Karnopp's), named for what they are, not for their law.
pub use lugre::LugreGpu;
pub use lugre::PIPELINE_NAME as LAW_PIPELINE_NAME;
pub use lugre::hardware_lanes as law_hardware_lanes;
pub use lugre::table_lines as law_table_lines;

/// The laws' own pipelines' WGSL written into `dir` (`pidm info --shader`,
/// beside the engine's variants); their file names.
pub fn write_law_sources(dir: &std::path::Path) -> std::io::Result<Vec<String>> {
    lugre::write_sources(dir)
}

/// The laws' own pipelines' footprints, named as `pidm info`'s table
/// lists them.
pub fn law_footprints() -> Result<Vec<(String, spirv::Footprint)>, GpuError> {
    lugre::footprints()
}
pub use knobs::{
    CHUNK_ROUNDS, LANES, PROBE_ITERATIONS, SLICE_ITERATIONS, SOFTWARE_CHUNK_ROUNDS,
    SOFTWARE_LANES_PER_THREAD, Tail, WORKGROUP_SIZE, compact, cpu_tail, f32_check, lanes,
    lanes_for, order, slice_iterations, workgroup_size,
};
pub use shader::{Parts, Variant};
pub use warps::Order;

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use thiserror::Error;
use wgpu::util::DeviceExt;

use crate::laws::Settings;
use crate::laws::floor::check;
use crate::laws::karnopp::integrate::{Run, initial_measure, run_instance};
use crate::measurement::{Measured, reduce};
use crate::model::{Instance, Measure};
use layout::HostLayout;
use layout::control::Control;

/// Status the shader gives an instance when a single iteration needs more
/// loop iterations than the driver allows one invocation (llvmpipe/lavapipe
/// stop every loop of an invocation after 65,535 loop iterations in total).
/// [`run_batch`] integrates such instances on the CPU instead and marks
/// them ([`GpuOutcome::cpu_fallback`]), so callers never see this status.
pub const STATUS_LOOP_LIMIT: u32 = 100;

pub use crate::laws::Precision;

pub use crate::laws::floor::check::Route;
pub use crate::laws::karnopp::{f32_needs_f64, is_integrator_failure};

/// What went wrong on the GPU path.
#[derive(Debug, Error)]
pub enum GpuError {
    /// No adapter fits the request.
    #[error(
        "no GPU adapter found ({tried}); install a Vulkan driver (on Debian/Ubuntu \
         `apt-get install mesa-vulkan-drivers libvulkan1` gives the lavapipe software \
         adapter) and set WGPU_BACKEND=vulkan"
    )]
    NoAdapter {
        /// What was enumerated and why each candidate was refused.
        tried: String,
    },
    /// Only software adapters were found, and they were not allowed.
    #[error(
        "no hardware GPU; only the software adapter ({software}), which runs the shader on the \
         CPU, slower than the CPU path"
    )]
    OnlySoftware {
        /// The software adapter found, e.g. "llvmpipe (LLVM 15.0.6, 256
        /// bits) (Vulkan)".
        software: String,
    },
    /// f64 was requested from an adapter without `SHADER_F64`.
    #[error("adapter {adapter} does not support 64-bit floats in shaders (SHADER_F64)")]
    F64Unsupported { adapter: String },
    /// The device could not be opened.
    #[error("requesting a device from {adapter} failed: {message}")]
    DeviceRequest { adapter: String, message: String },
    /// The shader did not parse, validate or compile.
    #[error("the {precision:?} integrate shader failed to compile:\n{message}")]
    ShaderCompile {
        precision: Precision,
        message: String,
    },
    /// The device was lost or reported an error outside any error scope
    /// (NVIDIA's driver loses the device when its compiler fails).
    #[error("the GPU device {adapter} failed: {message}")]
    Device { adapter: String, message: String },
    /// The pipeline compiled but its self-test batch disagreed with the CPU.
    #[error(
        "the {precision} pipeline on {adapter} failed its self-test against the CPU and is not \
         used: {message}"
    )]
    SelfTest {
        precision: Precision,
        adapter: String,
        message: String,
    },
    /// A readback buffer could not be mapped.
    #[error("mapping a readback buffer failed: {0}")]
    BufferMapping(String),
    /// The user asked the run to stop (Ctrl-C) between two slices.
    #[error("interrupted between two time slices")]
    Interrupted,
    /// wgpu reported an error while running a batch.
    #[error("the GPU reported an error while running a batch: {0}")]
    Execution(String),
    /// Instances stayed unfinished after more slices than their step budget
    /// allows (a shader that stopped advancing).
    #[error("{unfinished} instances still unfinished after {slices} slices")]
    Stalled { unfinished: u32, slices: u64 },
}

/// The result of one instance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuOutcome {
    /// Slider displacement over the measured periods, in metres; zero unless
    /// the status keeps values (as [`crate::measurement::Measured::travel`]).
    pub displacement: [f64; 2],
    /// The rest of the run's [`Measured`]: the scene periods the
    /// displacement spans, the standard errors [m per own drive cycle], the
    /// periods integrated and the detected cycle.
    pub span: f64,
    pub se: [f64; 2],
    pub periods: u32,
    pub lag: u32,
    /// One of the `STATUS_*` constants of [`crate::laws::status`].
    pub status: u32,
    /// The kind of motion the measurement found.
    pub motion: crate::model::motion::Motion,
    /// Steps taken (accepted, rejected and events).
    pub steps: u32,
    /// True when the CPU integrated this instance instead (in f64): the
    /// driver's loop limiter kept the shader from advancing it at all, or
    /// it failed or met a band graze in f32 ([`f32_needs_f64`]).
    pub cpu_fallback: bool,
    /// Where [`GpuOutcome::cpu_fallback`] is set, the status the shader
    /// ended the instance with, which sent it to the CPU
    /// ([`STATUS_LOOP_LIMIT`], an f32 failure, or an f32 band graze,
    /// `STATUS_GRAZE`); 0 otherwise.
    pub shader_status: u32,
    /// True when the instance was among the last unfinished ones of a
    /// large batch and the CPU finished it (in f64) while the GPU stopped:
    /// see [`BatchOptions::cpu_tail`].
    pub finished_on_cpu: bool,
    /// True for an f32 window run among the heaviest of its batch, which
    /// was checked ([`crate::laws::floor::check`]): it keeps f32's value where
    /// its twin agreed, and carries the f64 reference's (with
    /// [`GpuOutcome::cpu_fallback`] set) where the twin disagreed or the
    /// check ran the reference directly.
    pub checked: bool,
    /// The replicas whose merged estimate it is (`crate::replicas`; 1: one
    /// run of its own).
    pub replicas: u32,
    /// The backward travel per axis [m per own drive cycle] and its
    /// standard error, where the run measured it (`Settings::backward`:
    /// `crate::measurement::reduce_variation` of the lane's variation
    /// entry, or of the CPU's run); zero otherwise.
    pub variation: [f64; 2],
    pub variation_se: [f64; 2],
}

impl GpuOutcome {
    /// The outcome of a reduced run, integrated on the GPU.
    pub fn of(m: &Measured, steps: u32) -> GpuOutcome {
        GpuOutcome {
            displacement: m.travel,
            span: m.span,
            se: m.se,
            periods: m.periods,
            lag: m.lag,
            status: m.status,
            motion: m.motion,
            steps,
            cpu_fallback: false,
            shader_status: 0,
            finished_on_cpu: false,
            checked: false,
            replicas: 1,
            variation: [0.0; 2],
            variation_se: [0.0; 2],
        }
    }

    /// This outcome with the backward travel of `run`'s variation `v`,
    /// reduced as the CPU's (`measurement::reduce_variation`), either law's.
    pub fn with_variation(
        self,
        inst: &Instance,
        run: &crate::laws::Run,
        v: &crate::laws::floor::variation::Variation,
    ) -> GpuOutcome {
        let (variation, variation_se) = crate::measurement::reduce_variation(inst, run, v);
        GpuOutcome {
            variation,
            variation_se,
            ..self
        }
    }
}
