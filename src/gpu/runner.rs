//! Integrating a batch: buffers sized by the adapter's limits, time-sliced
//! dispatches until every instance has finished or only the slow tail is
//! left, the readback of states and accumulators, and the CPU's part (the
//! tail, loop-limited iterations, f32 fallbacks and the check).

use super::*;
use crate::profile::{self, Phase};

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
    run_batch_packed(ctx, instances, None, settings, precision, options, progress)
}

/// [`run_batch_with`], with the instances' coefficients already packed
/// where `packed` is given and was packed for these instances' count, this
/// precision and these settings (else they are packed here).
pub fn run_batch_packed(
    ctx: &GpuContext,
    instances: &[Instance],
    packed: Option<&Packed>,
    settings: &Settings,
    precision: Precision,
    options: &BatchOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Vec<GpuOutcome>, GpuError> {
    let packed = packed.and_then(|p| p.bytes_for(instances.len(), precision, settings));
    // The adapter decides the check's route (`F32Check::Auto`) and the
    // lanes.
    let options = &BatchOptions {
        check: match options.check.route(ctx.is_hardware()) {
            Some(route) => F32Check::Route(route),
            None => F32Check::Off,
        },
        lanes: Some(options.lanes.unwrap_or_else(|| ctx.lanes())),
        ..*options
    };
    let out = {
        let _turn = ctx.busy.lock().unwrap_or_else(|e| e.into_inner());
        Runner::on(ctx, settings, options).all_in(precision, instances, packed, progress)
    };
    // A lost device fails the batch's readback with a generic mapping
    // error; the device's own message says why.
    ctx.check_health()?;
    out
}

/// The work of [`run_batch`] on any device: `pipeline` must come from
/// [`create_pipeline`] of its variant on that device, in the same
/// precision, with every part the instances need (else the batch fails
/// with [`GpuError::Execution`]), and `limits` are the device's.
#[allow(clippy::too_many_arguments)]
pub fn execute_gpu_inner(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    pipeline: (&wgpu::ComputePipeline, Variant),
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
        pipelines: Pipelines::Fixed(pipeline),
        limits,
        settings,
        options,
    };
    run.all_in(precision, instances, None, progress)
}

/// Workgroup counts (x, y) covering `n` instances within the per-dimension
/// limit. The shader numbers invocations `x + y * groups_x * WORKGROUP_SIZE`
/// (the prelude's, [`workgroup_size`]).
pub fn dispatch_size(n: usize, max_per_dimension: u32) -> (u32, u32) {
    workgroups(n, workgroup_size(), max_per_dimension)
}

/// Workgroup counts (x, y) of `size` invocations each covering `n`
/// invocations within the per-dimension limit: every law's dispatch
/// (Karnopp's through [`dispatch_size`], LuGre's in `gpu::lugre`).
pub fn workgroups(n: usize, size: u32, max_per_dimension: u32) -> (u32, u32) {
    let groups = (n as u64).div_ceil(size as u64).max(1);
    let x = groups.min(max_per_dimension as u64);
    let y = groups.div_ceil(x);
    (x as u32, y as u32)
}

