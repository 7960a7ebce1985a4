//! The phase-resolved estimate of the steady step for two drive
//! frequencies (docs/model.md section 4): the CPU mirror of
//! `shaders/shared/phase.wgsl` (same functions, same order of
//! operations); its constants reach the shader through the prelude and its
//! per-instance tables through the law's `Gauge` (`super::measure::Gauge`).
//!
//! **The idea.** With two frequencies the slider's travel over scene period
//! k is, once the motion has settled (measured: within one or two periods
//! for Table 1 and the text's set), a function of the faster drive's phase
//! at the start of that period, theta_k = frac(theta_0 + k rho), rho =
//! frac(f_hi / f_lo): d_k = g(theta_k). The steady step is the mean of g
//! over the circle (Weyl's equidistribution; for a rational rho = p / q the
//! motion repeats after q periods and the mean over those q phases is
//! exact). A running mean of d_k converges like 1/N because g has steep
//! parts (a jump of 60 um within 0.02 cycles on Table 1) and ringing
//! (wavelength about f_hi / f_r in cycles, f_r the stage resonance). The
//! trapezoid rule over the theta-sorted increments converges far faster:
//! measured on 10 incommensurate instances it is 10-100 times more accurate
//! than the running mean of the same periods at 500-1000 periods.
//!
//! **Fixed size.** The points k rho (k < L) of a window of L consecutive
//! periods have at most three distinct gaps (the three-gap theorem; Sós
//! 1958, Świerczkowski 1959): with a the index of the point nearest above 0
//! (gap alpha = frac(a rho)) and b that nearest below 1 (beta = 1 -
//! frac(b rho)), point k's right neighbour is k + a (gap alpha) if k < L -
//! a, else k - b (gap beta) if k >= b, else at gap alpha + beta; its left
//! neighbour likewise. So the trapezoid weight of period k, half the gaps
//! on either side, is constant between the cut indices {a, b, L - a, L -
//! b}, and the trapezoid sum over the window, sum_k w_k (X_{k+1} - X_k)
//! with X the slider position, is a combination of the slider positions
//! at six periods: [`window_coefficient`]. The weights depend on L and rho
//! only (a rotation of every phase changes no gap), so the host computes
//! (a, b, alpha, beta) once per window length ([`Gaps`], in
//! `Gauge::gaps`) and the run adds each position to the windows
//! that need it as the period passes: no per-period arrays.
//!
//! **The ladder.** Windows start where the measurement starts (`settle`).
//! Their lengths L_j grow by sqrt 2 ([`ladder_length`]: 60, 85, 120, ...,
//! 21,760 periods), so a window's first half and first quarter are windows
//! of the ladder too. At the end of window j the estimate is W_j, the
//! trapezoid over [0, L_j), and its error is judged by three comparisons,
//! each a different way a trapezoid fails:
//!
//! * W_j against W_{j-2}, the first half: Richardson's check. The
//!   trapezoid's error falls at least like 1 / L once g is resolved, so
//!   |W_j - W_{j-2}| is at least the error of W_j;
//! * the second half V_j against the first: both halves at the same
//!   resolution but different phases, so an error that depends on where
//!   the points fall shows as their difference (taken / 2);
//! * the four quarters: their sample standard deviation (taken / 2, the
//!   standard error of their mean; / 3 for quarters of at least
//!   [`QUARTER_TRUSTED`] periods) shows errors that agree between halves
//!   by chance.
//!
//! The standard error is the largest of the three, per axis
//! ([`evaluate`]). The quarters guard against a window too coarse for
//! the motion's features; a window of a rational ratio (a common period q)
//! whose largest gap is at most 2 / q has every phase it misses between
//! two it has, so it resolves the motion as finely as the whole period
//! would up to a factor 2, and its quarters (which do not) are left out
//! (`Gauge::phase_lattice`). Measured against 20,000-40,000-period references on 46
//! two-frequency instances (Table 1 and the text's set, incommensurate,
//! near resonances, two-decimal frequencies, voltages from -100 to 100 V,
//! duties 0.8-0.98) at 36-41 starting periods each: of 999 stops at the
//! default tolerance, 997 were within 3 standard errors + 0.002 um of the
//! reference; the other two (a text-set instance near a resonance) were
//! 0.0057 um off with a standard error of 0.001 um.
//!
//! **When a window may stop the run.** A trapezoid that misses a feature
//! narrower than its spacing agrees with itself at every coarser level:
//! measured, such plateaus (errors of 0.01-0.02 um with all three
//! comparisons below 0.005 um) lasted up to windows of 512 periods. So no
//! window shorter than [`MIN_WINDOW`] stops a run. Near a resonance (rho
//! close to a fraction p/q of small q) the points of a window bunch into q
//! clusters and the window resolves only about q phases, however long;
//! its quarters must resolve [`MIN_SITES`] / 4 phases each (1 / their
//! largest gap), or the window does not stop the run either. Nor does a
//! window whose phases bunch: where the clusters of a near resonance drift
//! too little within the window to fill its gaps, the quarters fall on the
//! same clusters as the window and agree whatever lies between them, so a
//! window's largest gap may be at most [`MAX_BUNCHING`] / its length,
//! unless the beat lies beyond the run ([`BUNCHED_HORIZON`]). The host
//! folds the rules into [`Gauge::phase_levels`], a bit per level.
//! Where rho = p / q is rational (a common period q), only windows of at
//! most q periods are used (longer ones repeat phases); the recurrence test
//! (`measure::recurrence`) finds such a motion exact at q.
//!
//! **Where it is weak.** Near a resonance the first window that resolves
//! enough phases is about the next continued-fraction denominator of rho
//! (the beat period), which can exceed `max_cycles`; the instance then
//! falls back to batch means (motion "irregular") or ends not steady.
//! Features narrower than a 680-period window's spacing that no level
//! resolves before the stop go unseen (the plateau above); the minimum
//! window is an empirical guard, not a proof.

