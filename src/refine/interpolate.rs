//! The finest raster of a refinement: integrated records where computed,
//! the bilinear interpolant of the smallest leaf cell elsewhere.
//!
//! An inferred point takes the bilinear interpolant of its leaf's four
//! corners for every value a map shows (steps, velocities, standard errors,
//! baseline steps); a point on the edge of two leaves takes the smaller
//! leaf's, whose corners are nearer. Its status is 0: a leaf's corners all
//! finished normally (a corner that did not flags its cell), so its
//! interior is taken to as well, and `/maps/inferred` says it was not
//! integrated. Its counts (`steps`, `periods`, `period_lag`) are 0 and its
//! motion undetermined: no integration took place there, and a kind of
//! motion is not interpolated.

use super::grid::Cell;
use super::rule::weights;
use super::waves::{INFERRED, Refinement};
use crate::model::AXES;
use crate::sweep::{Backward, Record};

/// The bilinear interpolant of the corner records (in
/// [`Cell::corners`] order) at (u, v).
pub fn bilinear(corners: &[Record; 4], u: f64, v: f64) -> Record {
    let w = weights(u, v);
    let mix = |f: &dyn Fn(&Record) -> [f64; AXES]| -> [f64; AXES] {
        let mut out = [0.0; AXES];
        for (c, w) in corners.iter().zip(w) {
            for (o, x) in out.iter_mut().zip(f(c)) {
                *o += w * x;
            }
        }
        out
    };
    Record {
        step: mix(&|r| r.step),
        velocity: mix(&|r| r.velocity),
        // Interpolated errors are no errors of an estimate: inferred = 1
        // marks them (docs/adaptive.md).
        step_se: mix(&|r| r.step_se),
        baseline_step: mix(&|r| r.baseline_step),
        // The backward travel and its ratio, interpolated as the step is
        // (the ratio of interpolated values would be no better).
        backward: Backward {
            travel: mix(&|r| r.backward.travel),
            travel_se: mix(&|r| r.backward.travel_se),
            ratio: mix(&|r| r.backward.ratio),
            ratio_se: mix(&|r| r.backward.ratio_se),
        },
        // Counts 0, motion undetermined: nothing was integrated here.
        ..Record::default()
    }
}

/// The raster and the inferred mask (1 where interpolated). `records`
/// holds a record for every point the refinement integrated.
pub fn raster(r: &Refinement, records: &[Option<Record>]) -> (Vec<Record>, Vec<u8>) {
    let grid = r.grid;
    let mut out = vec![Record::default(); grid.len()];
    let mut inferred = vec![1u8; grid.len()];
    // Largest leaves first, so a smaller one's values win on shared edges.
    let mut leaves: Vec<Cell> = r.leaves.clone();
    leaves.sort_by_key(|c| std::cmp::Reverse(c.size));
    for leaf in &leaves {
        let corners = leaf
            .corners()
            .map(|p| records[grid.index(p)].expect("a leaf's corners are integrated"));
        for p in leaf.points() {
            let k = grid.index(p);
            if r.level_of[k] == INFERRED {
                let (u, v) = leaf.local(p);
                out[k] = bilinear(&corners, u, v);
            }
        }
    }
    for (k, level) in r.level_of.iter().enumerate() {
        if *level != INFERRED {
            out[k] = records[k].expect("an integrated point has its record");
            inferred[k] = 0;
        }
    }
    (out, inferred)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::motion::Motion;

    #[test]
    fn an_inferred_point_has_no_kind_of_motion_and_no_counts() {
        let corner = |k: u32| Record {
            step: [k as f64 * 1e-7, 0.0],
            periods: 40 + k,
            period_lag: 5,
            steps: 1000,
            motion: Motion::Periodic,
            ..Record::default()
        };
        let got = bilinear(&[corner(0), corner(1), corner(2), corner(3)], 0.5, 0.5);
        assert_eq!(got.motion, Motion::Undetermined);
        assert_eq!((got.periods, got.period_lag, got.steps), (0, 0, 0));
        assert!(got.step[0] > 0.0);
        assert_eq!(got.implausibility(), None);
    }
}
