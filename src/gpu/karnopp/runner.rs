//! Karnopp's lanes for the engine, one per precision (`Single`, `Double`:
//! `Lanes`), and the host side of each (`Layout`: the f32 and f64
//! shaders' storage structs, their packing and reduction) for the runner.

use super::layout;
use super::shader::per_lane;
use crate::gpu::*;
use crate::laws::Replica;
use crate::laws::floor::variation::Variation;

/// The host side of one precision of Karnopp's lanes: packing, outcomes,
/// replicas and continuation (the engine's part is [`Lanes`]).
pub(in crate::gpu) trait Layout: Lanes<Pilot = GpuOutcome> {
    /// The CPU mirror's state of this precision.
    type Mirror;
    fn mirror(st: &Self::State) -> Self::Mirror;
    fn pack(inst: &Instance, settings: &Settings) -> Self::Coefficients;
    /// A waveform batch's segment buffer as bytes, each instance's
    /// segments located in its coefficients (`layout::segment_buffer`).
    fn segment_buffer(instances: &[Instance], coefficients: &mut [Self::Coefficients]) -> Vec<u8>;
    /// The shader's parts that packed coefficients use.
    fn parts(c: &Self::Coefficients) -> Parts;
    /// The outcome of a finished fixed window.
    fn unpack(inst: &Instance, st: &Self::State) -> GpuOutcome;
    /// The outcome of a finished steady measurement, through the one
    /// reduction every backend's results pass through.
    fn reduce(inst: &Instance, st: &Self::State, m: &Self::Measure) -> GpuOutcome;
    /// The CPU integrator's run for an unfinished shader state (and the
    /// accumulators of a steady measurement), where the CPU can continue
    /// from it (f64), or `None` where the CPU must start the instance over
    /// (f32: the slow tail is where f32 is least sure; the f64 reference
    /// starts it over).
    fn continuable(inst: &Instance, st: &Self::State, m: Option<&Self::Measure>) -> Option<Run>;
    /// [`Layout::continuable`]'s run with the backward travel's entry `v`
    /// of the lane (`shaders/karnopp/variation.wgsl`) as the CPU's
    /// variation (f64; `None` in f32, which never measures it).
    fn followed(
        inst: &Instance,
        st: &Self::State,
        m: Option<&Self::Measure>,
        v: &Self::Measure,
    ) -> Option<(Run, Variation)>;
    /// Packs replica `r` of a split run (`inst` the replica's instance).
    fn pack_replica(inst: &Instance, settings: &Settings, r: Replica) -> Self::Coefficients;
    /// A replica's run as a group reads it (`replicas::Member::of`): status,
    /// `measured` and period, and the accumulators, in SI units.
    fn group_run(st: &Self::State, m: &Self::Measure) -> Run;
    /// The status, `measured` and period of a state, as a group's step
    /// reads them between dispatches.
    fn progress(st: &Self::State) -> (u32, u32, u32);
    /// Byte offsets of `State::measured` and `Measure::verdict`, which the
    /// host writes to set a group's replicas going again.
    const MEASURED_OFFSET: usize;
    const VERDICT_OFFSET: usize;
}

/// A steady outcome from the shader's state and accumulators converted to
/// the CPU's, in SI units.
pub(in crate::gpu) fn reduce_shader(
    inst: &Instance,
    state: crate::laws::karnopp::integrate::State,
    measure: crate::laws::karnopp::integrate::Measure,
) -> GpuOutcome {
    let steps = state.steps;
    GpuOutcome::of(&reduce(inst, &Run { state, measure }.ended()), steps)
}

pub(in crate::gpu) struct Single;
pub(in crate::gpu) struct Double;

impl Lanes for Single {
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
    fn steps(st: &Self::State) -> u32 {
        st.steps
    }
    type Pilot = GpuOutcome;
    fn pilot(inst: &Instance, settings: &Settings) -> Option<GpuOutcome> {
        Some(pilot(inst, settings))
    }
    fn pilot_steps(p: &GpuOutcome) -> u32 {
        p.steps
    }
    fn finished(inst: &Instance, st: &Self::State) -> bool {
        layout::single::finished(inst, st)
    }
    fn slice_bound(instances: &[Instance], settings: &Settings) -> u64 {
        crate::gpu::runner::slice_bound(instances, settings)
    }
}

