//! LuGre's lanes for the engine ([`Lugre`]), and a batch of LuGre
//! instances through it: the host sets up each run, the engine's queue
//! runs them (the lanes measure their period ends themselves), the host
//! resumes each run from what its lane kept, and the CPU continues the
//! batch's slow tail from the runs' period starts.

use super::layout::{Recurrence, STAGE_BYTES, StageMatrix};
use super::{
    Arithmetic, ENTRY_POINT, Form, HARDWARE_ATTEMPTS, HARDWARE_WORKGROUP_SIZE, LANE_STOPPED, Lane,
    Params, SOFTWARE_ATTEMPTS, SOFTWARE_BACKWARD_ATTEMPTS, SOFTWARE_LANES, SOFTWARE_WORKGROUP_SIZE,
    parse_and_validate, source,
};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use bytemuck::Zeroable;
use rayon::prelude::*;
use wgpu::util::DeviceExt;

use super::layout::{Coefficients, corner_buffer};

/// The binding of a waveform variant's corners (`corners.wgsl`).
pub(super) const CORNER_BINDING: u32 = 16;
use crate::gpu::lanes::{Kernel, Lanes, Work};
use crate::gpu::layout::double::{Head, Measure as GpuMeasure};
use crate::gpu::readback::{mappable, read_buffer};
use crate::gpu::runner::{Runner, storage};
use crate::gpu::{BatchOptions, GpuContext, GpuError, Precision};
use crate::laws::Run;
use crate::laws::Settings;
use crate::laws::floor::variation::Variation;
use crate::laws::lugre::run::{Periods, continue_until};
use crate::model::{Instance, Measure};
use crate::profile::{self, Phase};

/// A run and, where the batch measures the backward travel
/// (`Settings::backward`), its variation: what `laws::lugre::run`'s
/// `run_with_variation_until` gives.
pub type Followed = (Run, Option<Variation>);

/// What a batch cost.
#[derive(Clone, Debug, Default)]
pub struct BatchReport {
    /// The instances (indices into the call's) the CPU finished: the
    /// slow tail of their batch ([`LugreGpu::cpu_tail`]).
    pub on_cpu: Vec<usize>,
    /// Dispatches (each followed by a readback of the engine's counters).
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
    /// What the variant drives and measures: a waveform (or backward)
    /// variant drives every run from its corners (binding 16,
    /// `shaders/lugre/corners.wgsl`), else sawtooths only; a backward one
    /// also measures each run's backward travel (`variation.wgsl`).
    pub(super) form: Form,
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
    /// The lanes a batch keeps busy after its first dispatch (the engine's
    /// queue, `BatchOptions::lanes`); `None`: `PIDM_GPU_LANES`, else
    /// this law's default for the adapter ([`SOFTWARE_LANES`] on a
    /// software one). Tests use few, so lanes take several runs.
    pub lanes: Option<usize>,
    /// Read every steady run's whole accumulators back, not only the
    /// heads and the accumulators the reductions need
    /// (`BatchOptions::whole_accumulators`): tests compare whole runs.
    pub whole_accumulators: bool,
}