use super::Real;
// The ladder's per-instance tables are the gauge's (a law holds them).
use super::gauge::Gauge;
pub use super::gauge::{Gaps, LEVELS};
use super::precision::only_f64;
use super::vec2::Vec2;

/// The shortest windows of the two interleaved doubling ladders [scene
/// periods]: even levels are 60 2^(j/2), odd ones 85 2^((j-1)/2) (85/60
/// is about sqrt 2), so that windows end often enough for a run to stop
/// soon after its error is small.
pub const LADDER_EVEN: u32 = 60;
pub const LADDER_ODD: u32 = 85;
/// The shortest window that may stop a run [scene periods] (see the
/// module docs: plateaus of a trapezoid that misses a narrow feature
/// lasted up to 512-period windows).
pub const MIN_WINDOW: u32 = 680;
/// The phases a stopping window must resolve: four times the phases each
/// of its quarters resolves (1 / its largest gap) must be at least this.
pub const MIN_SITES: f64 = 340.0;
/// The most a stopping window's phases may bunch: its largest gap times
/// its length [cycles] at most this. Near a resonance p / q the phases of
/// every window shorter than the beat fall into q clusters, and the
/// quarters then resolve the same q phases as the window: their agreement
/// tests nothing, and a feature between the clusters goes unseen.
/// Measured: 14.666 / 19.142 Hz (rho 0.3052, 1.4e-4 cycles a period from
/// 47 / 154) stopped at 682 periods 0.026 um off with a standard error of
/// 0.0011 um; its windows bunch 4.2 to 12.6 times up to 5,440 periods.
/// A badly approximable ratio's bunch at most about 2.6 (three-gap
/// theorem).
pub const MAX_BUNCHING: f64 = 4.0;
/// A bunched window may still stop a run whose horizon (the periods it may
/// measure) resolves at most this many times the window's phases: the
/// beat lies beyond the run, every window within reach samples the same
/// clusters, and the measurement is of the motion the run can see. The
/// text's stage at 11 Hz against 11 pi / 2 Hz (226 clusters of 355 / 226,
/// a beat of about 33,000 periods; horizon 20,000: 2.6 times) stops at
/// 962 periods within 0.0002 um of its 20,000-period mean; 14.666 /
/// 19.142 Hz (horizon 10,000, beyond its beat: 45 times) does not.
pub const BUNCHED_HORIZON: f64 = 3.0;
/// The lowest level whose end is judged: its quarters are level j - 4.
pub const FIRST_JUDGED: u32 = 4;
/// Rounding allowed when a gap is compared with 2 / q [lattice gaps].
pub const LATTICE_SLACK: f64 = 1e-6;
/// Quarters of at least this many periods count their spread as an error
/// scale of a trapezoid that converges like 1 / L or faster: the window,
/// four times as long, is taken to be at least a third as far off as the
/// quarters scatter (s_Q / 3). Shorter quarters are still in the
/// pre-asymptotic regime and count as a sample of four (s_Q / 2). Measured
/// on the 46 instances of the module docs: s_Q / 3 from 240 on added no
/// miss; s_Q / 4 did.
pub const QUARTER_TRUSTED: u32 = 240;

