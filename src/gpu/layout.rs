//! The engine's host mirrors of the shader's storage structs, shared by
//! every law: [`HostLayout`] and the `host_struct!` macro that declares
//! them, WGSL's vectors, the per-dispatch [`control`] structs of
//! `shaders/engine/`, and, per precision ([`single`], [`double`]), the
//! floor's measurement structs of `shaders/shared/` (`Gaps`, `Snapshot`,
//! `LevelSums`, `Phase`, `Measure`, the queue's `Head`) with their
//! conversion to the CPU's. A law's own structs (its coefficients and
//! state) are in its folder's `layout.rs`.
//!
//! Padding is explicit, so the structs are `Pod` and their bytes are
//! exactly what the shader reads; each law's layout test holds every size
//! and member offset against naga's layouter of its shader.

pub use crate::laws::floor::units::Units;

/// A struct shared with the shader: its WGSL name and the byte offset of
/// every member, in declaration order, which a unit test holds against
/// naga's layout of the shader.
pub trait HostLayout: bytemuck::Pod {
    /// The name of the WGSL struct it mirrors.
    const NAME: &'static str;
    /// (member name, byte offset) in declaration order.
    fn members() -> Vec<(&'static str, usize)>;
}

/// Declares a `#[repr(C)]` `Pod` struct and its [`HostLayout`].
macro_rules! host_struct {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[$field_meta:meta])* pub $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
        pub struct $name {
            $( $(#[$field_meta])* pub $field: $ty ),*
        }

        impl $crate::gpu::layout::HostLayout for $name {
            const NAME: &'static str = stringify!($name);
            fn members() -> Vec<(&'static str, usize)> {
                vec![$( (stringify!($field), std::mem::offset_of!($name, $field)) ),*]
            }
        }
    };
}
pub(crate) use host_struct;

/// Passes of the shader's loop-limiter probe (`loop_limiter_intact`): more
/// than the two a truncated loop can still make when the compiler has
/// peeled its first pass.
pub const PROBE_PASSES: u32 = 4;

/// WGSL's `vec2<u32>` (8-byte aligned).
#[repr(C, align(8))]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct U32x2 {
    pub x: u32,
    pub y: u32,
}

/// WGSL's `vec2<f32>` (8-byte aligned).
#[repr(C, align(8))]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct F32x2 {
    pub x: f32,
    pub y: f32,
}

/// WGSL's `vec2<f64>` (16-byte aligned).
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct F64x2 {
    pub x: f64,
    pub y: f64,
}

/// The per-dispatch controls (precision independent).
pub mod control {
    host_struct! {
        /// The controls of one dispatch (a read-only storage buffer).
        pub struct Control {
            /// Iterations of `iterate` in the dispatch.
            pub max_iterations: u32,
            /// 1 when the shader must first set every state to its initial
            /// value.
            pub initialize: u32,
            /// Always 1.0: a factor the shader compiler cannot fold, which
            /// keeps the compensated time sum exact.
            pub one: f32,
            /// Passes of the shader's loop-limiter probe, hidden from the
            /// shader compiler ([`super::PROBE_PASSES`] but in tests).
            pub probe: u32,
            /// Passes the probe must complete for the iteration to stand;
            /// equal to `probe`.
            pub probe_min: u32,
            /// Always 0: hidden from the shader compiler like `probe`.
            pub zero: u32,
            /// Entries of the queue (`order`) lanes may take: 0 in a
            /// batch's first dispatch, where every lane starts its own.
            pub queued: u32,
            /// Lanes that take from the queue when they hold no instance
            /// at the dispatch's start (replica members queued again,
            /// `gpu::groups`); 0 in the first dispatch.
            pub lanes: u32,
            /// The round's cap on an instance's steps ([`NO_CAP`]: none):
            /// a lane parks an instance at its first iteration boundary
            /// at or past it (`pidm::gpu::slices`, the rounds).
            pub cap: u32,
        }
    }

    /// [`Control::cap`] of a dispatch that parks nothing.
    pub const NO_CAP: u32 = u32::MAX;

