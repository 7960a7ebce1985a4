//! The GPU backend: the WGSL shader in `shaders/integrate/`, a
//! file-by-file mirror of [`crate::cpu::integrate`], run through wgpu with
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
//!   ([`crate::backend::check`], [`BatchOptions::check`]): by twins at a
//!   looser tolerance on a hardware adapter (while the CPU integrates the
//!   failures and grazes), by the f64 reference on the CPU on a software
//!   one ([`GpuOutcome::checked`]).
//! * Compiled pipelines are kept in a [`wgpu::PipelineCache`] on disk where
//!   the adapter supports one (Vulkan), so a later run skips the driver's
//!   compile ([`cache`]).

pub mod cache;
mod knobs;
pub mod layout;
pub mod readback;
pub mod shader;

pub use knobs::{
    LANES, SLICE_ITERATIONS, WORKGROUP_SIZE, f32_check, gpu_phases, lanes, slice_iterations,
    workgroup_size,
};
pub use shader::Variant;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use rayon::prelude::*;

use thiserror::Error;
use wgpu::util::DeviceExt;

use crate::backend::check;
use crate::cpu::integrate::{Run, Settings, initial_measure, run_instance};
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

pub use crate::backend::Precision;

pub use crate::backend::check::Route;
pub use crate::backend::{f32_needs_f64, is_integrator_failure};

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

/// One adapter as wgpu enumerates it.
#[derive(Clone, Debug, PartialEq)]
pub struct AdapterSummary {
    pub name: String,
    pub device_type: String,
    pub backend: String,
    /// The driver and its version, as the adapter reports them.
    pub driver: String,
    /// True when the adapter offers `SHADER_F64`.
    pub f64: bool,
    /// True when the adapter keeps compiled pipelines in a cache wgpu can
    /// save (`PIPELINE_CACHE`).
    pub pipeline_cache: bool,
    pub max_storage_buffer_binding_size: u64,
    pub max_buffer_size: u64,
    pub max_compute_workgroups_per_dimension: u32,
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
    /// One of the `STATUS_*` constants of [`crate::cpu::integrate`].
    pub status: u32,
    /// The kind of motion the measurement found.
    pub motion: crate::motion::Motion,
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
    /// was checked ([`crate::backend::check`]): it keeps f32's value where
    /// its twin agreed, and carries the f64 reference's (with
    /// [`GpuOutcome::cpu_fallback`] set) where the twin disagreed or the
    /// check ran the reference directly.
    pub checked: bool,
}

/// Tuning knobs of [`run_batch_with`]; [`Default`] is what [`run_batch`]
/// uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatchOptions {
    /// Iterations of `iterate` per dispatch.
    pub slice_iterations: u32,
    /// Largest number of instances per dispatch batch, on top of the
    /// device's limits (tests force small batches with it).
    pub max_batch: Option<usize>,
    /// Read every steady instance's whole accumulators back, not only the
    /// heads and the accumulators that the reductions need
    /// ([`readback`]); tests compare the two.
    pub whole_accumulators: bool,
    /// Passes the shader's loop-limiter probe makes; at least
    /// [`layout::PROBE_PASSES`]. Tests raise it beyond 65,535 so that on
    /// llvmpipe no iteration can complete its probe, which exercises the
    /// fallback of [`STATUS_LOOP_LIMIT`] instances to the CPU.
    pub probe_passes: u32,
    /// Lanes working through a batch, at most (tests use few, so lanes
    /// take several instances each).
    pub lanes: usize,
    /// Hand the slow tail of a batch to the CPU: once every instance has
    /// started and at most this many are unfinished, the GPU stops and the
    /// CPU finishes those, in parallel: from where the GPU left them in f64
    /// (the shader mirrors the CPU step for step, so no work is lost), from
    /// their start in f32 (the f32 mirror could continue an f32 state, but
    /// the slow tail is where f32 is least sure of itself, and the f64
    /// reference costs the CPU no more), so those f32 instances carry the CPU's
    /// f64 values and the run's summary counts them among the integrations
    /// that ran on the CPU. `None` is the default of
    /// [`BatchOptions::tail_size`] for batches of at least
    /// [`CPU_TAIL_MIN_BATCH`] instances in either precision, and nothing for
    /// a smaller one; `Some(0)` never hands over. A GPU lane takes tens of microseconds a step, a CPU core about
    /// one: once few instances are left, the GPU runs them at one lane's
    /// speed each while the CPU's threads would be faster, and an instance a
    /// hundred times longer than its batch's others (a sliding mode on the
    /// rim of the band) would hold the whole batch. Which instances form
    /// the tail depends on the batch, so a map split into other batches
    /// (chunks, shards, a resumed run) differs on them by the GPU's
    /// difference from the CPU: rounding or the tolerance's scatter in f64,
    /// f32's own error in f32 (within 0.005 um + 1 % of the f64 step on the
    /// random scenes of results/gpu.md since issue 19).
    pub cpu_tail: Option<usize>,
    /// How an f32 batch checks its heaviest window runs
    /// ([`crate::backend::check`]); f64 batches are not checked.
    pub check: F32Check,
}

/// How an f32 batch checks its heaviest window runs
/// ([`crate::backend::check`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum F32Check {
    /// [`Route::Reference`] on a software adapter (its "GPU" is the CPU's
    /// own cores, where native f64 code takes about a third of the
    /// shader's time per step), [`Route::Twins`] on any other. A batch run
    /// through [`execute_gpu_inner`], which does not see the adapter,
    /// takes twins.
    Auto,
    /// Always this route.
    Route(Route),
    /// No check: the self-test's (it judges the shader alone), and for
    /// measurements (`PIDM_F32_CHECK=off`).
    Off,
}

impl F32Check {
    /// The route of this choice on an adapter that `is_hardware` or not;
    /// `None` when off.
    pub fn route(self, is_hardware: bool) -> Option<Route> {
        match self {
            F32Check::Auto if is_hardware => Some(Route::Twins),
            F32Check::Auto => Some(Route::Reference),
            F32Check::Route(route) => Some(route),
            F32Check::Off => None,
        }
    }
}

/// How often progress is reported while the CPU integrates the checked runs
/// and fallbacks after the batches: often enough for a progress bar, and
/// the wait ends as soon as the pass does.
const CPU_PASS_REPORT: std::time::Duration = std::time::Duration::from_millis(100);

/// The smallest batch whose slow tail goes to the CPU by default (smaller
/// ones, the self-test's and most tests', stay on the GPU to their end).
pub const CPU_TAIL_MIN_BATCH: usize = 1000;

/// Unfinished instances per CPU thread below which an f64 batch hands its
/// tail to the CPU: a core steps about twenty times as fast as a GPU lane,
/// so with fewer than about that many instances per thread left, the CPU
/// finishes them sooner than the GPU would.
pub const CPU_TAIL_PER_THREAD: usize = 16;

impl BatchOptions {
    /// The unfinished instances of a batch of `n` that the CPU takes over
    /// when it has `threads` threads (see [`BatchOptions::cpu_tail`]): by
    /// default, for batches of at least [`CPU_TAIL_MIN_BATCH`], 1 % of
    /// the batch or [`CPU_TAIL_PER_THREAD`] per thread, whichever is more,
    /// but never more than a quarter of the batch.
    pub fn tail_size(&self, _precision: Precision, n: usize, threads: usize) -> usize {
        match self.cpu_tail {
            Some(k) => k,
            None if n >= CPU_TAIL_MIN_BATCH => {
                (n / 100).max(CPU_TAIL_PER_THREAD * threads).min(n / 4)
            }
            None => 0,
        }
    }
}

