//! What the steady measurement reads of one instance, computed once per
//! instance (or replica) in f64 from the instance alone: a law without
//! constants of its own for it (LuGre) takes [`Setup`] as its
//! [`Gauge`]; Karnopp's `Coefficients` copies it among its own, flat, as
//! its WGSL struct holds them.

use super::Real;
use super::measure::{Gauge, gauge_by_fields};
use super::phase::{Gaps, LEVELS};
use super::precision::only_f64;
use super::vec2::Vec2;

/// The measurement's constants ([`Gauge`]'s, which say what each is).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Setup {
    pub steady: bool,
    pub period: Real,
    pub period_lo: Real,
    pub settle: u32,
    pub batch_length: u32,
    pub min_batch: u32,
    pub common_period: u32,
    pub se_limit2: Vec2,
    pub repeat_x: Real,
    pub repeat_v: Real,
    pub phase_levels: u32,
    pub phase_lattice: u32,
    pub gaps: [Gaps; LEVELS],
    pub replica: u32,
    pub replicas: u32,
}

gauge_by_fields!(Setup);

only_f64! {
use super::measure::{
    beat_batch_length, common_period, first_batch_length, repeat_tolerances,
};
use super::phase::{Replica, ladder, ladder_on};
use crate::laws::Settings;
use crate::model::{Axis, Instance, Measure};

impl Setup {
    /// The constants of replica `r` of `inst` (`Replica::NONE`: the whole
    /// run), in `inst`'s units.
    pub fn new(inst: &Instance, settings: &Settings, r: Replica) -> Setup {
        let [ax, ay] = &inst.axes;
        let per_axis = |f: &dyn Fn(&Axis) -> f64| Vec2::new(f(ax), f(ay));
        let period = inst.period();
        let cycles_per_period = per_axis(&|a| a.frequency * period);
        let frequency = per_axis(&|a| a.frequency);
        let driven = [ax.is_driven(), ay.is_driven()];
        let step_tolerance = inst.measure.step_tolerance();
        let se_limit = cycles_per_period * step_tolerance;
        let (deflection, stage_rate) = stage_scales(inst);
        let (repeat_x, repeat_v) = repeat_tolerances(settings.tolerance, deflection, stage_rate);
        // A cycle split's piece (`Replica::cycle`) has no stop rule of its
        // own: its recurrence test keeps the states where its piece starts
        // and ends (a "common period" of the piece's length), its ladder
        // and batch means are off, and it runs to its `cycles`.
        let piece = (r.cycle > 0).then(|| r.cycle_segment().1);
        let common_period =
            piece.unwrap_or_else(|| common_period(frequency, cycles_per_period, driven));
        let steady = matches!(inst.measure, Measure::Steady { .. });
        // The faster drive's advance per scene period [cycles].
        let rho = cycles_per_period.max_element().fract();
        let ladder_on = steady && piece.is_none() && ladder_on(driven, rho, common_period);
        // A replica's ladder is its group's virtual run's: the periods the
        // run (its replicas' together) may measure.
        let horizon = inst.cycles.saturating_sub(inst.settle).saturating_mul(r.count);
        let ladder = ladder(
            r.virtual_step(rho),
            ladder_on,
            common_period.saturating_mul(r.count),
            horizon,
        );
        Setup {
            steady,
            period,
            // Exact in f64.
            period_lo: 0.0,
            settle: inst.settle,
            batch_length: first_batch_length(cycles_per_period, driven, inst.cycles),
            min_batch: match piece {
                Some(_) => u32::MAX,
                None => beat_batch_length(cycles_per_period, driven),
            },
            common_period,
            se_limit2: se_limit * se_limit,
            repeat_x,
            repeat_v,
            phase_levels: ladder.levels,
            phase_lattice: ladder.lattice,
            gaps: ladder.gaps,
            replica: if piece.is_some() { 0 } else { r.index },
            replicas: if piece.is_some() { 1 } else { r.count },
        }
    }
}

/// The two scales of `inst`'s stages that set the recurrence test's
/// tolerances ([`repeat_tolerances`]): the largest static deflection of a
/// driven stage, |gain voltage| / stiffness, and the fastest rate of a
/// stage alone, sqrt(k / m) + c / m, in `inst`'s units.
pub fn stage_scales(inst: &Instance) -> (f64, f64) {
    let [ax, ay] = &inst.axes;
    let per_axis = |f: &dyn Fn(&Axis) -> f64| Vec2::new(f(ax), f(ay));
    let amplitude = per_axis(&|a| if a.is_driven() { a.gain * a.voltage } else { 0.0 });
    let stiffness = per_axis(&|a| a.stiffness);
    let deflection = (amplitude.abs() * stiffness.map(|k| 1.0 / k)).max_element();
    let mass = per_axis(&|a| a.stage_mass);
    let sigma = per_axis(&|a| a.damping).zip(mass, |c, m| c / (2.0 * m));
    let w2 = stiffness / mass;
    let rate = w2.zip(sigma, |w2, s| w2.sqrt() + 2.0 * s);
    (deflection, rate.max_element())
}
}
