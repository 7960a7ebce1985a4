//! How well a fit's misfit agrees with its data's standard errors: the
//! chi-square survival function (the p-value of chi2 on dof degrees of
//! freedom, as SciPy's `chi2.sf`), from the regularized incomplete gamma
//! function (Numerical Recipes' series and Lentz's continued fraction).

/// Below this p-value the data's standard errors are too small for the
/// misfit (or the model misses the data): the fit warns and reports the
/// standard errors scaled by sqrt(reduced chi2) beside the given ones.
pub const P_WARN: f64 = 1e-3;

/// The probability that chi2 on `dof` degrees of freedom reaches `chi2`
/// by chance, where the residuals are in units of their true standard
/// errors; `None` for `dof` <= 0.
pub fn p_value(chi2: f64, dof: i64) -> Option<f64> {
    if dof <= 0 || !chi2.is_finite() {
        return None;
    }
    Some(upper_gamma(dof as f64 / 2.0, chi2.max(0.0) / 2.0))
}

/// The regularized upper incomplete gamma function Q(a, x).
fn upper_gamma(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    if x < a + 1.0 {
        1.0 - lower_series(a, x)
    } else {
        upper_fraction(a, x)
    }
}

/// P(a, x) by its series, for x < a + 1.
fn lower_series(a: f64, x: f64) -> f64 {
    let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
    for _ in 0..1000 {
        n += 1.0;
        term *= x / n;
        sum += term;
        if term.abs() < sum.abs() * 1e-16 {
            break;
        }
    }
    (sum.ln() - x + a * x.ln() - ln_gamma(a)).exp()
}

/// Q(a, x) by its continued fraction (modified Lentz), for x >= a + 1.
fn upper_fraction(a: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / TINY;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..1000 {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < TINY {
            d = TINY;
        }
        c = b + an / c;
        if c.abs() < TINY {
            c = TINY;
        }
        d = 1.0 / d;
        let delta = d * c;
        h *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    (-x + a * x.ln() - ln_gamma(a)).exp() * h
}

/// The fewest degrees of freedom behind the errors of the axes `data`
/// measures: none where every axis' come from the file (known), a
/// setting's repeats' pooled ones, or the fit's own (`fit_dof`, at least
/// 1) where a scale comes from the residuals.
pub fn estimated_dof(data: &super::data::Data, fit_dof: i64) -> Option<f64> {
    use super::data::SeSource;
    (0..crate::model::AXES)
        .filter(|&a| data.measured_on(a) > 0)
        .filter_map(|a| match data.se_source[a] {
            SeSource::File => None,
            SeSource::Repeats => data.pooled[a].map(|p| p.dof.max(1) as f64),
            SeSource::Residuals => Some(fit_dof.max(1) as f64),
        })
        .reduce(f64::min)
}

/// The share of a unit normal within one standard deviation: a 68 %
/// interval's level (a rise of chi2 by 1 where the errors are known).
pub const LEVEL_68: f64 = 0.682_689_492_137_085_9;

/// The rise of chi2 that bounds a `level` interval of one key where the
/// data's errors are estimated with `dof` degrees of freedom (Student's
/// t quantile squared, the F(1, dof) quantile), or known (`None`: the
/// chi-square quantile on one degree of freedom, 1 and 3.84).
pub fn rise(level: f64, dof: Option<f64>) -> f64 {
    let within = |x: f64| match dof {
        Some(nu) => 1.0 - incomplete_beta(nu / (nu + x * x), nu / 2.0, 0.5),
        None => 1.0 - upper_gamma(0.5, x * x / 2.0),
    };
    let (mut lo, mut hi) = (0.0, 1e3);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if within(mid) < level {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi)).powi(2)
}

/// The regularized incomplete beta function I_x(a, b) (Numerical Recipes'
/// continued fraction).
fn incomplete_beta(x: f64, a: f64, b: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let front =
        (ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln()).exp();
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_fraction(x, a, b) / a
    } else {
        1.0 - front * beta_fraction(1.0 - x, b, a) / b
    }
}

/// The continued fraction of [`incomplete_beta`] (modified Lentz).
fn beta_fraction(x: f64, a: f64, b: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    d = if d.abs() < TINY { TINY } else { d };
    d = 1.0 / d;
    let mut h = d;
    for m in 1..1000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        for aa in [
            m * (b - m) * x / ((qam + m2) * (a + m2)),
            -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2)),
        ] {
            d = 1.0 + aa * d;
            d = if d.abs() < TINY { TINY } else { d };
            c = 1.0 + aa / c;
            c = if c.abs() < TINY { TINY } else { c };
            d = 1.0 / d;
            h *= d * c;
        }
        if (d * c - 1.0).abs() < 1e-16 {
            break;
        }
    }
    h
}

/// ln Gamma(x) for x > 0 (Lanczos, g = 7, 9 terms: about 1e-15 relative).
fn ln_gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let sum = G[1..]
        .iter()
        .enumerate()
        .fold(G[0], |s, (i, g)| s + g / (x + i as f64 + 1.0));
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + sum.ln()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SciPy's `chi2.sf(chi2, dof)` to 1e-9 relative: the 5 % and 0.1 %
    /// points and a few others.
    #[test]
    fn p_values_are_scipys() {
        let check = |chi2: f64, dof: i64, want: f64| {
            let got = p_value(chi2, dof).unwrap();
            assert!(
                (got - want).abs() <= 1e-9 * want,
                "chi2 {chi2} dof {dof}: {got} against {want}"
            );
        };
        check(3.841_458_820_694_124, 1, 0.05);
        check(18.307_038_053_275_146, 10, 0.05);
        check(29.588_298_445_074_41, 10, 0.001);
        check(10.0, 10, 0.440_493_285_065_212_57);
        check(0.5, 3, 0.918_891_411_654_675_8);
        check(100.0, 30, 1.856_802_336_510_231_4e-9);
        assert_eq!(p_value(0.0, 4), Some(1.0));
        assert_eq!(p_value(1.0, 0), None);
    }

    /// SciPy's `t.ppf((1 + level) / 2, dof) ** 2` and `chi2.ppf(level, 1)`.
    #[test]
    fn rises_are_scipys_quantiles() {
        let check = |level: f64, dof: Option<f64>, want: f64| {
            let got = rise(level, dof);
            assert!(
                (got - want).abs() <= 1e-9 * want,
                "{level} {dof:?}: {got} against {want}"
            );
        };
        check(LEVEL_68, None, 1.0);
        check(0.95, None, 3.841_458_820_694_124);
        check(0.95, Some(24.0), 4.259_677_272_690_229);
        check(LEVEL_68, Some(24.0), 1.042_996_234_277_328);
        check(0.95, Some(3.0), 10.127_964_486_013_923);
    }

    #[test]
    fn ln_gamma_is_the_factorial() {
        for (n, fact) in [(1.0, 1.0), (5.0, 24.0), (11.0, 3_628_800.0)] {
            assert!((ln_gamma(n) - f64::ln(fact)).abs() < 1e-12);
        }
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-12);
    }
}