impl Default for BatchOptions {
    fn default() -> Self {
        BatchOptions {
            slice_iterations: slice_iterations(),
            max_batch: None,
            whole_accumulators: false,
            probe_passes: layout::PROBE_PASSES,
            lanes: lanes(),
            cpu_tail: None,
            check: f32_check(),
        }
    }
}

/// Every adapter on the given backends (the instance's other settings come
/// from wgpu's environment variables).
fn adapters_on(backends: wgpu::Backends) -> Vec<wgpu::Adapter> {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle().with_env();
    desc.backends = backends;
    pollster::block_on(wgpu::Instance::new(desc).enumerate_adapters(backends))
}

/// Every adapter wgpu can open, on the backends `WGPU_BACKEND` names or on
/// all.
fn adapters() -> Vec<wgpu::Adapter> {
    adapters_on(wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all()))
}

fn summary(adapter: &wgpu::Adapter) -> AdapterSummary {
    let info = adapter.get_info();
    let limits = adapter.limits();
    AdapterSummary {
        name: info.name.clone(),
        device_type: format!("{:?}", info.device_type),
        backend: format!("{:?}", info.backend),
        driver: driver_of(&info),
        f64: adapter.features().contains(wgpu::Features::SHADER_F64),
        pipeline_cache: adapter.features().contains(wgpu::Features::PIPELINE_CACHE),
        max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
        max_buffer_size: limits.max_buffer_size,
        max_compute_workgroups_per_dimension: limits.max_compute_workgroups_per_dimension,
    }
}

/// "NVIDIA 580.159.04": the driver's name and version.
fn driver_of(info: &wgpu::AdapterInfo) -> String {
    match (info.driver.is_empty(), info.driver_info.is_empty()) {
        (false, false) => format!("{} {}", info.driver, info.driver_info),
        (false, true) => info.driver.clone(),
        (true, false) => info.driver_info.clone(),
        (true, true) => "unknown driver".to_string(),
    }
}

/// Every adapter wgpu enumerates (honouring `WGPU_BACKEND`).
pub fn list_adapters() -> Vec<AdapterSummary> {
    adapters().iter().map(summary).collect()
}

/// Whether an adapter runs one precision and trusts it: `Ok` once its
/// pipeline compiled and passed the self-test against the CPU, else why
/// not (no `SHADER_F64`, no compute shaders, a device, compile or
/// self-test failure).
#[derive(Clone, Debug, PartialEq)]
pub struct PrecisionCheck {
    pub precision: Precision,
    pub trusted: Result<(), String>,
}

impl PrecisionCheck {
    /// "f64 yes (self-test passed)" or "f32 no (...)".
    pub fn describe(&self) -> String {
        match &self.trusted {
            Ok(()) => format!("{} yes (self-test passed)", self.precision),
            Err(why) => format!("{} no ({why})", self.precision),
        }
    }
}

/// Every adapter wgpu enumerates with, per precision, whether it runs and
/// passes its self-test: opens a device on each and compiles and self-tests
/// each precision it offers (seconds per adapter when the pipeline is not
/// cached).
pub fn check_adapters() -> Vec<(AdapterSummary, Vec<PrecisionCheck>)> {
    adapters()
        .iter()
        .map(|adapter| {
            let summary = summary(adapter);
            let compute = adapter
                .get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS);
            let ctx = if compute {
                GpuContext::from_adapter(adapter).map_err(|e| e.to_string())
            } else {
                Err("no compute shaders".to_string())
            };
            let checks = [Precision::F32, Precision::F64]
                .into_iter()
                .map(|precision| {
                    let trusted = match &ctx {
                        Err(why) => Err(why.clone()),
                        Ok(_) if precision == Precision::F64 && !summary.f64 => {
                            Err("no SHADER_F64".to_string())
                        }
                        Ok(ctx) => match ctx.prepare(precision) {
                            Ok(_) => Ok(()),
                            Err(GpuError::SelfTest { message, .. }) => {
                                Err(format!("self-test failed: {message}"))
                            }
                            Err(e) => Err(e.to_string()),
                        },
                    };
                    PrecisionCheck { precision, trusted }
                })
                .collect();
            (summary, checks)
        })
        .collect()
}

/// A private runtime folder for this process when `XDG_RUNTIME_DIR` is
/// unset or invalid (not a folder of this user's that only it may enter),
/// to set before wgpu looks for adapters: Mesa's GL driver otherwise prints
/// "error: XDG_RUNTIME_DIR is invalid or not set in the environment", which
/// a user of pidm can do nothing about. `None` when the variable is valid
/// or no such folder can be made. The folder, `pidm-runtime-<uid>-<pid>`
/// in the temporary folder with mode 0700, is new and empty: the caller
/// removes it when the process ends ([`std::fs::remove_dir`] leaves it if
/// a driver put something there).
pub fn private_runtime_dir() -> Option<std::path::PathBuf> {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt};
    // SAFETY: getuid cannot fail and touches no memory.
    let uid = unsafe { libc::getuid() };
    let private = |path: &std::path::Path| {
        std::fs::symlink_metadata(path)
            .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.mode() & 0o077 == 0)
    };
    if let Some(dir) = std::env::var_os("XDG_RUNTIME_DIR").filter(|d| !d.is_empty())
        && private(std::path::Path::new(&dir))
    {
        return None;
    }
    let dir = std::env::temp_dir().join(format!("pidm-runtime-{uid}-{}", std::process::id()));
    std::fs::DirBuilder::new().mode(0o700).create(&dir).ok()?;
    private(&dir).then_some(dir)
}

/// True for adapters that run on the CPU (lavapipe, llvmpipe, SwiftShader,
/// WARP).
fn is_software(info: &wgpu::AdapterInfo) -> bool {
    let name = info.name.to_lowercase();
    info.device_type == wgpu::DeviceType::Cpu
        || ["llvmpipe", "lavapipe", "swiftshader", "softpipe", "warp"]
            .iter()
            .any(|n| name.contains(n))
}

/// True for adapters whose shader loops stop silently after 65,535
/// iterations (Mesa's llvmpipe, behind lavapipe and its GL driver).
fn has_loop_limiter(info: &wgpu::AdapterInfo) -> bool {
    let name = info.name.to_lowercase();
    name.contains("llvmpipe") || name.contains("lavapipe")
}

/// Preference among usable adapters: discrete, integrated, virtual, other,
/// software; f64 support breaks ties.
fn rank(adapter: &wgpu::Adapter) -> (u32, bool) {
    let info = adapter.get_info();
    let kind = if is_software(&info) {
        0
    } else {
        match info.device_type {
            wgpu::DeviceType::DiscreteGpu => 4,
            wgpu::DeviceType::IntegratedGpu => 3,
            wgpu::DeviceType::VirtualGpu => 2,
            _ => 1,
        }
    };
    (
        kind,
        adapter.features().contains(wgpu::Features::SHADER_F64),
    )
}

/// What making a pipeline ready cost, for the user's information.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preparation {
    /// Finding the adapter and opening the device [s].
    pub open_s: f64,
    /// The part of `open_s` spent loading the drivers and enumerating
    /// their adapters, before the device is requested [s].
    pub adapters_s: f64,
    /// Creating the pipeline: the driver's compile, or a pipeline-cache hit
    /// [s].
    pub pipeline_s: f64,
    /// The self-test batch [s].
    pub self_test_s: f64,
}

/// Errors the device reported outside any error scope, and its loss.
#[derive(Default)]
struct DeviceHealth {
    failure: Mutex<Option<String>>,
}

impl DeviceHealth {
    fn record(&self, message: String) {
        let mut failure = self.failure.lock().unwrap_or_else(|e| e.into_inner());
        if failure.is_none() {
            *failure = Some(message);
        }
    }