/// Window length of ladder level `j` [scene periods].
pub fn ladder_length(j: u32) -> u32 {
    let base = if j.is_multiple_of(2) {
        LADDER_EVEN
    } else {
        LADDER_ODD
    };
    base << (j / 2)
}

/// The accumulators of the window ladder. Each window's entry adds up the
/// slider positions at its cut periods times their coefficients; once the
/// window has ended it holds the trapezoid estimate of the mean travel per
/// scene period [m] over the window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phase {
    /// W_j: the window [0, L_j).
    pub whole: [Vec2; LEVELS],
    /// V_j: its second half [L_{j-2}, L_j) (j >= 2).
    pub second: [Vec2; LEVELS],
    /// Its third and fourth quarters [2 L_{j-4}, 3 L_{j-4}) and [3
    /// L_{j-4}, L_j) (j >= 4): a ring of two levels, `2 (j % 2)` and the
    /// next, since a level's quarters are in progress only while its
    /// second half is.
    pub quarters: [Vec2; 4],
    /// A replica's sums of the last level it reached ([`LevelSums`]),
    /// for its group's merge; unused by a run of its own.
    pub pending: LevelSums,
}

impl Phase {
    pub const ZERO: Phase = Phase {
        whole: [Vec2::ZERO; LEVELS],
        second: [Vec2::ZERO; LEVELS],
        quarters: [Vec2::ZERO; 4],
        pending: LevelSums::ZERO,
    };
}

pub use crate::laws::settings::Replica;

/// What judging ladder level j reads ([`evaluate_sums`]): W_j, W_{j-2}
/// (its first half), V_j (its second half) and the sums of its four
/// quarters. A replica keeps them at the level's end for its group's
/// merge, which adds the replicas' sums and judges those.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelSums {
    pub whole: Vec2,
    pub half: Vec2,
    pub second: Vec2,
    pub quarters: [Vec2; 4],
}

impl LevelSums {
    pub const ZERO: LevelSums = LevelSums {
        whole: Vec2::ZERO,
        half: Vec2::ZERO,
        second: Vec2::ZERO,
        quarters: [Vec2::ZERO; 4],
    };
}

/// The trapezoid weight of phase `k` (0 <= k < `length`) of a window:
/// half the gaps to its two neighbours [cycles].
pub fn window_weight(g: &Gaps, length: u32, k: u32) -> Real {
    let right = if k + g.a < length {
        g.alpha
    } else if k >= g.b {
        g.beta
    } else {
        g.alpha + g.beta
    };
    let left = if k >= g.a {
        g.alpha
    } else if k + g.b < length {
        g.beta
    } else {
        g.alpha + g.beta
    };
    0.5 * (left + right)
}

/// The coefficient of the slider position at virtual period `at` of a
/// window (its index from the window's start, `at < length + count`) in
/// the window's trapezoid sum, for a run of its own (`count` 1: the
/// window's own periods) or a replica of `count` ([`Replica`]: its period
/// k is the virtual run's `count k + index`, and each of its positions
/// closes the virtual periods since its previous one): w_{at - count} -
/// w_at (w is 0 outside the window), non-zero only where one of the cuts
/// 0, a, b, L - a, L - b and L lies in (at - count, at]. For a run of its
/// own, the cut must be `at` itself.
pub fn window_coefficient(g: &Gaps, length: u32, at: u32, count: u32) -> Real {
    // c in (at - count, at], without going below zero.
    let cut = |c: u32| at < c + count && c <= at;
    if !(cut(0)
        || cut(length)
        || cut(g.a)
        || cut(g.b)
        || (g.a <= length && cut(length - g.a))
        || (g.b <= length && cut(length - g.b)))
    {
        return 0.0;
    }
    let mut before = 0.0;
    if at >= count {
        before = window_weight(g, length, at - count);
    }
    let mut here = 0.0;
    if at < length {
        here = window_weight(g, length, at);
    }
    before - here
}

