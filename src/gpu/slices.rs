//! One batch on the device, in time slices: its buffers; the first
//! dispatch, which starts every instance on a lane of its own for
//! [`BatchOptions::probe_iterations`] iterations; the queue of the
//! unfinished ones, dearest first ([`warps::queue_order`]), that a few
//! lanes ([`BatchOptions::lanes`]) work through, each taking the next one
//! when its own finishes; the lanes still busy packed into fewer workgroups
//! once the queue is empty; and the readback of states and accumulators.
//! A batch so lasts its work over its lanes, not its longest instance,
//! until only its slow tail is left, which the CPU may take
//! ([`BatchOptions::cpu_tail`]). Which lane runs an instance, and when,
//! changes nothing of its result: its state lives in the `states` buffer.

use super::rounds::{HAND_OVER, ROUND_GROWTH_EIGHTHS, first_cap};
use super::runner::{Runner, storage};
use super::*;
use crate::profile::{self, Phase};
use layout::control::{NO_CAP, Tally};
use warps::{CriticalPath, LaneBytes, NO_INSTANCE, Probed, Warps, queue_order};

/// The engine's queue in WGSL (`shaders/engine/queue.wgsl`: the controls,
/// counters, lanes, order and tallies, and taking an instance), which
/// every law's source includes before its entry point.
pub fn engine_queue() -> String {
    format!(
        "\n// ---- shaders/engine/queue.wgsl\n{}",
        include_str!("../../shaders/engine/queue.wgsl")
    )
}

/// What a batch does between its dispatches besides refilling lanes: a
/// replica batch's groups (`super::groups`) merge, and may send the jobs
/// that waited for the merge back to the queue.
pub(super) trait Between {
    /// After a dispatch that left `finished` jobs finished or waiting (the
    /// counter the shader keeps): the jobs to queue again, whose states
    /// (in `states` and `measures`) it has already set going again.
    fn after(
        &mut self,
        runner: &Runner,
        states: &wgpu::Buffer,
        measures: &wgpu::Buffer,
        finished: u64,
    ) -> Result<Vec<u32>, GpuError>;

    /// Whether the CPU takes what is left of the batch now, with the queue
    /// empty and `unfinished` jobs neither finished nor waiting.
    fn hand_over(&self, unfinished: u64) -> bool;
}

/// The engine's counters before the parked instances' list
/// (`shaders/engine/queue.wgsl`'s `Counters`).
const COUNTER_WORDS: usize = 3;

/// The counters after a dispatch.
#[derive(Clone, Copy, Debug)]
struct Counts {
    /// Queue entries taken (and overrun).
    next: u64,
    /// Instances finished or parked.
    finished: u64,
    /// Instances parked at the cap since the queue was last written.
    parked: u64,
}

/// A batch's device buffers.
struct Buffers {
    coefficients: wgpu::Buffer,
    states: wgpu::Buffer,
    measures: wgpu::Buffer,
    heads: wgpu::Buffer,
    /// The instance each lane holds, one entry per instance (the first
    /// dispatch has a lane for each).
    lanes: wgpu::Buffer,
    lanes_read: wgpu::Buffer,
    counters: wgpu::Buffer,
    counters_read: wgpu::Buffer,
    order: wgpu::Buffer,
    tallies: wgpu::Buffer,
    tallies_read: wgpu::Buffer,
    /// The kernel's per-lane buffers (`Kernel::per_lane`), with their
    /// bindings.
    per_lane: Vec<(u32, wgpu::Buffer)>,
}

