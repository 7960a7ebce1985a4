//! Karnopp's host mirrors of its shader's storage structs, one set per
//! precision, and the packing of instances into them; each precision's
//! module also holds the floor's structs (`crate::gpu::layout`), so that a
//! Karnopp lane's buffers are one module's.
//!
//! Every struct here has a WGSL twin of the same name in
//! `shaders/karnopp/`. Padding is explicit, so the structs are `Pod` and
//! their bytes are exactly what the shader reads; the test
//! `shader_layout_matches_host_structs` checks every size and member offset
//! against naga's layouter, so the two cannot drift apart.
//!
//! The f32 shader runs in micrometres and milliseconds (see [`Units`]), which
//! keeps every intermediate of the integrator, notably the derivatives of the
//! stage Taylor series (rate^n), inside the f32 range. The f64 shader runs in
//! SI units, exactly like the CPU. Either way the per-instance constants are
//! [`crate::laws::karnopp::integrate::Coefficients`], computed in f64 and rounded once.

use crate::laws::Settings;
use crate::laws::status::STATUS_OK;
use crate::model::{AXES, Instance};

use crate::gpu::layout::host_struct;
pub use crate::gpu::layout::{F32x2, F64x2, HostLayout, PROBE_PASSES, U32x2, Units, control};

/// Declares the storage structs of one precision in a module, with the
/// packing of instances and the unpacking of results.
macro_rules! precision_structs {
    ($module:ident, $mirror:ident) => {
        /// Storage structs of one precision.
        pub mod $module {
            use super::*;
            use crate::laws::floor::{Vec2, phase};
            use crate::laws::karnopp::$mirror::integrate as mirror;
            // The floor's structs of this precision, as this module's own.
            pub use crate::gpu::layout::$mirror::*;
            use mirror::coefficients::Oscillator as MirrorOscillator;

            fn u32x2(v: [u32; 2]) -> U32x2 {
                U32x2 { x: v[0], y: v[1] }
            }

            fn v2(v: mirror::Vec2) -> V2 {
                V2 { x: v.x, y: v.y }
            }

            fn vec2(v: V2) -> mirror::Vec2 {
                mirror::Vec2::new(v.x, v.y)
            }

            host_struct! {
                /// `pidm::laws::karnopp::integrate::coefficients::Oscillator`.
                pub struct Oscillator {
                    pub mass: V2,
                    pub sigma: V2,
                    pub w2: V2,
                    pub rate: V2,
                    pub inv_mass: V2,
                    pub inv_w2: V2,
                }
            }

            host_struct! {
                /// `pidm::laws::karnopp::integrate::Coefficients` in shader units.
                pub struct Coefficients {
                    pub stiffness: V2,
                    pub damping: V2,
                    pub inv_stiffness: V2,
                    pub stick: Oscillator,
                    pub slip: Oscillator,
                    pub amplitude: V2,
                    pub frequency: V2,
                    pub duty: V2,
                    pub inv_duty: V2,
                    pub inv_fall: V2,
                    pub rise_slope: V2,
                    pub fall_slope: V2,
                    pub phase: V2,
                    pub cycles_per_period: V2,
                    pub rise_time: V2,
                    pub rise_time_lo: V2,
                    pub fall_time: V2,
                    pub fall_time_lo: V2,
                    pub first_corner: V2,
                    pub first_corner_lo: V2,
                    pub stage_share: V2,
                    pub slider_share: V2,
                    pub slip_scale: V2,
                    pub slip_b: V2,
                    pub load_need: V2,
                    pub load_accel: V2,
                    pub neg_load: V2,
                    pub neg_load_accel: V2,
                    pub slip_b_max: Real,
                    pub hold2: Real,
                    pub safe_hold2: Real,
                    pub ms2: Real,
                    pub two_ms2: Real,
                    pub coulomb: Real,
                    pub fc_over_ms: Real,
                    pub band: Real,
                    pub band2: Real,
                    pub period: Real,
                    pub period_lo: Real,
                    pub event_step_stuck: Real,
                    pub event_step_slip: Real,
                    pub min_step: Real,
                    pub tolerance: Real,
                    pub collocation_tolerance: Real,
                    pub cycles: u32,
                    pub settle: u32,
                    pub budget: u32,
                    pub frictionless: u32,
                    pub driven: U32x2,
                    pub phase_fixed: U32x2,
                    pub cycles_fixed: U32x2,
                    pub cycles_fixed_lo: U32x2,
                    /// The axes' segments in the batch's buffer (binding
                    /// 12), set per batch (`segment_buffer`); the count is
                    /// 0 where the drive is a sawtooth's.
                    pub segment_first: U32x2,
                    pub segment_count: U32x2,
                    pub se_limit2: V2,
                    pub repeat_x: Real,
                    pub repeat_v: Real,
                    pub steady: u32,
                    pub common_period: u32,
                    pub batch_length: u32,
                    pub min_batch: u32,
                    pub phase_levels: u32,
                    pub phase_lattice: u32,
                    pub replica: u32,
                    pub replicas: u32,
                    pub gaps: [Gaps; phase::LEVELS],
                }
            }

            host_struct! {
                /// `pidm::laws::karnopp::integrate::State` in shader units, plus the
                /// low part of the two-part time.
                pub struct State {
                    pub x_p: V2,
                    pub v_p: V2,
                    pub x_s: V2,
                    pub v_s: V2,
                    pub v_rel: V2,
                    pub held: V2,
                    pub settle_x_s: V2,
                    pub cycle_phase: V2,
                    pub next_corner: V2,
                    pub corner_at: V2,
                    pub corner_at_lo: V2,
                    pub time: Real,
                    pub time_lo: Real,
                    pub h_slip: Real,
                    pub h_accepted: Real,
                    pub err_accepted: Real,
                    pub _pad: Real,
                    pub segment: U32x2,
                    pub mode: u32,
                    pub period: u32,
                    pub status: u32,
                    pub steps: u32,
                    pub stalled: u32,
                    pub rejections: u32,
                    pub measured: u32,
                    /// GPU only: dispatches in a row in which the loop limiter
                    /// cut the instance's first iteration short (`entry.wgsl`).
                    pub limited: u32,
                    pub _pad_v: U32x2,
                }
            }

            /// The CPU state, in SI units, that a reduction reads of a
            /// finished shader state: status, period and slider positions.
            pub fn reduced_state(st: &State) -> crate::laws::karnopp::integrate::State {
                let length = |v: V2| Vec2::new(v.x as f64, v.y as f64) * (1.0 / UNITS.metre);
                let mut out = crate::laws::karnopp::integrate::State {
                    mode: crate::laws::karnopp::integrate::MODE_STICK,
                    status: STATUS_OK,
                    ..Default::default()
                };
                out.x_s = length(st.x_s);
                out.settle_x_s = length(st.settle_x_s);
                out.status = st.status;
                out.period = st.period;
                out.measured = st.measured;
                out.steps = st.steps;
                out
            }

            fn oscillator(o: &MirrorOscillator) -> Oscillator {
                Oscillator {
                    mass: v2(o.mass),
                    sigma: v2(o.sigma),
                    w2: v2(o.w2),
                    rate: v2(o.rate),
                    inv_mass: v2(o.inv_mass),
                    inv_w2: v2(o.inv_w2),
                }
            }

            /// Packs one instance and the batch settings in shader units:
            /// the CPU mirror's coefficients (`Coefficients::of`: computed
            /// in f64 from the instance in these units and rounded once).
            pub fn pack(inst: &Instance, settings: &Settings) -> Coefficients {
                pack_replica(inst, settings, crate::laws::Replica::NONE)
            }

            /// [`pack`] for replica `r` of a split run (`inst` the
            /// replica's instance; `Coefficients::of_replica`).
            pub fn pack_replica(
                inst: &Instance,
                settings: &Settings,
                r: crate::laws::Replica,
            ) -> Coefficients {
                packed(&mirror::Coefficients::of_replica(inst, settings, r))
            }

            /// The CPU mirror's coefficients `c` in this layout (LuGre's
            /// runs pack their own: `crate::gpu::lugre`).
            pub fn packed(c: &mirror::Coefficients) -> Coefficients {
                // The shader drives sawtooths: its rise is the mirror's
                // first segment and its fall the second (none at duty 1).
                let rise = |f: fn(&mirror::drive::Segment) -> mirror::Real| {
                    v2(mirror::Vec2::new(
                        f(&c.segments[0][0]),
                        f(&c.segments[1][0]),
                    ))
                };
                let fall = |f: fn(&mirror::drive::Segment) -> mirror::Real| {
                    let at = |i: usize| c.segments[i].get(1).map_or(0.0, f);
                    v2(mirror::Vec2::new(at(0), at(1)))
                };
                Coefficients {
                    stiffness: v2(c.stiffness),
                    damping: v2(c.damping),
                    inv_stiffness: v2(c.inv_stiffness),
                    stick: oscillator(&c.stick),
                    slip: oscillator(&c.slip),
                    amplitude: v2(c.amplitude),
                    frequency: v2(c.frequency),
                    duty: rise(|s| s.end),
                    inv_duty: rise(|s| s.per_cycle),
                    inv_fall: fall(|s| -s.per_cycle),
                    rise_slope: rise(|s| s.slope),
                    fall_slope: fall(|s| s.slope),
                    phase: v2(c.phase),
                    cycles_per_period: v2(c.cycles_per_period),
                    rise_time: rise(|s| s.time),
                    rise_time_lo: rise(|s| s.time_lo),
                    fall_time: fall(|s| s.time),
                    fall_time_lo: fall(|s| s.time_lo),
                    first_corner: v2(c.first_corner),
                    first_corner_lo: v2(c.first_corner_lo),
                    stage_share: v2(c.stage_share),
                    slider_share: v2(c.slider_share),
                    slip_scale: v2(c.slip_scale),
                    slip_b: v2(c.slip_b),
                    load_need: v2(c.load_need),
                    load_accel: v2(c.load_accel),
                    neg_load: v2(c.neg_load),
                    neg_load_accel: v2(c.neg_load_accel),
                    slip_b_max: c.slip_b_max,
                    hold2: c.hold2,
                    safe_hold2: c.safe_hold2,
                    ms2: c.ms2,
                    two_ms2: c.two_ms2,
                    coulomb: c.coulomb,
                    fc_over_ms: c.fc_over_ms,
                    band: c.band,
                    band2: c.band2,
                    period: c.period,
                    period_lo: c.period_lo,
                    event_step_stuck: c.event_step_stuck,
                    event_step_slip: c.event_step_slip,
                    min_step: c.min_step,
                    tolerance: c.tolerance,
                    collocation_tolerance: c.collocation_tolerance,
                    cycles: c.cycles,
                    settle: c.settle,
                    budget: c.budget,
                    frictionless: c.frictionless as u32,
                    driven: U32x2 {
                        x: c.driven[0] as u32,
                        y: c.driven[1] as u32,
                    },
                    phase_fixed: u32x2(c.phase_fixed),
                    cycles_fixed: u32x2(c.cycles_fixed),
                    cycles_fixed_lo: u32x2(c.cycles_fixed_lo),
                    segment_first: U32x2::default(),
                    segment_count: {
                        let count = |s: &[mirror::drive::Segment]| {
                            if mirror::drive::is_sawtooth(s) {
                                0
                            } else {
                                s.len() as u32
                            }
                        };
                        U32x2 {
                            x: count(&c.segments[0]),
                            y: count(&c.segments[1]),
                        }
                    },
                    se_limit2: v2(c.se_limit2),
                    repeat_x: c.repeat_x,
                    repeat_v: c.repeat_v,
                    steady: c.steady as u32,
                    common_period: c.common_period,
                    batch_length: c.batch_length,
                    min_batch: c.min_batch,
                    phase_levels: c.phase_levels,
                    phase_lattice: c.phase_lattice,
                    replica: c.replica,
                    replicas: c.replicas,
                    gaps: gaps(&c.gaps),
                }
            }

            /// The CPU mirror's state this shader state stands for: the
            /// same quantities in the same units, so the mirror can
            /// continue an instance where the GPU stopped.
            pub fn to_cpu(st: &State) -> mirror::State {
                mirror::State {
                    x_p: vec2(st.x_p),
                    v_p: vec2(st.v_p),
                    x_s: vec2(st.x_s),
                    v_s: vec2(st.v_s),
                    v_rel: vec2(st.v_rel),
                    held: vec2(st.held),
                    settle_x_s: vec2(st.settle_x_s),
                    cycle_phase: vec2(st.cycle_phase),
                    next_corner: vec2(st.next_corner),
                    corner_at: vec2(st.corner_at),
                    corner_at_lo: vec2(st.corner_at_lo),
                    time: st.time,
                    time_lo: st.time_lo,
                    h_slip: st.h_slip,
                    h_accepted: st.h_accepted,
                    err_accepted: st.err_accepted,
                    segment: [st.segment.x, st.segment.y],
                    mode: st.mode,
                    period: st.period,
                    status: st.status,
                    steps: st.steps,
                    stalled: st.stalled,
                    rejections: st.rejections,
                    measured: st.measured,
                }
            }

            impl Coefficients {
                /// The shader's parts these coefficients use: a steady
                /// measurement, the phase ladder, a non-zero load term
                /// (`Parts::of_coefficients`, in this precision).
                pub fn parts(&self) -> crate::gpu::shader::Parts {
                    let nonzero = |v: V2| v.x != 0.0 || v.y != 0.0;
                    crate::gpu::shader::Parts {
                        steady: self.steady == 1,
                        phase: self.steady == 1 && self.phase_levels != 0,
                        load: nonzero(self.load_need)
                            || nonzero(self.load_accel)
                            || nonzero(self.neg_load)
                            || nonzero(self.neg_load_accel),
                        waveform: self.segment_count.x != 0 || self.segment_count.y != 0,
                        // A setting, not a coefficient: the runner adds it
                        // (`Parts::with_settings`).
                        backward: false,
                    }
                }
            }

            host_struct! {
                /// `pidm::laws::karnopp::integrate::drive::Segment`.
                pub struct Segment {
                    pub end: Real,
                    pub length: Real,
                    pub level: Real,
                    pub per_cycle: Real,
                    pub slope: Real,
                    pub time: Real,
                    pub time_lo: Real,
                    pub _pad: Real,
                }
            }

            /// A waveform batch's segment buffer (binding 12): every
            /// instance's segments, x then y, each axis' first entry and
            /// count set in its coefficients (a sawtooth's too: the
            /// waveform variant reads every instance's segments, which are
            /// the sawtooth's coefficients' arithmetic, bit for bit).
            pub fn segment_buffer(
                instances: &[Instance],
                coefficients: &mut [Coefficients],
            ) -> Vec<Segment> {
                let mut out = Vec::new();
                for (inst, c) in instances.iter().zip(coefficients.iter_mut()) {
                    let segments = mirror::Coefficients::segments_of(inst);
                    let mut first = [0u32; AXES];
                    let mut count = [0u32; AXES];
                    for axis in 0..AXES {
                        first[axis] = out.len() as u32;
                        count[axis] = segments[axis].len() as u32;
                        out.extend(segments[axis].iter().map(|s| Segment {
                            end: s.end,
                            length: s.length,
                            level: s.level,
                            per_cycle: s.per_cycle,
                            slope: s.slope,
                            time: s.time,
                            time_lo: s.time_lo,
                            _pad: 0.0,
                        }));
                    }
                    c.segment_first = u32x2(first);
                    c.segment_count = u32x2(count);
                }
                out
            }

            /// True once the instance ended, normally or with a status.
            pub fn finished(inst: &Instance, st: &State) -> bool {
                st.status != STATUS_OK || st.period >= inst.cycles || st.measured != 0
            }

            /// The outcome of a finished state, back in SI units: the slider
            /// displacement over the measured periods, or zero where the
            /// instance did not finish normally (as the CPU reports it).
            pub fn unpack(inst: &Instance, st: &State) -> crate::gpu::GpuOutcome {
                let mut displacement = [0.0; AXES];
                if st.status == STATUS_OK && st.period >= inst.cycles {
                    displacement = [
                        (st.x_s.x as f64 - st.settle_x_s.x as f64) / UNITS.metre,
                        (st.x_s.y as f64 - st.settle_x_s.y as f64) / UNITS.metre,
                    ];
                }
                crate::gpu::GpuOutcome {
                    displacement,
                    span: (inst.cycles - inst.settle) as f64,
                    se: [0.0; AXES],
                    periods: inst.cycles,
                    lag: 0,
                    status: st.status,
                    motion: crate::model::motion::Motion::Undetermined,
                    steps: st.steps,
                    cpu_fallback: false,
                    shader_status: 0,
                    finished_on_cpu: false,
                    checked: false,
                    replicas: 1,
                    variation: [0.0; AXES],
                    variation_se: [0.0; AXES],
                }
            }
        }
    };
}

precision_structs!(single, single);
precision_structs!(double, double);

#[cfg(test)]
mod tests;