    host_struct! {
        /// What one lane did in one dispatch (`pidm::gpu::warps`).
        pub struct Tally {
            /// Iterations by kind (`constants::ITERATION_*` 0-3): boundary,
            /// stick, slip, rejected trial.
            pub kinds: [u32; 4],
            /// Event locations, period ends, instances taken from the
            /// queue, and the instance held at the end (`u32::MAX`: none).
            pub more: [u32; 4],
            /// Scene periods the held instance has run, at the end.
            pub progress: f32,
            /// The f64 helpers' emulated divisions and roots (`recip`,
            /// `root`, `recip_root` calls; 0 in f32) in the dispatch.
            pub emulated: u32,
            pub _pad_v: super::U32x2,
        }
    }
}

/// Declares the floor's storage structs of one precision in a module
/// (`$floor`: the floor's CPU module of that precision).
macro_rules! floor_structs {
    ($module:ident, $real:ty, $v2:ident, $floor:ident) => {
        /// The floor's storage structs of one precision.
        pub mod $module {
            use super::*;
            use crate::laws::floor::Vec2;
            use crate::laws::floor::{measure, phase};

            /// The scalar type of this precision.
            pub type Real = $real;
            /// WGSL's `vec2<Real>`.
            pub type V2 = $v2;

            /// The unit system this precision computes in (the floor's).
            pub const UNITS: Units = crate::laws::floor::$floor::precision::UNITS;

            host_struct! {
                /// `pidm::laws::floor::phase::Gaps`: the three-gap
                /// table of one window length.
                pub struct Gaps {
                    pub a: u32,
                    pub b: u32,
                    pub alpha: Real,
                    pub beta: Real,
                }
            }

            host_struct! {
                /// `pidm::laws::floor::measure::Snapshot` in shader units.
                pub struct Snapshot {
                    pub x_p: V2,
                    pub v_p: V2,
                    pub v_s: V2,
                    pub x_s: V2,
                    pub mode: u32,
                    pub _pad_u: u32,
                    pub _pad_v: U32x2,
                }
            }

            host_struct! {
                /// `pidm::laws::floor::phase::LevelSums` in shader units
                /// (its quarters as four members: the shader indexes no
                /// private array at run time).
                pub struct LevelSums {
                    pub whole: V2,
                    pub half: V2,
                    pub second: V2,
                    pub q0: V2,
                    pub q1: V2,
                    pub q2: V2,
                    pub q3: V2,
                }
            }

            host_struct! {
                /// `pidm::laws::floor::phase::Phase` in shader units.
                pub struct Phase {
                    pub whole: [V2; phase::LEVELS],
                    pub second: [V2; phase::LEVELS],
                    pub quarters: [V2; 4],
                    pub pending: LevelSums,
                }
            }

            host_struct! {
                /// `pidm::laws::floor::measure::Measure` in shader units.
                pub struct Measure {
                    pub last_x_s: V2,
                    pub batch_start: V2,
                    pub d_min: V2,
                    pub d_max: V2,
                    pub travel: V2,
                    pub sums: [V2; measure::BATCHES],
                    pub snaps: [Snapshot; measure::SNAPSHOTS],
                    pub next_end: u32,
                    pub measured: u32,
                    pub filled: u32,
                    pub batch_length: u32,
                    pub in_batch: u32,
                    pub snapshots: u32,
                    pub lag: u32,
                    pub verdict: u32,
                    pub span: u32,
                    pub pending_level: u32,
                    pub _pad_v: U32x2,
                    pub se2: V2,
                    pub phase: Phase,
                }
            }

            host_struct! {
                /// What the host reads of every finished steady
                /// measurement (WGSL's `Head`, `shaders/engine/queue.wgsl`): all that the
                /// reduction of a periodic or phase-resolved verdict reads
                /// ([`crate::measurement::reduce`]).
                pub struct Head {
                    pub travel: V2,
                    pub se2: V2,
                    pub next_end: u32,
                    pub lag: u32,
                    pub verdict: u32,
                    pub span: u32,
                }
            }

            impl Head {
                /// Whether the measurement ended with a verdict whose
                /// reduction reads only the head: periodic or
                /// phase-resolved.
                pub fn suffices(&self) -> bool {
                    self.verdict == measure::VERDICT_PERIODIC
                        || self.verdict == measure::VERDICT_PHASE
                }

                /// Accumulators with the head's members and zero elsewhere:
                /// all that the reduction of those verdicts reads.
                pub fn measure(&self) -> Measure {
                    Measure {
                        travel: self.travel,
                        se2: self.se2,
                        next_end: self.next_end,
                        lag: self.lag,
                        verdict: self.verdict,
                        span: self.span,
                        ..Measure::default()
                    }
                }
            }

            /// The CPU's accumulators in SI units for a shader's
            /// (positions over metres, velocities over metres per second).
            pub fn measure_to_cpu(m: &Measure) -> measure::Measure {
                let length = |v: V2| Vec2::new(v.x as f64, v.y as f64) * (1.0 / UNITS.metre);
                let speed = UNITS.second / UNITS.metre;
                let velocity = |v: V2| Vec2::new(v.x as f64, v.y as f64) * speed;
                let extreme = |v: V2| {
                    length(v).map(|x| {
                        if x.abs() >= Real::MAX as f64 / UNITS.metre {
                            x.signum() * f64::INFINITY
                        } else {
                            x
                        }
                    })
                };
                measure::Measure {
                    last_x_s: length(m.last_x_s),
                    batch_start: length(m.batch_start),
                    d_min: extreme(m.d_min),
                    d_max: extreme(m.d_max),
                    travel: length(m.travel),
                    sums: m.sums.map(length),
                    snaps: m.snaps.map(|s| measure::Snapshot {
                        x_p: length(s.x_p),
                        v_p: velocity(s.v_p),
                        v_s: velocity(s.v_s),
                        x_s: length(s.x_s),
                        mode: s.mode,
                    }),
                    next_end: m.next_end,
                    measured: m.measured,
                    filled: m.filled,
                    batch_length: m.batch_length,
                    in_batch: m.in_batch,
                    snapshots: m.snapshots,
                    lag: m.lag,
                    verdict: m.verdict,
                    span: m.span,
                    pending_level: m.pending_level,
                    se2: Vec2::new(m.se2.x as f64, m.se2.y as f64)
                        * (1.0 / (UNITS.metre * UNITS.metre)),
                    phase: crate::laws::floor::phase::Phase {
                        whole: m.phase.whole.map(length),
                        second: m.phase.second.map(length),
                        quarters: m.phase.quarters.map(length),
                        pending: crate::laws::floor::phase::LevelSums {
                            whole: length(m.phase.pending.whole),
                            half: length(m.phase.pending.half),
                            second: length(m.phase.pending.second),
                            quarters: [
                                m.phase.pending.q0,
                                m.phase.pending.q1,
                                m.phase.pending.q2,
                                m.phase.pending.q3,
                            ]
                            .map(length),
                        },
                    },
                }
            }

            /// The phase ladder's three-gap tables in shader units.
            pub fn gaps(
                g: &[crate::laws::floor::$floor::phase::Gaps; phase::LEVELS],
            ) -> [Gaps; phase::LEVELS] {
                g.map(|g| Gaps {
                    a: g.a,
                    b: g.b,
                    alpha: g.alpha,
                    beta: g.beta,
                })
            }
        }
    };
}