impl Buffers {
    fn new<L: Lanes>(
        device: &wgpu::Device,
        work: &Work<L>,
        steady: bool,
        kernel: Kernel,
    ) -> Buffers {
        let n = work.coefficients.len();
        let loop_limiter = kernel.loop_limiter;
        let init = |label: &str, contents: &[u8], copy: bool| {
            let mut usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
            if copy {
                usage |= wgpu::BufferUsages::COPY_SRC;
            }
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        // The accumulators: one per instance where any instance is steady
        // (and a scratch entry per lane, one per instance at most, on a
        // loop-limited adapter: `steady.wgsl`), else one unused entry
        // (windows never touch them); twice that where the kernel keeps
        // each instance's backward travel in a second half.
        let per_steady = if steady || kernel.backward { n } else { 1 };
        let halves = if kernel.backward { 2 } else { 1 };
        let measures =
            per_steady * super::staging::measure_entries(steady && loop_limiter) * halves;
        let identity: Vec<u32> = (0..n as u32).collect();
        Buffers {
            coefficients: init(
                "coefficients",
                bytemuck::cast_slice(work.coefficients),
                false,
            ),
            states: match work.states {
                Some(states) => init("states", bytemuck::cast_slice(states), true),
                None => storage(device, "states", (n * size_of::<L::State>()) as u64),
            },
            measures: storage(
                device,
                "measures",
                (size_of::<L::Measure>() * measures) as u64,
            ),
            heads: storage(device, "heads", (size_of::<L::Head>() * per_steady) as u64),
            lanes: init("lanes", bytemuck::cast_slice(&identity), true),
            lanes_read: readback::mappable(device, "lanes readback", 4 * n as u64),
            // next, finished, parked, then the parked instances' list.
            counters: init("counters", &vec![0u8; 4 * (COUNTER_WORDS + n)], true),
            counters_read: readback::mappable(
                device,
                "counters readback",
                4 * n.max(COUNTER_WORDS) as u64,
            ),
            order: init("order", bytemuck::cast_slice(&identity), false),
            tallies: storage(device, "tallies", (n * size_of::<Tally>()) as u64),
            tallies_read: readback::mappable(
                device,
                "tallies readback",
                (n * size_of::<Tally>()) as u64,
            ),
            per_lane: kernel
                .per_lane
                .iter()
                .map(|&(binding, bytes)| (binding, storage(device, "per lane", n as u64 * bytes)))
                .collect(),
        }
    }

    /// The bind group of a dispatch with `control`: the bindings the
    /// kernel uses (one without steady measurements binds neither
    /// accumulators nor heads) and the law's own.
    fn bind_group(
        &self,
        device: &wgpu::Device,
        kernel: Kernel,
        control: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let mut buffers = vec![
            (0, &self.coefficients),
            (1, &self.states),
            (2, control),
            (3, &self.counters),
            (4, &self.lanes),
            (7, &self.order),
            (8, &self.tallies),
        ];
        if kernel.steady {
            buffers.extend([(5, &self.measures), (6, &self.heads)]);
        }
        buffers.extend(kernel.extra.iter().copied());
        buffers.extend(
            self.per_lane
                .iter()
                .map(|(binding, buffer)| (*binding, buffer)),
        );
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .into_iter()
            .map(|(binding, buffer)| wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("integrate"),
            layout: &kernel.pipeline.get_bind_group_layout(0),
            entries: &entries,
        })
    }
}

/// The run's warps and the batch's critical path, counted where the run
/// is profiled.
struct Counted {
    warps: Warps,
    path: CriticalPath,
    profiling: bool,
}

impl Counted {
    /// Counts one dispatch of `lanes` lanes.
    fn dispatch(&mut self, tallies: &[Tally], lanes: usize) {
        if self.profiling {
            self.warps.add_dispatch(tallies);
            self.path.add_dispatch(tallies, lanes);
        }
    }
}

/// What a batch's dispatches spent ([`Sliced`]).
struct Spent {
    dispatches: u64,
    offered: u64,
}

/// A batch's queue after its first dispatch, and when to stop.
struct Queue {
    /// The jobs still to start, dearest first.
    order: Vec<u32>,
    /// Jobs finished (or waiting) so far.
    finished: u64,
    /// Unfinished jobs the CPU may take once the queue is empty.
    tail_size: u64,
    slice_limit: Option<u64>,
    /// The first round's cap on an instance's steps, where the batch runs
    /// in rounds ([`first_cap`]); `None`: in one, the tail taken by the
    /// clock.
    cap: Option<u32>,
    /// Parked instances a round may end with that the CPU takes.
    hand_over: u64,
}

