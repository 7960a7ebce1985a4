//! The LuGre integrator's exp (for x <= 0), hypot and fourth root, built
//! from + - * / and sqrt so that the shader (`shaders/lugre/model.wgsl`,
//! `rodas.wgsl`) computes the same bits: WGSL's f64 has neither exp nor
//! pow, and a libm's rounding would differ from the shader's in a few
//! arguments in a thousand, enough for the step control to take other
//! steps. They give libm's bits on all but a few arguments (their tests).

/// The degree of [`exp_nonpositive`]'s Taylor polynomial: its truncation
/// error on |r| <= ln 2 / 2 is 4e-18 relative.
pub const EXP_DEGREE: usize = 13;

/// 1 / n! for n = 0..=EXP_DEGREE, each correctly rounded (n! is exact in
/// f64).
pub const EXP_TAYLOR: [f64; EXP_DEGREE + 1] = {
    let mut c = [0.0; EXP_DEGREE + 1];
    let mut factorial = 1u64;
    let mut n = 0;
    while n <= EXP_DEGREE {
        if n > 0 {
            factorial *= n as u64;
        }
        c[n] = 1.0 / factorial as f64;
        n += 1;
    }
    c
};

/// ln 2 in two parts (fdlibm's): the high part's last 21 bits are zero, so
/// k ln2_hi is exact for every k the reduction meets (|k| <= 1075).
pub const EXP_LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
pub const EXP_LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);

/// Below this argument exp rounds to 0 (exp(-745.2) < 2^-1075).
pub const EXP_MIN: f64 = -745.2;

/// 2^-(2^j) for j = 0..10, exact.
pub const EXP_HALVINGS: [f64; 10] = {
    let mut h = [0.0; 10];
    let mut j = 0;
    while j < 10 {
        h[j] = f64::from_bits((1023 - (1u64 << j)) << 52);
        j += 1;
    }
    h
};

/// Veltkamp's splitter for f64: 2^27 + 1.
pub const SPLITTER: f64 = 134_217_729.0;

/// x itself: the shader's `keep` multiplies by a 1 its compiler cannot
/// see, so that it keeps the two-part sums' algebra.
fn keep(x: f64) -> f64 {
    x
}

/// a + b = s + e exactly (Knuth's two-sum), as the shader's `two_sum`.
pub fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = keep(a + b);
    let bb = keep(s - a);
    (s, keep(a - keep(s - bb)) + keep(b - bb))
}

/// x = hi + lo with hi of at most 26 significant bits (Veltkamp), as the
/// shader's `split`.
pub fn split(x: f64) -> (f64, f64) {
    let c = keep(SPLITTER * x);
    let hi = keep(c - keep(c - x));
    (hi, x - hi)
}

/// a b = p + e exactly (Dekker's two-product, without fma: llvmpipe's
/// `fma` rounds the product), as the shader's `two_prod`.
pub fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = keep(a * b);
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    (p, ((keep(ah * bh) - p) + ah * bl + al * bh) + al * bl)
}

/// exp(x) for x <= 0 (NaN stays NaN) from + - * alone, as the shader's
/// `exp_nonpositive` computes it: x = k ln 2 + r with |r| <= ln 2 / 2
/// (Cody and Waite's two-part ln 2, r's rounding kept), exp(r) = (1 + r) +
/// (r^2 / 2 + r^3 P(r)) with 1 + r and r^2 in two parts (Knuth's two-sum,
/// Dekker's two-product) and one final rounding, then 2^k by exact
/// halvings (the small ones first, so that only the last product may leave
/// the normal range). Within one unit in the last place of exp(x) where
/// that is normal, and equal to Rust's (glibc's) exp but in about one
/// argument in a hundred (a double-double sum of every term would do ten
/// times better, but llvmpipe's compiler folds a two-sum fed by another
/// two-sum away).
pub fn exp_nonpositive(x: f64) -> f64 {
    if x.is_nan() {
        return x;
    }
    if x < EXP_MIN {
        return 0.0;
    }
    let k = (x * std::f64::consts::LOG2_E + 0.5).floor();
    let rh = keep(x - k * EXP_LN2_HI);
    let kl = keep(k * EXP_LN2_LO);
    let r = keep(rh - kl);
    let r_lo = keep(rh - r) - kl;
    let mut p = EXP_TAYLOR[EXP_DEGREE];
    for n in (3..EXP_DEGREE).rev() {
        p = p * r + EXP_TAYLOR[n];
    }
    let (r2, r2_lo) = two_prod(r, r);
    let tail = p * r2 * r;
    let (one_r, one_r_lo) = two_sum(1.0, r);
    let small = 0.5 * r2 + ((0.5 * r2_lo + tail) + r_lo * one_r);
    let mut e = one_r + (one_r_lo + small);
    let m = (-k) as u32;
    for (j, half) in EXP_HALVINGS.iter().enumerate() {
        if m & (1 << j) != 0 {
            e *= half;
        }
    }
    if m >= 1024 {
        e *= EXP_HALVINGS[9];
        e *= EXP_HALVINGS[9];
    }
    e
}

