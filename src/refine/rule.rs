//! The refinement rule, on plain values so that it can be tested without
//! integrating: what an integrated point says ([`Sample`]), its regime
//! [`Label`], and whether an interpolated value is close enough to an
//! integrated one ([`within`], [`judge`]).

use crate::model::AXES;
use crate::plot::Regime;
use crate::sweep::Record;

/// Relative part of the accuracy rule: an inferred value `a` stands for an
/// integrated `b` when `|a - b| <= tolerance + RELATIVE * |b|` (issue 22's
/// 0.02 um + 1 %).
pub const RELATIVE: f64 = 1e-2;

/// What the rule reads of an integrated point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Sample {
    /// The 2-DOF step per axis [m per own drive cycle].
    pub step: [f64; AXES],
    /// The 1-DOF steps [m] (zero when the scene has no baselines).
    pub baseline: [f64; AXES],
    /// Whether the instance (and its baselines) finished normally: status
    /// 0 (ok, periodic or converged steady). Any other status, "not steady"
    /// included, is a point the rule never interpolates across.
    pub ok: bool,
}

impl Sample {
    /// The sample of a record; `baselines`: whether the scene runs them.
    pub fn of_record(rec: &Record, baselines: bool) -> Sample {
        Sample {
            step: rec.step,
            baseline: if baselines {
                rec.baseline_step
            } else {
                [0.0; AXES]
            },
            ok: rec.status == 0 && (!baselines || rec.baseline_status == 0),
        }
    }

    /// The values the accuracy rule compares: both steps, then both
    /// baseline steps.
    pub fn values(&self) -> [f64; 2 * AXES] {
        [
            self.step[0],
            self.step[1],
            self.baseline[0],
            self.baseline[1],
        ]
    }

    /// Bilinear interpolation between the corners (in [`Cell::corners`]
    /// order) at (u, v); `ok` when every corner is.
    ///
    /// [`Cell::corners`]: super::grid::Cell::corners
    pub fn bilinear(corners: &[Sample; 4], u: f64, v: f64) -> Sample {
        let w = weights(u, v);
        let mix = |f: &dyn Fn(&Sample) -> f64| -> f64 {
            corners.iter().zip(w).map(|(c, w)| w * f(c)).sum()
        };
        Sample {
            step: [mix(&|s| s.step[0]), mix(&|s| s.step[1])],
            baseline: [mix(&|s| s.baseline[0]), mix(&|s| s.baseline[1])],
            ok: corners.iter().all(|c| c.ok),
        }
    }
}

/// Bilinear weights of the corners (i, j), (i, j + s), (i + s, j),
/// (i + s, j + s) at (u, v).
pub fn weights(u: f64, v: f64) -> [f64; 4] {
    [(1.0 - u) * (1.0 - v), (1.0 - u) * v, u * (1.0 - v), u * v]
}

/// The regime a point is in: per axis, the sign of the step with a dead
/// zone, and with baselines the coupling regime of `pidm plot` (2-DOF step
/// against 1-DOF step, [`Regime::classify`]); a failed point is a label of
/// its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Label {
    /// -1, 0 or 1 per axis: the step beyond minus, within, or beyond plus
    /// the tolerance.
    pub sign: [i8; AXES],
    /// The coupling regime per axis, when the scene has baselines.
    pub coupling: Option<[Regime; AXES]>,
    pub ok: bool,
}

/// The label of a sample; `tolerance` [m] is the sign's dead zone, and
/// `coupling`, for a scene with baselines, the coupling regime's zero [m]
/// (what counts as no step, or as no change: [`Regime::classify_within`]).
pub fn label(s: &Sample, tolerance: f64, coupling: Option<f64>) -> Label {
    let sign = s.step.map(|x| {
        if x > tolerance {
            1
        } else if x < -tolerance {
            -1
        } else {
            0
        }
    });
    let coupling = coupling
        .map(|zero| [0, 1].map(|a| Regime::classify_within(s.step[a], s.baseline[a], s.ok, zero)));
    Label {
        sign,
        coupling,
        ok: s.ok,
    }
}

