//! A batch of LuGre instances on the device, dispatch by dispatch (the
//! lanes measure their period ends themselves; the host reads two
//! counters after each), and the batch's slow tail on the CPU.

use super::buffers::Recurrence;
use super::{
    Arithmetic, ENTRY_POINT, HARDWARE_ATTEMPTS, HARDWARE_WORKGROUP_SIZE, LANE_STOPPED, Lane,
    Params, SOFTWARE_ATTEMPTS, SOFTWARE_WORKGROUP_SIZE, parse_and_validate, source,
};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use rayon::prelude::*;
use wgpu::util::DeviceExt;

use crate::gpu::layout::double::{Coefficients, Measure as GpuMeasure, packed};
use crate::gpu::readback::{mappable, read_buffer};
use crate::gpu::{GpuContext, GpuError, Precision};
use crate::laws::karnopp::integrate::{Run, Settings};
use crate::laws::lugre::run::{Kept, Periods, continue_until};
use crate::model::Instance;
use crate::profile::{self, Phase};

/// What a batch cost.
#[derive(Clone, Debug, Default)]
pub struct BatchReport {
    /// The instances (indices into the call's) the CPU finished: the
    /// slow tail of their batch ([`LugreGpu::cpu_tail`]).
    pub on_cpu: Vec<usize>,
    /// Dispatches (each followed by a readback of the counters).
    pub dispatches: u64,
    /// Scene periods the lanes measured on the device.
    pub periods: u64,
    /// Seconds of the whole batch, and of the dispatches with their
    /// readbacks.
    pub seconds: f64,
    pub gpu_seconds: f64,
}

/// The LuGre pipeline on one device.
pub struct LugreGpu<'a> {
    pub(super) ctx: &'a GpuContext,
    pub(super) pipeline: wgpu::ComputePipeline,
    pub(super) workgroup_size: u32,
    pub(super) arithmetic: Arithmetic,
    /// Step attempts per lane and dispatch.
    pub attempts: u32,
    /// The running instances a batch hands over to the CPU once no more
    /// are left (`crate::gpu::tail_size`, the Karnopp batches' rule: by
    /// default 1 % of a batch of at least 1,000, or 16 per thread,
    /// whichever is more, at most a quarter; `Some(0)`: none). The CPU
    /// continues each from the start of its current scene period, which
    /// its lane keeps with its measurement, so on llvmpipe, whose
    /// arithmetic the CPU's mirrors, the results are the same bits.
    pub cpu_tail: Option<usize>,
}

/// Compiles one entry point of the shader on `device` (runtime checks off:
/// every loop is bounded, every index below its array's length).
pub(super) fn compile(
    device: &wgpu::Device,
    workgroup_size: u32,
    arithmetic: Arithmetic,
    entry: &str,
    cache: Option<&wgpu::PipelineCache>,
) -> Result<wgpu::ComputePipeline, GpuError> {
    parse_and_validate(workgroup_size, arithmetic)?;
    let src = source(workgroup_size, arithmetic);
    // SAFETY: every loop of the shader is bounded by a constant or by
    // `control.attempts`; every index is a constant, a loop counter below
    // its array's length, a pivot (below R) or an instance below both
    // storage arrays' lengths.
    unsafe {
        crate::gpu::context::compile_trusted(
            device,
            src,
            ("shaders/lugre", entry),
            Precision::F64,
            cache,
        )
    }
}

/// A batch's buffers on the device.
pub(super) struct Batch<'g> {
    gpu: &'g LugreGpu<'g>,
    lanes: wgpu::Buffer,
    measures: wgpu::Buffer,
    recurrences: wgpu::Buffer,
    counters: wgpu::Buffer,
    counters_read: wgpu::Buffer,
    group: wgpu::BindGroup,
    groups: (u32, u32),
    // Kept alive with the bind group.
    _buffers: [wgpu::Buffer; 3],
}

/// What the device counts over a batch (`entry.wgsl`'s `Counters`): the
/// lanes stopped, and the lane dispatches that advanced a run.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(super) struct Counters {
    pub(super) stopped: u32,
    pub(super) advanced: u32,
}

