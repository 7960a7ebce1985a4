//! The stall search of one instance (docs/model.md section 7): the load along
//! the stalled axis, against its unloaded step's direction, at which that
//! axis' steady step is zero. Plain values, no integration: [`Search`]
//! says which load to probe next and takes each probe's step, so the
//! waves (`super::waves`) run on synthetic step functions in tests and on
//! a backend in a run.
//!
//! The search brackets, then bisects. With the unloaded step s0 (a forward
//! step, say, s0 > 0), the loads probed lie on the other side, L = -q R for
//! the fractions q of [`BRACKET`] of the room R = sqrt(f_c^2 - L_other^2)
//! along the axis (so |L| < f_c at every probe). The first probe whose
//! step is no longer forward (zero, or reversed) closes the bracket with
//! the last one that was (L = 0 at first); bisection then halves it until
//! it is at most twice the tolerance, and the stall load is its middle, so
//! within the tolerance of a zero crossing. The fractions start small and
//! double, so where the step is not monotone the crossing found is the
//! first the probes see from L = 0 outwards: the nearest to L = 0 unless
//! two crossings lie closer together than the probes (a step that turns
//! back to forward between two probes is not seen).

use crate::laws::status::STATUS_NOT_STEADY;
use crate::measurement::keeps_values;
use crate::measurement::status::STATUS_NO_STALL;
use crate::scene::BRACKET;

/// A step of at most this magnitude is no motion [m per own drive cycle]:
/// 1e-10 m (1e-4 um), the accuracy the integrator claims at its default
/// tolerance, far above the rounding of a stuck slider's travel, whose
/// sign says nothing (about 1e-21 m in f64 on Table 1, up to 8e-12 m in
/// f32, where the slider's position near 60 um is known to 4e-12 m). On
/// the stall slopes of 12-16 um/N it moves a stall load by 1e-5
/// N, a tenth of the default tolerance.
pub const STEP_ZERO_M: f64 = 1e-10;

/// What the stall search found for one instance, in SI units: the one
/// home of the stall maps' values (`crate::output::schema::STALL_DATASETS`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StallRecord {
    /// The stall load along the axis [N], signed (a forward step stalls at
    /// a negative load); 0 unless the status keeps values.
    pub load: f64,
    /// The axis' step at the bracket end nearer L = 0, where it still moves
    /// in the unloaded direction [m per own drive cycle] (the unloaded
    /// step where the first probe stalls; with no stall load, the step at
    /// the largest load probed).
    pub step_near: f64,
    /// The axis' step at the other end, where it has stopped or reversed
    /// [m per own drive cycle]; 0 with no stall load.
    pub step_far: f64,
    /// Integrations of the instance: the unloaded run and every probe (one
    /// per wave it took part in).
    pub waves: u32,
    /// 0 when found; 6 when found but a probe ran to max_cycles (its
    /// estimate was used); 8 ([`STATUS_NO_STALL`]) when the step keeps its
    /// direction at every load probed; a failed probe's status (1-5) when
    /// one failed, and then no value.
    pub status: u32,
}

impl StallRecord {
    /// The stall maps' columns of consecutive records, as the writer takes
    /// them (`crate::output::StallColumns`).
    pub fn columns(records: &[StallRecord]) -> crate::output::StallColumns {
        crate::output::StallColumns {
            load: records.iter().map(|r| r.load).collect(),
            step_near: records.iter().map(|r| r.step_near).collect(),
            step_far: records.iter().map(|r| r.step_far).collect(),
            waves: records.iter().map(|r| r.waves).collect(),
            status: records.iter().map(|r| r.status).collect(),
        }
    }