    fn failure(&self) -> Option<String> {
        self.failure
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

/// An open device with what the batches need to know about it.
pub struct GpuContext {
    device: wgpu::Device,
    queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    f64: bool,
    limits: wgpu::Limits,
    health: Arc<DeviceHealth>,
    /// The driver's pipeline cache, where the adapter offers one.
    cache: Option<cache::DiskCache>,
    /// Compiled and self-tested pipelines, [F32, F64], built on first use,
    /// with what building them cost.
    pipelines: Mutex<[Option<(wgpu::ComputePipeline, Preparation)>; 2]>,
    /// Time to find the adapter and open the device [s].
    opened_in: f64,
    /// The part of `opened_in` before the device was requested [s].
    adapters_in: f64,
    /// Held while a batch runs: batches on one context take turns (wgpu's
    /// GL backend does not survive two threads submitting at once).
    busy: Mutex<()>,
}

impl GpuContext {
    /// Opens the best adapter: a hardware one when there is one, a software
    /// one (lavapipe and the like) only when `allow_software`.
    pub fn new(allow_software: bool) -> Result<GpuContext, GpuError> {
        let started = std::time::Instant::now();
        let mut tried = Vec::new();
        let mut best: Option<wgpu::Adapter> = None;
        // The first software adapter refused, to say so plainly when it is
        // the only kind there is.
        let mut software_seen: Option<String> = None;
        // Unless WGPU_BACKEND says otherwise, the primary backends
        // (Vulkan, Metal, DX12) first: opening GL costs a tenth of a second,
        // and a GL adapter has no f64.
        let candidates = match wgpu::Backends::from_env() {
            Some(backends) => adapters_on(backends),
            None => {
                let mut found = adapters_on(wgpu::Backends::PRIMARY);
                let usable = |a: &wgpu::Adapter| allow_software || !is_software(&a.get_info());
                if !found.iter().any(usable) {
                    found.extend(adapters_on(wgpu::Backends::SECONDARY));
                }
                found
            }
        };
        for adapter in candidates {
            let info = adapter.get_info();
            let label = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
            let compute = adapter
                .get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS);
            if !compute {
                tried.push(format!("{label}: no compute shaders"));
                continue;
            }
            if is_software(&info) && !allow_software {
                tried.push(format!("{label}: software, not allowed"));
                software_seen.get_or_insert_with(|| {
                    let kind = if has_loop_limiter(&info) {
                        "lavapipe: "
                    } else {
                        ""
                    };
                    format!("{kind}{}, {:?}", info.name, info.backend)
                });
                continue;
            }
            tried.push(format!("{label}: usable"));
            if best.as_ref().is_none_or(|b| rank(&adapter) > rank(b)) {
                best = Some(adapter);
            }
        }
        let adapters_in = started.elapsed().as_secs_f64();
        if best.is_none()
            && let Some(software) = software_seen
        {
            return Err(GpuError::OnlySoftware { software });
        }
        let Some(adapter) = best else {
            let backends = wgpu::Backends::from_env()
                .map(|b| format!("WGPU_BACKEND={b:?}"))
                .unwrap_or_else(|| "all backends".to_string());
            let tried = if tried.is_empty() {
                format!("{backends}: none enumerated")
            } else {
                format!("{backends}: {}", tried.join("; "))
            };
            return Err(GpuError::NoAdapter { tried });
        };
        let mut ctx = Self::from_adapter(&adapter)?;
        ctx.opened_in = started.elapsed().as_secs_f64();
        ctx.adapters_in = adapters_in;
        Ok(ctx)
    }

    /// Opens a device on a given adapter, with its full limits, and
    /// `SHADER_F64` and `PIPELINE_CACHE` where offered.
    pub fn from_adapter(adapter: &wgpu::Adapter) -> Result<GpuContext, GpuError> {
        let started = std::time::Instant::now();
        let info = adapter.get_info();
        let offered = adapter.features();
        let f64 = offered.contains(wgpu::Features::SHADER_F64);
        let limits = adapter.limits();
        let features = offered & (wgpu::Features::SHADER_F64 | wgpu::Features::PIPELINE_CACHE);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("pidm"),
            required_features: features,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::DeviceRequest {
            adapter: info.name.clone(),
            message: e.to_string(),
        })?;
        // wgpu panics on errors outside any error scope unless a handler
        // takes them: record them (and the device's loss) instead, and turn
        // them into errors where the work checks.
        let health = Arc::new(DeviceHealth::default());
        let on_error = health.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            on_error.record(e.to_string())
        }));
        let on_lost = health.clone();
        device.set_device_lost_callback(move |reason, message| {
            on_lost.record(format!("device lost ({reason:?}): {message}"))
        });
        let cache = if features.contains(wgpu::Features::PIPELINE_CACHE) {
            cache::DiskCache::open(&device, &info)
        } else {
            None
        };
        Ok(GpuContext {
            device,
            queue,
            info,
            f64,
            limits,
            health,
            cache,
            pipelines: Mutex::new([None, None]),
            opened_in: started.elapsed().as_secs_f64(),
            adapters_in: 0.0,
            busy: Mutex::new(()),
        })
    }

    /// "NVIDIA H100 (Vulkan, DiscreteGpu)": the adapter, its backend and
    /// its type.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.info.name, self.info.backend, self.info.device_type
        )
    }

    /// The driver and its version.
    pub fn driver(&self) -> String {
        driver_of(&self.info)
    }

    /// True unless the adapter is a software rasteriser.
    pub fn is_hardware(&self) -> bool {
        !is_software(&self.info)
    }

    /// True when the device runs f64 shaders.
    pub fn supports_f64(&self) -> bool {
        self.f64
    }

    /// Where compiled pipelines are kept between runs, if anywhere.
    pub fn pipeline_cache_path(&self) -> Option<&std::path::Path> {
        self.cache.as_ref().map(|c| c.path())
    }

    /// The device's limits (the adapter's best).
    pub fn limits(&self) -> &wgpu::Limits {
        &self.limits
    }

    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The shader variant this adapter runs in a precision.
    pub fn variant(&self, precision: Precision) -> Variant {
        Variant {
            precision,
            loop_limiter: has_loop_limiter(&self.info),
        }
    }

    /// An error if the device failed or was lost so far.
    fn check_health(&self) -> Result<(), GpuError> {
        match self.health.failure() {
            Some(message) => Err(GpuError::Device {
                adapter: self.describe(),
                message,
            }),
            None => Ok(()),
        }
    }

    /// Compiles the pipeline of a precision and tests it against the CPU,
    /// once per context; a later call returns the first outcome's pipeline.
    /// Every driver failure becomes an error here, before any instance of a
    /// run is integrated.
    pub fn prepare(&self, precision: Precision) -> Result<wgpu::ComputePipeline, GpuError> {
        self.prepare_timed(precision).map(|(p, _)| p)
    }

    /// [`GpuContext::prepare`], with what the preparation cost (the first
    /// call's, also on later calls).
    pub fn prepare_timed(
        &self,
        precision: Precision,
    ) -> Result<(wgpu::ComputePipeline, Preparation), GpuError> {
        if precision == Precision::F64 && !self.f64 {
            return Err(GpuError::F64Unsupported {
                adapter: self.describe(),
            });
        }
        let slot = match precision {
            Precision::F32 => 0,
            Precision::F64 => 1,
        };
        let mut pipelines = self.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(p) = &pipelines[slot] {
            return Ok(p.clone());
        }
        let started = std::time::Instant::now();
        let variant = self.variant(precision);
        let pipeline = create_pipeline(
            &self.device,
            variant,
            self.cache.as_ref().map(|c| c.cache()),
        )?;
        self.check_health()?;
        let compiled = started.elapsed().as_secs_f64();
        self.self_test(&pipeline, precision, 0.0)?;
        let tested = started.elapsed().as_secs_f64();
        if let Some(cache) = &self.cache {
            cache.save();
        }
        let preparation = Preparation {
            open_s: self.opened_in,
            adapters_s: self.adapters_in,
            pipeline_s: compiled,
            self_test_s: tested - compiled,
        };
        pipelines[slot] = Some((pipeline.clone(), preparation));
        Ok((pipeline, preparation))
    }

    /// Compiles the pipeline of a precision (without caching it in this
    /// context) and runs the self-test against a CPU reference whose steps
    /// are shifted by `skew` [m]: a test hook for the refusal path (a skew
    /// beyond the precision's allowance must fail with
    /// [`GpuError::SelfTest`]).
    pub fn self_test_skewed(&self, precision: Precision, skew: f64) -> Result<(), GpuError> {
        if precision == Precision::F64 && !self.f64 {
            return Err(GpuError::F64Unsupported {
                adapter: self.describe(),
            });
        }
        let pipeline = create_pipeline(
            &self.device,
            self.variant(precision),
            self.cache.as_ref().map(|c| c.cache()),
        )?;
        self.check_health()?;
        self.self_test(&pipeline, precision, skew)
    }

    /// Runs the self-test batch (MODEL.md's Fig. 8 case, two periods, and
    /// its 1-DOF x baseline) on a fresh pipeline and compares with the CPU.
    /// `skew` [m] is added to the CPU reference's steps: zero for the real
    /// test; [`GpuContext::self_test_skewed`] lets tests feed a wrong
    /// reference to check that the pipeline is refused.
    fn self_test(
        &self,
        pipeline: &wgpu::ComputePipeline,
        precision: Precision,
        skew: f64,
    ) -> Result<(), GpuError> {
        let mut fig8 = Instance::TABLE1;
        fig8.axes[1].frequency = 20.0;
        fig8.cycles = 2;
        fig8.settle = 1;
        // A steady measurement of 10 Hz against 14 Hz: periodic with a lag
        // of 5 periods (a common period) after about 7.
        let mut steady = Instance::TABLE1;
        steady.axes[1].frequency = 14.0;
        steady.cycles = 40;
        steady.measure = Measure::Steady {
            step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
        };
        let instances = [fig8, fig8.baseline(0), steady];
        let settings = Settings::default();
        let fail = |message: String| GpuError::SelfTest {
            precision,
            adapter: self.describe(),
            message,
        };
        let outcomes = execute_gpu_inner(
            &self.device,
            &self.queue,
            pipeline,
            &self.limits,
            &instances,
            &settings,
            precision,
            &BatchOptions {
                check: F32Check::Off,
                ..BatchOptions::default()
            },
            &mut |_, _| {},
        );
        self.check_health()?;
        let outcomes = outcomes.map_err(|e| fail(e.to_string()))?;
        // f64 mirrors the CPU to rounding; f32 to its own precision.
        let allowance = match precision {
            Precision::F32 => 0.01e-6,
            Precision::F64 => 1e-12,
        };
        for (inst, got) in instances.iter().zip(&outcomes) {
            // An instance the batch handed to the CPU (a failure or a graze
            // in f32, the loop limiter) would compare the CPU with itself:
            // the shader must finish every self-test instance on its own.
            if got.cpu_fallback || got.finished_on_cpu {
                return Err(fail(format!(
                    "the shader ended an instance with status {} and left it to the CPU",
                    got.shader_status
                )));
            }
            let want = reduce(inst, &run_instance(inst, &settings));
            if got.status != want.status || got.lag != want.lag {
                return Err(fail(format!(
                    "status {} and cycle {} periods where the CPU ends with {} and {}",
                    got.status, got.lag, want.status, want.lag
                )));
            }
            for axis in 0..2 {
                let step = |m: &GpuOutcome| inst.measure_over(axis, m.displacement[axis], m.span).1;
                let (g, w) = (
                    step(got),
                    inst.measure_over(axis, want.travel[axis], want.span).1 + skew,
                );
                let err = (g - w).abs();
                if err.is_nan() || err > allowance {
                    return Err(fail(format!(
                        "axis {axis} steps {g:.6e} m where the CPU gives {w:.6e} m, {err:.2e} m \
                         apart, more than the {allowance:.0e} m allowed in {precision}"
                    )));
                }
            }
        }
        Ok(())
    }
}

