//! The Jacobian a fit's standard errors come from: forward and backward
//! differences of the weighted residuals, one batch, compared.
//!
//! Where they agree the column is their mean (a central difference). Where
//! they disagree by more than [`KINK`] the misfit has a kink at the best
//! point (a row changes its kind of motion there, say: the onset of
//! motion at a low voltage), and the column is the gentler side's, so that
//! the standard error says how far the data allow the key to move on the
//! side where it can, not the width of the cliff on the other.
//!
//! A probe that fails or that a scene rule refuses (a free
//! `coulomb_friction` probed below the scene's load, say) leaves its
//! column to the other side. A key neither side can probe has no column:
//! its standard error is unknown, and the fit says so.

use anyhow::{Result, bail};

/// Forward and backward slopes differing by more than this fraction of the
/// larger make a kink.
pub const KINK: f64 = 0.5;

/// A Jacobian (rows: residuals, columns: the free keys some side could
/// probe, `probed`) and, per free key, the residual where its sides
/// disagree most if they make a kink.
pub struct Sided {
    pub j: Vec<Vec<f64>>,
    pub kinks: Vec<Option<usize>>,
    /// The free keys that have a column, in order; the others could be
    /// probed on neither side.
    pub probed: Vec<usize>,
}

/// The candidates' residuals, a batch at a time (`None`: it failed).
pub type Eval<'a> = dyn FnMut(&[Vec<f64>]) -> Result<Vec<Option<Vec<f64>>>> + 'a;

/// The Jacobian at `u` (residuals `r0`) with difference steps `steps`,
/// one-sided where a step would leave the bounds `[lo, hi]`.
pub fn sided(
    eval: &mut Eval<'_>,
    bounds: (&[f64], &[f64]),
    u: &[f64],
    r0: &[f64],
    steps: &[f64],
) -> Result<Sided> {
    let (lo, hi) = bounds;
    let mut points = Vec::new();
    let mut slots = Vec::new();
    for j in 0..u.len() {
        for sign in [1.0, -1.0] {
            let mut v = u.to_vec();
            v[j] += sign * steps[j];
            if v[j] >= lo[j] && v[j] <= hi[j] {
                slots.push((j, sign));
                points.push(v);
            }
        }
    }
    let results = eval(&points)?;
    let mut sides: Vec<[Option<Vec<f64>>; 2]> = vec![[None, None]; u.len()];
    for ((j, sign), r) in slots.into_iter().zip(results) {
        // A failed or refused probe leaves the column to the other side.
        let Some(r) = r else {
            continue;
        };
        let slope = r
            .iter()
            .zip(r0)
            .map(|(a, b)| sign * (a - b) / steps[j])
            .collect();
        sides[j][usize::from(sign < 0.0)] = Some(slope);
    }
    let mut columns = Vec::with_capacity(u.len());
    let mut kinks = Vec::with_capacity(u.len());
    let mut probed = Vec::with_capacity(u.len());
    for (j, [forward, backward]) in sides.into_iter().enumerate() {
        let (column, kink) = match (forward, backward) {
            (Some(f), Some(b)) => combine(f, b),
            (Some(one), None) | (None, Some(one)) => (one, None),
            (None, None) => {
                kinks.push(None);
                continue;
            }
        };
        columns.push(column);
        kinks.push(kink);
        probed.push(j);
    }
    if probed.is_empty() {
        bail!("no free key could be probed next to the best point");
    }
    let j = (0..r0.len())
        .map(|i| columns.iter().map(|c| c[i]).collect())
        .collect();
    Ok(Sided { j, kinks, probed })
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// One column from its two sides: their mean, or at a kink the gentler
/// side with the residual where they differ most.
fn combine(forward: Vec<f64>, backward: Vec<f64>) -> (Vec<f64>, Option<usize>) {
    let gap: Vec<f64> = forward.iter().zip(&backward).map(|(f, b)| f - b).collect();
    let (nf, nb) = (norm(&forward), norm(&backward));
    if norm(&gap) <= KINK * nf.max(nb) {
        let mean = forward
            .iter()
            .zip(&backward)
            .map(|(f, b)| 0.5 * (f + b))
            .collect();
        return (mean, None);
    }
    let worst = (0..gap.len()).max_by(|&a, &b| gap[a].abs().total_cmp(&gap[b].abs()));
    (if nf <= nb { forward } else { backward }, worst)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Residuals of a 1-parameter model: r = [a (u - 1), |u - 1| * kink].
    fn check(kink: f64, expect_kink: bool, expect_slope: f64) {
        let mut eval = |us: &[Vec<f64>]| -> Result<Vec<Option<Vec<f64>>>> {
            Ok(us
                .iter()
                .map(|u| Some(vec![2.0 * (u[0] - 1.0), kink * (u[0] - 1.0).abs()]))
                .collect())
        };
        let s = sided(&mut eval, (&[0.0], &[3.0]), &[1.0], &[0.0, 0.0], &[0.1]).unwrap();
        assert_eq!(s.kinks[0].is_some(), expect_kink);
        assert!((s.j[0][0] - expect_slope).abs() < 1e-12, "{:?}", s.j);
    }

    #[test]
    fn a_kink_takes_the_gentler_side() {
        check(0.0, false, 2.0);
        check(100.0, true, 2.0);
    }

    /// A refused probe leaves the column to the other side; a key that
    /// neither side can probe has no column.
    #[test]
    fn a_failed_probe_falls_back_to_the_other_side() {
        // Key 0 refuses every point above u = 1, key 1 every point off 0.
        let mut eval = |us: &[Vec<f64>]| -> Result<Vec<Option<Vec<f64>>>> {
            Ok(us
                .iter()
                .map(|u| (u[0] <= 1.0 && u[1] == 0.0).then(|| vec![3.0 * (u[0] - 1.0)]))
                .collect())
        };
        let bounds: (&[f64], &[f64]) = (&[0.0, -1.0], &[3.0, 1.0]);
        let s = sided(&mut eval, bounds, &[1.0, 0.0], &[0.0], &[0.1, 0.1]).unwrap();
        assert_eq!(s.probed, vec![0]);
        assert!((s.j[0][0] - 3.0).abs() < 1e-12, "{:?}", s.j);
        assert_eq!(s.kinks, vec![None, None]);
    }
}
