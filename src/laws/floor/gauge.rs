//! How a law meets the floor's measurement: [`Gauge`], the constants it
//! reads of an instance, and [`Slider`], what it reads of a run's state and
//! the mark it sets on it (re-exported by `super::measure`).

use super::Real;
use super::vec2::Vec2;

/// Levels of the phase ladder (`super::phase`).
pub const LEVELS: usize = 18;

/// The three-gap structure of the phases k rho, 0 <= k < L, of a window of
/// L periods (`super::phase`'s docs): computed by the host in f64 and rounded once.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Gaps {
    /// The index of the phase nearest above 0 and that nearest below 1.
    pub a: u32,
    pub b: u32,
    /// frac(a rho) and 1 - frac(b rho) [cycles].
    pub alpha: Real,
    pub beta: Real,
}

/// What the measurement reads of an instance: constants every law computes
/// once per instance (Karnopp's `Coefficients` carries them among its own,
/// as its shader's struct does: `shaders/shared/measure.wgsl` reads them
/// by these names).
pub trait Gauge {
    /// The run is a steady measurement (not a window).
    fn steady(&self) -> bool;
    /// The scene period T in two parts, hi + lo [s] (lo zero but in f32).
    fn period(&self) -> Real;
    fn period_lo(&self) -> Real;
    /// Leading scene periods not measured.
    fn settle(&self) -> u32;
    /// The first batch length and the shortest a batch may be judged at
    /// [scene periods]: the slowest beat of the drives.
    fn batch_length(&self) -> u32;
    fn min_batch(&self) -> u32;
    /// The drives' common period [scene periods] (0: none short enough).
    fn common_period(&self) -> u32;
    /// The squared step tolerance per scene period, per axis [m^2].
    fn se_limit2(&self) -> Vec2;
    /// The recurrence test's tolerances on positions [m] and velocities
    /// [m/s] (`repeat_tolerances`).
    fn repeat_x(&self) -> Real;
    fn repeat_v(&self) -> Real;
    /// The phase ladder's levels that may stop the run (a bit each), its
    /// lattice rule and its three-gap tables (`super::phase`).
    fn phase_levels(&self) -> u32;
    fn phase_lattice(&self) -> u32;
    fn gaps(&self) -> &[Gaps; LEVELS];
    /// This run's replica and its group's size (1: none).
    fn replica(&self) -> u32;
    fn replicas(&self) -> u32;
}

/// Implements [`Gauge`] for a struct that holds the constants as fields of
/// the same names, each accessor inlined where the measurement reads it
/// (at every iteration: `at_period_end`) (the floor's `Setup`, Karnopp's `Coefficients`); `Gauge`,
/// `Real`, `Vec2`, `Gaps` and `LEVELS` of the struct's precision in scope.
macro_rules! gauge_by_fields {
    ($t:ty) => {
        impl Gauge for $t {
            #[inline]
            fn steady(&self) -> bool {
                self.steady
            }
            #[inline]
            fn period(&self) -> Real {
                self.period
            }
            #[inline]
            fn period_lo(&self) -> Real {
                self.period_lo
            }
            #[inline]
            fn settle(&self) -> u32 {
                self.settle
            }
            #[inline]
            fn batch_length(&self) -> u32 {
                self.batch_length
            }
            #[inline]
            fn min_batch(&self) -> u32 {
                self.min_batch
            }
            #[inline]
            fn common_period(&self) -> u32 {
                self.common_period
            }
            #[inline]
            fn se_limit2(&self) -> Vec2 {
                self.se_limit2
            }
            #[inline]
            fn repeat_x(&self) -> Real {
                self.repeat_x
            }
            #[inline]
            fn repeat_v(&self) -> Real {
                self.repeat_v
            }
            #[inline]
            fn phase_levels(&self) -> u32 {
                self.phase_levels
            }
            #[inline]
            fn phase_lattice(&self) -> u32 {
                self.phase_lattice
            }
            #[inline]
            fn gaps(&self) -> &[Gaps; LEVELS] {
                &self.gaps
            }
            #[inline]
            fn replica(&self) -> u32 {
                self.replica
            }
            #[inline]
            fn replicas(&self) -> u32 {
                self.replicas
            }
        }
    };
}
pub(crate) use gauge_by_fields;

/// What the measurement reads of a run's state, and the mark it sets on
/// it: every law's state has these (Karnopp's `State`, LuGre's, and their
/// shaders' structs by the same names).
pub trait Slider {
    /// The scene period the run is in.
    fn period(&self) -> u32;
    /// Whether the run's time within its period has reached t + t_lo
    /// (two-part times; t_lo is zero unless the law keeps time in two
    /// parts).
    fn reached(&self, t: Real, t_lo: Real) -> bool;
    /// Stage and slider positions [m] and velocities [m/s], and the
    /// friction mode (a law's own code) the recurrence test compares.
    fn x_p(&self) -> Vec2;
    fn v_p(&self) -> Vec2;
    fn x_s(&self) -> Vec2;
    fn v_s(&self) -> Vec2;
    fn mode(&self) -> u32;
    /// 0 while measuring, 1 once complete, 2 while a replica waits
    /// ([`super::measure::VERDICT_WAITING`]).
    fn measured(&self) -> u32;
    fn set_measured(&mut self, measured: u32);
}

/// Implements [`Slider`] for a state that holds its fields under the
/// trait's names (`period`, `x_p`, `v_p`, `x_s`, `v_s`, `mode`,
/// `measured`), with `$reached(&state, t, t_lo)` saying whether its time
/// has reached t + t_lo (the floor's `Record`, Karnopp's `State`);
/// `Slider`, `Real` and `Vec2` of the state's precision in scope.
macro_rules! slider_by_fields {
    ($t:ty, $reached:path) => {
        impl Slider for $t {
            #[inline]
            fn period(&self) -> u32 {
                self.period
            }
            #[inline]
            fn reached(&self, t: Real, t_lo: Real) -> bool {
                $reached(self, t, t_lo)
            }
            #[inline]
            fn x_p(&self) -> Vec2 {
                self.x_p
            }
            #[inline]
            fn v_p(&self) -> Vec2 {
                self.v_p
            }
            #[inline]
            fn x_s(&self) -> Vec2 {
                self.x_s
            }
            #[inline]
            fn v_s(&self) -> Vec2 {
                self.v_s
            }
            #[inline]
            fn mode(&self) -> u32 {
                self.mode
            }
            #[inline]
            fn measured(&self) -> u32 {
                self.measured
            }
            #[inline]
            fn set_measured(&mut self, measured: u32) {
                self.measured = measured;
            }
        }
    };
}
pub(crate) use slider_by_fields;