/// glibc's hypot (2.35 and later, `sysdeps/ieee754/dbl-64/e_hypot.c`,
/// its kernel without fma), as the shader's `hypot`: equal to Rust's
/// `f64::hypot` on x86-64 glibc, bit for bit.
pub fn hypot(x: f64, y: f64) -> f64 {
    if !x.is_finite() || !y.is_finite() {
        return if x.is_infinite() || y.is_infinite() {
            f64::INFINITY
        } else {
            x + y
        };
    }
    let (x, y) = (x.abs(), y.abs());
    let (ax, ay) = if x < y { (y, x) } else { (x, y) };
    if ax > HYPOT_LARGE {
        if ay <= ax * HYPOT_EPS {
            return ax + ay;
        }
        return hypot_kernel(ax * HYPOT_SCALE, ay * HYPOT_SCALE) * HYPOT_UNSCALE;
    }
    if ay < HYPOT_TINY {
        if ax >= ay * HYPOT_INV_EPS {
            return ax + ay;
        }
        return hypot_kernel(ax * HYPOT_UNSCALE, ay * HYPOT_UNSCALE) * HYPOT_SCALE;
    }
    if ay <= ax * HYPOT_EPS {
        return ax + ay;
    }
    hypot_kernel(ax, ay)
}

/// glibc's hypot kernel for ax >= ay: the square root of the sum of
/// squares, corrected once.
fn hypot_kernel(ax: f64, ay: f64) -> f64 {
    let h = (ax * ax + ay * ay).sqrt();
    let (t1, t2) = if h <= 2.0 * ay {
        let delta = h - ay;
        (ax * (2.0 * delta - ax), (delta - 2.0 * (ax - ay)) * delta)
    } else {
        let delta = h - ax;
        (
            2.0 * delta * (ax - 2.0 * ay),
            (4.0 * delta - ay) * ay + delta * delta,
        )
    };
    h - (t1 + t2) / (2.0 * h)
}

/// glibc hypot's constants: scaling by 2^-600 above 2^511 and by 2^600
/// below 2^-511, and 2^-54, below which the smaller term vanishes.
pub const HYPOT_SCALE: f64 = f64::from_bits((1023 - 600) << 52);
pub const HYPOT_UNSCALE: f64 = f64::from_bits((1023 + 600) << 52);
pub const HYPOT_LARGE: f64 = f64::from_bits((1023 + 511) << 52);
pub const HYPOT_TINY: f64 = f64::from_bits((1023 - 511) << 52);
pub const HYPOT_EPS: f64 = f64::from_bits((1023 - 54) << 52);
pub const HYPOT_INV_EPS: f64 = f64::from_bits((1023 + 54) << 52);