/// The window [`start`, `start + length`) of the virtual run (a run's own
/// periods where it is of its own), its sum with the slider position `x`
/// at the run's period `k` added where that position is in the window's
/// sum (from the window's first period to the one that closes it).
fn add_to_window(
    sum: Vec2,
    g: &Gaps,
    start: u32,
    length: u32,
    k: u32,
    r: Replica,
    x: Vec2,
) -> Vec2 {
    let v = r.count * k + r.index;
    if v < start || v >= start + length + r.count {
        return sum;
    }
    let coefficient = window_coefficient(g, length, v - start, r.count);
    if coefficient != 0.0 {
        return sum + x * coefficient;
    }
    sum
}

/// Whether the run's period `k` is the first at or after virtual period
/// `at`: where a window starting there takes its first position, and one
/// ending there its last.
fn first_at(k: u32, r: Replica, at: u32) -> bool {
    let v = r.count * k + r.index;
    v >= at && v < at + r.count
}

/// What a judged window found: the estimate of the mean travel per scene
/// period [m] and its squared standard error per axis [m^2].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseEstimate {
    pub value: Vec2,
    pub se2: Vec2,
    /// The window's length [scene periods; of the virtual run for a
    /// replica]; 0 when no window was judged.
    pub span: u32,
    /// The window's ladder level.
    pub level: u32,
}

/// Adds the slider position `x` at period `k` of the measurement (k = 0 at
/// its start) to every window that has a cut there, and judges the window
/// that ends there, if any may stop the run ([`Gauge::phase_levels`]).
/// Windows are processed level by level, and a level ending at `k` is
/// judged before a longer level starts its quarters there. A replica
/// ([`Replica`]) adds its positions to the virtual run's windows, and does
/// not judge them: where a level ends it keeps the level's sums in
/// `p.pending` for its group's merge and returns the level with a zero
/// estimate.
pub fn phase_period_end(c: &impl Gauge, p: &mut Phase, k: u32, x: Vec2) -> PhaseEstimate {
    // The virtual run's step is the host's concern (its tables).
    let r = Replica {
        index: c.replica(),
        count: c.replicas(),
        turns: 0,
        cycle: 0,
    };
    let mut judged = PhaseEstimate::default();
    for j in 0..LEVELS as u32 {
        let length = ladder_length(j);
        let level = j as usize;
        p.whole[level] = add_to_window(p.whole[level], &c.gaps()[level], 0, length, k, r, x);
        if j >= 2 {
            let half = ladder_length(j - 2);
            p.second[level] =
                add_to_window(p.second[level], &c.gaps()[level - 2], half, half, k, r, x);
        }
        if j >= FIRST_JUDGED {
            let quarter = ladder_length(j - 4);
            let ring = 2 * (j % 2) as usize;
            if first_at(k, r, 2 * quarter) {
                p.quarters[ring] = Vec2::ZERO;
                p.quarters[ring + 1] = Vec2::ZERO;
            }
            p.quarters[ring] = add_to_window(
                p.quarters[ring],
                &c.gaps()[level - 4],
                2 * quarter,
                quarter,
                k,
                r,
                x,
            );
            p.quarters[ring + 1] = add_to_window(
                p.quarters[ring + 1],
                &c.gaps()[level - 4],
                3 * quarter,
                quarter,
                k,
                r,
                x,
            );
            if first_at(k, r, length) && (c.phase_levels() >> j) & 1 == 1 {
                if r.count > 1 {
                    p.pending = level_sums(p, j);
                    judged = PhaseEstimate {
                        value: Vec2::ZERO,
                        se2: Vec2::ZERO,
                        span: length,
                        level: j,
                    };
                } else {
                    judged = evaluate(p, j, (c.phase_lattice() >> j) & 1 == 1);
                }
            }
        }
    }
    judged
}