    /// Why a stored stall record cannot have been written by a run, if it
    /// cannot (the readers' check, like `sweep::Record::implausibility`):
    /// a known status, finite values, zeros where the status keeps none, a
    /// zero far step and load with no stall load, and at least one wave.
    pub fn implausibility(&self) -> Option<String> {
        use crate::measurement::status::Status;
        if Status::from_code(self.status).is_none() {
            return Some(format!(
                "its stall status is {}, which is no status code",
                self.status
            ));
        }
        let values = [
            ("stall load", self.load),
            ("near step", self.step_near),
            ("far step", self.step_far),
        ];
        if let Some((what, v)) = values.iter().find(|(_, v)| !v.is_finite()) {
            return Some(format!("its {what} is {v}"));
        }
        if self.waves == 0 {
            return Some("it took no wave".to_owned());
        }
        let zeros: &[(&str, f64)] = match self.status {
            STATUS_NO_STALL => &values[..1],
            s if !keeps_values(s) => &values,
            _ => &[],
        };
        if self.status == STATUS_NO_STALL && self.step_far != 0.0 {
            return Some(format!(
                "its stall status is 8 (no stall load) but its far step is {:e}, not 0",
                self.step_far
            ));
        }
        zeros.iter().find(|(_, v)| *v != 0.0).map(|(what, v)| {
            format!(
                "its stall status is {} but its {what} is {v:e}, not 0",
                self.status
            )
        })
    }
}

/// Where one instance's search stands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Search {
    /// The sign of the unloaded step: +1 forward, -1 backward.
    sign: f64,
    /// The room along the axis, sqrt(f_c^2 - L_other^2) [N].
    room: f64,
    tolerance: f64,
    /// The largest load magnitude known to keep the step's direction, and
    /// the step there [N, m].
    near: (f64, f64),
    /// The smallest load magnitude known to stop or reverse it, and the
    /// step there, once bracketed.
    far: Option<(f64, f64)>,
    /// The next bracketing probe (index into [`BRACKET`]).
    next: usize,
    waves: u32,
    /// 6 once a probe was not steady.
    status: u32,
    result: Option<StallRecord>,
}

impl Search {
    /// A search from the unloaded run's step along the axis [m per own
    /// drive cycle] and status, with `room` [N] along the axis and
    /// `tolerance` [N]. It is over at once where the unloaded run failed
    /// (its status, no value), where the unloaded step is no motion (at
    /// most [`STEP_ZERO_M`]: the axis does not move, its stall load is 0),
    /// and where there is no room (f_c = 0: no load is allowed, so none
    /// stalls it).
    pub fn new(step: f64, status: u32, room: f64, tolerance: f64) -> Search {
        let mut search = Search {
            sign: if step < 0.0 { -1.0 } else { 1.0 },
            room,
            tolerance,
            near: (0.0, step),
            far: None,
            next: 0,
            waves: 1,
            status: if status == STATUS_NOT_STEADY {
                STATUS_NOT_STEADY
            } else {
                0
            },
            result: None,
        };
        if !keeps_values(status) {
            search.fail(status);
        } else if step.abs() <= STEP_ZERO_M {
            search.far = Some((0.0, step));
            search.finish_found();
        } else if room <= 0.0 || room.is_nan() {
            search.finish_none();
        }
        search
    }

    /// The result, once the search is over.
    pub fn result(&self) -> Option<StallRecord> {
        self.result
    }

    /// The signed load to probe next [N], or `None` once the search is
    /// over.
    pub fn probe(&self) -> Option<f64> {
        if self.result.is_some() {
            return None;
        }
        let magnitude = match self.far {
            None => BRACKET[self.next] * self.room,
            Some(far) => 0.5 * (self.near.0 + far.0),
        };
        Some(-self.sign * magnitude)
    }