impl Layout for Single {
    type Mirror = crate::laws::karnopp::single::integrate::State;
    fn mirror(st: &Self::State) -> Self::Mirror {
        layout::single::to_cpu(st)
    }
    fn pack(inst: &Instance, settings: &Settings) -> Self::Coefficients {
        layout::single::pack(inst, settings)
    }
    fn segment_buffer(instances: &[Instance], coefficients: &mut [Self::Coefficients]) -> Vec<u8> {
        bytemuck::cast_slice(&layout::single::segment_buffer(instances, coefficients)).to_vec()
    }
    fn parts(c: &Self::Coefficients) -> Parts {
        c.parts()
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
    fn followed(
        _: &Instance,
        _: &Self::State,
        _: Option<&Self::Measure>,
        _: &Self::Measure,
    ) -> Option<(Run, Variation)> {
        None
    }
    fn continuable(_: &Instance, _: &Self::State, _: Option<&Self::Measure>) -> Option<Run> {
        None
    }
    fn pack_replica(inst: &Instance, settings: &Settings, r: Replica) -> Self::Coefficients {
        layout::single::pack_replica(inst, settings, r)
    }
    fn group_run(st: &Self::State, m: &Self::Measure) -> Run {
        Run {
            state: layout::single::reduced_state(st),
            measure: layout::single::measure_to_cpu(m),
        }
    }
    fn progress(st: &Self::State) -> (u32, u32, u32) {
        (st.status, st.measured, st.period)
    }
    const MEASURED_OFFSET: usize = std::mem::offset_of!(layout::single::State, measured);
    const VERDICT_OFFSET: usize = std::mem::offset_of!(layout::single::Measure, verdict);
}

impl Lanes for Double {
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
    fn steps(st: &Self::State) -> u32 {
        st.steps
    }
    type Pilot = GpuOutcome;
    fn pilot(inst: &Instance, settings: &Settings) -> Option<GpuOutcome> {
        Some(pilot(inst, settings))
    }
    fn pilot_steps(p: &GpuOutcome) -> u32 {
        p.steps
    }
    fn finished(inst: &Instance, st: &Self::State) -> bool {
        layout::double::finished(inst, st)
    }
    fn slice_bound(instances: &[Instance], settings: &Settings) -> u64 {
        crate::gpu::runner::slice_bound(instances, settings)
    }
}

impl Layout for Double {
    type Mirror = crate::laws::karnopp::integrate::State;
    fn mirror(st: &Self::State) -> Self::Mirror {
        layout::double::to_cpu(st)
    }
    fn pack(inst: &Instance, settings: &Settings) -> Self::Coefficients {
        layout::double::pack(inst, settings)
    }
    fn segment_buffer(instances: &[Instance], coefficients: &mut [Self::Coefficients]) -> Vec<u8> {
        bytemuck::cast_slice(&layout::double::segment_buffer(instances, coefficients)).to_vec()
    }
    fn parts(c: &Self::Coefficients) -> Parts {
        c.parts()
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
    fn continuable(inst: &Instance, st: &Self::State, m: Option<&Self::Measure>) -> Option<Run> {
        let c = crate::laws::karnopp::integrate::Coefficients::new(
            inst,
            &Settings::default(),
            f64::EPSILON,
        );
        Some(Run {
            state: layout::double::to_cpu(st),
            measure: match m {
                Some(m) => layout::double::measure_to_cpu(m),
                None => initial_measure(&c),
            },
        })
    }
    fn followed(
        inst: &Instance,
        st: &Self::State,
        m: Option<&Self::Measure>,
        v: &Self::Measure,
    ) -> Option<(Run, Variation)> {
        let run = Self::continuable(inst, st, m)?;
        Some((run, crate::gpu::layout::variation_to_cpu(v)))
    }
    fn pack_replica(inst: &Instance, settings: &Settings, r: Replica) -> Self::Coefficients {
        layout::double::pack_replica(inst, settings, r)
    }
    fn group_run(st: &Self::State, m: &Self::Measure) -> Run {
        Run {
            state: layout::double::to_cpu(st),
            measure: layout::double::measure_to_cpu(m),
        }
    }
    fn progress(st: &Self::State) -> (u32, u32, u32) {
        (st.status, st.measured, st.period)
    }
    const MEASURED_OFFSET: usize = std::mem::offset_of!(layout::double::State, measured);
    const VERDICT_OFFSET: usize = std::mem::offset_of!(layout::double::Measure, verdict);
}

/// A round's pilot run: the CPU's f64 run from the start, counted as the
/// CPU tail's (`rounds::first_cap`).
fn pilot(inst: &Instance, settings: &Settings) -> GpuOutcome {
    GpuOutcome {
        finished_on_cpu: true,
        ..on_cpu(inst, settings, None)
    }
}

/// One instance integrated on the CPU, which the shader mirrors, as a GPU
/// outcome (the caller marks why it ran there): from its start, or from a
/// run the f64 shader left unfinished. One that measures the backward
/// travel from its start keeps it ([`on_cpu_followed`]); from a shader's
/// run it needs the lane's variation, which only `on_cpu_followed` takes.
pub(in crate::gpu) fn on_cpu(
    inst: &Instance,
    settings: &Settings,
    from: Option<Run>,
) -> GpuOutcome {
    if settings.backward && from.is_none() {
        return on_cpu_followed(inst, settings, None);
    }
    let run = match from {
        Some(run) => {
            crate::laws::karnopp::integrate::continue_instance_until(inst, settings, run, || false)
                .expect("never asked to stop")
        }
        None => run_instance(inst, settings),
    };
    GpuOutcome::of(&reduce(inst, &run.ended()), run.state.steps)
}

/// [`on_cpu`] keeping the backward travel (`Settings::backward`): from its
/// start, or from a run and variation the f64 shader left unfinished
/// (`Layout::followed`), as `laws::karnopp::variation` keeps it.
pub(in crate::gpu) fn on_cpu_followed(
    inst: &Instance,
    settings: &Settings,
    from: Option<(Run, Variation)>,
) -> GpuOutcome {
    use crate::laws::karnopp::variation;
    let (run, v) = match from {
        Some((run, mut v)) => {
            let c = crate::laws::karnopp::integrate::Coefficients::of(inst, settings);
            let run =
                variation::continue_until(&c, run, &mut v, || false).expect("never asked to stop");
            (run, v)
        }
        None => variation::run_until(inst, settings, || false).expect("never asked to stop"),
    };
    let run = run.ended();
    let (variation, variation_se) = crate::measurement::reduce_variation(inst, &run, &v);
    GpuOutcome {
        variation,
        variation_se,
        ..GpuOutcome::of(&reduce(inst, &run), run.record.steps)
    }
}

/// The binding of a waveform variant's segments (`segments.wgsl`).
pub(in crate::gpu) const SEGMENT_BINDING: u32 = 12;

/// A waveform variant's segment buffer for a batch of `instances`, whose
/// coefficients it locates their segments in; `None` for a sawtooth
/// variant, which binds none.
pub(in crate::gpu) fn segment_binding<L: Layout>(
    device: &wgpu::Device,
    variant: Variant,
    instances: &[Instance],
    coefficients: &mut [L::Coefficients],
) -> Option<wgpu::Buffer> {
    if !variant.parts.waveform {
        return None;
    }
    let bytes = L::segment_buffer(instances, coefficients);
    Some(wgpu::util::DeviceExt::create_buffer_init(
        device,
        &wgpu::util::BufferInitDescriptor {
            label: Some("segments"),
            contents: &bytes,
            usage: wgpu::BufferUsages::STORAGE,
        },
    ))
}

/// The bindings of a batch's segment buffer, where it has one.
pub(in crate::gpu) fn segment_entries(
    segments: &Option<wgpu::Buffer>,
) -> Vec<(u32, &wgpu::Buffer)> {
    segments.iter().map(|b| (SEGMENT_BINDING, b)).collect()
}

impl<'p> Kernel<'p> {
    /// Karnopp's pipeline of `variant`, binding `segments` where it is a
    /// waveform variant's ([`segment_binding`]).
    pub(in crate::gpu) fn with_segments(
        pipeline: &'p wgpu::ComputePipeline,
        variant: Variant,
        extra: &'p [(u32, &'p wgpu::Buffer)],
    ) -> Kernel<'p> {
        Kernel {
            extra,
            ..Kernel::of_variant(pipeline, variant)
        }
    }

    /// Karnopp's pipeline of `variant`.
    pub(in crate::gpu) fn of_variant(
        pipeline: &'p wgpu::ComputePipeline,
        variant: Variant,
    ) -> Kernel<'p> {
        Kernel {
            pipeline,
            steady: variant.parts.steady,
            loop_limiter: variant.loop_limiter,
            backward: variant.parts.backward,
            workgroup_size: workgroup_size(),
            extra: &[],
            per_lane: per_lane(variant),
        }
    }
}
