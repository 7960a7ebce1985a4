//! Sobol' indices of one output, as SALib's `sobol.analyze` reports them
//! without second-order indices (issue 61): first-order indices by
//! Saltelli et al. (2010), total ones by Jansen (1999), each with a
//! bootstrap half-width at 95 %.
//!
//! The sample (Saltelli's scheme): two independent base matrices A and B
//! of `n` rows in the unit cube `[0, 1)^k`, and for each key i the matrix
//! AB_i, A with column i from B: `n (k + 2)` runs, in SALib's row order per
//! base row: A, AB_1 ... AB_k, B. The base matrices are plain Monte Carlo
//! from the searches' seeded generator (SALib draws a Sobol' sequence):
//! the estimators are the same, their error falls as 1 / sqrt(n).

use super::rng::SplitMix64;
use anyhow::{Result, ensure};

/// The bootstrap's resamples, as SALib's default.
pub const RESAMPLES: usize = 100;

/// The normal quantile of a two-sided 95 % interval, SALib's
/// `norm.ppf(0.975)`.
const Z95: f64 = 1.959_963_984_540_054;

/// `n (k + 2)` points of the unit cube `[0, 1)^k` in SALib's row order:
/// per base row A, AB_1 ... AB_k, B.
pub fn saltelli_sample(n: usize, k: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = SplitMix64(seed);
    let mut out = Vec::with_capacity(n * (k + 2));
    for _ in 0..n {
        let a: Vec<f64> = (0..k).map(|_| rng.unit()).collect();
        let b: Vec<f64> = (0..k).map(|_| rng.unit()).collect();
        out.push(a.clone());
        for i in 0..k {
            let mut ab = a.clone();
            ab[i] = b[i];
            out.push(ab);
        }
        out.push(b);
    }
    out
}

/// One output's indices per key, each with its bootstrap half-width.
#[derive(Clone, Debug, PartialEq)]
pub struct Indices {
    pub first: Vec<f64>,
    pub first_conf: Vec<f64>,
    pub total: Vec<f64>,
    pub total_conf: Vec<f64>,
}

/// The indices of `y`, the outputs of [`saltelli_sample`]'s rows for `k`
/// keys, in its order. The outputs are standardised first, as SALib's
/// are; the bootstrap draws `resamples` sets of base rows from `seed`.
pub fn analyze(y: &[f64], k: usize, resamples: usize, seed: u64) -> Result<Indices> {
    ensure!(k > 0, "no keys to analyse");
    ensure!(
        !y.is_empty() && y.len().is_multiple_of(k + 2),
        "{} outputs are not whole base rows of {} runs",
        y.len(),
        k + 2
    );
    ensure!(y.iter().all(|v| v.is_finite()), "an output is not finite");
    let n = y.len() / (k + 2);
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let sd = (y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / y.len() as f64).sqrt();
    ensure!(sd > 0.0, "the output does not vary: no index is defined");
    let z: Vec<f64> = y.iter().map(|v| (v - mean) / sd).collect();
    let row = |r: usize, col: usize| z[r * (k + 2) + col];
    let all: Vec<usize> = (0..n).collect();
    let mut rng = SplitMix64(seed);
    let draws: Vec<Vec<usize>> = (0..resamples)
        .map(|_| (0..n).map(|_| rng.below(n)).collect())
        .collect();
    let mut out = Indices {
        first: vec![0.0; k],
        first_conf: vec![0.0; k],
        total: vec![0.0; k],
        total_conf: vec![0.0; k],
    };
    for i in 0..k {
        let estimate = |rows: &[usize]| {
            let (a, ab, b) = (
                |r: usize| row(r, 0),
                |r: usize| row(r, i + 1),
                |r: usize| row(r, k + 1),
            );
            let var = variance(rows.iter().map(|&r| a(r)).chain(rows.iter().map(|&r| b(r))));
            let m = rows.len() as f64;
            let first = rows.iter().map(|&r| b(r) * (ab(r) - a(r))).sum::<f64>() / m;
            let total = rows.iter().map(|&r| (a(r) - ab(r)).powi(2)).sum::<f64>() / m;
            (first / var, 0.5 * total / var)
        };
        (out.first[i], out.total[i]) = estimate(&all);
        let boot: Vec<(f64, f64)> = draws.iter().map(|d| estimate(d)).collect();
        out.first_conf[i] = Z95 * sample_sd(boot.iter().map(|b| b.0));
        out.total_conf[i] = Z95 * sample_sd(boot.iter().map(|b| b.1));
    }
    Ok(out)
}