/// Compiles one entry point of the shader (of a [`Form`]) on `device`
/// (runtime checks off: every loop is bounded, every index below its
/// array's length).
pub(super) fn compile(
    device: &wgpu::Device,
    (workgroup_size, arithmetic, form): (u32, Arithmetic, Form),
    entry: &str,
    cache: Option<&wgpu::PipelineCache>,
) -> Result<wgpu::ComputePipeline, GpuError> {
    parse_and_validate(workgroup_size, arithmetic, form)?;
    let src = source(workgroup_size, arithmetic, form);
    // SAFETY: every loop of the shader is bounded by a constant or by
    // `control.attempts`; every index is a constant, a loop counter below
    // its array's length, a pivot (below R) or an instance below both
    // storage arrays' lengths, a corner's below its axis' count (at most
    // MAX_CORNERS, `layout::corner_buffer`).
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

/// Whether every driven axis of `inst` is a sawtooth without a slew
/// limit that bites: its corners are its duty's sawtooth's, which the
/// sawtooth variant drives by the same arithmetic, bit for bit.
pub fn drives_sawtooths(inst: &Instance) -> bool {
    use crate::laws::floor::drive::{Waveform, axis_corners};
    inst.axes.iter().all(|a| {
        !a.is_driven()
            || (matches!(a.shape, crate::model::Shape::Sawtooth)
                && axis_corners(a) == Waveform::Sawtooth { duty: a.duty }.corners())
    })
}

/// LuGre's lanes as the engine sees them (`gpu::lanes::Lanes`): the
/// steady measurement's coefficients, accumulators and heads, and a
/// [`Lane`] per instance.
pub(super) struct Lugre;

impl Lanes for Lugre {
    const PRECISION: Precision = Precision::F64;
    type Coefficients = Coefficients;
    type State = Lane;
    type Measure = GpuMeasure;
    type Head = Head;
    fn head_suffices(h: &Head) -> bool {
        h.suffices()
    }
    fn from_head(h: &Head) -> GpuMeasure {
        h.measure()
    }
    fn steps(st: &Lane) -> u32 {
        st.steps
    }
    /// The run, with its variation where the batch measures the backward
    /// travel (`Settings::backward`).
    type Pilot = Followed;
    fn pilot(inst: &Instance, settings: &Settings) -> Option<Followed> {
        use crate::laws::lugre::run::{run_instance_until, run_with_variation_until};
        match settings.backward {
            true => run_with_variation_until(inst, settings, || false).map(|(r, v)| (r, Some(v))),
            false => run_instance_until(inst, settings, || false).map(|r| (r, None)),
        }
    }
    fn pilot_steps(p: &Followed) -> u32 {
        p.0.record.steps
    }
    fn finished(_: &Instance, st: &Lane) -> bool {
        st.flag == LANE_STOPPED
    }
    /// Karnopp's bound holds: a lane's every slice makes a step attempt
    /// (at most the run's budget, `Periods::new`), measures a period end
    /// (one per cycle) or ends a run, on each instance it holds.
    fn slice_bound(instances: &[Instance], settings: &Settings) -> u64 {
        crate::gpu::runner::slice_bound(instances, settings)
    }
}

impl<'a> LugreGpu<'a> {
    /// Compiles the integrator on `ctx`, which must offer f64: the
    /// variant of its kind of adapter.
    pub fn new(ctx: &'a GpuContext) -> Result<LugreGpu<'a>, GpuError> {
        LugreGpu::variant(ctx, ctx.is_hardware(), Form::Sawtooth)
    }

    /// This pipeline's self-test batch (run on its first compile in a
    /// context) against the CPU's steps moved by `skew` [m per own drive
    /// cycle]: a skew beyond `selftest::ALLOWANCE_M` must fail it (tests).
    pub fn self_test_skewed(&self, skew: f64) -> Result<(), GpuError> {
        self.self_test_with(super::selftest::Skew {
            step: skew,
            backward: 0.0,
        })
    }

    /// [`LugreGpu::self_test_skewed`] of a backward pipeline, the CPU's
    /// backward travels moved by `skew` [m per own drive cycle]: a skew
    /// beyond `gpu::BACKWARD_ALLOWANCE_M` must fail it (tests).
    pub fn self_test_backward_skewed(&self, skew: f64) -> Result<(), GpuError> {
        self.self_test_with(super::selftest::Skew {
            step: 0.0,
            backward: skew,
        })
    }

    fn self_test_with(&self, skew: super::selftest::Skew) -> Result<(), GpuError> {
        let once = LugreGpu {
            pipeline: self.pipeline.clone(),
            cpu_tail: Some(0),
            lanes: None,
            whole_accumulators: false,
            ..*self
        };
        super::selftest::self_test(&once, skew)
    }

    /// Whether this pipeline drives any waveform (from its corners), not
    /// sawtooths only.
    pub fn drives_waveforms(&self) -> bool {
        self.form.waveform()
    }

    /// The context this pipeline runs in.
    pub fn context(&self) -> &'a GpuContext {
        self.ctx
    }

    /// Whether this pipeline measures the backward travel.
    pub fn measures_backward(&self) -> bool {
        self.form.backward()
    }

    /// [`LugreGpu::new`] for a batch of `instances` run with `settings`:
    /// the backward variant where the run measures the backward travel,
    /// else the waveform variant where one of them drives an axis other
    /// than by the sawtooth (a waveform or a slew limit), else the
    /// sawtooth's.
    pub fn for_instances(
        ctx: &'a GpuContext,
        instances: &[Instance],
        settings: &Settings,
    ) -> Result<LugreGpu<'a>, GpuError> {
        let form = match settings.backward {
            true => Form::Backward,
            false => Form::of(instances.iter().any(|inst| !drives_sawtooths(inst))),
        };
        LugreGpu::variant(ctx, ctx.is_hardware(), form)
    }

    /// The variant a hardware adapter gets (its workgroup size, the fused
    /// arithmetic and every period end a lane reaches measured in the same
    /// dispatch), on any f64 adapter: on a software one (llvmpipe) with its
    /// software attempts per dispatch, so that the tests run the hardware's
    /// shader there too. Its period ends are not counted against llvmpipe's
    /// loop limit: a window's have no loops, but many steady ones in one
    /// dispatch could reach it, so on a software adapter it is for tests.
    pub fn hardware_variant(ctx: &'a GpuContext, waveform: bool) -> Result<LugreGpu<'a>, GpuError> {
        LugreGpu::variant(ctx, true, Form::of(waveform))
    }

    /// The variant of `form` for a hardware adapter (`hardware`, as
    /// [`LugreGpu::hardware_variant`]) or a software one, on any f64
    /// adapter (tests).
    pub fn variant(
        ctx: &'a GpuContext,
        hardware: bool,
        form: Form,
    ) -> Result<LugreGpu<'a>, GpuError> {
        if !ctx.supports_f64() {
            return Err(GpuError::F64Unsupported {
                adapter: ctx.describe(),
            });
        }
        let name = match (hardware, form) {
            (true, Form::Sawtooth) => "lugre (hardware)",
            (true, Form::Waveform) => "lugre (hardware, waveform)",
            (true, Form::Backward) => "lugre (hardware, backward)",
            (false, Form::Sawtooth) => "lugre (software)",
            (false, Form::Waveform) => "lugre (software, waveform)",
            (false, Form::Backward) => "lugre (software, backward)",
        };
        let (workgroup_size, arithmetic) = match hardware {
            true => (HARDWARE_WORKGROUP_SIZE, Arithmetic::Fused),
            false => (SOFTWARE_WORKGROUP_SIZE, Arithmetic::Native),
        };
        // A software adapter's attempts per dispatch stay within
        // llvmpipe's loop limit, whichever variant it runs.
        let attempts = match (ctx.is_hardware(), form.backward()) {
            (true, _) => HARDWARE_ATTEMPTS,
            (false, false) => SOFTWARE_ATTEMPTS,
            (false, true) => SOFTWARE_BACKWARD_ATTEMPTS,
        };
        // One compile per context and variant: every batch of a run takes
        // the same pipeline (the driver's cache on disk spares later runs
        // it too).
        let shape = (workgroup_size, arithmetic, form);
        let pipeline = ctx.law_pipeline(
            name,
            |cache| compile(ctx.device(), shape, ENTRY_POINT, cache),
            |pipeline| {
                super::selftest::self_test(
                    &LugreGpu {
                        ctx,
                        pipeline: pipeline.clone(),
                        workgroup_size,
                        arithmetic,
                        form,
                        attempts,
                        // The shader must finish every self-test run itself.
                        cpu_tail: Some(0),
                        lanes: None,
                        whole_accumulators: false,
                    },
                    super::selftest::Skew::default(),
                )
            },
        )?;
        Ok(LugreGpu {
            ctx,
            pipeline,
            workgroup_size,
            arithmetic,
            form,
            attempts,
            cpu_tail: crate::gpu::cpu_tail().0,
            lanes: None,
            whole_accumulators: false,
        })
    }

    /// Integrates LuGre `instances` to the ends of their measurements: a
    /// floor `Run` each, as `laws::lugre::run_instance_until` gives.
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

    /// [`LugreGpu::run`], asking `stop` before each batch and between the
    /// CPU tail's periods ([`GpuError::Interrupted`] when it says yes;
    /// between dispatches the engine asks the process's stop request,
    /// `crate::interrupt`, as for Karnopp's batches) and telling `done` how
    /// many instances finished (for a progress bar).
    pub fn run_until(
        &self,
        instances: &[Instance],
        settings: &Settings,
        stop: impl Fn() -> bool + Sync,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<(Vec<Run>, BatchReport), GpuError> {
        let (followed, report) = self.followed_until(instances, settings, stop, done)?;
        Ok((followed.into_iter().map(|(run, _)| run).collect(), report))
    }

    /// [`LugreGpu::run_until`] with each run's variation where `settings`
    /// ask for the backward travel (a backward pipeline measures it).
    ///
    /// # Panics
    /// If `settings` ask for the backward travel of a pipeline that does
    /// not measure it.
    pub fn followed_until(
        &self,
        instances: &[Instance],
        settings: &Settings,
        stop: impl Fn() -> bool + Sync,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<(Vec<Followed>, BatchReport), GpuError> {
        assert!(
            !settings.backward || self.form.backward(),
            "the backward travel needs a backward pipeline"
        );
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

    /// [`LugreGpu::run_until`]'s runs as the engine's outcomes, reduced as
    /// Karnopp's lanes' are (`GpuOutcome::of` of `measurement::reduce`),
    /// those of the CPU tail marked `finished_on_cpu`.
    pub fn outcomes_until(
        &self,
        instances: &[Instance],
        settings: &Settings,
        stop: impl Fn() -> bool + Sync,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<crate::gpu::GpuOutcome>, GpuError> {
        let (runs, report) = self.followed_until(instances, settings, stop, done)?;
        let mut out: Vec<crate::gpu::GpuOutcome> = instances
            .iter()
            .zip(&runs)
            .map(|(inst, (run, variation))| {
                let measured = crate::measurement::reduce(inst, run);
                let outcome = crate::gpu::GpuOutcome::of(&measured, run.record.steps);
                match variation {
                    Some(v) => outcome.with_variation(inst, run, v),
                    None => outcome,
                }
            })
            .collect();
        report
            .on_cpu
            .iter()
            .for_each(|&k| out[k].finished_on_cpu = true);
        Ok(out)
    }

    /// The most instances one batch takes: what the device's storage
    /// bindings, buffers and dispatches hold.
    pub(super) fn max_batch(&self) -> usize {
        let largest = [
            size_of::<Params>(),
            size_of::<Lane>(),
            size_of::<Coefficients>(),
            size_of::<GpuMeasure>(),
            size_of::<Head>(),
            size_of::<Recurrence>(),
            STAGE_BYTES,
            size_of::<StageMatrix>(),
            size_of::<crate::gpu::layout::control::Tally>(),
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        crate::gpu::batch_limit(self.ctx.limits(), largest, self.workgroup_size)
    }

    /// The pipeline as the engine binds it, with the batch's own buffers
    /// (`bound`: the parameters and recurrence snapshots, [`Self::upload`]).
    pub(super) fn kernel<'k>(&'k self, bound: &'k [(u32, &'k wgpu::Buffer)]) -> Kernel<'k> {
        Kernel {
            pipeline: &self.pipeline,
            steady: true,
            loop_limiter: false,
            backward: self.form.backward(),
            workgroup_size: self.workgroup_size,
            extra: bound,
            per_lane: &[],
        }
    }

    /// The lanes a batch keeps busy after its first dispatch:
    /// [`LugreGpu::lanes`], else `PIDM_GPU_LANES`, else the engine's
    /// [`crate::gpu::LANES`] on hardware and [`SOFTWARE_LANES`] on a
    /// software adapter.
    fn lanes(&self) -> usize {
        let default = match self.ctx.is_hardware() {
            true => crate::gpu::LANES,
            false => SOFTWARE_LANES,
        };
        self.lanes
            .or_else(crate::gpu::knobs::lanes_knob)
            .unwrap_or(default)
    }

    /// The engine's options for a LuGre batch: this pipeline's attempts
    /// per dispatch (the first dispatch's too), the adapter's lanes, the
    /// CPU tail and how the accumulators come back.
    pub(super) fn options(&self) -> BatchOptions {
        BatchOptions {
            slice_iterations: self.attempts,
            probe_iterations: self.attempts,
            lanes: Some(self.lanes()),
            cpu_tail: self.cpu_tail,
            whole_accumulators: self.whole_accumulators,
            ..BatchOptions::default()
        }
    }

    /// One batch of [`LugreGpu::run_until`] through the engine's queue
    /// (`Runner::slices`), counted in `report`.
    pub(super) fn run_batch(
        &self,
        instances: &[Instance],
        settings: &Settings,
        (stop, done): (&(impl Fn() -> bool + Sync), &(dyn Fn(u64) + Sync)),
        report: &mut BatchReport,
    ) -> Result<Vec<Followed>, GpuError> {
        let mut books: Vec<Periods> = instances
            .iter()
            .map(|inst| Periods::new(inst, settings))
            .collect();
        if settings.backward {
            for book in &mut books {
                book.variation = Some(Box::new(Variation::new(book.setup())));
            }
        }
        if books.is_empty() {
            return Ok(Vec::new());
        }
        if stop() {
            return Err(GpuError::Interrupted);
        }
        let n = books.len();
        let (coefficients, states, extra) = profile::time(Phase::Upload, || self.upload(&books))?;
        let bound: Vec<(u32, &wgpu::Buffer)> =
            extra.iter().map(|(b, buffer)| (*b, buffer)).collect();
        let kernel = self.kernel(&bound);
        let options = self.options();
        let started = Instant::now();
        let mut reported = 0;
        let mut progress = |finished: u64| {
            done(finished.saturating_sub(reported));
            reported = reported.max(finished);
        };
        let sliced = {
            let _turn = self.ctx.busy.lock().unwrap_or_else(|e| e.into_inner());
            let runner = Runner::on(self.ctx, settings, &options);
            let work = Work {
                instances,
                coefficients: &coefficients,
                states: Some(&states),
            };
            runner.slices::<Lugre>(work, kernel, &mut progress, None, None)?
        };
        self.ctx.check_health()?;
        report.dispatches += sliced.dispatches;
        report.gpu_seconds += started.elapsed().as_secs_f64();
        let (mut lanes, measures, variations) = sliced.readback;
        // The round's pilot ran whole on the CPU: its runs stand, and its
        // lanes (left after the first dispatch) are done.
        for (k, _) in &sliced.pilot {
            lanes[*k].flag = LANE_STOPPED;
        }
        let recurrences = self.recurrences(&extra[1].1, &lanes)?;
        for (k, book) in books.iter_mut().enumerate() {
            // A batch of windows reads no accumulators.
            let measure = measures.get(k).copied().unwrap_or_else(GpuMeasure::zeroed);
            let mut kept = lanes[k].kept(&measure, &recurrences[k]);
            if !matches!(instances[k].measure, Measure::Steady { .. }) {
                // A window's accumulators stay as its run started them.
                kept.measure = book.run.measure;
            }
            book.resume(&kept);
            // The variation at the lane's last period end, where the CPU
            // tail continues its run (`variation.wgsl`).
            if let (Some(v), Some(entry)) = (book.variation.as_deref_mut(), variations.get(k)) {
                *v = crate::gpu::layout::variation_to_cpu(entry);
            }
        }
        for (k, (run, variation)) in sliced.pilot {
            books[k].run = run;
            books[k].variation = variation.map(Box::new);
            report.on_cpu.push(k);
        }
        if lanes.iter().any(|l| l.flag != LANE_STOPPED) {
            report
                .on_cpu
                .extend(cpu_tail(&mut books, &lanes, (stop, done))?);
        }
        let periods: u64 = lanes.iter().map(|l| l.period as u64).sum();
        report.periods += periods;
        record([
            n as u64,
            sliced.dispatches,
            sliced.offered,
            lanes.iter().map(|l| l.steps as u64).sum(),
            periods,
        ]);
        Ok(books
            .into_iter()
            .map(|b| (b.run, b.variation.map(|v| *v)))
            .collect())
    }

    /// A batch's coefficients (the measurement's, packed), its runs as the
    /// host sets them up, and its own buffers: the parameters (binding 9),
    /// room for the recurrence snapshots (binding 10), a waveform
    /// variant's corners ([`CORNER_BINDING`]), and on hardware
    /// room for each instance's Rodas4 stages and W (bindings 14 and 15,
    /// `shaders/lugre/hold_memory.wgsl`), each with its binding.
    #[allow(clippy::type_complexity)]
    pub(super) fn upload(
        &self,
        books: &[Periods],
    ) -> Result<(Vec<Coefficients>, Vec<Lane>, Vec<(u32, wgpu::Buffer)>), GpuError> {
        let device = self.ctx.device();
        let mut params: Vec<Params> = books.iter().map(Params::of).collect();
        let corners = match self.form.waveform() {
            true => Some(corner_buffer(books, &mut params).map_err(GpuError::Execution)?),
            false => None,
        };
        let models = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("lugre models"),
            contents: bytemuck::cast_slice(&params),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let recurrences = storage(
            device,
            "lugre recurrences",
            (books.len() * size_of::<Recurrence>()) as u64,
        );
        let mut own = vec![(9, models), (10, recurrences)];
        if let Some(corners) = corners {
            let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("lugre corners"),
                contents: bytemuck::cast_slice(&corners),
                usage: wgpu::BufferUsages::STORAGE,
            });
            own.push((CORNER_BINDING, buffer));
        }
        if self.arithmetic == Arithmetic::Fused {
            let n = books.len() as u64;
            let stages = storage(device, "lugre stages", n * STAGE_BYTES as u64);
            let w_bytes = n * size_of::<StageMatrix>() as u64;
            let matrices = storage(device, "lugre stage matrices", w_bytes);
            own.extend([(14, stages), (15, matrices)]);
        }
        Ok((
            books
                .iter()
                .map(|b| Coefficients::of(b.setup(), b.cycles()))
                .collect(),
            books.iter().map(Lane::start).collect(),
            own,
        ))
    }

    /// Every lane's recurrence snapshots, read back where some run is
    /// still going (the CPU tail continues it from them); else none
    /// (a finished run's result does not read them).
    fn recurrences(
        &self,
        buffer: &wgpu::Buffer,
        lanes: &[Lane],
    ) -> Result<Vec<Recurrence>, GpuError> {
        if lanes.iter().all(|l| l.flag == LANE_STOPPED) {
            return Ok(vec![Recurrence::zeroed(); lanes.len()]);
        }
        let _reading = profile::span(Phase::Readback);
        let device = self.ctx.device();
        let read = mappable(device, "lugre recurrences read", buffer.size());
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &read, 0, buffer.size());
        self.ctx.queue().submit([encoder.finish()]);
        let bytes = read_buffer(device, &read)?;
        profile::add_bytes_read(bytes.len() as u64);
        Ok(bytes
            .chunks_exact(size_of::<Recurrence>())
            .map(bytemuck::pod_read_unaligned)
            .collect())
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