/// The sums judging level `j` (>= 4) reads, at its end ([`LevelSums`]).
pub fn level_sums(p: &Phase, j: u32) -> LevelSums {
    let level = j as usize;
    let ring = 2 * (j % 2) as usize;
    LevelSums {
        whole: p.whole[level],
        half: p.whole[level - 2],
        second: p.second[level],
        quarters: [
            p.whole[level - 4],
            p.second[level - 2],
            p.quarters[ring],
            p.quarters[ring + 1],
        ],
    }
}

/// The estimate of level `j` (>= 4) of a run of its own at its end
/// ([`evaluate_sums`]).
pub fn evaluate(p: &Phase, j: u32, lattice: bool) -> PhaseEstimate {
    evaluate_sums(&level_sums(p, j), j, lattice)
}

/// The estimate of level `j` (>= 4) from its sums (a run's own, or the
/// virtual run's: a group's replicas' added up): W_j, with the squared
/// standard error max(|W_j - W_{j-2}|, |V_j - W_{j-2}| / 2, s_Q / 2 or s_Q
/// / 3 ([`QUARTER_TRUSTED`]))^2 per axis, s_Q the sample standard
/// deviation of its four quarters (module docs), left out where the window
/// is a near-complete `lattice`. No root and no division: squares are
/// compared.
pub fn evaluate_sums(s: &LevelSums, j: u32, lattice: bool) -> PhaseEstimate {
    let w = s.whole;
    let half = s.half;
    let richardson = (w - half) * (w - half);
    let halves = (s.second - half) * (s.second - half) * 0.25;
    let q = s.quarters;
    let mean = (q[0] + q[1] + q[2] + q[3]) * 0.25;
    let mut squares = Vec2::ZERO;
    for v in q {
        squares = squares + (v - mean) * (v - mean);
    }
    // The sample variance (3 degrees of freedom) over 4, the squared
    // standard error of the quarters' mean; over 9 for trusted quarters.
    let mut quarters = squares * (1.0 / 12.0);
    if ladder_length(j - 4) >= QUARTER_TRUSTED {
        quarters = squares * (1.0 / 27.0);
    }
    if lattice {
        quarters = Vec2::ZERO;
    }
    let se2 = richardson.zip(halves, Real::max).zip(quarters, Real::max);
    PhaseEstimate {
        value: w,
        se2,
        span: ladder_length(j),
        level: j,
    }
}

only_f64! {
/// The gaps of the phases k rho, 0 <= k < `length`, for 0 < rho < 1
/// (irrational, or rational with a denominator of at least `length`, so
/// that no two phases coincide). The nearest phases to 0 from above and to
/// 1 from below are records of k rho as k grows; each new record is the
/// sum of the two current ones (the three-gap recursion), taken many at a
/// time as in Euclid's algorithm, so this costs O(log length) steps.
pub fn gaps(rho: f64, length: u32) -> Gaps {
    let phase = |k: u64| (k as f64 * rho).fract();
    let (mut a, mut b) = (1u64, 1u64);
    let length = length.max(2) as u64;
    loop {
        let alpha = phase(a);
        let beta = 1.0 - phase(b);
        if a + b >= length || alpha <= 0.0 || beta <= 0.0 {
            break;
        }
        if alpha > beta {
            // a + m b lies at alpha - m beta: a new lowest phase for every
            // m with alpha - m beta > 0.
            let by_gap = ((alpha / beta).ceil() as u64).saturating_sub(1).max(1);
            let by_length = (length - 1 - a) / b;
            a += b * by_gap.min(by_length).max(1);
        } else {
            let by_gap = ((beta / alpha).ceil() as u64).saturating_sub(1).max(1);
            let by_length = (length - 1 - b) / a;
            b += a * by_gap.min(by_length).max(1);
        }
    }
    Gaps {
        a: a as u32,
        b: b as u32,
        alpha: phase(a),
        beta: 1.0 - phase(b),
    }
}

/// The largest gap between the phases of a window of `length` periods
/// [cycles]: alpha + beta where some phase has that gap, else the larger.
pub fn largest_gap(g: &Gaps, length: u32) -> f64 {
    if (length as u64) < (g.a as u64 + g.b as u64) {
        g.alpha + g.beta
    } else {
        g.alpha.max(g.beta)
    }
}

/// How unevenly the phases of the ladder's windows that may stop a run
/// (from [`MIN_WINDOW`] on) lie for a faster drive that advances by `rho`
/// cycles a period: the largest of their largest gaps times their lengths
/// (1 for evenly spaced phases; about 2 for a run of its own at a badly
/// approximable ratio). A trapezoid over unevenly spaced phases resolves
/// fewer features than its periods, and its error estimates miss it
/// (`pidm::replicas`).
pub fn spread(rho: f64) -> f64 {
    (0..LEVELS as u32)
        .map(ladder_length)
        .filter(|&length| length >= MIN_WINDOW)
        .map(|length| largest_gap(&gaps(rho, length), length) * length as f64)
        .fold(0.0, f64::max)
}

/// The ladder of an instance whose faster drive advances by `rho` cycles
/// per scene period (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ladder {
    /// Each window length's three-gap table.
    pub gaps: [Gaps; LEVELS],
    /// The levels that may stop the run, a bit each: none where the ladder
    /// is off (one axis undriven, or a common period of at most
    /// [`MIN_WINDOW`] periods, which the recurrence test settles), and only
    /// levels of at most `common_period` periods where there is one.
    pub levels: u32,
    /// The levels whose window is a near-complete lattice of the common
    /// period (largest gap at most 2 / q): judged without their quarters.
    pub lattice: u32,
    /// The levels that would be in `levels` but for bunching
    /// ([`MAX_BUNCHING`]): where some are and `levels` has none, a group
    /// of replicas may still interleave between the clusters.
    pub resolving: u32,
}

