//! The f32 mirror's results in the units and precision of the f64
//! reference, so the reductions (`pidm::measurement`) read them as they
//! read the reference's: lengths in metres, velocities in metres per
//! second, times in seconds, each converted to f64 exactly and then scaled.

use super::integrate::{Measure, Run, State, Vec2, measure::Snapshot};
use super::precision::UNITS;
use crate::laws::karnopp::integrate as si;

fn scaled(v: Vec2, factor: f64) -> si::Vec2 {
    si::Vec2::new(v.x as f64 * factor, v.y as f64 * factor)
}

fn length(v: Vec2) -> si::Vec2 {
    scaled(v, 1.0 / UNITS.metre)
}

fn velocity(v: Vec2) -> si::Vec2 {
    scaled(v, UNITS.second / UNITS.metre)
}

/// The state in SI units.
pub fn state(st: &State) -> si::State {
    let time = |t: f32| t as f64 / UNITS.second;
    si::State {
        x_p: length(st.x_p),
        v_p: velocity(st.v_p),
        x_s: length(st.x_s),
        v_s: velocity(st.v_s),
        v_rel: velocity(st.v_rel),
        held: scaled(st.held, 1.0),
        settle_x_s: length(st.settle_x_s),
        cycle_phase: scaled(st.cycle_phase, 1.0),
        next_corner: scaled(st.next_corner, 1.0),
        corner_at: scaled(st.corner_at, 1.0 / UNITS.second),
        corner_at_lo: scaled(st.corner_at_lo, 1.0 / UNITS.second),
        time: time(st.time),
        time_lo: time(st.time_lo),
        h_slip: time(st.h_slip),
        h_accepted: time(st.h_accepted),
        err_accepted: st.err_accepted as f64,
        segment: st.segment,
        mode: st.mode,
        period: st.period,
        status: st.status,
        steps: st.steps,
        stalled: st.stalled,
        rejections: st.rejections,
        measured: st.measured,
    }
}

/// The steady measurement's accumulators in SI units.
pub fn measure(m: &Measure) -> si::Measure {
    let snapshot = |s: &Snapshot| si::measure::Snapshot {
        x_p: length(s.x_p),
        v_p: velocity(s.v_p),
        v_s: velocity(s.v_s),
        x_s: length(s.x_s),
        mode: s.mode,
    };
    si::Measure {
        last_x_s: length(m.last_x_s),
        batch_start: length(m.batch_start),
        d_min: length(m.d_min),
        d_max: length(m.d_max),
        travel: length(m.travel),
        sums: m.sums.map(length),
        snaps: m.snaps.each_ref().map(snapshot),
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
        se2: scaled(m.se2, 1.0 / (UNITS.metre * UNITS.metre)),
        phase: si::phase::Phase {
            whole: m.phase.whole.map(length),
            second: m.phase.second.map(length),
            quarters: m.phase.quarters.map(length),
            pending: si::phase::LevelSums {
                whole: length(m.phase.pending.whole),
                half: length(m.phase.pending.half),
                second: length(m.phase.pending.second),
                quarters: m.phase.pending.quarters.map(length),
            },
        },
    }
}

/// A finished run in SI units.
pub fn run(r: &Run) -> si::Run {
    si::Run {
        state: state(&r.state),
        measure: measure(&r.measure),
    }
}