impl<'g> Batch<'g> {
    /// The buffers of `books`' runs: their parameters, coefficients and
    /// lanes, and room for their accumulators and recurrence snapshots.
    pub(super) fn new(gpu: &'g LugreGpu<'g>, books: &[Periods], attempts: u32) -> Batch<'g> {
        let device = gpu.ctx.device();
        let n = books.len() as u64;
        let params: Vec<Params> = books.iter().map(Params::of).collect();
        let lanes: Vec<Lane> = books.iter().map(Lane::start).collect();
        let coefficients: Vec<Coefficients> =
            books.iter().map(|b| packed(b.coefficients())).collect();
        let init = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | usage,
            })
        };
        let copied = wgpu::BufferUsages::COPY_SRC;
        let models = init("lugre models", bytemuck::cast_slice(&params), copied);
        let lane_buffer = init("lugre lanes", bytemuck::cast_slice(&lanes), copied);
        let coefficients = init(
            "lugre coefficients",
            bytemuck::cast_slice(&coefficients),
            copied,
        );
        let control = init(
            "lugre control",
            bytemuck::cast_slice(&[attempts, 0, 0, 0]),
            copied,
        );
        let counters = init("lugre counters", &[0; size_of::<Counters>()], copied);
        let zeroed = |label: &str, size: usize| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: n * size as u64,
                usage: wgpu::BufferUsages::STORAGE | copied,
                mapped_at_creation: false,
            })
        };
        let measures = zeroed("lugre measures", size_of::<GpuMeasure>());
        let recurrences = zeroed("lugre recurrences", size_of::<Recurrence>());
        let bound = [
            (0, &models),
            (1, &lane_buffer),
            (2, &control),
            (6, &coefficients),
            (7, &measures),
            (8, &recurrences),
            (9, &counters),
        ];
        let entries: Vec<wgpu::BindGroupEntry> = bound
            .iter()
            .map(|(binding, buffer)| wgpu::BindGroupEntry {
                binding: *binding,
                resource: buffer.as_entire_binding(),
            })
            .collect();
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("lugre"),
            layout: &gpu.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let groups = crate::gpu::workgroups(
            books.len(),
            gpu.workgroup_size,
            gpu.ctx.limits().max_compute_workgroups_per_dimension,
        );
        Batch {
            gpu,
            lanes: lane_buffer,
            measures,
            recurrences,
            counters_read: mappable(device, "lugre counters read", counters.size()),
            counters,
            group,
            groups,
            _buffers: [models, coefficients, control],
        }
    }

    /// One dispatch, and the counters after it.
    pub(super) fn dispatch(&mut self) -> Result<Counters, GpuError> {
        let (device, queue) = (self.gpu.ctx.device(), self.gpu.ctx.queue());
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.gpu.pipeline);
            pass.set_bind_group(0, &self.group, &[]);
            pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
        }
        let size = self.counters.size();
        encoder.copy_buffer_to_buffer(&self.counters, 0, &self.counters_read, 0, size);
        queue.submit([encoder.finish()]);
        let bytes = read_buffer(device, &self.counters_read)?;
        Ok(bytemuck::pod_read_unaligned(&bytes))
    }

    /// The lanes as they are on the device.
    pub(super) fn lanes(&self) -> Result<Vec<Lane>, GpuError> {
        self.read_all(&self.lanes)
    }

    /// Every lane's run as the device keeps it (`Lane::kept`).
    pub(super) fn kept(&self) -> Result<Vec<(Lane, Kept)>, GpuError> {
        let lanes = self.lanes()?;
        let measures: Vec<GpuMeasure> = self.read_all(&self.measures)?;
        let recurrences: Vec<Recurrence> = self.read_all(&self.recurrences)?;
        Ok(lanes
            .into_iter()
            .zip(measures.iter().zip(&recurrences))
            .map(|(lane, (m, r))| (lane, lane.kept(m, r)))
            .collect())
    }

    /// A storage buffer's structs, copied back.
    fn read_all<T: Pod>(&self, buffer: &wgpu::Buffer) -> Result<Vec<T>, GpuError> {
        let device = self.gpu.ctx.device();
        let read = mappable(device, "lugre read", buffer.size());
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &read, 0, buffer.size());
        self.gpu.ctx.queue().submit([encoder.finish()]);
        let bytes = read_buffer(device, &read)?;
        profile::add_bytes_read(bytes.len() as u64);
        Ok(bytes
            .chunks_exact(size_of::<T>())
            .map(bytemuck::pod_read_unaligned)
            .collect())
    }
}

