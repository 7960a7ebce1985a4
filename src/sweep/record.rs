//! [`Record`], one instance's entry in the maps: made from an outcome
//! ([`record`]), and refused when it cannot have been written by a run
//! ([`Record::implausibility`], [`stored_motion`]).

use super::Outcome;
use crate::laws::status::STATUS_OK;
use crate::measurement::keeps_values;
use crate::measurement::status::Status;
use crate::model::motion::Motion;
use crate::model::{AXES, Instance};

/// One instance's entry in the maps, in SI units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Record {
    /// Step per own drive cycle [m].
    pub step: [f64; AXES],
    /// Mean slider velocity [m/s].
    pub velocity: [f64; AXES],
    /// Standard error of each step [m per own drive cycle]: 0 for a window
    /// and a periodic motion.
    pub step_se: [f64; AXES],
    /// Scene periods integrated, settle included.
    pub periods: u32,
    /// Scene periods of the detected cycle, 0 when none.
    pub period_lag: u32,
    /// The kind of motion a steady measurement found: undetermined for a
    /// window, a failed or "not steady" run, and an inferred point of a
    /// refined map (`/maps/motion`).
    pub motion: Motion,
    /// The replicas whose merged estimate the values are (`crate::replicas`;
    /// 1: one run of its own; 0: not integrated, an inferred point).
    pub replicas: u32,
    pub status: u32,
    pub steps: u32,
    /// 1-DOF steps with the other axis undriven [m] (zero when not asked).
    pub baseline_step: [f64; AXES],
    /// Worst status of the two baselines.
    pub baseline_status: u32,
    /// The slider's backward travel [m per own drive cycle] and its
    /// standard error; the backward ratio backward / (|step| + backward)
    /// and its standard error ([`Backward`]; zeros unless the scene asks,
    /// `[output] backward`).
    pub backward: Backward,
}

/// One instance's backward travel per axis (docs/model.md section 4,
/// "Backward travel").
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Backward {
    /// (total variation - |step|) / 2 per own drive cycle [m], at least 0.
    pub travel: [f64; AXES],
    pub travel_se: [f64; AXES],
    /// travel / (|step| + travel), 0 where that is 0 / 0.
    pub ratio: [f64; AXES],
    pub ratio_se: [f64; AXES],
}

impl Backward {
    /// From the step and the total variation T per own drive cycle and
    /// their standard errors [m]: B = (T - |S|) / 2, 0 where rounding or
    /// the estimates' noise puts T below |S|; its error from both, taken
    /// as independent; the ratio r = B / (|S| + B) = (T - |S|) / (T + |S|)
    /// and its error by the delta method.
    pub fn of(step: f64, step_se: f64, variation: f64, variation_se: f64) -> (f64, f64, f64, f64) {
        let (s, t) = (step.abs(), variation.max(step.abs()));
        let travel = 0.5 * (t - s);
        let travel_se = 0.5 * step_se.hypot(variation_se);
        let sum = t + s;
        if sum <= 0.0 {
            return (travel, travel_se, 0.0, 0.0);
        }
        let ratio = (t - s) / sum;
        let ratio_se = 2.0 * (s * variation_se).hypot(t * step_se) / (sum * sum);
        (travel, travel_se, ratio, ratio_se)
    }

    /// The values of each axis, in `schema::BACKWARD_DATASETS`' order.
    pub fn columns(&self, axis: usize) -> [f64; 4] {
        [
            self.travel[axis],
            self.travel_se[axis],
            self.ratio[axis],
            self.ratio_se[axis],
        ]
    }

    /// From each axis' values in `schema::BACKWARD_DATASETS`' order.
    pub fn from_columns(columns: [[f64; 4]; AXES]) -> Backward {
        Backward {
            travel: columns.map(|c| c[0]),
            travel_se: columns.map(|c| c[1]),
            ratio: columns.map(|c| c[2]),
            ratio_se: columns.map(|c| c[3]),
        }
    }
}

