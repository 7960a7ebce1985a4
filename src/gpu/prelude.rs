//! The floor's prelude: what every law's shader starts from, generated from
//! the Rust constants (one home per rule): the scalar type `Real` and
//! `V2`, the status codes (`crate::laws::status`), the kinds a lane counts
//! (`crate::laws::floor::kinds`), the steady measurement's and the phase
//! ladder's constants, and the arithmetic helpers (`div`, `root` and their
//! kin, which on NVIDIA replace f64 division and square root). A law's
//! prelude adds its own constants after it (`gpu::karnopp::shader`,
//! `gpu::lugre::shader`).

use crate::laws::Precision;
use crate::laws::floor::{kinds, measure, phase};

/// The naga capabilities the shader needs in one precision.
pub fn capabilities(precision: Precision) -> naga::valid::Capabilities {
    match precision {
        Precision::F32 => naga::valid::Capabilities::empty(),
        Precision::F64 => naga::valid::Capabilities::FLOAT64,
    }
}

/// The floor's prelude in `precision`, with the phase ladder on where
/// `phase` (the `PHASE` switch of `shaders/shared/measure.wgsl`).
pub fn floor(precision: Precision, phase: bool) -> String {
    let (real, eps, max, helpers) = match precision {
        Precision::F32 => ("f32", f32::EPSILON as f64, f32::MAX as f64, F32_HELPERS),
        Precision::F64 => ("f64", f64::EPSILON, f64::MAX, F64_HELPERS),
    };
    format!(
        "alias Real = {real};\n\
         const EPSILON: Real = {eps:e};\n\
         const INFINITY: Real = {max:e};\n\
         alias V2 = vec2<Real>;\n\
         const PHASE: bool = {phase};\n\
         {constants}\n{helpers}\n{COMMON_HELPERS}\n",
        constants = crate::laws::status::wgsl_constants()
            + &kinds::wgsl_constants()
            + &measure::wgsl_constants()
            + &phase::wgsl_constants(),
    )
}

/// The f64 arithmetic helpers. NVIDIA's Vulkan compiler (driver 580) fails
/// ("NVVM compilation failed: 3") on the integrator when it contains f64
/// division or square root, so f64 builds both from `inverseSqrt` (which it
/// compiles) and fused multiply-adds: Newton's iteration to full precision,
/// then one correction, which gives the correctly rounded result in all but
/// rare halfway cases (so the shader computes what the CPU computes). The
/// guess squares its argument, so the helpers hold for 1e-154 < |b| <
/// 1e154; the integrator's non-zero divisors, in SI units, are expected
/// to stay inside it.
/// Outside it they differ from the CPU: `recip(0)` is the largest finite
/// value, not infinity.
pub const F64_HELPERS: &str = "\
// 1 / b: a first guess from inverseSqrt(b^2), three Newton steps (each
// doubles the correct digits of the driver's guess), then a correction.
fn recip(b: Real) -> Real {
    emulated += 1u;
    if b == Real(0.0) {
        return INFINITY;
    }
    var y = inverseSqrt(b * b);
    y = select(y, -y, b < Real(0.0));
    y = fma(y, fma(-b, y, Real(1.0)), y);
    y = fma(y, fma(-b, y, Real(1.0)), y);
    y = fma(y, fma(-b, y, Real(1.0)), y);
    return fma(y, fma(-b, y, Real(1.0)), y);
}

// a / b, rounded as the CPU rounds it (but for rare halfway cases).
fn div(a: Real, b: Real) -> Real {
    if b == Real(0.0) {
        return a * recip(b);
    }
    let y = recip(b);
    let q = a * y;
    return fma(fma(-b, q, a), y, q);
}

// sqrt(x) for 0 < x < INFINITY, rounded as the CPU rounds it, and the
// inverse square root it came from: inverseSqrt, three Newton steps, one
// correction.
struct RootParts {
    s: Real,
    y: Real,
}

fn root_parts(x: Real) -> RootParts {
    var y = inverseSqrt(x);
    let half = Real(0.5) * x;
    y = y * fma(-half * y, y, Real(1.5));
    y = y * fma(-half * y, y, Real(1.5));
    y = y * fma(-half * y, y, Real(1.5));
    let s = x * y;
    return RootParts(fma(fma(-s, s, x), Real(0.5) * y, s), y);
}

// sqrt(x) for x >= 0 (and x itself for 0 and NaN).
fn root(x: Real) -> Real {
    emulated += 1u;
    if !(x > Real(0.0)) || x > INFINITY {
        return x;
    }
    return root_parts(x).s;
}

// 1 / sqrt(x) rounded as the CPU's 1.0 / x.sqrt() (the reciprocal of the
// rounded root): the root, then its reciprocal from the root's own
// inverse square root, already within an ulp of it, in one Newton step
// and recip's correction (not recip's whole sequence). x as root takes it.
fn recip_root(x: Real) -> Real {
    if !(x > Real(0.0)) || x > INFINITY {
        return recip(root(x));
    }
    emulated += 1u;
    let r = root_parts(x);
    let y = fma(r.y, fma(-r.s, r.y, Real(1.0)), r.y);
    return fma(y, fma(-r.s, y, Real(1.0)), y);
}
";

/// The f32 helpers: the hardware's own division and square root.
pub const F32_HELPERS: &str = "\
fn recip(b: Real) -> Real {
    return Real(1.0) / b;
}

fn div(a: Real, b: Real) -> Real {
    return a / b;
}

fn root(x: Real) -> Real {
    return sqrt(x);
}

fn recip_root(x: Real) -> Real {
    return Real(1.0) / sqrt(x);
}
";

/// Helpers common to both precisions, and the count of emulated f64
/// operations (`recip`, `root` and `recip_root` calls, a division counted
/// as its `recip`) the lane's tally reports: f32 counts none.
pub const COMMON_HELPERS: &str = "\
var<private> emulated: u32;

fn div2(a: V2, b: V2) -> V2 {
    return V2(div(a.x, b.x), div(a.y, b.y));
}
";

/// `src` with every use of the private variable `copy` (`copy.` after no
/// name character, dot or slash) written `held.`: a hardware lane's
/// value read where it is used, from the device memory `held` names,
/// not kept in registers. The WGSL text stays one, the llvmpipe
/// variant's, whose holder file declares `copy`; a comment's
/// `docs/model.md` is left alone.
pub fn read_where_used(src: &str, copy: &str, held: &str) -> String {
    let copy = format!("{copy}.");
    let held = format!("{held}.");
    let mut out = String::with_capacity(src.len() + src.len() / 8);
    let mut rest = src;
    while let Some(at) = rest.find(&copy) {
        let before = rest[..at].chars().next_back();
        let is_name = !before.is_some_and(|c| c.is_alphanumeric() || "_/.".contains(c));
        out += &rest[..at];
        out += if is_name { &held } else { &copy };
        rest = &rest[at + copy.len()..];
    }
    out + rest
}
