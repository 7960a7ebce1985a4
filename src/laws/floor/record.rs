//! The run's record: where a run of any law stands, in f64 and SI units,
//! as everything above the laws reads it (the measurement's reduction,
//! the replicas' groups, trajectories, the backends). A law keeps its own
//! integrator state and hands this out (Karnopp's `State::record`); LuGre
//! keeps its run in one directly. Laws differ in their state, never in
//! their record.

use super::double::gauge::Slider;
use super::double::measure::Measure;
use super::double::{Real, Vec2};
use crate::laws::status::STATUS_OK;

/// The law-neutral part of a run's state: what the steady measurement
/// reads ([`Slider`]) and what its reduction, the replicas and a
/// trajectory's file read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Record {
    /// Stage positions [m] and velocities [m/s].
    pub x_p: Vec2,
    pub v_p: Vec2,
    /// Slider positions [m] and velocities [m/s].
    pub x_s: Vec2,
    pub v_s: Vec2,
    /// Slider positions when the measured periods began [m].
    pub settle_x_s: Vec2,
    /// Time within the current scene period [s].
    pub time: f64,
    /// The law's mode code the recurrence test compares (Karnopp's stick,
    /// slip or band; 0 for a law without modes).
    pub mode: u32,
    /// Index of the current scene period.
    pub period: u32,
    /// `crate::laws::status`.
    pub status: u32,
    /// Steps taken so far (the law's own count: accepted, rejected and
    /// events).
    pub steps: u32,
    /// 0 while measuring, 1 once a steady measurement is complete, 2 while
    /// a replica waits for its group's merge (`measure::VERDICT_WAITING`).
    pub measured: u32,
}

impl Record {
    /// A run at rest at zero displacement at the start of period 0, mode 0
    /// (docs/model.md section 4).
    pub fn at_rest() -> Record {
        Record {
            status: STATUS_OK,
            ..Record::default()
        }
    }
}

/// Where a run ended or waits: its [`Record`] and the steady measurement's
/// accumulators (unused by a window).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Run {
    pub record: Record,
    pub measure: Measure,
}

impl Run {
    /// Lets a replica that waits for its group's merge go on ([`release`]).
    pub fn release(&mut self) {
        release(&mut self.record, &mut self.measure);
    }
}

/// Lets a replica of any law that waits for its group's merge
/// (`measure::VERDICT_WAITING`) go on: measuring again.
pub fn release(slider: &mut impl Slider, m: &mut Measure) {
    use super::double::measure::{VERDICT_RUNNING, VERDICT_WAITING};
    if m.verdict == VERDICT_WAITING {
        m.verdict = VERDICT_RUNNING;
        slider.set_measured(0);
    }
}

impl From<&Record> for Record {
    fn from(r: &Record) -> Record {
        *r
    }
}

impl Record {
    /// Whether the record's time within its period has reached t + t_lo
    /// (f64 keeps time in one part).
    #[inline]
    fn reached(&self, t: f64, t_lo: f64) -> bool {
        self.time > t || (self.time == t && 0.0 >= t_lo)
    }
}

// The record as the floor's measurement reads it (LuGre measures on its
// record).
super::double::gauge::slider_by_fields!(Record, Record::reached);