/// Compiles the integrator for one precision on a device, with the variant
/// a device of that kind needs (`loop_limiter` for llvmpipe), through the
/// driver's pipeline `cache` where there is one. The source is validated
/// with naga first, so errors come with source locations.
pub fn create_pipeline(
    device: &wgpu::Device,
    variant: Variant,
    cache: Option<&wgpu::PipelineCache>,
) -> Result<wgpu::ComputePipeline, GpuError> {
    let precision = variant.precision;
    shader::parse_and_validate(variant)?;
    let src = shader::source(variant);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let internal = device.push_error_scope(wgpu::ErrorFilter::Internal);
    // wgpu's default runtime checks clamp every dynamic array index and add
    // a counter to every loop. Both keep the driver's compiler from
    // unrolling the integrator's short loops, so arrays stay in scratch
    // memory: on lavapipe the shader then compiles six times slower and
    // runs four times slower. The integrator needs neither check.
    // Compilation happens here for most drivers and at the first dispatch
    // for llvmpipe; either may take seconds.
    let mut checks = wgpu::ShaderRuntimeChecks::checked();
    checks.bounds_checks = false;
    checks.force_loop_bounding = false;
    // SAFETY: every array index in the shader is a constant or a counter of
    // a loop bounded by the array's length, the storage arrays are indexed
    // only below both their `arrayLength`s, and every loop is bounded: by a
    // constant, by `max_iterations`, or (the loop-limiter probe) by
    // `control.probe` passes.
    let module = unsafe {
        device.create_shader_module_trusted(
            wgpu::ShaderModuleDescriptor {
                label: Some("shaders/integrate"),
                source: wgpu::ShaderSource::Wgsl(src.into()),
            },
            checks,
        )
    };
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("advance_slice"),
        layout: None,
        module: &module,
        entry_point: Some(shader::ENTRY_POINT),
        compilation_options: Default::default(),
        cache,
    });
    let internal = pollster::block_on(internal.pop());
    let validation = pollster::block_on(validation.pop());
    if let Some(e) = validation.or(internal) {
        return Err(GpuError::ShaderCompile {
            precision,
            message: e.to_string(),
        });
    }
    Ok(pipeline)
}