    /// Takes the step [m per own drive cycle] and status of the probe at
    /// [`Search::probe`]'s load.
    pub fn offer(&mut self, step: f64, status: u32) {
        let Some(load) = self.probe() else {
            return;
        };
        self.waves += 1;
        if !keeps_values(status) {
            self.fail(status);
            return;
        }
        if status == STATUS_NOT_STEADY {
            self.status = STATUS_NOT_STEADY;
        }
        let at = (load.abs(), step);
        let moving = step * self.sign > STEP_ZERO_M;
        if moving {
            self.near = at;
        } else {
            self.far = Some(at);
        }
        match self.far {
            None => {
                self.next += 1;
                if self.next == BRACKET.len() {
                    self.finish_none();
                }
            }
            Some(far) => {
                // Within the tolerance, or at the resolution of the loads.
                let middle = 0.5 * (self.near.0 + far.0);
                if far.0 - self.near.0 <= 2.0 * self.tolerance
                    || middle <= self.near.0
                    || middle >= far.0
                {
                    self.finish_found();
                }
            }
        }
    }

    fn fail(&mut self, status: u32) {
        self.result = Some(StallRecord {
            waves: self.waves,
            status,
            ..StallRecord::default()
        });
    }

    fn finish_found(&mut self) {
        let far = self.far.expect("bracketed");
        // + 0.0: a stall load of zero is +0, whatever the sign.
        self.result = Some(StallRecord {
            load: -self.sign * 0.5 * (self.near.0 + far.0) + 0.0,
            step_near: self.near.1,
            step_far: far.1,
            waves: self.waves,
            status: self.status,
        });
    }