/// Whether a steady run has a phase ladder: both axes driven, the faster
/// drive advancing by a fraction `rho` > 0 of a cycle a period, and no
/// common period of at most [`MIN_WINDOW`] periods (0: none; the
/// recurrence test settles those). Its levels may still all be barred
/// ([`MAX_BUNCHING`]), where a group's virtual run may have some.
pub fn ladder_on(driven: [bool; 2], rho: f64, common_period: u32) -> bool {
    driven[0] && driven[1] && rho > 0.0 && (common_period == 0 || common_period > MIN_WINDOW)
}

/// The ladder's tables and levels ([`Ladder`]) of a run whose faster
/// drive advances by `rho` cycles a period, with a common period of
/// `common_period` periods (0: none) and at most `horizon` periods
/// measured: a run of its own, or the virtual run of a group of replicas
/// ([`Replica::virtual_step`]), whose windows are a run's, each replica
/// taking about a `count`th of their periods.
pub fn ladder(rho: f64, on: bool, common_period: u32, horizon: u32) -> Ladder {
    let mut tables = [Gaps::default(); LEVELS];
    if !on {
        return Ladder {
            gaps: tables,
            levels: 0,
            lattice: 0,
            resolving: 0,
        };
    }
    for (j, g) in tables.iter_mut().enumerate() {
        *g = gaps(rho, ladder_length(j as u32));
    }
    let mut levels = 0u32;
    let mut lattice = 0u32;
    let mut resolving = 0u32;
    let reach = match common_period {
        0 => horizon,
        q => horizon.min(q),
    };
    let gap_in_reach = largest_gap(&gaps(rho, reach), reach);
    for j in FIRST_JUDGED..LEVELS as u32 {
        let length = ladder_length(j);
        let quarter = ladder_length(j - 4);
        let sites = 4.0 / largest_gap(&tables[(j - 4) as usize], quarter);
        let fits = common_period == 0 || length <= common_period;
        let gap = largest_gap(&tables[j as usize], length);
        let bunched = gap * length as f64 > MAX_BUNCHING && gap > BUNCHED_HORIZON * gap_in_reach;
        let resolves = length >= MIN_WINDOW && sites >= MIN_SITES && fits;
        if resolves {
            resolving |= 1 << j;
        }
        if resolves && !bunched {
            levels |= 1 << j;
            if common_period > 0 && gap * common_period as f64 <= 2.0 + LATTICE_SLACK {
                lattice |= 1 << j;
            }
        }
    }
    Ladder {
        gaps: tables,
        levels,
        lattice,
        resolving,
    }
}
}