/// Where a runner's batches get their pipeline.
#[derive(Clone, Copy)]
pub(super) enum Pipelines<'a> {
    /// A context's: the one with the parts a batch needs
    /// ([`GpuContext::pipeline_for`]).
    Context(&'a GpuContext),
    /// One compiled pipeline, for every batch.
    Fixed((&'a wgpu::ComputePipeline, Variant)),
}

pub(super) struct Runner<'a> {
    pub(super) device: &'a wgpu::Device,
    pub(super) queue: &'a wgpu::Queue,
    pipelines: Pipelines<'a>,
    pub(super) limits: &'a wgpu::Limits,
    pub(super) settings: &'a Settings,
    pub(super) options: &'a BatchOptions,
}

impl<'a> Runner<'a> {
    /// A runner on `ctx`'s device and pipelines.
    pub(super) fn on(
        ctx: &'a GpuContext,
        settings: &'a Settings,
        options: &'a BatchOptions,
    ) -> Runner<'a> {
        Runner {
            device: &ctx.device,
            queue: &ctx.queue,
            pipelines: Pipelines::Context(ctx),
            limits: &ctx.limits,
            settings,
            options,
        }
    }

    /// This runner with other settings and options.
    pub(super) fn with<'b>(
        &'b self,
        settings: &'b Settings,
        options: &'b BatchOptions,
    ) -> Runner<'b> {
        Runner {
            settings,
            options,
            ..*self
        }
    }

    /// A batch's coefficients: `packed` where they were packed ahead, else
    /// packed here.
    pub(super) fn coefficients<L: Layout>(
        &self,
        instances: &[Instance],
        packed: Option<&[u8]>,
    ) -> Vec<L::Coefficients> {
        let _packing = profile::span(Phase::Pack);
        match packed {
            Some(bytes) => match bytemuck::try_cast_slice(bytes) {
                Ok(c) => c.to_vec(),
                Err(_) => bytes
                    .chunks_exact(size_of::<L::Coefficients>())
                    .map(bytemuck::pod_read_unaligned)
                    .collect(),
            },
            None => instances
                .par_iter()
                .map(|inst| L::pack(inst, self.settings))
                .collect(),
        }
    }

    /// The pipeline for a batch with these coefficients: one whose variant
    /// has every part they use.
    /// Whether this runner's adapter ends shader loops early (llvmpipe):
    /// its pipelines then check every iteration.
    fn loop_limiter(&self) -> bool {
        match self.pipelines {
            Pipelines::Context(ctx) => ctx.variant(Precision::F64, Parts::default()).loop_limiter,
            Pipelines::Fixed((_, variant)) => variant.loop_limiter,
        }
    }

    pub(super) fn pipeline<L: Layout>(
        &self,
        precision: Precision,
        coefficients: &[L::Coefficients],
    ) -> Result<(wgpu::ComputePipeline, Variant), GpuError> {
        let needs = coefficients
            .par_iter()
            .map(L::parts)
            .reduce(Parts::default, Parts::union)
            .with_settings(self.settings);
        match self.pipelines {
            Pipelines::Context(ctx) => ctx.pipeline_for(precision, needs),
            Pipelines::Fixed((pipeline, variant)) if variant.parts.covers(needs) => {
                Ok((pipeline.clone(), variant))
            }
            Pipelines::Fixed((_, variant)) => Err(GpuError::Execution(format!(
                "the pipeline of the {} variant cannot run instances that need {}",
                variant.parts.name(),
                needs.name()
            ))),
        }
    }

    /// [`Self::all`] in `precision`.
    fn all_in(
        &self,
        precision: Precision,
        instances: &[Instance],
        packed: Option<&[u8]>,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<Vec<GpuOutcome>, GpuError> {
        match precision {
            Precision::F32 => self.all::<Single>(instances, packed, progress),
            Precision::F64 => self.all::<Double>(instances, packed, progress),
        }
    }

    /// The most instances one batch of `instances` may hold: what a binding
    /// holds of the largest per-instance entry, the state (or a steady
    /// measurement's accumulators) or a lane's entries where the variant
    /// holds a step in device memory (the batch has a lane per instance).
    fn batch_size<L: Layout>(&self, instances: &[Instance]) -> usize {
        let state_size = if super::readback::any_steady(instances) {
            size_of::<L::State>()
                .max(size_of::<L::Measure>() * super::staging::measure_entries(self.loop_limiter()))
        } else {
            size_of::<L::State>()
        };
        let held = Variant {
            precision: L::PRECISION,
            loop_limiter: self.loop_limiter(),
            parts: Parts::default(),
        };
        let state_size = super::karnopp::shader::per_lane(held)
            .iter()
            .fold(state_size, |m, &(_, bytes)| m.max(bytes as usize));
        max_batch_instances(
            self.limits,
            size_of::<L::Coefficients>(),
            state_size,
            self.options,
        )
    }

    /// Runs all instances, batch by batch; `packed` holds their
    /// coefficients where they were packed ahead.
    fn all<L: Layout>(
        &self,
        instances: &[Instance],
        packed: Option<&[u8]>,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<Vec<GpuOutcome>, GpuError> {
        let per_batch = self.batch_size::<L>(instances);
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
        let stride = size_of::<L::Coefficients>();
        for chunk in instances.chunks(per_batch) {
            let done_before = out.len() as u64;
            let mut chunk_progress =
                |done: u64| progress((done_before + done) * main_share / total.max(1), total);
            let first = out.len() * stride;
            let chunk_packed = packed.map(|b| &b[first..first + chunk.len() * stride]);
            out.extend(self.batch::<L>(chunk, chunk_packed, &mut chunk_progress)?);
        }
        // Instances the driver's loop limiter kept from advancing at all,
        // and f32 instances that failed or met a band graze, are
        // integrated on the CPU; f32's heaviest window runs are checked
        // (`laws::floor::check`), on the CPU (the reference route) or by twins
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
                let _cpu = profile::span(Phase::CpuPart);
                outcomes.extend(self.on_cpu_all(instances, &jobs));
                outcomes
            }
            Some(Route::Reference) => {
                let mut jobs = fallback;
                jobs.extend(picked.into_iter().map(checked_job));
                let rest = total - main_share;
                let n = (jobs.len() as u64).max(1);
                let _cpu = profile::span(Phase::CpuPart);
                self.on_cpu_all_reporting(instances, &jobs, &mut |done| {
                    progress(main_share + done.min(n) * rest / n, total)
                })
            }
            None => profile::time(Phase::CpuPart, || self.on_cpu_all(instances, &fallback)),
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

    /// The twins of f32's `picked` runs ([`crate::laws::floor::check`]),
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
            twins.extend(
                twin_runner.batch::<L>(chunk, None, &mut |done| progress(done_before + done))?,
            );
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
    pub(super) fn batch<L: Layout>(
        &self,
        instances: &[Instance],
        packed: Option<&[u8]>,
        progress: &mut dyn FnMut(u64),
    ) -> Result<Vec<GpuOutcome>, GpuError> {
        let n = instances.len();
        if n == 0 {
            return Ok(Vec::new());
        }
        let device = self.device;
        let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let result = self.batch_inner::<L>(instances, packed, progress);
        let memory_error = pollster::block_on(memory.pop());
        let validation_error = pollster::block_on(validation.pop());
        if let Some(e) = validation_error.or(memory_error) {
            return Err(GpuError::Execution(e.to_string()));
        }
        result
    }

    fn batch_inner<L: Layout>(
        &self,
        instances: &[Instance],
        packed: Option<&[u8]>,
        progress: &mut dyn FnMut(u64),
    ) -> Result<Vec<GpuOutcome>, GpuError> {
        // Replicas on the lanes a small batch leaves idle, in either
        // precision.
        let lanes = self.options.lanes.unwrap_or(LANES);
        let count = crate::replicas::count_queued(self.settings.replicas, lanes, instances.len());
        // The device's replica groups merge steps only: a run that
        // measures the backward travel runs each instance alone (the GPU
        // backend gives the instances that split to the CPU's groups:
        // `backend::gpu`'s `groups_on_cpu`).
        let split = (!self.settings.backward)
            .then(|| groups::Split::of(instances, self.settings, count))
            .flatten();
        if let Some(split) = split {
            return self.batch_split::<L>(instances, split, progress);
        }
        let n = instances.len();
        let mut coefficients = self.coefficients::<L>(instances, packed);
        let (pipeline, variant) = self.pipeline::<L>(L::PRECISION, &coefficients)?;
        let segments = segment_binding::<L>(self.device, variant, instances, &mut coefficients);
        let extra = segment_entries(&segments);
        let Sliced {
            readback: (states, measure_list, variations),
            pilot,
            ..
        } = self.slices::<L>(
            Work {
                instances,
                coefficients: &coefficients,
                states: None,
            },
            Kernel::with_segments(&pipeline, variant, &extra),
            progress,
            None,
            None,
        )?;
        drop(coefficients);
        let out = self.outcomes::<L>(instances, &states, (&measure_list, &variations), pilot);
        progress(n as u64);
        Ok(out)
    }

    /// The outcomes of a batch's jobs from their states, (steady)
    /// measurements and backward-travel entries (`variations`: empty where
    /// the kernel measured none), but those of `done`, the CPU's already (a
    /// round's pilot, [`Sliced::pilot`]); the CPU finishes what the device
    /// left unfinished.
    pub(super) fn outcomes<L: Layout>(
        &self,
        instances: &[Instance],
        states: &[L::State],
        (measure_list, variations): (&[L::Measure], &[L::Measure]),
        done: Vec<(usize, GpuOutcome)>,
    ) -> Vec<GpuOutcome> {
        let n = instances.len();
        let reducing = profile::span(Phase::Reduce);
        let is_steady = |k: usize| matches!(instances[k].measure, Measure::Steady { .. });
        // The outcomes, and the states of the unfinished ones.
        let (mut out, tail) = {
            let out: Vec<GpuOutcome> = (0..n)
                .into_par_iter()
                .map(|k| {
                    let outcome = if is_steady(k) {
                        L::reduce(&instances[k], &states[k], &measure_list[k])
                    } else {
                        L::unpack(&instances[k], &states[k])
                    };
                    match variations.get(k) {
                        Some(v) if L::finished(&instances[k], &states[k]) => {
                            let m = is_steady(k).then(|| &measure_list[k]);
                            with_variation(
                                &instances[k],
                                outcome,
                                L::followed(&instances[k], &states[k], m, v),
                            )
                        }
                        _ => outcome,
                    }
                })
                .collect();
            let is_done: std::collections::HashSet<usize> = done.iter().map(|(k, _)| *k).collect();
            let tail: Vec<(usize, L::State)> = (0..n)
                .into_par_iter()
                .filter(|&k| !is_done.contains(&k) && !L::finished(&instances[k], &states[k]))
                .map(|k| (k, states[k]))
                .collect();
            (out, tail)
        };
        drop(reducing);
        let _tail = profile::span(Phase::CpuPart);
        // The slow tail, if the GPU stopped before it: on the CPU, in
        // parallel, from where the GPU left it (f64) or from the start
        // (f32).
        let tail_outcomes: Vec<GpuOutcome> = tail
            .par_iter()
            .with_max_len(1)
            .map(|(k, st)| {
                let m = is_steady(*k).then(|| &measure_list[*k]);
                let inst = &instances[*k];
                let outcome = match variations.get(*k) {
                    Some(v) => on_cpu_followed(inst, self.settings, L::followed(inst, st, m, v)),
                    None => on_cpu(inst, self.settings, L::continuable(inst, st, m)),
                };
                GpuOutcome {
                    finished_on_cpu: true,
                    ..outcome
                }
            })
            .collect();
        for ((k, _), outcome) in tail.iter().zip(tail_outcomes) {
            out[*k] = outcome;
        }
        for (k, outcome) in done {
            out[k] = outcome;
        }
        out
    }
}

/// `outcome` with the backward travel of `followed` (a finished lane's run
/// and variation entry, as the CPU's: `Layout::followed`).
fn with_variation(
    inst: &Instance,
    outcome: GpuOutcome,
    followed: Option<(Run, crate::laws::floor::variation::Variation)>,
) -> GpuOutcome {
    match followed {
        Some((run, v)) => outcome.with_variation(inst, &run.ended(), &v),
        None => outcome,
    }
}

/// A storage buffer of `size` bytes that results can be copied out of and
/// the host may write into (a replica group lets its jobs go on).
pub(super) fn storage(device: &wgpu::Device, label: &str, size: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST,
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
pub(super) fn slice_bound(instances: &[Instance], settings: &Settings) -> u64 {
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