/// The population variance (numpy's `var`, ddof 0).
fn variance(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = values.clone().count() as f64;
    let mean = values.clone().sum::<f64>() / n;
    values.map(|v| (v - mean).powi(2)).sum::<f64>() / n
}

/// The sample standard deviation (ddof 1).
fn sample_sd(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = values.clone().count() as f64;
    let mean = values.clone().sum::<f64>() / n;
    (values.map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Ishigami's function on [-pi, pi]^3 (a = 7, b = 0.1), whose indices
    /// are known in closed form.
    fn ishigami(u: &[f64]) -> f64 {
        let x: Vec<f64> = u.iter().map(|v| -PI + 2.0 * PI * v).collect();
        x[0].sin() + 7.0 * x[1].sin().powi(2) + 0.1 * x[2].powi(4) * x[0].sin()
    }

    /// The closed-form indices: V = a^2/8 + b pi^4/5 + b^2 pi^8/18 + 1/2,
    /// V1 = (1 + b pi^4/5)^2 / 2, V2 = a^2/8, V13 = b^2 pi^8 (1/18 - 1/50).
    fn ishigami_truth() -> ([f64; 3], [f64; 3]) {
        let (a, b) = (7.0_f64, 0.1_f64);
        let p4 = PI.powi(4);
        let v1 = 0.5 * (1.0 + b * p4 / 5.0).powi(2);
        let v2 = a * a / 8.0;
        let v13 = b * b * PI.powi(8) * (1.0 / 18.0 - 1.0 / 50.0);
        let v = v1 + v2 + v13;
        ([v1 / v, v2 / v, 0.0], [(v1 + v13) / v, v2 / v, v13 / v])
    }

    #[test]
    fn ishigamis_indices_are_found_within_their_intervals() {
        let (k, n) = (3, 20_000);
        let rows = saltelli_sample(n, k, 5);
        assert_eq!(rows.len(), n * (k + 2));
        let y: Vec<f64> = rows.iter().map(|u| ishigami(u)).collect();
        let s = analyze(&y, k, RESAMPLES, 9).unwrap();
        let (first, total) = ishigami_truth();
        assert!((first[0] - 0.3139).abs() < 1e-4 && (total[2] - 0.2437).abs() < 1e-4);
        for i in 0..k {
            let checks = [
                (s.first[i], s.first_conf[i], first[i]),
                (s.total[i], s.total_conf[i], total[i]),
            ];
            for (got, conf, want) in checks {
                assert!(conf > 0.0 && conf < 0.05, "{s:?}");
                assert!(
                    (got - want).abs() < 2.0 * conf,
                    "key {i}: {got} ± {conf} vs {want}"
                );
            }
        }
    }

    /// SALib's row order: A, AB_1 ... AB_k, B per base row, AB_i being A
    /// with column i from B.
    #[test]
    fn the_sample_is_in_salibs_row_order() {
        let k = 4;
        let rows = saltelli_sample(3, k, 1);
        for base in rows.chunks(k + 2) {
            let (a, b) = (&base[0], &base[k + 1]);
            for i in 0..k {
                for j in 0..k {
                    assert_eq!(base[i + 1][j], if i == j { b[j] } else { a[j] });
                }
            }
        }
        assert_eq!(saltelli_sample(3, k, 1), rows);
        assert_ne!(saltelli_sample(3, k, 2), rows);
    }

    /// An output of one key alone: that key explains all of it, the other
    /// none (exactly: its AB runs equal A's); a constant output and a
    /// partial base row are refused.
    #[test]
    fn one_key_explains_all_and_bad_outputs_are_refused() {
        let rows = saltelli_sample(2000, 2, 3);
        let y: Vec<f64> = rows.iter().map(|u| (3.0 * u[0]).exp()).collect();
        let s = analyze(&y, 2, RESAMPLES, 1).unwrap();
        assert!(
            (s.first[0] - 1.0).abs() < 0.1 && (s.total[0] - 1.0).abs() < 0.05,
            "{s:?}"
        );
        assert_eq!((s.first[1], s.total[1]), (0.0, 0.0));
        assert!(analyze(&[1.0; 8], 2, RESAMPLES, 1).is_err());
        assert!(analyze(&y[..7], 2, RESAMPLES, 1).is_err());
    }
}