    fn finish_none(&mut self) {
        self.result = Some(StallRecord {
            load: 0.0,
            step_near: self.near.1,
            step_far: 0.0,
            waves: self.waves,
            status: STATUS_NO_STALL,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs a search to the end on a step function of the load, returning
    /// the result and the loads probed.
    fn run(step: impl Fn(f64) -> (f64, u32), room: f64, tolerance: f64) -> (StallRecord, Vec<f64>) {
        let (s0, st0) = step(0.0);
        let mut search = Search::new(s0, st0, room, tolerance);
        let mut probes = Vec::new();
        while let Some(load) = search.probe() {
            probes.push(load);
            let (s, st) = step(load);
            search.offer(s, st);
            assert!(probes.len() < 200, "the search does not end");
        }
        (search.result().expect("over"), probes)
    }

    /// A step within [`STEP_ZERO_M`] of zero is no motion: a stuck slider's
    /// rounding (1e-21 m in f64, 8e-12 m in f32) stalls at zero load, and a
    /// step that falls to it under load has stalled there.
    #[test]
    fn rounding_of_a_stuck_slider_is_no_motion() {
        for s0 in [0.0, -8.5e-22, 1.7e-21, 7.6e-12, -1.9e-12] {
            let (r, probes) = run(|_| (s0, 0), 1.0, 1e-4);
            assert_eq!((r.load.to_bits(), r.waves), (0f64.to_bits(), 1), "{s0}");
            assert!(probes.is_empty());
        }
        let (r, _) = run(
            |l: f64| (if l > -0.05 { 1e-7 } else { 1e-21 }, 0),
            1.0,
            1e-4,
        );
        assert!((r.load + 0.05).abs() <= 1e-4, "{r:?}");
    }

    /// The two stall loads on straight lines through the reference
    /// unloaded steps and slopes: each found within the tolerance, on the
    /// side against the unloaded step, with steps of both signs at the
    /// bracket ends and the waves bracketing and bisection take.
    #[test]
    fn a_linear_step_stalls_within_the_tolerance_on_the_loaded_side() {
        for (s0, slope, want, waves) in [
            (0.616e-6, 16.2e-6, -0.0380, 12),
            (-0.942e-6, 12.1e-6, 0.0779, 14),
        ] {
            let (r, probes) = run(|l| (s0 + slope * l, 0), 1.0, 1e-4);
            assert_eq!(r.status, 0);
            assert!((r.load - want).abs() < 1e-3, "{r:?}");
            let exact = -s0 / slope;
            assert!((r.load - exact).abs() <= 1e-4, "{} vs {exact}", r.load);
            assert!(r.step_near * s0 > 0.0 && r.step_far * s0 <= 0.0, "{r:?}");
            assert!(probes.iter().all(|l| l * s0 < 0.0), "{probes:?}");
            assert_eq!(r.waves as usize, 1 + probes.len());
            assert_eq!(r.waves, waves, "{probes:?}");
        }
    }

    /// Table-driven edge cases through one helper: what the search ends
    /// with, and after how many waves.
    #[test]
    fn searches_end_as_the_model_says() {
        type Step = Box<dyn Fn(f64) -> (f64, u32)>;
        let cases: Vec<(&str, Step, f64, u32, u32)> = vec![
            // (name, step(L), room, status, waves)
            (
                "never reverses: no stall load",
                Box::new(|l: f64| (1e-6 + 1e-6 * l.abs(), 0)),
                1.0,
                STATUS_NO_STALL,
                1 + BRACKET.len() as u32,
            ),
            ("unloaded run failed", Box::new(|_| (0.0, 3)), 1.0, 3, 1),
            (
                "a probe fails",
                Box::new(|l: f64| if l == 0.0 { (1e-6, 0) } else { (0.0, 1) }),
                1.0,
                1,
                2,
            ),
            (
                "stuck unloaded: stall load 0",
                Box::new(|_| (0.0, 0)),
                1.0,
                0,
                1,
            ),
            (
                "no room (f_c = 0)",
                Box::new(|_| (1e-6, 0)),
                0.0,
                STATUS_NO_STALL,
                1,
            ),
            (
                "a probe not steady keeps its estimate",
                Box::new(|l: f64| (1e-6 + 2e-5 * l, if l == 0.0 { 0 } else { 6 })),
                1.0,
                STATUS_NOT_STEADY,
                12,
            ),
        ];
        for (name, step, room, status, waves) in cases {
            let (r, _) = run(step, room, 1e-4);
            assert_eq!((r.status, r.waves), (status, waves), "{name}: {r:?}");
            assert_eq!(r.implausibility(), None, "{name}: {r:?}");
            if status == STATUS_NO_STALL || !keeps_values(status) {
                assert_eq!(r.load, 0.0, "{name}");
            }
        }
    }

    /// A step that stops (stays exactly zero) over a range of loads stalls
    /// where it first stops, and a step that turns back to forward beyond
    /// its first zero crossing reports the crossing nearest L = 0.
    #[test]
    fn the_crossing_nearest_zero_load_is_the_stall_load() {
        let stops = |l: f64| ((1e-6 + 2e-5 * l).max(0.0), 0);
        let (r, _) = run(stops, 1.0, 1e-5);
        assert!((r.load + 0.05).abs() <= 1e-5, "{r:?}");
        assert_eq!(r.step_far, 0.0);
        // Reverses at -0.05 N, forward again beyond -0.4 N.
        let wiggles = |l: f64| ((l + 0.05) * (l + 0.4) * 1e-4, 0);
        let (r, _) = run(wiggles, 1.0, 1e-5);
        assert!((r.load + 0.05).abs() <= 1e-5, "{r:?}");
    }

    #[test]
    fn stored_records_that_cannot_be_right_are_named() {
        let ok = StallRecord {
            load: -0.04,
            step_near: 1e-9,
            step_far: -1e-9,
            waves: 12,
            status: 0,
        };
        assert_eq!(ok.implausibility(), None);
        let bad = [
            (StallRecord { status: 7, ..ok }, "no status code"),
            (
                StallRecord {
                    load: f64::NAN,
                    ..ok
                },
                "its stall load is NaN",
            ),
            (StallRecord { waves: 0, ..ok }, "no wave"),
            (StallRecord { status: 2, ..ok }, "its stall load is"),
            (
                StallRecord {
                    status: STATUS_NO_STALL,
                    step_far: 0.0,
                    ..ok
                },
                "stall load",
            ),
            (
                StallRecord {
                    status: STATUS_NO_STALL,
                    load: 0.0,
                    ..ok
                },
                "far step",
            ),
        ];
        for (record, why) in bad {
            let got = record.implausibility().expect("refused");
            assert!(got.contains(why), "{record:?}: {got}");
        }
    }
}