/// Whether `interpolated` stands for `exact`: `|a - b| <= tolerance +`
/// [`RELATIVE`]` * |b|`.
pub fn within(interpolated: f64, exact: f64, tolerance: f64) -> bool {
    (interpolated - exact).abs() <= tolerance + RELATIVE * exact.abs()
}

/// How an interpolated sample compares with the integrated one at the same
/// point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Judgement {
    /// The largest difference of a compared value [m].
    pub miss: f64,
    /// Whether the interpolant fails there: a value beyond [`within`], or
    /// another label.
    pub off: bool,
}

/// Judges the interpolant at one integrated point.
pub fn judge(
    interpolated: &Sample,
    exact: &Sample,
    tolerance: f64,
    coupling: Option<f64>,
    baselines: bool,
) -> Judgement {
    let compared = if baselines { 2 * AXES } else { AXES };
    let (a, b) = (interpolated.values(), exact.values());
    let mut miss: f64 = 0.0;
    let mut off = !exact.ok || !interpolated.ok;
    for k in 0..compared {
        miss = miss.max((a[k] - b[k]).abs());
        off |= !within(a[k], b[k], tolerance);
    }
    off |= label(interpolated, tolerance, coupling) != label(exact, tolerance, coupling);
    Judgement { miss, off }
}

/// Whether the corners of a cell carry one label (and all finished
/// normally): a cell whose corners disagree is always refined.
pub fn corners_agree(corners: &[Sample; 4], tolerance: f64, coupling: Option<f64>) -> bool {
    let first = label(&corners[0], tolerance, coupling);
    first.ok
        && corners[1..]
            .iter()
            .all(|c| label(c, tolerance, coupling) == first)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x: f64, y: f64) -> Sample {
        Sample {
            step: [x, y],
            baseline: [x, 0.0],
            ok: true,
        }
    }

    #[test]
    fn the_accuracy_rule_is_tolerance_plus_one_percent() {
        let t = 2e-8;
        assert!(within(1e-6 + 2.9e-8, 1e-6, t));
        assert!(!within(1e-6 + 3.1e-8, 1e-6, t));
        assert!(within(0.0, 1.9e-8, t));
        assert!(!within(0.0, 2.03e-8, t));
    }

    #[test]
    fn labels_are_signs_with_a_dead_zone_and_coupling() {
        let t = 2e-8;
        assert_eq!(label(&sample(1e-7, -1e-8), t, None).sign, [1, 0]);
        assert_eq!(label(&sample(-3e-8, 3e-8), t, None).sign, [-1, 1]);
        let corners = [sample(1e-7, 0.0); 4];
        assert!(corners_agree(&corners, t, Some(t)));
        let mut bad = corners;
        bad[3].ok = false;
        assert!(!corners_agree(&bad, t, Some(t)));
        let mut flipped = corners;
        flipped[2].step[0] = -1e-7;
        assert!(!corners_agree(&flipped, t, None));
        // The 2-DOF step above its baseline: amplified, not unchanged.
        let mut amplified = corners;
        amplified[1].step[0] = 1.5e-7;
        assert!(corners_agree(
            &amplified[..2].repeat(2).try_into().unwrap(),
            t,
            None
        ));
        assert!(!corners_agree(&amplified, t, Some(t)));
    }

    #[test]
    fn bilinear_interpolation_is_exact_on_bilinear_functions() {
        let f = |u: f64, v: f64| sample(1e-7 + 2e-7 * u - 3e-7 * v + 1e-7 * u * v, 4e-7 * v);
        let corners = [f(0.0, 0.0), f(0.0, 1.0), f(1.0, 0.0), f(1.0, 1.0)];
        for (u, v) in [(0.5, 0.5), (0.25, 0.75), (1.0, 0.0)] {
            let got = Sample::bilinear(&corners, u, v);
            let j = judge(&got, &f(u, v), 1e-12, Some(1e-12), true);
            assert!(!j.off && j.miss < 1e-20, "{u} {v}: {j:?}");
        }
        let j = judge(&sample(0.0, 0.0), &sample(1e-7, 0.0), 2e-8, None, false);
        assert!(j.off);
        assert_eq!(j.miss, 1e-7);
    }
}