/// Integrates a batch on the GPU and returns one outcome per instance, in
/// order. `progress(done, total)` is called after every slice.
pub fn run_batch(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    precision: Precision,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<GpuOutcome>, GpuError> {
    run_batch_with(
        ctx,
        instances,
        settings,
        precision,
        &BatchOptions::default(),
        progress,
    )
}

/// [`run_batch`] with explicit [`BatchOptions`].
pub fn run_batch_with(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    precision: Precision,
    options: &BatchOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<GpuOutcome>, GpuError> {
    let pipeline = ctx.prepare(precision)?;
    // The adapter decides the check's route (`F32Check::Auto`).
    let options = &BatchOptions {
        check: match options.check.route(ctx.is_hardware()) {
            Some(route) => F32Check::Route(route),
            None => F32Check::Off,
        },
        ..*options
    };
    let out = {
        let _turn = ctx.busy.lock().unwrap_or_else(|e| e.into_inner());
        execute_gpu_inner(
            &ctx.device,
            &ctx.queue,
            &pipeline,
            &ctx.limits,
            instances,
            settings,
            precision,
            options,
            progress,
        )
    };
    // A lost device fails the batch's readback with a generic mapping
    // error; the device's own message says why.
    ctx.check_health()?;
    out
}

/// The shader's state of every instance after `iterations` iterations of
/// the integrator (one dispatch, each instance on a lane of its own), as
/// the CPU mirror of precision `L` holds it: for tests that pin the shader
/// to its mirror step by step. On lavapipe `iterations` must stay small
/// enough (hundreds) for the loop limiter never to undo one.
fn states_after<L: Layout>(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    iterations: u32,
) -> Result<Vec<L::Mirror>, GpuError> {
    let pipeline = ctx.prepare(L::PRECISION)?;
    let options = BatchOptions {
        slice_iterations: iterations.max(1),
        lanes: instances.len().max(1),
        cpu_tail: Some(0),
        ..BatchOptions::default()
    };
    let states = {
        let _turn = ctx.busy.lock().unwrap_or_else(|e| e.into_inner());
        let run = Runner {
            device: &ctx.device,
            queue: &ctx.queue,
            pipeline: &pipeline,
            limits: &ctx.limits,
            settings,
            options: &options,
        };
        run.slices::<L>(instances, &mut |_| {}, Some(1))?.0
    };
    ctx.check_health()?;
    Ok(states.iter().map(L::mirror).collect())
}

/// [`states_after`] in f32: the states of the f32 shader as its CPU mirror
/// (`pidm::cpu::single`) holds them.
pub fn f32_states_after(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    iterations: u32,
) -> Result<Vec<crate::cpu::single::integrate::State>, GpuError> {
    states_after::<Single>(ctx, instances, settings, iterations)
}

/// [`states_after`] in f64: the states of the f64 shader as the CPU
/// reference holds them.
pub fn f64_states_after(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    iterations: u32,
) -> Result<Vec<crate::cpu::integrate::State>, GpuError> {
    states_after::<Double>(ctx, instances, settings, iterations)
}

/// The work of [`run_batch`] on any device: `pipeline` must come from
/// [`create_pipeline`] on that device with the same precision, and `limits`
/// are the device's.
#[allow(clippy::too_many_arguments)]
pub fn execute_gpu_inner(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    pipeline: &wgpu::ComputePipeline,
    limits: &wgpu::Limits,
    instances: &[Instance],
    settings: &Settings,
    precision: Precision,
    options: &BatchOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<GpuOutcome>, GpuError> {
    let run = Runner {
        device,
        queue,
        pipeline,
        limits,
        settings,
        options,
    };
    match precision {
        Precision::F32 => run.all::<Single>(instances, progress),
        Precision::F64 => run.all::<Double>(instances, progress),
    }
}

/// The host side of one precision: its storage structs and their packing.
trait Layout {
    const PRECISION: Precision;
    type Coefficients: HostLayout + Send;
    type State: HostLayout + Send + Sync;
    type Measure: HostLayout + Send + Sync;
    /// What the host reads of every finished steady measurement.
    type Head: HostLayout + Send + Sync;
    /// Whether a measurement with this head ended with a verdict whose
    /// reduction reads only the head (periodic or phase-resolved).
    fn head_suffices(h: &Self::Head) -> bool;
    /// The accumulators that the reduction of such a head reads.
    fn from_head(h: &Self::Head) -> Self::Measure;
    /// The CPU mirror's state of this precision.
    type Mirror;
    fn mirror(st: &Self::State) -> Self::Mirror;
    fn pack(inst: &Instance, settings: &Settings) -> Self::Coefficients;
    /// The outcome of a finished fixed window.
    fn unpack(inst: &Instance, st: &Self::State) -> GpuOutcome;
    /// The outcome of a finished steady measurement, through the one
    /// reduction every backend's results pass through.
    fn reduce(inst: &Instance, st: &Self::State, m: &Self::Measure) -> GpuOutcome;
    fn finished(inst: &Instance, st: &Self::State) -> bool;
    /// The CPU integrator's run for an unfinished shader state (and the
    /// accumulators of a steady measurement), where the CPU can continue
    /// from it (f64), or `None` where the CPU must start the instance over
    /// (f32: the slow tail is where f32 is least sure; the f64 reference
    /// starts it over).
    fn continuable(inst: &Instance, st: &Self::State, m: Option<&Self::Measure>) -> Option<Run>;
}

/// A steady outcome from the shader's state and accumulators converted to
/// the CPU's, in SI units.
fn reduce_shader(
    inst: &Instance,
    state: crate::cpu::integrate::State,
    measure: crate::cpu::integrate::Measure,
) -> GpuOutcome {
    let steps = state.steps;
    GpuOutcome::of(&reduce(inst, &Run { state, measure }), steps)
}

/// Whether any instance of a batch measures the steady step (its batch
/// then needs one set of accumulators per instance).
fn any_steady(instances: &[Instance]) -> bool {
    instances
        .iter()
        .any(|inst| matches!(inst.measure, Measure::Steady { .. }))
}

/// Every state of a batch and, for a batch with a steady instance, every
/// measurement, as read back from the device.
type Readback<L> = (Vec<<L as Layout>::State>, Vec<<L as Layout>::Measure>);

struct Single;
struct Double;

impl Layout for Single {
    const PRECISION: Precision = Precision::F32;
    type Coefficients = layout::single::Coefficients;
    type State = layout::single::State;
    type Measure = layout::single::Measure;
    type Head = layout::single::Head;
    fn head_suffices(h: &Self::Head) -> bool {
        h.suffices()
    }
    fn from_head(h: &Self::Head) -> Self::Measure {
        h.measure()
    }
    type Mirror = crate::cpu::single::integrate::State;
    fn mirror(st: &Self::State) -> Self::Mirror {
        layout::single::to_cpu(st)
    }
    fn pack(inst: &Instance, settings: &Settings) -> Self::Coefficients {
        layout::single::pack(inst, settings)
    }
    fn unpack(inst: &Instance, st: &Self::State) -> GpuOutcome {
        layout::single::unpack(inst, st)
    }
    fn reduce(inst: &Instance, st: &Self::State, m: &Self::Measure) -> GpuOutcome {
        reduce_shader(
            inst,
            layout::single::reduced_state(st),
            layout::single::measure_to_cpu(m),
        )
    }
    fn finished(inst: &Instance, st: &Self::State) -> bool {
        layout::single::finished(inst, st)
    }
    fn continuable(_: &Instance, _: &Self::State, _: Option<&Self::Measure>) -> Option<Run> {
        None
    }
}

impl Layout for Double {
    const PRECISION: Precision = Precision::F64;
    type Coefficients = layout::double::Coefficients;
    type State = layout::double::State;
    type Measure = layout::double::Measure;
    type Head = layout::double::Head;
    fn head_suffices(h: &Self::Head) -> bool {
        h.suffices()
    }
    fn from_head(h: &Self::Head) -> Self::Measure {
        h.measure()
    }
    type Mirror = crate::cpu::integrate::State;
    fn mirror(st: &Self::State) -> Self::Mirror {
        layout::double::to_cpu(st)
    }
    fn pack(inst: &Instance, settings: &Settings) -> Self::Coefficients {
        layout::double::pack(inst, settings)
    }
    fn unpack(inst: &Instance, st: &Self::State) -> GpuOutcome {
        layout::double::unpack(inst, st)
    }
    fn reduce(inst: &Instance, st: &Self::State, m: &Self::Measure) -> GpuOutcome {
        reduce_shader(
            inst,
            layout::double::to_cpu(st),
            layout::double::measure_to_cpu(m),
        )
    }
    fn finished(inst: &Instance, st: &Self::State) -> bool {
        layout::double::finished(inst, st)
    }
    fn continuable(inst: &Instance, st: &Self::State, m: Option<&Self::Measure>) -> Option<Run> {
        let c = crate::cpu::integrate::Coefficients::new(inst, &Settings::default(), f64::EPSILON);
        Some(Run {
            state: layout::double::to_cpu(st),
            measure: match m {
                Some(m) => layout::double::measure_to_cpu(m),
                None => initial_measure(&c),
            },
        })
    }
}

/// Largest number of instances one dispatch batch may hold on a device.
pub fn max_batch_instances(
    limits: &wgpu::Limits,
    coefficients_size: usize,
    state_size: usize,
    options: &BatchOptions,
) -> usize {
    let binding = limits.max_storage_buffer_binding_size;
    let buffer = limits.max_buffer_size;
    let largest = coefficients_size.max(state_size) as u64;
    let by_memory = binding.min(buffer) / largest;
    let dim = limits.max_compute_workgroups_per_dimension as u64;
    let by_dispatch = dim * dim * workgroup_size() as u64;
    let mut n = by_memory.min(by_dispatch).min(usize::MAX as u64) as usize;
    if let Some(m) = options.max_batch {
        n = n.min(m);
    }
    n.max(1)
}

/// Workgroup counts (x, y) covering `n` instances within the per-dimension
/// limit. The shader numbers invocations `x + y * groups_x * WORKGROUP_SIZE`
/// (the prelude's, [`workgroup_size`]).
pub fn dispatch_size(n: usize, max_per_dimension: u32) -> (u32, u32) {
    let groups = (n as u64).div_ceil(workgroup_size() as u64).max(1);
    let x = groups.min(max_per_dimension as u64);
    let y = groups.div_ceil(x);
    (x as u32, y as u32)
}

struct Runner<'a> {
    device: &'a wgpu::Device,
    queue: &'a wgpu::Queue,
    pipeline: &'a wgpu::ComputePipeline,
    limits: &'a wgpu::Limits,
    settings: &'a Settings,
    options: &'a BatchOptions,
}

impl Runner<'_> {
    /// Runs all instances, batch by batch.
    fn all<L: Layout>(
        &self,
        instances: &[Instance],
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<Vec<GpuOutcome>, GpuError> {
        let state_size = if any_steady(instances) {
            size_of::<L::State>().max(size_of::<L::Measure>())
        } else {
            size_of::<L::State>()
        };
        let per_batch = max_batch_instances(
            self.limits,
            size_of::<L::Coefficients>(),
            state_size,
            self.options,
        );
        let total = instances.len() as u64;
        let route = match L::PRECISION {
            Precision::F32 => self.options.check.route(true),
            Precision::F64 => None,
        };
        // Progress keeps a share for the check's work after the batches
        // (the twins, or the CPU's pass over the checked runs and the
        // fallbacks): the main runs count up to `main_share` of `total`,
        // that work the rest.
        let main_share = match route {
            Some(_) => {
                let checked = check::checked_count(instances.len()) as u64;
                total * total / (total + checked).max(1)
            }
            None => total,
        };
        let mut out = Vec::with_capacity(instances.len());
        for chunk in instances.chunks(per_batch) {
            let done_before = out.len() as u64;
            let mut chunk_progress =
                |done: u64| progress((done_before + done) * main_share / total.max(1), total);
            out.extend(self.batch::<L>(chunk, &mut chunk_progress)?);
        }
        // Instances the driver's loop limiter kept from advancing at all,
        // and f32 instances that failed or met a band graze, are
        // integrated on the CPU; f32's heaviest window runs are checked
        // (`backend::check`), on the CPU (the reference route) or by twins
        // on the device while the CPU integrates the others.
        let fallback: Vec<CpuJob> = out
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                o.status == STATUS_LOOP_LIMIT
                    || (L::PRECISION == Precision::F32 && f32_needs_f64(o.status))
            })
            .map(|(k, o)| CpuJob {
                index: k,
                shader_status: o.status,
                checked: false,
            })
            .collect();
        // Chosen among the runs the device finished itself, so the CPU's
        // work on the others cannot change which.
        let picked = match route {
            Some(_) => check::heaviest(&heaviest_candidates(instances, &out)),
            None => Vec::new(),
        };
        let checked_job = |k: usize| CpuJob {
            index: k,
            shader_status: 0,
            checked: true,
        };
        let cpu_outcomes = match route {
            Some(Route::Twins) => {
                let (fallback_outcomes, twins) = std::thread::scope(|scope| {
                    let cpu = scope.spawn(|| self.on_cpu_all(instances, &fallback));
                    let rest = total - main_share;
                    let n = (picked.len() as u64).max(1);
                    let mut twin_progress =
                        |done: u64| progress(main_share + done.min(n) * rest / n, total);
                    let twins =
                        self.twins::<L>(instances, &out, &picked, per_batch, &mut twin_progress);
                    (cpu.join().expect("the CPU's runs do not panic"), twins)
                });
                let disagree = twins?;
                for &k in &picked {
                    out[k].checked = true;
                }
                let jobs: Vec<CpuJob> = disagree.into_iter().map(checked_job).collect();
                let mut outcomes = fallback_outcomes;
                outcomes.extend(self.on_cpu_all(instances, &jobs));
                outcomes
            }
            Some(Route::Reference) => {
                let mut jobs = fallback;
                jobs.extend(picked.into_iter().map(checked_job));
                let rest = total - main_share;
                let n = (jobs.len() as u64).max(1);
                self.on_cpu_all_reporting(instances, &jobs, &mut |done| {
                    progress(main_share + done.min(n) * rest / n, total)
                })
            }
            None => self.on_cpu_all(instances, &fallback),
        };
        for (k, outcome) in cpu_outcomes {
            out[k] = outcome;
        }
        progress(total, total);
        Ok(out)
    }

    /// The CPU's f64 runs of `jobs`, in parallel: (index, outcome) each.
    fn on_cpu_all(&self, instances: &[Instance], jobs: &[CpuJob]) -> Vec<(usize, GpuOutcome)> {
        self.on_cpu_counted(instances, jobs, &AtomicU64::new(0))
    }

    /// [`Self::on_cpu_all`], counting finished jobs in `done`.
    fn on_cpu_counted(
        &self,
        instances: &[Instance],
        jobs: &[CpuJob],
        done: &AtomicU64,
    ) -> Vec<(usize, GpuOutcome)> {
        jobs.par_iter()
            .with_max_len(1)
            .map(|job| {
                let outcome = GpuOutcome {
                    cpu_fallback: true,
                    shader_status: job.shader_status,
                    checked: job.checked,
                    ..on_cpu(&instances[job.index], self.settings, None)
                };
                done.fetch_add(1, Ordering::Relaxed);
                (job.index, outcome)
            })
            .collect()
    }

    /// [`Self::on_cpu_all`] on another thread, with `progress(done jobs)`
    /// called from this one every [`CPU_PASS_REPORT`] while it runs (the
    /// reference route's pass can take as long as the batches on a
    /// software adapter).
    fn on_cpu_all_reporting(
        &self,
        instances: &[Instance],
        jobs: &[CpuJob],
        progress: &mut dyn FnMut(u64),
    ) -> Vec<(usize, GpuOutcome)> {
        let done = AtomicU64::new(0);
        let caller = std::thread::current();
        std::thread::scope(|scope| {
            let pass = scope.spawn(|| {
                let outcomes = self.on_cpu_counted(instances, jobs, &done);
                caller.unpark();
                outcomes
            });
            while !pass.is_finished() {
                progress(done.load(Ordering::Relaxed));
                std::thread::park_timeout(CPU_PASS_REPORT);
            }
            progress(done.load(Ordering::Relaxed));
            pass.join().expect("the CPU's runs do not panic")
        })
    }

    /// The twins of f32's `picked` runs ([`crate::backend::check`]),
    /// nudged and at the looser tolerance, in batches of at most `per_batch`, each to its end
    /// on the device (no slow tail); returns the runs whose twin
    /// disagrees, or did not finish on the device with the run's status.
    /// `progress(done)` counts finished twins.
    fn twins<L: Layout>(
        &self,
        instances: &[Instance],
        out: &[GpuOutcome],
        picked: &[usize],
        per_batch: usize,
        progress: &mut dyn FnMut(u64),
    ) -> Result<Vec<usize>, GpuError> {
        let twin_settings = check::twin_settings(self.settings);
        let twin_options = BatchOptions {
            cpu_tail: Some(0),
            ..*self.options
        };
        let twin_runner = Runner {
            settings: &twin_settings,
            options: &twin_options,
            ..*self
        };
        let twin_instances: Vec<Instance> = picked
            .iter()
            .map(|&k| check::twin_instance(&instances[k]))
            .collect();
        let mut twins = Vec::with_capacity(picked.len());
        for chunk in twin_instances.chunks(per_batch.max(1)) {
            let done_before = twins.len() as u64;
            twins.extend(twin_runner.batch::<L>(chunk, &mut |done| progress(done_before + done))?);
        }
        Ok(picked
            .iter()
            .zip(&twins)
            .filter(|&(&k, twin)| {
                let run = &out[k];
                let agree = twin.status == run.status
                    && !twin.cpu_fallback
                    && !twin.finished_on_cpu
                    && check::twins_agree(
                        &instances[k],
                        (run.displacement, run.span),
                        (twin.displacement, twin.span),
                    );
                !agree
            })
            .map(|(&k, _)| k)
            .collect())
    }

    /// Runs one batch that fits the device in one dispatch.
    fn batch<L: Layout>(
        &self,
        instances: &[Instance],
        progress: &mut dyn FnMut(u64),
    ) -> Result<Vec<GpuOutcome>, GpuError> {
        let n = instances.len();
        if n == 0 {
            return Ok(Vec::new());
        }
        let device = self.device;
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let result = self.batch_inner::<L>(instances, progress);
        let memory_error = pollster::block_on(memory.pop());
        let validation_error = pollster::block_on(validation.pop());
        if let Some(e) = validation_error.or(memory_error) {
            return Err(GpuError::Execution(e.to_string()));
        }
        result
    }

    /// Dispatches slices until the batch is done, or only its slow tail is
    /// left, or `slice_limit` slices have run; returns every state and,
    /// for a batch with a steady instance, every measurement.
    fn slices<L: Layout>(
        &self,
        instances: &[Instance],
        progress: &mut dyn FnMut(u64),
        slice_limit: Option<u64>,
    ) -> Result<Readback<L>, GpuError> {
        let device = self.device;
        let queue = self.queue;
        let n = instances.len();
        let preparing = std::time::Instant::now();
        let coefficients: Vec<L::Coefficients> = instances
            .par_iter()
            .map(|inst| L::pack(inst, self.settings))
            .collect();
        let coefficients_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("coefficients"),
            contents: bytemuck::cast_slice(&coefficients),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let state_bytes = (n * size_of::<L::State>()) as u64;
        let states = storage(device, "states", state_bytes);
        let states_read = readback::mappable(device, "states readback", state_bytes);
        // The steady measurement's accumulators: one per instance where
        // any instance is steady, else one unused entry (windows never
        // touch them).
        let steady = any_steady(instances);
        let measure_bytes = (size_of::<L::Measure>() * if steady { n } else { 1 }) as u64;
        let measures = storage(device, "measures", measure_bytes);
        let head_bytes = (size_of::<L::Head>() * if steady { n } else { 1 }) as u64;
        let heads = storage(device, "heads", head_bytes);
        let heads_read = readback::mappable(device, "heads readback", head_bytes);
        // Lane k starts on instance k; the counters say which instance is
        // next and how many finished.
        let lane_count = n.min(self.options.lanes.max(1));
        let lane_indices: Vec<u32> = (0..lane_count as u32).collect();
        let lanes_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("lanes"),
            contents: bytemuck::cast_slice(&lane_indices),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let counters = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("counters"),
            contents: bytemuck::cast_slice(&[lane_count as u32, 0u32]),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let counters_read = readback::mappable(device, "counters readback", 8);
        // Two controls: the first dispatch initialises the states.
        let control = |initialize: u32| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("control"),
                contents: bytemuck::bytes_of(&Control {
                    max_iterations: self.options.slice_iterations,
                    initialize,
                    one: 1.0,
                    probe: self.options.probe_passes.max(layout::PROBE_PASSES),
                    probe_min: self.options.probe_passes.max(layout::PROBE_PASSES),
                    zero: 0,
                }),
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let controls = [control(1), control(0)];
        let layout = self.pipeline.get_bind_group_layout(0);
        let bind_groups: Vec<wgpu::BindGroup> = controls
            .iter()
            .map(|c| {
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("integrate"),
                    layout: &layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: coefficients_buffer.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: states.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: c.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: counters.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: lanes_buffer.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 5,
                            resource: measures.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 6,
                            resource: heads.as_entire_binding(),
                        },
                    ],
                })
            })
            .collect();
        let (gx, gy) = dispatch_size(lane_count, self.limits.max_compute_workgroups_per_dimension);
        // A lane works through its instances one after another.
        let rounds = n.div_ceil(lane_count) as u64;
        let max_slices = slice_bound(instances, self.settings).saturating_mul(rounds);
        let tail_size =
            self.options
                .tail_size(L::PRECISION, n, rayon::current_num_threads()) as u64;
        let mut slice: u64 = 0;
        let prepared = preparing.elapsed();
        let dispatching = std::time::Instant::now();
        loop {
            let mut encoder = device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(self.pipeline);
                pass.set_bind_group(0, &bind_groups[usize::from(slice > 0)], &[]);
                pass.dispatch_workgroups(gx, gy, 1);
            }
            encoder.copy_buffer_to_buffer(&counters, 0, &counters_read, 0, 8);
            queue.submit([encoder.finish()]);
            let bytes = readback::read_buffer(device, &counters_read)?;
            let next = u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]) as u64;
            let finished = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) as u64;
            let unfinished = (n as u64).saturating_sub(finished) as u32;
            slice += 1;
            progress(finished.min(n as u64));
            // Every instance started, and only the slow tail is left.
            if unfinished == 0 || (next >= n as u64 && (unfinished as u64) <= tail_size) {
                break;
            }
            if slice_limit.is_some_and(|limit| slice >= limit) {
                break;
            }
            if crate::sweep::interrupt_requested() {
                return Err(GpuError::Interrupted);
            }
            if slice >= max_slices {
                return Err(GpuError::Stalled {
                    unfinished,
                    slices: slice,
                });
            }
        }
        let dispatched = dispatching.elapsed();
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&states, 0, &states_read, 0, state_bytes);
        if steady {
            encoder.copy_buffer_to_buffer(&heads, 0, &heads_read, 0, head_bytes);
        }
        queue.submit([encoder.finish()]);
        let mut states_timed = readback::Mapped::default();
        let states: Vec<L::State> =
            readback::with_mapped_timed(device, &states_read, &mut states_timed, |bytes| {
                match bytemuck::try_cast_slice(bytes) {
                    Ok(states) => states.to_vec(),
                    // A mapping not aligned for the struct (no driver seen).
                    Err(_) => bytes
                        .chunks_exact(size_of::<L::State>())
                        .map(bytemuck::pod_read_unaligned)
                        .collect(),
                }
            })?;
        let mut read = readback::AccumulatorsRead::default();
        let measure_list: Vec<L::Measure> = if steady {
            readback::accumulators::<L>(
                device,
                queue,
                self.options.whole_accumulators,
                instances,
                &states,
                (&heads_read, &measures),
                &mut read,
            )?
        } else {
            Vec::new()
        };
        if gpu_phases() {
            let mb = |bytes: u64| bytes as f64 / 1e6;
            eprintln!(
                "pidm: GPU batch of {n}: coefficients packed and buffers made in {:.3} s; \
                 {slice} dispatches in {:.3} s; states {:.1} MB mapped in {:.3} s and read in \
                 {:.3} s; heads {:.1} MB read in {:.3} s; accumulators ({:?}, {} of them) {:.1} \
                 MB mapped in {:.3} s and read in {:.3} s",
                prepared.as_secs_f64(),
                dispatched.as_secs_f64(),
                mb(state_bytes),
                states_timed.wait.as_secs_f64(),
                states_timed.read.as_secs_f64(),
                if steady { mb(head_bytes) } else { 0.0 },
                read.heads.wait.as_secs_f64() + read.heads.read.as_secs_f64(),
                read.plan,
                read.count,
                mb((read.count * size_of::<L::Measure>()) as u64),
                read.whole.wait.as_secs_f64(),
                read.whole.read.as_secs_f64(),
            );
        }
        Ok((states, measure_list))
    }

    fn batch_inner<L: Layout>(
        &self,
        instances: &[Instance],
        progress: &mut dyn FnMut(u64),
    ) -> Result<Vec<GpuOutcome>, GpuError> {
        let n = instances.len();
        let slicing = std::time::Instant::now();
        let (states, measure_list) = self.slices::<L>(instances, progress, None)?;
        let sliced = slicing.elapsed();
        let reducing = std::time::Instant::now();
        let is_steady = |k: usize| matches!(instances[k].measure, Measure::Steady { .. });
        // The outcomes, and the states of the unfinished ones.
        let (mut out, tail) = {
            let out: Vec<GpuOutcome> = (0..n)
                .into_par_iter()
                .map(|k| {
                    if is_steady(k) {
                        L::reduce(&instances[k], &states[k], &measure_list[k])
                    } else {
                        L::unpack(&instances[k], &states[k])
                    }
                })
                .collect();
            let tail: Vec<(usize, L::State)> = (0..n)
                .into_par_iter()
                .filter(|&k| !L::finished(&instances[k], &states[k]))
                .map(|k| (k, states[k]))
                .collect();
            (out, tail)
        };
        if gpu_phases() {
            eprintln!(
                "pidm: GPU batch of {n}: {:.3} s from packing to freeing the buffers; outcomes \
                 in {:.3} s, {} left to the CPU",
                sliced.as_secs_f64(),
                reducing.elapsed().as_secs_f64(),
                tail.len()
            );
        }
        // The slow tail, if the GPU stopped before it: on the CPU, in
        // parallel, from where the GPU left it (f64) or from the start
        // (f32).
        let tail_outcomes: Vec<GpuOutcome> = tail
            .par_iter()
            .with_max_len(1)
            .map(|(k, st)| {
                let m = is_steady(*k).then(|| &measure_list[*k]);
                GpuOutcome {
                    finished_on_cpu: true,
                    ..on_cpu(
                        &instances[*k],
                        self.settings,
                        L::continuable(&instances[*k], st, m),
                    )
                }
            })
            .collect();
        for ((k, _), outcome) in tail.iter().zip(tail_outcomes) {
            out[*k] = outcome;
        }
        progress(n as u64);
        Ok(out)
    }
}