floor_structs!(single, f32, F32x2, single);
floor_structs!(double, f64, F64x2, double);

/// The backward travel's entry of an f64 instance (the second half of the
/// accumulators' buffer: `shaders/karnopp/variation.wgsl`) as the CPU's
/// [`Variation`](crate::laws::floor::variation::Variation), in SI units:
/// the step's accumulators kept of the total variation, with the total in
/// `snaps[0].x_p`, its value when the measured periods began in
/// `snaps[0].v_p`, the ring of totals in `snaps[k].x_s` and their count in
/// `snapshots`.
pub fn variation_to_cpu(m: &double::Measure) -> crate::laws::floor::variation::Variation {
    use crate::laws::floor::double::measure::{SNAPSHOTS, Snapshot};
    let length =
        |v: double::V2| crate::laws::floor::Vec2::new(v.x, v.y) * (1.0 / double::UNITS.metre);
    let mut measure = double::measure_to_cpu(m);
    measure.snaps = [Snapshot::default(); SNAPSHOTS];
    measure.snapshots = 0;
    crate::laws::floor::variation::Variation::from_parts(
        length(m.snaps[0].x_p),
        length(m.snaps[0].v_p),
        measure,
        m.snaps.map(|s| length(s.x_s)),
        m.snapshots,
    )
}