/// The constants above that the shader reads, as WGSL declarations for its
/// prelude.
pub fn wgsl_constants() -> String {
    let u = |name: &str, v: u32| format!("const {name}: u32 = {v}u;\n");
    [
        u("LEVELS", LEVELS as u32),
        u("LADDER_EVEN", LADDER_EVEN),
        u("LADDER_ODD", LADDER_ODD),
        u("FIRST_JUDGED", FIRST_JUDGED),
        u("QUARTER_TRUSTED", QUARTER_TRUSTED),
    ]
    .concat()
}

only_f64! {
#[cfg(test)]
mod tests {
    use super::*;

    /// The trapezoid weights of phases k rho, k < length, from sorting the
    /// phases (the definition) [cycles].
    fn sorted_weights(rho: f64, length: u32) -> Vec<f64> {
        let phases: Vec<f64> = (0..length).map(|k| (k as f64 * rho).fract()).collect();
        let mut order: Vec<usize> = (0..length as usize).collect();
        order.sort_by(|&i, &j| phases[i].total_cmp(&phases[j]));
        let n = order.len();
        let mut w = vec![0.0; n];
        for (r, &k) in order.iter().enumerate() {
            let next = if r + 1 < n { phases[order[r + 1]] } else { phases[order[0]] + 1.0 };
            let previous = if r > 0 { phases[order[r - 1]] } else { phases[order[n - 1]] - 1.0 };
            w[k] = 0.5 * (next - previous);
        }
        w
    }

    /// The three-gap weights equal the sorted trapezoid's for irrational
    /// ratios, near resonances and ladder lengths alike; and the window's
    /// sum of coefficients times positions is the weighted sum of
    /// increments.
    #[test]
    fn window_weights_are_the_sorted_trapezoid() {
        let rhos = [
            2f64.sqrt() - 1.0,
            0.108_716_026_241_799_4,
            (5f64.sqrt() - 1.0) / 2.0,
            0.000_3,
            0.501,
            0.570_796_326_794_896_6,
            0.999_7,
        ];
        for rho in rhos {
            for length in [2, 3, 7, 60, 85, 240, 680, 985, 1000, 1360, 4096] {
                // 0.501 = 501 / 1000 and 116 / 1067 repeat their phases
                // beyond 1000 and 1067 periods (the ladder never uses such
                // windows).
                if (rho == 0.501 && length > 1000) || (rho < 0.2 && rho > 0.1 && length > 1067) {
                    continue;
                }
                let g = gaps(rho, length);
                let expected = sorted_weights(rho, length);
                for (k, &e) in expected.iter().enumerate() {
                    let w = window_weight(&g, length, k as u32);
                    assert!((w - e).abs() < 1e-12, "rho {rho} L {length} k {k}: {w} != {e}");
                }
                // Increments d_k = sin-like values; positions their sums.
                let d: Vec<f64> = (0..length).map(|k| (k as f64 * 0.37).sin() + 0.1).collect();
                let direct: f64 = d.iter().zip(&expected).map(|(a, b)| a * b).sum();
                let mut x = 0.0;
                let mut sum = Vec2::ZERO;
                for i in 0..=length {
                    sum = add_to_window(sum, &g, 0, length, i, Replica::NONE, Vec2::splat(x));
                    if i < length {
                        x += d[i as usize];
                    }
                }
                assert!((sum.x - direct).abs() < 1e-9, "rho {rho} L {length}");
            }
        }
    }

    /// A window of the virtual run split over `count` replicas: each
    /// replica adds its own positions (offset by anything: only its own
    /// differences count), and their sums add up to the virtual run's
    /// trapezoid sum over its L periods, for windows that start anywhere.
    #[test]
    fn replica_sums_add_up_to_the_virtual_runs() {
        let rho = 2f64.sqrt() - 1.0;
        for count in [1u32, 2, 3, 8] {
            for (start, length) in [(0u32, 680u32), (340, 340), (170, 85), (0, 60)] {
                let virtual_rho = rho / count as f64;
                let g = gaps(virtual_rho, length);
                let expected = sorted_weights(virtual_rho, length);
                // The travel over virtual period K (any function will do).
                let d = |v: u32| ((v as f64) * 0.37).sin() + 0.1 + (v as f64 * 0.011).cos();
                let direct: f64 = (0..length).map(|v| expected[v as usize] * d(start + v)).sum();
                let mut total = 0.0;
                for index in 0..count {
                    let r = Replica {
                        index,
                        count,
                        turns: 0,
                        cycle: 0,
                    };
                    let mut x = 17.0 * index as f64;
                    let mut sum = Vec2::ZERO;
                    for k in 0..=(start + length) / count + 1 {
                        sum = add_to_window(sum, &g, start, length, k, r, Vec2::splat(x));
                        x += d(count * k + index);
                    }
                    total += sum.x;
                }
                assert!(
                    (total - direct).abs() < 1e-9,
                    "count {count} window [{start}, +{length}): {total} against {direct}"
                );
            }
        }
    }

    #[test]
    fn ladder_lengths_nest_by_halves_and_quarters() {
        for j in FIRST_JUDGED..LEVELS as u32 {
            assert_eq!(ladder_length(j), 2 * ladder_length(j - 2));
            assert_eq!(ladder_length(j), 4 * ladder_length(j - 4));
        }
        assert_eq!(ladder_length(7), MIN_WINDOW);
        assert_eq!(ladder_length(LEVELS as u32 - 1), 21_760);
    }

    /// Near 10/9 (21.34 and 23.66 Hz) no window shorter than the common
    /// period resolves enough phases; 14.14 / 10 Hz stops from 680 on.
    #[test]
    fn the_levels_that_may_stop_a_run() {
        let near = ladder(0.108_716_026_241_799_4, true, 1067, 20_000);
        assert_eq!(near.levels, 0);
        let irrational = ladder(2f64.sqrt() - 1.0, true, 0, 20_000);
        assert_eq!(irrational.levels.trailing_zeros(), 7);
        assert_eq!(irrational.levels >> 7, (1 << (LEVELS - 7)) - 1);
        assert_eq!(irrational.lattice, 0);
        assert_eq!(ladder(2f64.sqrt() - 1.0, false, 0, 20_000).levels, 0);
        // 21.34 / 32.94 Hz: 1647 / 1067, whose 680- and 960-period windows
        // have no gap above 2 / 1067; 25.98 / 37.58 Hz (1879 / 1299) has
        // gaps of 3 / 1299 at 960.
        let lattice = ladder(1647.0 / 1067.0 - 1.0, true, 1067, 20_000);
        assert_eq!(lattice.levels, (1 << 7) | (1 << 8));
        assert_eq!(lattice.lattice, (1 << 7) | (1 << 8));
        let gappy = ladder(1879.0 / 1299.0 - 1.0, true, 1299, 20_000);
        assert_eq!(gappy.levels, (1 << 7) | (1 << 8));
        assert_eq!(gappy.lattice, 0);
    }

    /// 14.666 / 19.142 Hz lies 1.4e-4 cycles a period from 47 / 154: its
    /// windows bunch into 154 clusters up to 5,440 periods, and its beat
    /// (7,333 periods, also its common period) lies within a run of
    /// 10,000, so no window stops that run; a run of 3,000 periods sees
    /// the same clusters throughout and may stop at 680. The text's stage
    /// at 11 pi / 2 Hz bunches into 226 clusters whose beat (about 33,000
    /// periods) lies beyond a run of 20,000, not beyond one of 200,000.
    #[test]
    fn bunched_windows_stop_only_runs_short_of_their_beat() {
        let near = 19.142 / 14.666 - 1.0;
        assert_eq!(ladder(near, true, 7333, 10_000).levels, 0);
        assert_eq!(ladder(near, true, 7333, 3_000).levels.trailing_zeros(), 7);
        let pi: f64 = 17.278_759_594_743_86 / 11.0 - 1.0;
        assert!((226.0 * pi - 129.0).abs() < 1e-4);
        let short = ladder(pi, true, 0, 20_000).levels;
        let long = ladder(pi, true, 0, 200_000).levels;
        assert_ne!(short & (1 << 8), 0);
        assert_eq!(long & ((1 << 12) - 1), 0);
    }
}
}
