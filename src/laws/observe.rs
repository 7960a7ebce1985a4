//! What a trajectory sees of a run, whatever the law: each step's motion
//! as a function of time, which the recorder samples on its own grid
//! (`crate::trajectory`). An observer never changes the run: a recorded
//! run ends in the same state, bit for bit, as the map's run of the same
//! instance.

use crate::model::AXES;

/// Stage and slider positions [m] per axis.
pub type Positions = ([f64; AXES], [f64; AXES]);

/// Sees every step of a run that moves its state.
pub trait Observer {
    /// A step of scene period `period` from local time `start` to `end`
    /// [s]; `positions_at(t)` gives the positions at local time `t` in
    /// `[start, end]` (at `end` exactly the state the run moves to).
    fn step(&mut self, period: u32, start: f64, end: f64, positions_at: &dyn Fn(f64) -> Positions);
}