impl<'a> LugreGpu<'a> {
    /// Compiles the integrator on `ctx`, which must offer f64: the
    /// variant of its kind of adapter.
    pub fn new(ctx: &'a GpuContext) -> Result<LugreGpu<'a>, GpuError> {
        LugreGpu::variant(ctx, ctx.is_hardware())
    }

    /// The variant a hardware adapter gets (its workgroup size, the fused
    /// arithmetic and every period end a lane reaches measured in the same
    /// dispatch), on any f64 adapter: on a software one (llvmpipe) with its
    /// software attempts per dispatch, so that the tests run the hardware's
    /// shader there too. Its period ends are not counted against llvmpipe's
    /// loop limit: a window's have no loops, but many steady ones in one
    /// dispatch could reach it, so on a software adapter it is for tests.
    pub fn hardware_variant(ctx: &'a GpuContext) -> Result<LugreGpu<'a>, GpuError> {
        let mut gpu = LugreGpu::variant(ctx, true)?;
        if !ctx.is_hardware() {
            gpu.attempts = SOFTWARE_ATTEMPTS;
        }
        Ok(gpu)
    }

    /// The variant for a hardware adapter (`hardware`) or a software one.
    fn variant(ctx: &'a GpuContext, hardware: bool) -> Result<LugreGpu<'a>, GpuError> {
        if !ctx.supports_f64() {
            return Err(GpuError::F64Unsupported {
                adapter: ctx.describe(),
            });
        }
        let (workgroup_size, attempts, arithmetic, name) = if hardware {
            let name = "lugre (hardware)";
            (
                HARDWARE_WORKGROUP_SIZE,
                HARDWARE_ATTEMPTS,
                Arithmetic::Fused,
                name,
            )
        } else {
            let name = "lugre (software)";
            (
                SOFTWARE_WORKGROUP_SIZE,
                SOFTWARE_ATTEMPTS,
                Arithmetic::Native,
                name,
            )
        };
        // One compile per context and variant: every batch of a run takes
        // the same pipeline (the driver's cache on disk spares later runs
        // it too).
        let pipeline = ctx.law_pipeline(name, |cache| {
            compile(ctx.device(), workgroup_size, arithmetic, ENTRY_POINT, cache)
        })?;
        Ok(LugreGpu {
            ctx,
            pipeline,
            workgroup_size,
            arithmetic,
            attempts,
            cpu_tail: crate::gpu::cpu_tail().0,
        })
    }

    /// Integrates LuGre `instances` to the ends of their measurements: an
    /// `integrate::Run` each, as `laws::lugre::run_instance_until` gives.
    ///
    /// # Panics
    /// If an instance's friction is not LuGre's.
    pub fn run(
        &self,
        instances: &[Instance],
        settings: &Settings,
    ) -> Result<(Vec<Run>, BatchReport), GpuError> {
        self.run_until(instances, settings, || false, &|_| {})
    }

    /// [`LugreGpu::run`], asking `stop` between dispatches and between
    /// the CPU tail's periods ([`GpuError::Interrupted`] when it says yes)
    /// and telling `done` how many instances finished (for a progress
    /// bar).
    pub fn run_until(
        &self,
        instances: &[Instance],
        settings: &Settings,
        stop: impl Fn() -> bool + Sync,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<(Vec<Run>, BatchReport), GpuError> {
        let started = Instant::now();
        let mut report = BatchReport::default();
        let mut runs = Vec::with_capacity(instances.len());
        for chunk in instances.chunks(self.max_batch()) {
            let (offset, tail) = (runs.len(), report.on_cpu.len());
            runs.extend(self.run_batch(chunk, settings, (&stop, done), &mut report)?);
            report.on_cpu[tail..].iter_mut().for_each(|k| *k += offset);
        }
        report.seconds = started.elapsed().as_secs_f64();
        Ok((runs, report))
    }

    /// The most instances one batch takes: what the device's storage
    /// bindings, buffers and dispatches hold.
    pub(super) fn max_batch(&self) -> usize {
        let largest = [
            size_of::<Params>(),
            size_of::<Lane>(),
            size_of::<Coefficients>(),
            size_of::<GpuMeasure>(),
            size_of::<Recurrence>(),
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        crate::gpu::batch_limit(self.ctx.limits(), largest, self.workgroup_size)
    }

    /// One batch of [`LugreGpu::run_until`], counted in `report`.
    pub(super) fn run_batch(
        &self,
        instances: &[Instance],
        settings: &Settings,
        (stop, done): (&(impl Fn() -> bool + Sync), &(dyn Fn(u64) + Sync)),
        report: &mut BatchReport,
    ) -> Result<Vec<Run>, GpuError> {
        let mut books: Vec<Periods> = instances
            .iter()
            .map(|inst| Periods::new(inst, settings))
            .collect();
        if books.is_empty() {
            return Ok(Vec::new());
        }
        let n = books.len();
        let tail = crate::gpu::tail_size(self.cpu_tail, n, rayon::current_num_threads());
        let mut batch = profile::time(Phase::Upload, || Batch::new(self, &books, self.attempts));
        let dispatches_before = report.dispatches;
        let (mut finished, mut advanced, mut slots) = (0, 0, 0);
        // Every lane starts its run at once (there is no queue): once no
        // more than the tail's size are going, the CPU takes them.
        while finished < n && (report.dispatches == dispatches_before || n - finished > tail) {
            if stop() {
                return Err(GpuError::Interrupted);
            }
            let t = Instant::now();
            let counters = profile::time(Phase::Dispatch, || batch.dispatch())?;
            let took = t.elapsed();
            let running = n - finished;
            report.dispatches += 1;
            report.gpu_seconds += took.as_secs_f64();
            profile::add_lanes(n as u64, running as u64, took);
            profile::add_bytes_read(size_of::<Counters>() as u64);
            slots += running as u64 * self.attempts as u64;
            if counters.advanced == advanced {
                return Err(GpuError::Stalled {
                    unfinished: running as u32,
                    slices: report.dispatches,
                });
            }
            advanced = counters.advanced;
            let now = counters.stopped as usize;
            if now > finished {
                done((now - finished) as u64);
                finished = now;
            }
        }
        let kept = profile::time(Phase::Readback, || batch.kept())?;
        for (book, (_, kept)) in books.iter_mut().zip(&kept) {
            book.resume(kept);
        }
        let lanes: Vec<Lane> = kept.into_iter().map(|(lane, _)| lane).collect();
        if finished < n {
            report
                .on_cpu
                .extend(cpu_tail(&mut books, &lanes, (stop, done))?);
        }
        let periods: u64 = lanes.iter().map(|l| l.period as u64).sum();
        report.periods += periods;
        record([
            n as u64,
            report.dispatches - dispatches_before,
            slots,
            lanes.iter().map(|l| l.steps as u64).sum(),
            periods,
        ]);
        Ok(books.into_iter().map(|b| b.run).collect())
    }
}

/// A batch's slow tail on the CPU: every run its lane still has going,
/// continued from the start of its current period (each `book` resumed
/// where the device kept it), in parallel. Returns their indices in the
/// batch.
fn cpu_tail(
    books: &mut [Periods],
    lanes: &[Lane],
    (stop, done): (&(impl Fn() -> bool + Sync), &(dyn Fn(u64) + Sync)),
) -> Result<Vec<usize>, GpuError> {
    let _cpu = profile::span(Phase::CpuPart);
    let going: Vec<usize> = (0..lanes.len())
        .filter(|&k| lanes[k].flag != LANE_STOPPED)
        .collect();
    let ended = books
        .par_iter_mut()
        .zip(lanes)
        .filter(|(_, lane)| lane.flag != LANE_STOPPED)
        .map(|(book, lane)| {
            let ended = continue_until(book, lane.period_start(), stop);
            if ended {
                done(1);
            }
            ended
        })
        .collect::<Vec<bool>>();
    match ended.iter().all(|&e| e) {
        true => Ok(going),
        false => Err(GpuError::Interrupted),
    }
}

/// The run's LuGre batches so far, for the phase table ([`table_lines`]):
/// instances, dispatches, the attempt slots of the lanes running at each
/// dispatch's start and the attempts they made (their `steps`), and the
/// period ends the lanes measured.
static TOTALS: [AtomicU64; 5] = [const { AtomicU64::new(0) }; 5];

/// Adds a batch's figures (in [`TOTALS`]' order) to the run's, inside
/// the integrator's work only (not a self-test's).
fn record(figures: [u64; 5]) {
    if profile::integrating() {
        for (total, n) in TOTALS.iter().zip(figures) {
            total.fetch_add(n, Ordering::Relaxed);
        }
    }
}

/// The phase table's line of the run's LuGre batches: how many dispatches
/// (each a round trip for two counters), how many period ends the lanes
/// measured on the device, and what share of the running lanes' attempt
/// slots held a Rodas4 step attempt (the rest: lanes done with their runs
/// within the dispatch, or, on a software adapter, waiting at a second
/// period end for the next dispatch); empty where no LuGre batch ran on a
/// GPU.
pub fn table_lines() -> String {
    let [instances, dispatches, slots, attempts, periods] =
        TOTALS.each_ref().map(|t| t.load(Ordering::Relaxed));
    if instances == 0 {
        return String::new();
    }
    format!(
        "pidm: phase LuGre on the GPU: {instances} instances, {dispatches} dispatches \
         (each a round trip for two counters), {periods} period ends measured on the \
         device; {attempts} Rodas4 step attempts filled {:.1} % of the running lanes' slots\n",
        100.0 * attempts as f64 / slots.max(1) as f64
    )
}
