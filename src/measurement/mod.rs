//! The reduction of a finished run to what a map shows (docs/model.md section
//! 4): the mean travel and the periods it spans, each axis' standard error,
//! the periods integrated, the detected cycle and the status. Every
//! backend's results pass through [`reduce`]: the CPU's runs directly, the
//! GPU's once their states and accumulators are read back in f64.
//!
//! The per-period bookkeeping and the stop rule are
//! `laws::floor::measure` (mirrored by the shader); this module only
//! reads what they left.

pub mod status;

use crate::laws::floor::Vec2;
use crate::laws::floor::measure::{
    Measure as MeasureState, VERDICT_CONVERGED, VERDICT_PERIODIC, VERDICT_PHASE, cut, estimate_from,
};
use crate::laws::floor::variation::Variation;
use crate::laws::status::STATUS_NOT_STEADY;
use crate::laws::status::STATUS_OK;
use crate::laws::{Record, Run};
use crate::model::motion::Motion;
use crate::model::{AXES, Instance, Measure};

/// What one run measured. Lengths in metres.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Measured {
    /// Slider travel over the measured span per axis [m]; zero unless the
    /// status is OK or "not steady".
    pub travel: [f64; AXES],
    /// Scene periods the travel spans (0 when nothing was measured).
    pub span: f64,
    /// Standard error of each axis' step [m per own drive cycle]: 0 for a
    /// window and for a periodic motion.
    pub se: [f64; AXES],
    /// Scene periods integrated, settle included.
    pub periods: u32,
    /// Scene periods of the detected cycle, 0 when none was detected.
    pub lag: u32,
    pub status: u32,
    /// The kind of motion the measurement's verdict shows.
    pub motion: Motion,
}

/// Whether a status keeps its instance's values: OK and "not steady" (the
/// best estimate, with its standard error) do; every failure leaves zeros.
pub fn keeps_values(status: u32) -> bool {
    status == STATUS_OK || status == STATUS_NOT_STEADY
}

/// Reduces a finished run of `inst`.
pub fn reduce(inst: &Instance, run: &Run) -> Measured {
    let st = &run.record;
    let m = &run.measure;
    let failed = Measured {
        status: st.status,
        periods: st.period,
        ..Measured::default()
    };
    if st.status != STATUS_OK {
        return failed;
    }
    match inst.measure {
        Measure::Window => {
            if st.period < inst.cycles {
                // Not finished: no backend hands such a run over.
                return failed;
            }
            Measured {
                travel: window_displacement(inst, st),
                span: (inst.cycles - inst.settle) as f64,
                se: [0.0; AXES],
                periods: inst.cycles,
                lag: 0,
                status: STATUS_OK,
                motion: Motion::Undetermined,
            }
        }
        Measure::Steady { .. } => {
            let periods = m.next_end;
            let source = choose(inst, run);
            let (travel, span, se2) = values(m, source);
            let status = source.status();
            if span == 0.0 {
                return Measured {
                    status,
                    periods,
                    ..Measured::default()
                };
            }
            let (lag, motion) = match source {
                Source::Periodic => (m.lag, Motion::Periodic),
                Source::Phase { verdict: true } => (0, Motion::QuasiPeriodic),
                _ if status == STATUS_OK => (0, Motion::Irregular),
                _ => (0, Motion::Undetermined),
            };
            Measured {
                travel: travel.to_array(),
                span,
                se: se_per_cycle(inst, se2),
                periods,
                lag,
                status,
                motion,
            }
        }
    }
}

/// Each axis' standard error per own drive cycle [m] of a squared
/// standard error per scene period [m^2].
fn se_per_cycle(inst: &Instance, se2: Vec2) -> [f64; AXES] {
    std::array::from_fn(|i| se2[i].sqrt() / (inst.axes[i].frequency * inst.period()))
}

/// Which of a steady run's estimates its map shows (docs/model.md section
/// 4): chosen on the step's accumulators, and used as it is for a quantity
/// that follows them (`laws::floor::variation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Source {
    /// The detected cycle: exact, no standard error.
    Periodic,
    /// The phase ladder's judged window (`laws::floor::phase`): the
    /// verdict's, or the latest, which a run that ends not steady reports
    /// where its standard error is smaller than the batch means'.
    Phase { verdict: bool },
    /// The batch means from MSER's cut on; `converged` is the verdict.
    Batches { cut: u32, converged: bool },
    /// Not one batch complete (a tiny max_cycles): the periods measured
    /// so far, with the largest single-period travel as the error.
    Partial,
}

impl Source {
    fn status(self) -> u32 {
        match self {
            Source::Periodic | Source::Phase { verdict: true } => STATUS_OK,
            Source::Batches {
                converged: true, ..
            } => STATUS_OK,
            _ => STATUS_NOT_STEADY,
        }
    }
}