impl Record {
    /// Why a stored record cannot have been written by a run, if it cannot:
    /// every status must be a known code, every value finite, an instance
    /// that did not finish normally must have zeros in its map entries,
    /// and only an instance with status 0 has a kind of motion (any other
    /// status is undetermined; a motion code that does not exist is
    /// refused as it is read, by [`stored_motion`]). Readers of result
    /// files and checkpoints ask this of every record they take in.
    pub fn implausibility(&self) -> Option<String> {
        for (what, code) in [
            ("status", self.status),
            ("baseline status", self.baseline_status),
        ] {
            if Status::from_code(code).is_none() {
                return Some(format!("its {what} is {code}, which is no status code"));
            }
        }
        if self.status == crate::measurement::status::STATUS_NO_STALL {
            return Some(format!(
                "its status is {} ({}), which only a stall map holds",
                self.status,
                Status::describe(self.status)
            ));
        }
        if self.status != STATUS_OK && self.motion != Motion::Undetermined {
            return Some(format!(
                "its status is {} ({}) but its motion is {}, not {}",
                self.status,
                Status::describe(self.status),
                self.motion.name(),
                Motion::Undetermined.name()
            ));
        }
        let b = &self.backward;
        let values = [
            ("step_x", self.step[0]),
            ("step_y", self.step[1]),
            ("velocity_x", self.velocity[0]),
            ("velocity_y", self.velocity[1]),
            ("step_x_se", self.step_se[0]),
            ("step_y_se", self.step_se[1]),
            ("backward_x", b.travel[0]),
            ("backward_y", b.travel[1]),
            ("backward_x_se", b.travel_se[0]),
            ("backward_y_se", b.travel_se[1]),
            ("backward_ratio_x", b.ratio[0]),
            ("backward_ratio_y", b.ratio[1]),
            ("backward_ratio_x_se", b.ratio_se[0]),
            ("backward_ratio_y_se", b.ratio_se[1]),
            ("baseline step_x", self.baseline_step[0]),
            ("baseline step_y", self.baseline_step[1]),
        ];
        if let Some((what, value)) = values.iter().find(|(_, v)| !v.is_finite()) {
            return Some(format!("its {what} is {value}"));
        }
        if let Some((what, value)) = values[4..14].iter().find(|(_, v)| *v < 0.0) {
            return Some(format!("its {what} is {value:e}, below 0"));
        }
        if let Some((what, value)) = values[10..12].iter().find(|(_, v)| *v > 1.0) {
            return Some(format!("its {what} is {value:e}, above 1"));
        }
        let failed = !keeps_values(self.status);
        let kept = values[..14].iter().find(|(_, v)| *v != 0.0);
        match kept {
            Some((what, value)) if failed => Some(format!(
                "its status is {} ({}) but its {what} is {value:e}, not 0",
                self.status,
                Status::describe(self.status)
            )),
            _ => None,
        }
    }
}

/// The kind of motion of a stored code (`/maps/motion`, a checkpoint's
/// record), or why it cannot be right, in the words of
/// [`Record::implausibility`]: a `Record` holds a [`Motion`], so a code
/// that is none is refused here, as it is read.
pub fn stored_motion(code: u8) -> Result<Motion, String> {
    Motion::from_code(code).ok_or_else(|| {
        format!(
            "its motion is {code}, which is no motion code (flag_values {:?})",
            Motion::flag_values()
        )
    })
}

/// Turns a displacement outcome into map entries.
pub fn record(inst: &Instance, out: &Outcome) -> Record {
    let mut rec = Record {
        status: out.status,
        steps: out.steps,
        step_se: out.se,
        periods: out.periods,
        period_lag: out.lag,
        motion: out.motion,
        replicas: out.replicas,
        ..Record::default()
    };
    for i in 0..AXES {
        let (velocity, step) = inst.measure_over(i, out.displacement[i], out.span);
        rec.velocity[i] = velocity;
        rec.step[i] = step;
        // No variation kept (not asked, or a slider that never moved):
        // no backward travel.
        if out.variation[i] != 0.0 || out.variation_se[i] != 0.0 {
            let variation = inst.measure_over(i, out.variation[i], out.span).1;
            let b = &mut rec.backward;
            (b.travel[i], b.travel_se[i], b.ratio[i], b.ratio_se[i]) =
                Backward::of(step, out.se[i], variation, out.variation_se[i]);
        }
    }
    rec
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Code 8 (no stall load) is the stall search's, held in
    /// `/maps/stall_status_*` only: a map record carrying it cannot be
    /// right.
    #[test]
    fn a_stall_status_is_no_map_status() {
        let rec = Record {
            status: crate::measurement::status::STATUS_NO_STALL,
            ..Record::default()
        };
        let why = rec.implausibility().expect("refused");
        assert!(why.contains("which only a stall map holds"), "{why}");
    }

    #[test]
    fn only_a_finished_record_has_a_kind_of_motion() {
        let ok = Record {
            step: [1e-7, -2e-7],
            motion: Motion::Periodic,
            ..Record::default()
        };
        assert_eq!(ok.implausibility(), None);
        // A window, an inferred point: status 0 and undetermined.
        assert_eq!(Record::default().implausibility(), None);
        // "Not steady" keeps its estimate but has no kind of motion.
        let not_steady = Record {
            status: crate::laws::status::STATUS_NOT_STEADY,
            ..ok
        };
        let why = not_steady.implausibility().expect("refused");
        assert!(
            why.starts_with("its status is 6 (not steady")
                && why.ends_with("but its motion is periodic, not undetermined"),
            "{why}"
        );
        let failed = Record {
            status: 1,
            motion: Motion::Irregular,
            ..Record::default()
        };
        let why = failed.implausibility().expect("refused");
        assert!(why.contains("its motion is irregular"), "{why}");
        let failed = Record {
            motion: Motion::Undetermined,
            ..failed
        };
        assert_eq!(failed.implausibility(), None);
        // Stored codes: every kind, and no other.
        for motion in Motion::ALL {
            assert_eq!(stored_motion(motion.code()), Ok(motion));
        }
        let why = stored_motion(5).unwrap_err();
        assert_eq!(
            why,
            "its motion is 5, which is no motion code (flag_values [0, 1, 2, 3, 4])"
        );
    }
}