/// x^(1/4) for x >= 0, as the shader's `fourth_root`: sqrt(sqrt(x))
/// with one Newton correction on the exact residual (two-products), so
/// that it is correctly rounded but in rare cases, and equal to Rust's
/// `powf(0.25)` (glibc's pow) but in about one argument in a thousand
/// (sqrt(sqrt(x)) differs in one in eight).
pub fn fourth_root(x: f64) -> f64 {
    let s = x.sqrt().sqrt();
    let (p, e) = two_prod(s, s);
    let (q, f) = two_prod(p, p);
    let rho = (keep(q - x) + f) + 2.0 * p * e;
    let refined = s - rho / (4.0 * s * s * s);
    if refined.is_finite() { refined } else { s }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Within one unit in the last place of Rust's exp (1e-15 relative)
    /// over the normal range, equal to it in all but a few arguments in a
    /// thousand, and within one subnormal unit below it; exact at 0.
    #[test]
    fn exp_nonpositive_is_exp() {
        assert_eq!(exp_nonpositive(0.0), 1.0);
        assert_eq!(exp_nonpositive(-0.0), 1.0);
        assert_eq!(exp_nonpositive(f64::NEG_INFINITY), 0.0);
        assert!(exp_nonpositive(f64::NAN).is_nan());
        assert_eq!(exp_nonpositive(-746.0), 0.0);
        let (mut worst, mut ulps, mut differ) = (0.0_f64, 0_u64, 0_u32);
        let mut x = 0.0_f64;
        let mut k = 0u32;
        // Dense near 0 (where the model lives), then out to the end.
        while x > -746.0 {
            let (got, want) = (exp_nonpositive(x), x.exp());
            if want >= f64::MIN_POSITIVE {
                worst = worst.max(((got - want) / want).abs());
                ulps = ulps.max(got.to_bits().abs_diff(want.to_bits()));
                differ += u32::from(got != want);
            } else {
                assert!((got - want).abs() <= 5e-324, "{x}: {got:e} {want:e}");
            }
            k += 1;
            // Steps that are no round numbers, finer near 0.
            x -= 1.234567e-4 * (1.0 + x.abs()) * (1.0 + (k % 7) as f64 / 7.0);
        }
        assert!(k > 10_000, "{k} points");
        assert!(
            worst <= 1e-15 && ulps <= 1,
            "{worst:e} relative, {ulps} ulps"
        );
        assert!(differ * 50 <= k, "{differ} of {k} differ from Rust's exp");
    }

    /// Pseudo-random numbers in [0, 1).
    fn uniform(seed: &mut u64) -> f64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    /// glibc's hypot, bit for bit (where Rust's hypot is glibc's: x86-64
    /// Linux), over magnitudes from 1e-300 to 1e300.
    #[test]
    fn hypot_is_glibc_s() {
        assert_eq!(hypot(3.0, 4.0), 5.0);
        assert_eq!(hypot(-2.5, 0.0), 2.5);
        assert_eq!(hypot(0.0, 0.0), 0.0);
        assert_eq!(hypot(f64::INFINITY, f64::NAN), f64::INFINITY);
        let mut seed = 7;
        let mut differ = 0;
        for k in 0..200_000 {
            let e = (uniform(&mut seed) * 1380.0 - 690.0) * if k % 2 == 0 { 1.0 } else { 0.02 };
            let a = (uniform(&mut seed) - 0.5) * e.exp();
            let b = (uniform(&mut seed) - 0.5) * (e + (uniform(&mut seed) - 0.5) * 80.0).exp();
            let (got, want) = (hypot(a, b), a.hypot(b));
            assert!(got.to_bits().abs_diff(want.to_bits()) <= 1, "{a:e} {b:e}");
            differ += u32::from(got != want);
        }
        if cfg!(all(
            target_os = "linux",
            target_env = "gnu",
            target_arch = "x86_64"
        )) {
            assert_eq!(differ, 0, "differ from glibc's hypot");
        }
    }

    /// Within one unit in the last place of powf(0.25), equal to it in all
    /// but about one argument in a thousand.
    #[test]
    fn fourth_root_is_powf_quarter() {
        assert_eq!(fourth_root(16.0), 2.0);
        assert_eq!(fourth_root(0.0), 0.0);
        let mut seed = 11;
        let (mut differ, n) = (0, 100_000);
        for _ in 0..n {
            let x = (uniform(&mut seed) * 80.0 - 40.0).exp();
            let (got, want) = (fourth_root(x), x.powf(0.25));
            assert!(got.to_bits().abs_diff(want.to_bits()) <= 1, "{x:e}");
            differ += u32::from(got != want);
        }
        assert!(differ * 200 <= n, "{differ} of {n} differ from powf(0.25)");
    }

    /// The constants: 1/n! and the halvings.
    #[test]
    fn exp_constants_are_exact() {
        assert_eq!(EXP_TAYLOR[0], 1.0);
        assert_eq!(EXP_TAYLOR[3], 1.0 / 6.0);
        for (j, h) in EXP_HALVINGS.iter().enumerate() {
            assert_eq!(*h, 2f64.powi(-(1 << j)));
        }
        assert_eq!(EXP_LN2_HI + EXP_LN2_LO, std::f64::consts::LN_2);
        assert_eq!(EXP_LN2_HI.to_bits() & 0x1f_ffff, 0);
    }
}