/// The estimate a finished steady run's map shows.
fn choose(inst: &Instance, run: &Run) -> Source {
    let m = &run.measure;
    if m.verdict == VERDICT_PERIODIC {
        return Source::Periodic;
    }
    if m.verdict == VERDICT_PHASE {
        assert!(m.span > 0, "a phase verdict has a judged window");
        return Source::Phase { verdict: true };
    }
    let converged = m.verdict == VERDICT_CONVERGED;
    let batches = if m.filled > 0 {
        Source::Batches {
            cut: cut(m),
            converged,
        }
    } else {
        Source::Partial
    };
    if m.span == 0 || converged {
        return batches;
    }
    // The larger of an estimate's standard errors per own cycle.
    let worst = |se2: Vec2| se_per_cycle(inst, se2).into_iter().fold(0.0, f64::max);
    let (_, span, se2) = values(m, batches);
    if span == 0.0 || worst(m.se2) < worst(se2) {
        Source::Phase { verdict: false }
    } else {
        batches
    }
}

/// The travel [m], the periods it spans and the squared standard error of
/// the mean travel per scene period [m^2] of estimate `source` of the
/// accumulators `m` (a step's, or a quantity's that follows it).
fn values(m: &MeasureState, source: Source) -> (Vec2, f64, Vec2) {
    match source {
        Source::Periodic => (m.travel, m.lag as f64, Vec2::ZERO),
        Source::Phase { .. } => (m.travel, m.span as f64, m.se2),
        Source::Batches { cut, .. } => {
            let e = estimate_from(m, cut);
            (e.travel, e.span as f64, e.se2)
        }
        Source::Partial => {
            let largest = m.d_min.abs().zip(m.d_max.abs(), f64::max);
            let largest = largest.map(|v| if v.is_finite() { v } else { 0.0 });
            (
                m.last_x_s - m.batch_start,
                m.in_batch as f64,
                largest * largest,
            )
        }
    }
}

/// The slider's total variation over the span of the estimate [`reduce`]
/// gives the step [m], and its standard error per own drive cycle [m]:
/// the same estimate of the accumulators that followed the step's
/// (`laws::floor::variation::follow`), or over a window's periods.
/// Zeros where the step keeps no values.
pub fn reduce_variation(inst: &Instance, run: &Run, v: &Variation) -> ([f64; AXES], [f64; AXES]) {
    let st = &run.record;
    let zero = ([0.0; AXES], [0.0; AXES]);
    if st.status != STATUS_OK {
        return zero;
    }
    match inst.measure {
        Measure::Window => {
            if st.period < inst.cycles {
                return zero;
            }
            ((v.total - v.settle_total).to_array(), [0.0; AXES])
        }
        Measure::Steady { .. } => {
            let (travel, span, se2) = values(&v.measure, choose(inst, run));
            if span == 0.0 {
                return zero;
            }
            (travel.to_array(), se_per_cycle(inst, se2))
        }
    }
}

/// The slider travel over a fixed window that a run's final record holds
/// [m], or zero where it did not finish normally (`st`: a record, or a
/// law's state that gives one).
pub fn window_displacement(inst: &Instance, st: impl Into<Record>) -> [f64; AXES] {
    let st: Record = st.into();
    if st.status == STATUS_OK && st.period >= inst.cycles {
        (st.x_s - st.settle_x_s).to_array()
    } else {
        [0.0; AXES]
    }
}

/// What a backend returns for one instance: its [`Measured`] and the
/// work it took.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outcome {
    /// Slider travel over the measured span [m]; zero unless the status
    /// keeps values ([`crate::measurement::keeps_values`]).
    pub displacement: [f64; AXES],
    /// Scene periods the displacement spans.
    pub span: f64,
    /// Standard error of each axis' step [m per own drive cycle].
    pub se: [f64; AXES],
    /// Scene periods integrated, settle included.
    pub periods: u32,
    /// Scene periods of the detected cycle, 0 when none.
    pub lag: u32,
    pub status: u32,
    /// The kind of motion (`crate::model::motion`).
    pub motion: Motion,
    pub steps: u32,
    /// A GPU or f32 backend integrated this one on the CPU in f64 instead
    /// (the slow tail of a batch, an iteration the driver's loop limiter
    /// cut, or an f32 run that failed or met a band graze).
    pub on_cpu: bool,
    /// Of those, an f32 run that stopped at a band graze
    /// (`laws::status::STATUS_GRAZE`).
    pub graze: bool,
    /// An f32 window run among the heaviest of its batch, checked
    /// (`laws::floor::check`): by a twin that agreed (f32's value kept), or
    /// integrated again in f64 (`on_cpu` set too).
    pub checked: bool,
    /// The replicas whose merged estimate it is (`crate::replicas`; 1: one
    /// run of its own).
    pub replicas: u32,
    /// The slider's total variation over the span [m] and its standard
    /// error [m per own drive cycle] (`reduce_variation`), where the run
    /// kept it (`Settings::backward`); zeros otherwise.
    pub variation: [f64; AXES],
    pub variation_se: [f64; AXES],
}

impl Outcome {
    /// The outcome of a reduced run.
    pub fn of(m: &Measured, steps: u32, on_cpu: bool) -> Outcome {
        Outcome {
            displacement: m.travel,
            span: m.span,
            se: m.se,
            periods: m.periods,
            lag: m.lag,
            status: m.status,
            motion: m.motion,
            steps,
            on_cpu,
            graze: false,
            checked: false,
            replicas: 1,
            variation: [0.0; AXES],
            variation_se: [0.0; AXES],
        }
    }

    /// Step per own drive cycle [m] of axis `i`.
    pub fn step(&self, inst: &Instance, i: usize) -> f64 {
        inst.measure_over(i, self.displacement[i], self.span).1
    }
}