/// The periods an instance is expected to run, for ranking the queue: a
/// window's cycles; a steady measurement's settling and sixteen batches of
/// its beat (a common period or the slowest beat between the drives),
/// which a periodic motion undercuts and an irregular one may outrun, but
/// at most its `max_cycles`.
pub(super) fn expected_periods(inst: &Instance) -> f64 {
    use crate::laws::floor::{Vec2, measure};
    match inst.measure {
        Measure::Window => inst.cycles as f64,
        Measure::Steady { .. } => {
            let period = inst.period();
            let [x, y] = inst.axes;
            let cycles = Vec2::new(x.frequency * period, y.frequency * period);
            let driven = [x.voltage != 0.0, y.voltage != 0.0];
            let beat = measure::beat_batch_length(cycles, driven) as f64;
            (inst.settle as f64 + measure::MIN_BATCHES as f64 * beat).min(inst.cycles as f64)
        }
    }
}

impl Runner<'_> {
    /// One dispatch of `lanes` lanes with `group`; returns the counters
    /// after it.
    fn dispatch(
        &self,
        b: &Buffers,
        kernel: Kernel,
        group: &wgpu::BindGroup,
        lanes: usize,
    ) -> Result<Counts, GpuError> {
        let (gx, gy) = workgroups(
            lanes,
            kernel.workgroup_size,
            self.limits.max_compute_workgroups_per_dimension,
        );
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(kernel.pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        let bytes = 4 * COUNTER_WORDS as u64;
        encoder.copy_buffer_to_buffer(&b.counters, 0, &b.counters_read, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let words = self.read_words(b, bytes)?;
        Ok(Counts {
            next: words[0] as u64,
            finished: words[1] as u64,
            parked: words[2] as u64,
        })
    }

    /// The first `bytes` of `b.counters_read` as words, once a copy into
    /// it has been submitted.
    fn read_words(&self, b: &Buffers, bytes: u64) -> Result<Vec<u32>, GpuError> {
        readback::with_mapped_prefix(self.device, &b.counters_read, bytes, |bytes| {
            bytes
                .chunks_exact(4)
                .map(|w| u32::from_le_bytes(w.try_into().unwrap()))
                .collect()
        })
    }

    /// The `parked` instances the lanes parked at the cap since the queue
    /// was last written, in index order (the order the lanes parked them
    /// in is theirs, not the runs').
    fn parked(&self, b: &Buffers, parked: u64) -> Result<Vec<u32>, GpuError> {
        let bytes = 4 * parked;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let from = 4 * COUNTER_WORDS as u64;
        encoder.copy_buffer_to_buffer(&b.counters, from, &b.counters_read, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let mut list = self.read_words(b, bytes)?;
        list.sort_unstable();
        Ok(list)
    }

    /// The tallies of the first `lanes` lanes of the last dispatch.
    fn tallies(&self, b: &Buffers, lanes: usize) -> Result<Vec<Tally>, GpuError> {
        let bytes = (lanes * size_of::<Tally>()) as u64;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&b.tallies, 0, &b.tallies_read, 0, bytes);
        self.queue.submit([encoder.finish()]);
        readback::with_mapped_prefix(self.device, &b.tallies_read, bytes, |bytes| {
            bytes
                .chunks_exact(size_of::<Tally>())
                .map(bytemuck::pod_read_unaligned)
                .collect()
        })
    }

    /// Packs the instances the first `active` lanes hold into the first
    /// lanes; returns how many lanes now hold one.
    fn compact(&self, b: &Buffers, active: usize) -> Result<usize, GpuError> {
        let bytes = 4 * active as u64;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&b.lanes, 0, &b.lanes_read, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let mut held: Vec<u32> =
            readback::with_mapped_prefix(self.device, &b.lanes_read, bytes, |bytes| {
                bytes
                    .chunks_exact(4)
                    .map(|w| u32::from_le_bytes(w.try_into().unwrap()))
                    .filter(|&k| k != NO_INSTANCE)
                    .collect()
            })?;
        let busy = held.len();
        held.resize(active, NO_INSTANCE);
        self.queue
            .write_buffer(&b.lanes, 0, bytemuck::cast_slice(&held));
        Ok(busy)
    }

    /// A control buffer: `queued` entries of the queue, which the first
    /// `lanes` lanes may take when they hold no instance.
    fn control(
        &self,
        max_iterations: u32,
        initialize: u32,
        queued: u32,
        lanes: u32,
        cap: u32,
    ) -> wgpu::Buffer {
        let probe = self.options.probe_passes.max(layout::PROBE_PASSES);
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("control"),
                contents: bytemuck::bytes_of(&Control {
                    max_iterations,
                    initialize,
                    one: 1.0,
                    probe,
                    probe_min: probe,
                    zero: 0,
                    queued,
                    lanes,
                    cap,
                }),
                usage: wgpu::BufferUsages::STORAGE,
            })
    }

    /// Dispatches slices until the batch is done, or only its slow tail is
    /// left, or `slice_limit` slices have run ([`Sliced`]). `between`
    /// runs after every dispatch (a replica batch's groups).
    pub(super) fn slices<L: Lanes>(
        &self,
        work: Work<L>,
        kernel: Kernel,
        progress: &mut dyn FnMut(u64),
        slice_limit: Option<u64>,
        mut between: Option<&mut dyn Between>,
    ) -> Result<Sliced<L>, GpuError> {
        let instances = work.instances;
        let n = instances.len();
        let steady = kernel.steady && super::readback::any_steady(instances);
        let uploading = profile::span(Phase::Upload);
        let b = Buffers::new::<L>(self.device, &work, steady, kernel);
        let probe_iterations = self.options.probe_iterations.max(1);
        let probe_control = self.control(probe_iterations, 1, 0, 0, NO_CAP);
        let probe_group = b.bind_group(self.device, kernel, &probe_control);
        drop(uploading);
        let dispatching = profile::span(Phase::Dispatch);
        let profiling = profile::enabled();
        let mut count_in = Counted {
            warps: Warps::default(),
            path: CriticalPath {
                instances: n,
                lanes: n,
                ..CriticalPath::default()
            },
            profiling,
        };
        // The first dispatch: every instance on a lane of its own.
        let started = std::time::Instant::now();
        let mut finished = self.dispatch(&b, kernel, &probe_group, n)?.finished;
        let tallies = self.tallies(&b, n)?;
        profile::add_lanes(
            kernel.whole_workgroups(n) as u64,
            n as u64,
            started.elapsed(),
        );
        let mut spent = Spent {
            dispatches: 1,
            offered: n as u64 * probe_iterations as u64,
        };
        count_in.dispatch(&tallies, n);
        let mut again = match between.as_deref_mut() {
            Some(between) => between.after(self, &b.states, &b.measures, finished)?,
            None => Vec::new(),
        };
        finished -= again.len() as u64;
        progress(finished.min(n as u64));
        let probed: Vec<Probed> = tallies
            .iter()
            .enumerate()
            .filter_map(|(k, tally)| {
                tally.held().map(|_| Probed {
                    index: k as u32,
                    tally: *tally,
                    expected_periods: expected_periods(&instances[k]),
                })
            })
            .collect();
        let mut order = queue_order(&probed, self.options.order);
        order.append(&mut again);
        let tail_size =
            self.options
                .tail_size(L::PRECISION, n, rayon::current_num_threads()) as u64;
        let stop_now = order.is_empty()
            || order.len() as u64 <= tail_size
            || slice_limit.is_some_and(|limit| limit <= 1);
        let mut pilot = Vec::new();
        if !stop_now {
            let rounds = tail_size > 0 && between.is_none();
            let cap = match rounds {
                true => first_cap::<L>(instances, self.settings, &mut order, tail_size),
                false => None,
            }
            .map(|(cap, outcomes)| {
                pilot = outcomes;
                cap
            });
            let queue = Queue {
                order,
                // The pilot's instances finished on the CPU.
                finished: finished + pilot.len() as u64,
                tail_size,
                hand_over: match self.options.cpu_tail {
                    Some(_) => tail_size,
                    None => HAND_OVER * tail_size,
                },
                slice_limit,
                cap,
            };
            self.work_through::<L>(
                (instances, &b, kernel),
                queue,
                progress,
                between,
                (&mut count_in, &mut spent),
            )?;
        }
        drop(dispatching);
        let out = self.read_back::<L>(instances, &b, steady, kernel.backward)?;
        if profiling {
            self.record_profile::<L>(instances, &out, &probed, steady, count_in);
        }
        Ok(Sliced {
            readback: out,
            probe_tallies: tallies,
            pilot,
            dispatches: spent.dispatches,
            offered: spent.offered,
        })
    }

    /// The dispatches after the first: `queue`'s first entries on the
    /// lanes, each lane taking the next entry when its own instance
    /// finishes, the busy lanes packed into fewer workgroups once the
    /// queue is empty, and what `between` queues again added to its end.
    fn work_through<L: Lanes>(
        &self,
        (instances, b, kernel): (&[Instance], &Buffers, Kernel),
        queue: Queue,
        progress: &mut dyn FnMut(u64),
        mut between: Option<&mut dyn Between>,
        (count_in, spent): (&mut Counted, &mut Spent),
    ) -> Result<(), GpuError> {
        let n = instances.len();
        let Queue {
            mut order,
            mut finished,
            tail_size,
            slice_limit,
            mut cap,
            hand_over,
        } = queue;
        // The queue, and its first entries on the lanes.
        let lanes = self.options.lanes.unwrap_or(LANES).clamp(1, order.len());
        let mut first = order[..lanes].to_vec();
        first.resize(kernel.whole_workgroups(lanes).min(n), NO_INSTANCE);
        self.queue
            .write_buffer(&b.lanes, 0, bytemuck::cast_slice(&first));
        let mut group = self.requeue(b, kernel, (&order, lanes), lanes as u32, finished, cap);
        count_in.path.lanes = lanes;
        let mut active = lanes;
        let rounds = n.div_ceil(lanes) as u64;
        // A round of the cap adds a slice at most, and there are fewer than
        // 32 of them.
        let max_slices = L::slice_bound(instances, self.settings).saturating_mul(rounds) + 33;
        let mut unfinished_before = n as u64 - finished;
        let mut slice: u64 = 1;
        loop {
            let started = std::time::Instant::now();
            let counts = self.dispatch(b, kernel, &group, active)?;
            let mut next = counts.next;
            finished = counts.finished;
            let dispatched = kernel.whole_workgroups(active);
            let busy = unfinished_before.min(active as u64);
            profile::add_lanes(dispatched as u64, busy, started.elapsed());
            spent.dispatches += 1;
            spent.offered += busy * self.options.slice_iterations as u64;
            if count_in.profiling {
                let tallies = self.tallies(b, dispatched.min(n))?;
                count_in.dispatch(&tallies, lanes);
            }
            if let Some(between) = between.as_deref_mut() {
                let again = between.after(self, &b.states, &b.measures, finished)?;
                if !again.is_empty() {
                    // What no lane took yet, then the jobs queued again,
                    // on the idle lanes right after the busy ones packed
                    // together: scattered over every workgroup they
                    // would fill few of a warp's slots.
                    let taken = (next as usize).min(order.len());
                    order = [&order[taken..], &again[..]].concat();
                    finished -= again.len() as u64;
                    let busy = match self.options.compact {
                        true => self.compact(b, active)?,
                        false => active,
                    };
                    active = (busy + order.len()).clamp(1, lanes);
                    group = self.requeue(b, kernel, (&order, 0), active as u32, finished, cap);
                    next = 0;
                }
            }
            let unfinished = (n as u64).saturating_sub(finished);
            unfinished_before = unfinished;
            slice += 1;
            progress((finished - counts.parked).min(n as u64));
            let drained = next >= order.len() as u64;
            if let Some(round_cap) = cap {
                // A round ends once every instance finished or parked.
                if drained && unfinished == 0 {
                    if counts.parked <= hand_over {
                        return Ok(());
                    }
                    order = self.parked(b, counts.parked)?;
                    finished -= counts.parked;
                    unfinished_before = counts.parked;
                    let next = round_cap as u64 * ROUND_GROWTH_EIGHTHS / 8;
                    cap = Some(next.min(NO_CAP as u64 - 1) as u32);
                    active = order.len().clamp(1, lanes);
                    group = self.requeue(b, kernel, (&order, 0), active as u32, finished, cap);
                }
            } else {
                // Every instance started, and only the slow tail is left.
                let handed = drained
                    && between
                        .as_deref()
                        .is_some_and(|between| between.hand_over(unfinished));
                if unfinished == 0 || (drained && unfinished <= tail_size) || handed {
                    return Ok(());
                }
            }
            if slice_limit.is_some_and(|limit| slice >= limit) {
                return Ok(());
            }
            if crate::interrupt::interrupt_requested() {
                return Err(GpuError::Interrupted);
            }
            if slice >= max_slices {
                return Err(GpuError::Stalled {
                    unfinished: unfinished as u32,
                    slices: slice,
                });
            }
            // The queue is empty and a quarter of the lanes idle: the
            // busy ones into fewer workgroups.
            if self.options.compact && drained && 4 * unfinished <= 3 * active as u64 {
                active = self.compact(b, active)?.max(1);
            }
        }
    }

    /// Writes `order` as the queue, of which `taken` entries are on lanes,
    /// with `finished` jobs finished and none parked, and returns the bind
    /// group of the dispatches that work through it on `lanes` lanes under
    /// `cap` (`None`: no cap).
    fn requeue(
        &self,
        b: &Buffers,
        kernel: Kernel,
        (order, taken): (&[u32], usize),
        lanes: u32,
        finished: u64,
        cap: Option<u32>,
    ) -> wgpu::BindGroup {
        self.queue
            .write_buffer(&b.order, 0, bytemuck::cast_slice(order));
        self.queue.write_buffer(
            &b.counters,
            0,
            bytemuck::cast_slice(&[taken as u32, finished as u32, 0]),
        );
        let cap = cap.unwrap_or(NO_CAP);
        let control = self.control(
            self.options.slice_iterations,
            0,
            order.len() as u32,
            lanes,
            cap,
        );
        b.bind_group(self.device, kernel, &control)
    }

    /// A batch's lanes, each on its own instance, dispatched one slice of
    /// `iterations` at a time with no queue, for tests that follow a run
    /// step by step through the engine's protocol ([`Stepper`]).
    pub(super) fn stepper<'s, L: Lanes>(
        &'s self,
        work: Work<L>,
        kernel: Kernel<'s>,
        iterations: u32,
    ) -> Stepper<'s> {
        let n = work.instances.len();
        let steady = kernel.steady && super::readback::any_steady(work.instances);
        let b = Buffers::new::<L>(self.device, &work, steady, kernel);
        let control = self.control(iterations, 0, 0, n as u32, NO_CAP);
        let group = b.bind_group(self.device, kernel, &control);
        Stepper {
            runner: self,
            b,
            group,
            kernel,
            n,
        }
    }

    /// Records the batch's lanes, warps and critical path (`pidm
    /// --profile`).
    fn record_profile<L: Lanes>(
        &self,
        instances: &[Instance],
        out: &Readback<L>,
        probed: &[Probed],
        steady: bool,
        counted: Counted,
    ) {
        let n = instances.len();
        let Counted {
            warps, mut path, ..
        } = counted;
        path.longest_instance = out.0.iter().map(|s| L::steps(s) as u64).max().unwrap_or(0);
        path.mean_instance =
            out.0.iter().map(|s| L::steps(s) as f64).sum::<f64>() / n.max(1) as f64;
        // Predicted against taken, of the queued instances the device
        // finished.
        let (predicted, taken): (Vec<f64>, Vec<f64>) = probed
            .iter()
            .filter(|p| L::finished(&instances[p.index as usize], &out.0[p.index as usize]))
            .map(|p| {
                let taken = L::steps(&out.0[p.index as usize]) as f64;
                (warps::predicted_passes(p) + p.tally.passes() as f64, taken)
            })
            .unzip();
        path.ranking = warps::rank_correlation(&predicted, &taken);
        let bytes = LaneBytes {
            coefficients: size_of::<L::Coefficients>(),
            state: size_of::<L::State>(),
            measure: if steady { size_of::<L::Measure>() } else { 0 },
        };
        warps::record(&warps, path, bytes);
    }

    /// Every state, for a steady batch every measurement
    /// ([`readback::accumulators`]), and where the kernel measures the
    /// backward travel every instance's variation entry (the second half
    /// of the accumulators' buffer).
    fn read_back<L: Lanes>(
        &self,
        instances: &[Instance],
        b: &Buffers,
        steady: bool,
        backward: bool,
    ) -> Result<Readback<L>, GpuError> {
        let _reading = profile::span(Phase::Readback);
        let n = instances.len();
        let state_bytes = (n * size_of::<L::State>()) as u64;
        let head_bytes = (n * size_of::<L::Head>()) as u64;
        let states_read = readback::mappable(self.device, "states readback", state_bytes);
        let heads_read =
            steady.then(|| readback::mappable(self.device, "heads readback", head_bytes));
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&b.states, 0, &states_read, 0, state_bytes);
        if let Some(heads_read) = &heads_read {
            encoder.copy_buffer_to_buffer(&b.heads, 0, heads_read, 0, head_bytes);
        }
        self.queue.submit([encoder.finish()]);
        let states: Vec<L::State> = readback::with_mapped(self.device, &states_read, |bytes| {
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
        let measure_list: Vec<L::Measure> = match &heads_read {
            Some(heads_read) => readback::accumulators::<L>(
                self.device,
                self.queue,
                self.options.whole_accumulators,
                instances,
                &states,
                (heads_read, &b.measures),
                &mut read,
            )?,
            None => Vec::new(),
        };
        let variations = if backward {
            readback::variations::<L>(self.device, self.queue, &b.measures, n)?
        } else {
            Vec::new()
        };
        profile::add_bytes_read(
            state_bytes
                + if steady { head_bytes } else { 0 }
                + ((read.count + variations.len()) * size_of::<L::Measure>()) as u64,
        );
        Ok((states, measure_list, variations))
    }
}

/// What [`Runner::stepper`] gives: one dispatch at a time, the states read
/// back after each.
pub(super) struct Stepper<'s> {
    runner: &'s Runner<'s>,
    b: Buffers,
    group: wgpu::BindGroup,
    kernel: Kernel<'s>,
    n: usize,
}

impl Stepper<'_> {
    /// One dispatch; every instance's state after it.
    pub(super) fn step<L: Lanes>(&self) -> Result<Vec<L::State>, GpuError> {
        let r = self.runner;
        r.dispatch(&self.b, self.kernel, &self.group, self.n)?;
        let bytes = (self.n * size_of::<L::State>()) as u64;
        let read = readback::mappable(r.device, "stepper states", bytes);
        let mut encoder = r.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.b.states, 0, &read, 0, bytes);
        r.queue.submit([encoder.finish()]);
        readback::with_mapped(r.device, &read, |bytes| {
            bytes
                .chunks_exact(size_of::<L::State>())
                .map(bytemuck::pod_read_unaligned)
                .collect()
        })
    }
}
