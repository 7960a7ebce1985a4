//! The input distributions of a sensitivity study (issue 61) and what is
//! said of an output's spread: a key's value from a point of the unit cube
//! by the distribution's quantile function, truncated to the key's valid
//! range; an output's mean, SD and quantiles; and the model's noise
//! against the output's variance.

use anyhow::{Result, ensure};
use std::f64::consts::SQRT_2;

/// How a key varies across units of a design.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distribution {
    /// Uniform on `[low, high]`.
    Uniform { low: f64, high: f64 },
    /// Normal, truncated to the key's valid range.
    Normal { mean: f64, sd: f64 },
    /// Log-normal with this median and geometric SD `factor` (> 1): a
    /// sixth of the units lie above `median * factor`.
    LogNormal { median: f64, factor: f64 },
}

impl Distribution {
    /// Whether the parameters describe a distribution.
    pub fn check(&self) -> Result<()> {
        match *self {
            Distribution::Uniform { low, high } => {
                ensure!(
                    low.is_finite() && high.is_finite() && low < high,
                    "uniform = [{low}, {high}] is not a finite range with low < high"
                );
            }
            Distribution::Normal { mean, sd } => {
                ensure!(
                    mean.is_finite() && sd.is_finite() && sd > 0.0,
                    "normal = {{ mean = {mean}, sd = {sd} }} needs a finite mean and an sd above 0"
                );
            }
            Distribution::LogNormal { median, factor } => {
                ensure!(
                    median.is_finite() && median > 0.0 && factor.is_finite() && factor > 1.0,
                    "lognormal = {{ median = {median}, factor = {factor} }} needs a median above 0 and a factor above 1"
                );
            }
        }
        Ok(())
    }

    /// The share of the distribution outside `range` that truncation cuts
    /// off (0 where none: the output says when it is not).
    pub fn cut(&self, (lo, hi): (f64, f64)) -> f64 {
        let (a, b) = self.cdf_range((lo, hi));
        1.0 - (b - a)
    }

    /// The value at unit-cube coordinate `u` in [0, 1): the quantile of
    /// the distribution truncated to `range` (the key's valid values).
    pub fn value(&self, u: f64, range: (f64, f64)) -> f64 {
        let (a, b) = self.cdf_range(range);
        let p = a + u * (b - a);
        let x = match *self {
            Distribution::Uniform { low, high } => low + p * (high - low),
            Distribution::Normal { mean, sd } => mean + sd * normal_quantile(p),
            Distribution::LogNormal { median, factor } => {
                median * (factor.ln() * normal_quantile(p)).exp()
            }
        };
        x.clamp(range.0, range.1)
    }

    /// The distribution's CDF at the ends of `range`.
    fn cdf_range(&self, (lo, hi): (f64, f64)) -> (f64, f64) {
        let cdf = |x: f64| match *self {
            Distribution::Uniform { low, high } => ((x - low) / (high - low)).clamp(0.0, 1.0),
            Distribution::Normal { mean, sd } => normal_cdf((x - mean) / sd),
            Distribution::LogNormal { median, factor } => {
                if x <= 0.0 {
                    0.0
                } else {
                    normal_cdf((x / median).ln() / factor.ln())
                }
            }
        };
        (cdf(lo), cdf(hi))
    }
}

/// The standard normal CDF.
pub fn normal_cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x / SQRT_2)
}

/// The standard normal quantile, to about 1e-15: Acklam's rational
/// approximation, refined by one Halley step on the CDF.
pub fn normal_quantile(p: f64) -> f64 {
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.38357751867269e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    let x = if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    };
    let e = normal_cdf(x) - p;
    let u = e * (2.0 * std::f64::consts::PI).sqrt() * (0.5 * x * x).exp();
    x - u / (1.0 + 0.5 * x * u)
}

/// An output's spread across the sample (uncertainty propagation).
#[derive(Clone, Debug, PartialEq)]
pub struct Spread {
    pub mean: f64,
    /// The sample SD (ddof 1).
    pub sd: f64,
    /// The 5, 50 and 95 % quantiles (numpy's default, linear).
    pub quantiles: [f64; 3],
    /// The model's noise against the output's variance: the mean SE² over
    /// Var(Y) (ddof 1); above [`NOISE_WARNING`] the indices carry noise.
    pub noise: f64,
}