/// A storage buffer of `size` bytes that results can be copied out of.
fn storage(device: &wgpu::Device, label: &str, size: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// An upper bound on the slices one instance can need. Every iteration of
/// `advance` either takes a counted step (bounded by the step budget) or
/// passes drive corners and period ends (bounded by the drive cycles), and
/// every slice completes at least one iteration of the instance each lane
/// holds (the loop-limiter rollback may leave it at one) or finishes it
/// with [`STATUS_LOOP_LIMIT`]; a lane holds its instances one after
/// another.
fn slice_bound(instances: &[Instance], settings: &Settings) -> u64 {
    let mut most: u64 = 0;
    for inst in instances {
        let budget = settings.max_steps_per_period as u64 * inst.cycles as u64;
        let mut boundaries = inst.cycles as u64 + 1;
        for axis in &inst.axes {
            let cycles = (axis.frequency * inst.period() * inst.cycles as f64).ceil();
            boundaries += 2 * (cycles.max(0.0) as u64 + 1);
        }
        most = most.max(budget + boundaries + 2);
    }
    most + 2
}

/// An instance the CPU integrates in f64 after the device's batches: why
/// ([`GpuOutcome::shader_status`], [`GpuOutcome::checked`]).
struct CpuJob {
    index: usize,
    shader_status: u32,
    checked: bool,
}

/// f32 window runs the device finished itself with status ok, as (index,
/// steps): those [`check::heaviest`] chooses from.
fn heaviest_candidates(instances: &[Instance], out: &[GpuOutcome]) -> Vec<(usize, u32)> {
    out.iter()
        .zip(instances)
        .enumerate()
        .filter(|(_, (o, inst))| {
            check::is_candidate(inst, o.status, o.cpu_fallback || o.finished_on_cpu)
        })
        .map(|(k, (o, _))| (k, o.steps))
        .collect()
}

/// One instance integrated on the CPU, which the shader mirrors, as a GPU
/// outcome (the caller marks why it ran there): from its start, or from a
/// run the f64 shader left unfinished.
fn on_cpu(inst: &Instance, settings: &Settings, from: Option<Run>) -> GpuOutcome {
    let run = match from {
        Some(run) => crate::cpu::integrate::continue_instance_until(inst, settings, run, || false)
            .expect("never asked to stop"),
        None => run_instance(inst, settings),
    };
    GpuOutcome::of(&reduce(inst, &run), run.state.steps)
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
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default tail is 1 % of a large f64 batch and nothing in f32,
    /// whose results would then depend on how a map is split into batches.
    #[test]
    fn only_large_f64_batches_hand_their_tail_to_the_cpu() {
        let default = BatchOptions::default();
        // (options, precision, batch, CPU threads, tail).
        let check = |options: &BatchOptions, precision, n, threads, expected| {
            assert_eq!(
                options.tail_size(precision, n, threads),
                expected,
                "{precision:?} {n} on {threads} threads"
            );
        };
        check(&default, Precision::F64, 999, 16, 0);
        // A quarter of the batch at most.
        check(&default, Precision::F64, 1000, 16, 250);
        // 16 per thread.
        check(&default, Precision::F64, 4096, 16, 256);
        check(&default, Precision::F64, 4096, 2, 40);
        // 1 % of a large batch.
        check(&default, Precision::F64, 250_000, 16, 2500);
        // f32 the same way (issue 19): its instances restart on the CPU.
        check(&default, Precision::F32, 250_000, 16, 2500);
        check(&default, Precision::F32, 999, 16, 0);
        let explicit = BatchOptions {
            cpu_tail: Some(3),
            ..default
        };
        check(&explicit, Precision::F32, 10, 16, 3);
        check(&explicit, Precision::F64, 10, 16, 3);
    }

    #[test]
    fn dispatch_covers_every_instance_within_the_limit() {
        let wg = workgroup_size() as usize;
        let cases = [
            (1, 65535),
            (wg, 65535),
            (wg + 1, 65535),
            (9 * wg, 3),
            (9 * wg - 1, 3),
            (49 * wg, 7),
        ];
        for (n, max) in cases {
            let (x, y) = dispatch_size(n, max);
            assert!(
                x <= max && y <= max,
                "{n} instances, limit {max}: {x} x {y}"
            );
            assert!((x as usize) * (y as usize) * workgroup_size() as usize >= n);
        }
    }

    #[test]
    fn batches_respect_binding_limits() {
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: 1000,
            ..wgpu::Limits::default()
        };
        assert_eq!(
            max_batch_instances(&limits, 100, 200, &BatchOptions::default()),
            5
        );
        let small = BatchOptions {
            max_batch: Some(3),
            ..BatchOptions::default()
        };
        assert_eq!(max_batch_instances(&limits, 100, 200, &small), 3);
    }
}