/// The noise share above which a study warns.
pub const NOISE_WARNING: f64 = 0.01;

/// The spread of outputs `y` whose standard errors are `se`.
pub fn spread(y: &[f64], se: &[f64]) -> Result<Spread> {
    ensure!(
        y.len() >= 2 && se.len() == y.len(),
        "a spread needs two outputs or more, each with its SE"
    );
    let n = y.len() as f64;
    let mean = y.iter().sum::<f64>() / n;
    let var = y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    let mut sorted = y.to_vec();
    sorted.sort_by(f64::total_cmp);
    let at = |q: f64| {
        let h = q * (n - 1.0);
        let (k, f) = (h.floor() as usize, h - h.floor());
        let next = sorted[(k + 1).min(sorted.len() - 1)];
        sorted[k] + f * (next - sorted[k])
    };
    let se2 = se.iter().map(|s| s * s).sum::<f64>() / n;
    Ok(Spread {
        mean,
        sd: var.sqrt(),
        quantiles: [at(0.05), at(0.5), at(0.95)],
        noise: if var > 0.0 { se2 / var } else { f64::INFINITY },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_normal_quantile_inverts_the_cdf() {
        assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-14);
        assert_eq!(normal_quantile(0.5), 0.0);
        // Within what p itself knows: its rounding over the density.
        for k in -80..=80 {
            let x = k as f64 / 10.0;
            let p = normal_cdf(x);
            let density = (-0.5 * x * x).exp() / (2.0 * std::f64::consts::PI).sqrt();
            let known = 4.0 * f64::EPSILON * p / density;
            let back = normal_quantile(p);
            assert!((back - x).abs() < 1e-14 + known, "{x}: {back}");
        }
    }

    /// Each distribution's median and spread, and truncation to a range:
    /// values stay inside it, and the cut share is said.
    #[test]
    fn values_follow_each_distribution_inside_the_range() {
        let all = (f64::NEG_INFINITY, f64::INFINITY);
        let u = Distribution::Uniform {
            low: 2.0,
            high: 4.0,
        };
        assert_eq!((u.value(0.0, all), u.value(0.5, all)), (2.0, 3.0));
        let n = Distribution::Normal { mean: 1.0, sd: 0.1 };
        assert!((n.value(0.5, all) - 1.0).abs() < 1e-15);
        assert!((n.value(normal_cdf(1.0), all) - 1.1).abs() < 1e-12);
        let l = Distribution::LogNormal {
            median: 2.0,
            factor: 1.5,
        };
        assert!((l.value(0.5, all) - 2.0).abs() < 1e-14);
        assert!((l.value(normal_cdf(1.0), all) - 3.0).abs() < 1e-12);
        // A normal cut at 0.95 from below: values at or above it, 31 % cut.
        let range = (0.95, f64::INFINITY);
        assert!((n.cut(range) - normal_cdf(-0.5)).abs() < 1e-15);
        assert_eq!(n.cut(all), 0.0);
        for k in 0..100 {
            assert!(n.value(k as f64 / 100.0, range) >= 0.95);
        }
        assert!((n.value(0.0, range) - 0.95).abs() < 1e-12);
        assert!(Distribution::Normal { mean: 1.0, sd: 0.0 }.check().is_err());
        assert!(
            Distribution::LogNormal {
                median: 1.0,
                factor: 1.0
            }
            .check()
            .is_err()
        );
        assert!(
            Distribution::Uniform {
                low: 1.0,
                high: 1.0
            }
            .check()
            .is_err()
        );
    }

    /// numpy's `percentile([1, 2, 3, 4], [5, 50, 95])` is [1.15, 2.5, 3.85].
    #[test]
    fn a_spread_has_numpys_quantiles_and_the_noise_share() {
        let s = spread(&[4.0, 1.0, 3.0, 2.0], &[0.1; 4]).unwrap();
        let q = s.quantiles;
        assert!((q[0] - 1.15).abs() < 1e-12 && q[1] == 2.5 && (q[2] - 3.85).abs() < 1e-12);
        assert_eq!(s.mean, 2.5);
        assert!((s.sd - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert!((s.noise - 0.01 / (5.0 / 3.0)).abs() < 1e-15);
        assert!(spread(&[1.0], &[0.0]).is_err());
    }
}
