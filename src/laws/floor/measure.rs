//! The steady measurement (docs/model.md section 4): the per-period bookkeeping
//! of one instance and the rule that stops its run. The CPU mirror of
//! `shaders/shared/measure.wgsl` (same functions, same order of
//! operations); its constants reach the shader through the prelude.
//!
//! At the end of every scene period from `settle` on, [`period_end`]
//! records the slider's travel over the period into fixed-size batch
//! accumulators, and at the end of every common period of the drives it
//! compares the state with the states of the last [`SNAPSHOTS`] common
//! period ends. The run stops
//!
//! * *periodic*: the state (stage positions and velocities, slider
//!   velocity, mode; not the slider position, which translates) repeats
//!   after L common periods within `repeat_tolerances`: the travel over
//!   those L common periods is the steady step exactly;
//! * *phase-resolved*: with two drive frequencies, a window of the phase
//!   ladder (`super::phase`: trapezoid sums over the faster drive's phase)
//!   that may stop the run ends with every axis' standard error at most
//!   the step tolerance;
//! * *converged*: at least [`MIN_BATCHES`] batches, each spanning the
//!   slowest beat of the drives (`Gauge::min_batch`), are complete, what MSER keeps of them is
//!   stationary (its halves agree), and every axis' standard error
//!   ([`estimate`]) is at most the step tolerance.
//!
//! Otherwise it runs to `max_cycles` (the instance's `cycles`), and the
//! reduction (`pidm::measurement`) reports it "not steady" with its best
//! estimate. Everything here is fixed-size: no per-period arrays.
//!
//! The estimate ([`estimate`]): the transient is cut by MSER (White 1997,
//! "An effective truncation heuristic for bias reduction in simulation
//! output", Simulation 69(6); MSER-5 in White, Cobb and Spratt 2000) on the
//! batch sums, which makes it MSER-b with batches of at least one common
//! period. The standard error combines batch means over the kept batches
//! (Schmeiser 1982, with a fixed number of batches whose length doubles as
//! the run grows, as in Fishman and Yarberry 1997's LABATCH.2) with the
//! bounded-oscillation term, the range of the centred cumulative sum over
//! the kept periods divided by their number. Batch means alone claim far
//! too small errors for quasi-periodic motion (whose running mean converges
//! like 1/N) and for a stuck slider (whose increments telescope); the range
//! term is of the size of those errors. Batches span the slowest beat of
//! order at most [`BEAT_ORDER`], so their means are not correlated through
//! a beat (docs/model.md section 4's first trap). Beats of higher order and
//! transients that die slowly are slower than anything a finite set of
//! batches can see; the stop therefore also asks that the first and last
//! halves of the kept batches agree (Geweke 1992's comparison of early and
//! late means), which a motion still changing on a longer scale fails.

use super::Real;
use super::phase::{Phase, phase_period_end};
use super::precision::only_f64;
use super::vec2::Vec2;

pub use super::gauge::{Gauge, Slider};
pub(crate) use super::gauge::{gauge_by_fields, slider_by_fields};

/// Common-period ends whose states are kept for the recurrence test: the
/// longest lag found is this many common periods (subharmonic motion of
/// order up to 8).
pub const SNAPSHOTS: usize = 8;
/// Batch accumulators per axis. When all are full, neighbours are added in
/// pairs and the batch length doubles.
pub const BATCHES: usize = 32;
/// Complete batches needed before a statistical stop: after MSER has cut
/// at most half of them, at least 8 remain for batch means.
pub const MIN_BATCHES: u32 = 16;
/// The longest common period looked for [scene periods]: from the
/// frequencies as decimals (`decimal_common_period`), so that a map's
/// two-decimal frequencies (21.34 and 23.66 Hz: 1067 periods) repeat
/// exactly.
pub const MAX_COMMON_PERIOD: u32 = 100_000;
/// The longest common period the search over the frequency ratio looks for
/// (`short_common_period`), which also sets the batch length.
pub const SHORT_COMMON_PERIOD: u32 = 1000;
/// Decimal places a frequency is read with (`decimal_common_period`).
pub const DECIMALS: u32 = 6;
/// How close f 10^k must be to an integer, relative, for the frequency to
/// count as k decimals: 64 roundings of f64 (grid values computed as
/// `from + i step` are a few roundings off), so a frequency that is not a
/// short decimal passes by chance with a probability of about 1e-7.
pub const DECIMAL_ROUNDINGS: f64 = 64.0;
/// Beats of order up to this (|q r - p| for the frequency ratio r) set the
/// shortest batch when the drives have no common period. Stick-slip is
/// not smooth: measured on random instances, beats of order 20 (203
/// periods) and 21 (1,045 periods) moved the mean step by 0.05 um long
/// after batches spanning the beats of order up to 8 agreed, and on
/// sweeps/beats.toml one of order 105 (280 periods) by 0.026 um after
/// those up to order 64 agreed.
pub const BEAT_ORDER: u32 = 128;
/// Relative distance from an integer below which q r counts as one: the
/// drive then repeats after q scene periods to 1e-9 cycles, far below
/// anything the recurrence test sees.
pub const COMMENSURATE: f64 = 1e-9;
/// The recurrence test's position tolerance per radian of the integrator's
/// tolerance, relative to the largest static deflection of a stage under
/// its drive amplitude (|delta V| / k): the default tolerance 1e-4 rad and
/// Table 1's 60 um deflection give 6e-11 m, below the integrator's own
/// error in a step (about tolerance / 4 micrometres). Relative, so it means
/// the same in every unit system the shader computes in.
pub const REPEAT_PER_RADIAN: f64 = 1e-2;

/// The measurement is still running.
pub const VERDICT_RUNNING: u32 = 0;
/// The motion repeated: the step is exact.
pub const VERDICT_PERIODIC: u32 = 1;
/// The batch means' standard error fell within the step tolerance.
pub const VERDICT_CONVERGED: u32 = 2;
/// The phase-resolved estimate's standard error fell within the step
/// tolerance (`super::phase`).
pub const VERDICT_PHASE: u32 = 3;
/// A replica of a split run (`super::phase::Replica`) reached a level of
/// the phase ladder that may stop the run: it waits, `Slider::measured`
/// 2, while its group merges the replicas' sums of that level
/// (`pidm::replicas`), which stops the group or lets it go on.
pub const VERDICT_WAITING: u32 = 4;

/// The state at the end of one common period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Snapshot {
    pub x_p: Vec2,
    pub v_p: Vec2,
    pub v_s: Vec2,
    /// Slider position [m]: not compared, but the travel since it is the
    /// step of a periodic motion.
    pub x_s: Vec2,
    pub mode: u32,
}

/// The per-instance accumulators of a steady measurement. Lengths are in
/// metres, counts in scene periods.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measure {
    /// Slider position at the end of the previous period.
    pub last_x_s: Vec2,
    /// Slider position where the batch being filled began.
    pub batch_start: Vec2,
    /// Smallest and largest travel over one period, per axis.
    pub d_min: Vec2,
    pub d_max: Vec2,
    /// Travel over the detected cycle (periodic verdict), or the phase
    /// ladder's latest judged estimate times its window's length
    /// ([`Measure::span`]).
    pub travel: Vec2,
    /// Travel over each complete batch.
    pub sums: [Vec2; BATCHES],
    /// The last common-period ends, a ring indexed by `snapshots`.
    pub snaps: [Snapshot; SNAPSHOTS],
    /// The period whose end is processed next (guards against processing
    /// one end twice).
    pub next_end: u32,
    /// Periods measured (after `settle`).
    pub measured: u32,
    /// Complete batches, the current batch length and the periods in the
    /// batch being filled.
    pub filled: u32,
    pub batch_length: u32,
    pub in_batch: u32,
    /// Snapshots taken so far.
    pub snapshots: u32,
    /// The detected cycle [scene periods], 0 when none.
    pub lag: u32,
    pub verdict: u32,
    /// The phase ladder's latest judged window (the stopping one under a
    /// phase-resolved verdict): its length [scene periods] (0 when none
    /// was judged; `travel` then holds its estimate times the length) and
    /// the squared standard error of the mean travel per scene period
    /// [m^2].
    pub span: u32,
    /// A replica's last level reached (`super::phase::Replica`), whose
    /// sums `phase.pending` holds for its group's merge.
    pub pending_level: u32,
    pub se2: Vec2,
    /// The phase ladder's windows (`super::phase`).
    pub phase: Phase,
}

/// The accumulators of a run that has not started.
pub fn initial_measure(c: &impl Gauge) -> Measure {
    Measure {
        last_x_s: Vec2::ZERO,
        batch_start: Vec2::ZERO,
        d_min: Vec2::splat(Real::INFINITY),
        d_max: Vec2::splat(-Real::INFINITY),
        travel: Vec2::ZERO,
        sums: [Vec2::ZERO; BATCHES],
        snaps: [Snapshot::default(); SNAPSHOTS],
        next_end: 0,
        measured: 0,
        filled: 0,
        batch_length: c.batch_length(),
        in_batch: 0,
        snapshots: 0,
        lag: 0,
        verdict: VERDICT_RUNNING,
        span: 0,
        pending_level: 0,
        se2: Vec2::ZERO,
        phase: Phase::ZERO,
    }
}

/// Whether the state sits at a period end that [`period_end`] has not
/// processed yet (a steady measurement only).
pub fn at_period_end(c: &impl Gauge, st: &impl Slider, m: &Measure) -> bool {
    c.steady() && st.reached(c.period(), c.period_lo()) && m.next_end == st.period()
}

/// Processes the end of period `st.period()`: the state is at t = (period + 1)
/// T, before the boundary is passed. Sets `st.measured()` when the
/// measurement is complete.
pub fn period_end(c: &impl Gauge, st: &mut impl Slider, m: &mut Measure) {
    m.next_end = st.period() + 1;
    let ended = st.period() + 1;
    if ended < c.settle() {
        return;
    }
    if ended > c.settle() {
        let d = st.x_s() - m.last_x_s;
        m.d_min = m.d_min.zip(d, Real::min);
        m.d_max = m.d_max.zip(d, Real::max);
        m.measured += 1;
        m.in_batch += 1;
        if m.in_batch == m.batch_length {
            close_batch(m, st.x_s());
        }
    } else {
        m.batch_start = st.x_s();
    }
    m.last_x_s = st.x_s();
    if c.common_period() > 0 && (ended - c.settle()).is_multiple_of(c.common_period()) {
        recurrence(c, st, m);
    }
    if c.phase_levels() != 0 {
        let judged = phase_period_end(c, &mut m.phase, ended - c.settle(), st.x_s());
        if judged.span > 0 && m.verdict == VERDICT_RUNNING {
            if c.replicas() > 1 {
                m.pending_level = judged.level;
                m.verdict = VERDICT_WAITING;
            } else {
                m.travel = judged.value * judged.span as Real;
                m.span = judged.span;
                m.se2 = judged.se2;
                if judged.se2.x <= c.se_limit2().x && judged.se2.y <= c.se_limit2().y {
                    m.verdict = VERDICT_PHASE;
                }
            }
        }
    }
    if m.verdict == VERDICT_RUNNING
        && m.in_batch == 0
        && m.filled >= MIN_BATCHES
        && m.batch_length >= c.min_batch()
    {
        let e = estimate(m);
        if e.stationary && e.se2.x <= c.se_limit2().x && e.se2.y <= c.se_limit2().y {
            m.verdict = VERDICT_CONVERGED;
        }
    }
    if m.verdict == VERDICT_WAITING {
        st.set_measured(2);
    } else if m.verdict != VERDICT_RUNNING {
        st.set_measured(1);
    }
}

/// Stores the batch that ends at `x_s`; folds the batches in pairs when
/// all are full.
pub fn close_batch(m: &mut Measure, x_s: Vec2) {
    m.sums[m.filled as usize] = x_s - m.batch_start;
    m.filled += 1;
    m.batch_start = x_s;
    m.in_batch = 0;
    if m.filled as usize == BATCHES {
        for j in 0..BATCHES / 2 {
            m.sums[j] = m.sums[2 * j] + m.sums[2 * j + 1];
        }
        m.filled = (BATCHES / 2) as u32;
        m.batch_length *= 2;
    }
}

/// Compares the state with the last common-period ends, nearest first;
/// records the lag and the travel over it when one matches, else keeps the
/// state.
fn recurrence(c: &impl Gauge, st: &impl Slider, m: &mut Measure) {
    let now = Snapshot {
        x_p: st.x_p(),
        v_p: st.v_p(),
        v_s: st.v_s(),
        x_s: st.x_s(),
        mode: st.mode(),
    };
    let kept = m.snapshots.min(SNAPSHOTS as u32);
    for back in 1..=kept {
        let s = &m.snaps[((m.snapshots - back) % SNAPSHOTS as u32) as usize];
        if repeats(c, &now, s) {
            m.lag = back * c.common_period();
            m.travel = st.x_s() - s.x_s;
            m.verdict = VERDICT_PERIODIC;
            return;
        }
    }
    m.snaps[(m.snapshots % SNAPSHOTS as u32) as usize] = now;
    m.snapshots += 1;
}

/// Whether state `a` repeats state `b` within `repeat_tolerances`: the
/// same mode, and stage positions, stage velocities and slider velocities
/// each within their tolerance (the slider position translates and is not
/// compared). The recurrence test's rule, and the one a cycle split's
/// group joins its pieces by (`pidm::replicas::group`); the shader's
/// recurrence test inlines it.
pub fn repeats(c: &impl Gauge, a: &Snapshot, b: &Snapshot) -> bool {
    a.mode == b.mode
        && close(a.x_p, b.x_p, c.repeat_x())
        && close(a.v_p, b.v_p, c.repeat_v())
        && close(a.v_s, b.v_s, c.repeat_v())
}

fn close(a: Vec2, b: Vec2, tolerance: Real) -> bool {
    let d = (a - b).abs();
    d.x <= tolerance && d.y <= tolerance
}

/// The batch estimate of the mean travel per scene period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Travel over the kept batches [m].
    pub travel: Vec2,
    /// Periods in the kept batches.
    pub span: u32,
    /// Squared standard error of the mean travel per scene period [m^2].
    pub se2: Vec2,
    /// The kept batches look stationary: MSER's cut stayed below its
    /// limit, their means are not correlated ([`CORRELATION_Z`]), and the
    /// means of their first and last halves agree within [`STATIONARY_Z`]
    /// combined standard errors.
    pub stationary: bool,
}

/// The halves of the kept batches may differ by this many combined
/// standard errors (a Geweke-style check; Geweke 1992). A motion that
/// changes more slowly than the run has lasted (a beat of high order, a
/// transient that dies slowly) shows as a difference between the halves
/// that no statistic of the batches alone reveals.
pub const STATIONARY_Z: f64 = 2.0;

/// Batch means whose lag-1 autocorrelation exceeds this many standard
/// deviations of its value for independent means (1 / sqrt(count)) are
/// taken to be correlated: the batches are still shorter than the slowest
/// change of the motion, and batch means would claim too small an error
/// (the test of independence of LABATCH.2, Fishman and Yarberry 1997).
pub const CORRELATION_Z: f64 = 2.0;

/// Batch means and the range term over complete batches `start .. end`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Statistics {
    /// Travel over the batches [m].
    pub total: Vec2,
    /// Mean travel per scene period [m].
    pub mean: Vec2,
    /// Squared standard error of `mean` [m^2] (needs at least 2 batches).
    pub se2: Vec2,
    /// Whether each axis' batch means are correlated (lag 1).
    pub correlated: [bool; 2],
}

/// The statistics of batches `start .. end` (at least 2): batch means over
/// them, plus the range of their centred cumulative sum over the periods
/// they span.
pub fn statistics(m: &Measure, start: u32, end: u32) -> Statistics {
    let count = end - start;
    let mut total = Vec2::ZERO;
    for j in start..end {
        total = total + m.sums[j as usize];
    }
    let b = m.batch_length as Real;
    let inv_count = 1.0 / count as Real;
    let per_batch = total * inv_count;
    let mut squares = Vec2::ZERO;
    let mut lagged = Vec2::ZERO;
    let mut previous = Vec2::ZERO;
    let mut walk = Vec2::ZERO;
    let mut low = Vec2::ZERO;
    let mut high = Vec2::ZERO;
    for j in start..end {
        let e = m.sums[j as usize] - per_batch;
        squares = squares + e * e;
        lagged = lagged + e * previous;
        previous = e;
        walk = walk + e;
        low = low.zip(walk, Real::min);
        high = high.zip(walk, Real::max);
    }
    let inv_span = 1.0 / (count as Real * b);
    let range = (high - low) * inv_span;
    let inv_b = 1.0 / b;
    let batch = squares * (inv_count * (1.0 / (count - 1) as Real)) * (inv_b * inv_b);
    // lagged / squares > CORRELATION_Z / sqrt(count), without a root.
    let z = CORRELATION_Z as Real;
    let bound = squares * squares * (z * z * inv_count);
    Statistics {
        total,
        mean: total * inv_span,
        se2: batch + range * range,
        correlated: [
            lagged.x > 0.0 && lagged.x * lagged.x > bound.x,
            lagged.y > 0.0 && lagged.y * lagged.y > bound.y,
        ],
    }
}

/// The estimate from the complete batches: MSER's cut, then batch means
/// and the range of the centred cumulative sum over what is kept, and the
/// stationarity of what is kept. Needs at least one complete batch; with
/// one, the spread is unknown and the standard error is the largest
/// single-period travel.
pub fn estimate(m: &Measure) -> Estimate {
    estimate_from(m, cut(m))
}

/// The leading batches MSER cuts: the larger of the axes' cuts.
pub fn cut(m: &Measure) -> u32 {
    let cuts = mser_cut(m);
    cuts.x.max(cuts.y) as u32
}

/// [`estimate`] over the complete batches from `cut` on: the step's cut
/// for the step, and the step's cut for a quantity that follows it
/// (`crate::laws::floor::variation`: the same batches).
pub fn estimate_from(m: &Measure, cut: u32) -> Estimate {
    let n = m.filled;
    let kept = n - cut;
    let span = kept * m.batch_length;
    if kept < 2 {
        let mut total = Vec2::ZERO;
        for j in cut..n {
            total = total + m.sums[j as usize];
        }
        let largest = m.d_min.abs().zip(m.d_max.abs(), Real::max);
        return Estimate {
            travel: total,
            span,
            se2: largest * largest,
            stationary: false,
        };
    }
    let whole = statistics(m, cut, n);
    let half = kept / 2;
    let mut stationary = false;
    if half >= 2 && cut < n / 2 && !whole.correlated[0] && !whole.correlated[1] {
        let first = statistics(m, cut, cut + half);
        let last = statistics(m, n - half, n);
        let d = first.mean - last.mean;
        let z = STATIONARY_Z as Real;
        let allowed = (first.se2 + last.se2) * (z * z);
        stationary = d.x * d.x <= allowed.x && d.y * d.y <= allowed.y;
    }
    Estimate {
        travel: whole.total,
        span,
        se2: whole.se2,
        stationary,
    }
}

/// MSER's truncation per axis: the number of leading batches d <= n / 2
/// that minimises the squared deviations of the rest over (n - d)^2.
fn mser_cut(m: &Measure) -> Vec2 {
    let n = m.filled;
    let mut best = Vec2::splat(Real::INFINITY);
    let mut cut = Vec2::ZERO;
    for d in 0..=n / 2 {
        let left = (n - d) as Real;
        let inv_left = 1.0 / left;
        let mut total = Vec2::ZERO;
        for j in d..n {
            total = total + m.sums[j as usize];
        }
        let mean = total * inv_left;
        let mut squares = Vec2::ZERO;
        for j in d..n {
            let e = m.sums[j as usize] - mean;
            squares = squares + e * e;
        }
        let score = squares * (inv_left * inv_left);
        for i in 0..2 {
            if score[i] < best[i] {
                best[i] = score[i];
                cut[i] = d as Real;
            }
        }
    }
    cut
}

only_f64! {
/// The drives' common period [scene periods]: the smallest q at which
/// every driven axis completes a whole number of its cycles (the drive
/// then repeats, phases included): from the ratio of the frequencies up to
/// [`SHORT_COMMON_PERIOD`], else from the frequencies as the user wrote
/// them (decimals) up to [`MAX_COMMON_PERIOD`]; 0 when there is none.
pub fn common_period(frequency: Vec2, cycles_per_period: Vec2, driven: [bool; 2]) -> u32 {
    match short_common_period(cycles_per_period, driven) {
        0 => decimal_common_period(frequency, driven),
        q => q,
    }
}

/// The smallest q <= [`SHORT_COMMON_PERIOD`] at which every driven axis
/// completes a whole number of its cycles per scene period (within
/// [`COMMENSURATE`]), or 0: finds ratios such as 4:3 however the
/// frequencies were written.
pub fn short_common_period(cycles_per_period: Vec2, driven: [bool; 2]) -> u32 {
    (1..=SHORT_COMMON_PERIOD)
        .find(|&q| (0..2).all(|i| !driven[i] || is_whole(q as f64 * cycles_per_period[i])))
        .unwrap_or(0)
}

/// The common period of frequencies that are decimals of at most
/// [`DECIMALS`] places (rational reconstruction: f = n / 10^k exactly, to
/// [`DECIMAL_ROUNDINGS`] roundings), in exact integer arithmetic: with the
/// slowest driven frequency n_0 / d_0, axis i completes (n_i d_0) / (d_i
/// n_0) cycles per scene period, and q is the least common multiple of
/// those fractions' denominators; 0 if a frequency is no such decimal or q
/// exceeds [`MAX_COMMON_PERIOD`]. 21.34 and 23.66 Hz give 1067.
pub fn decimal_common_period(frequency: Vec2, driven: [bool; 2]) -> u32 {
    let mut fractions = [(0u128, 1u128); 2];
    for i in 0..2 {
        if !driven[i] {
            continue;
        }
        match as_decimal(frequency[i]) {
            Some(f) => fractions[i] = f,
            None => return 0,
        }
    }
    let slowest = (0..2)
        .filter(|&i| driven[i])
        .min_by(|&i, &j| frequency[i].total_cmp(&frequency[j]));
    let Some(s) = slowest else { return 0 };
    let (n0, d0) = fractions[s];
    let mut q: u128 = 1;
    for i in 0..2 {
        if !driven[i] {
            continue;
        }
        let (n, d) = fractions[i];
        let (num, den) = (n * d0, d * n0);
        let den = den / gcd(num, den);
        q = q / gcd(q, den) * den;
        if q > MAX_COMMON_PERIOD as u128 {
            return 0;
        }
    }
    q as u32
}

/// `x` as n / 10^k with the fewest places k <= [`DECIMALS`], if it is one
/// (module docs of [`DECIMAL_ROUNDINGS`]); n > 0.
fn as_decimal(x: f64) -> Option<(u128, u128)> {
    if !(x > 0.0 && x.is_finite()) {
        return None;
    }
    let mut scale: u128 = 1;
    for _ in 0..=DECIMALS {
        let scaled = x * scale as f64;
        let n = scaled.round();
        if (scaled - n).abs() <= DECIMAL_ROUNDINGS * f64::EPSILON * scaled && n >= 1.0 {
            let n = n as u128;
            let g = gcd(n, scale);
            return Some((n / g, scale / g));
        }
        scale *= 10;
    }
    None
}

fn gcd(mut a: u128, mut b: u128) -> u128 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

fn is_whole(x: f64) -> bool {
    (x - x.round()).abs() <= COMMENSURATE * x.abs().max(1.0)
}

/// The batch length that a statistical stop needs [scene periods]: the
/// common period where there is one; otherwise the slowest beat of order
/// up to [`BEAT_ORDER`] between the two drives, 1 / |q r - p| periods (r
/// the cycles per period of the faster axis), rounded up.
pub fn beat_batch_length(cycles_per_period: Vec2, driven: [bool; 2]) -> u32 {
    let common = short_common_period(cycles_per_period, driven);
    if common > 0 {
        return common;
    }
    let mut slowest: f64 = 1.0;
    for i in 0..2 {
        if !driven[i] {
            continue;
        }
        for q in 1..=BEAT_ORDER {
            let x = q as f64 * cycles_per_period[i];
            if is_whole(x) {
                continue;
            }
            let beat = 1.0 / (x - x.round()).abs();
            slowest = slowest.max(beat);
        }
    }
    slowest.ceil().min(u32::MAX as f64).max(1.0) as u32
}

/// The first batch length [scene periods]: the common period where there
/// is one; otherwise the beat's batch ([`beat_batch_length`]), but short
/// enough for [`MIN_BATCHES`] batches to fit in `max_cycles`, so that a
/// run stopped there still has batches to estimate its error from (it
/// cannot stop statistically before its batches span the beat).
pub fn first_batch_length(cycles_per_period: Vec2, driven: [bool; 2], max_cycles: u32) -> u32 {
    let beat = beat_batch_length(cycles_per_period, driven);
    if short_common_period(cycles_per_period, driven) > 0 {
        return beat;
    }
    beat.min((max_cycles / MIN_BATCHES).max(1))
}

/// The recurrence test's tolerances: on positions (relative to the
/// largest static `deflection` of a stage) and on velocities (positions
/// times the fastest rate of the stage), in the instance's units.
pub fn repeat_tolerances(tolerance: f64, deflection: f64, stage_rate: f64) -> (f64, f64) {
    let x = REPEAT_PER_RADIAN * tolerance * deflection;
    (x, x * stage_rate)
}

}

/// The constants above that the shader reads, as WGSL declarations for
/// its prelude.
pub fn wgsl_constants() -> String {
    let u = |name: &str, v: u32| format!("const {name}: u32 = {v}u;\n");
    let r = |name: &str, v: f64| format!("const {name}: Real = Real({v:e});\n");
    [
        u("SNAPSHOTS", SNAPSHOTS as u32),
        u("BATCHES", BATCHES as u32),
        u("MIN_BATCHES", MIN_BATCHES),
        u("VERDICT_RUNNING", VERDICT_RUNNING),
        u("VERDICT_PERIODIC", VERDICT_PERIODIC),
        u("VERDICT_CONVERGED", VERDICT_CONVERGED),
        u("VERDICT_PHASE", VERDICT_PHASE),
        u("VERDICT_WAITING", VERDICT_WAITING),
        r("STATIONARY_Z", STATIONARY_Z),
        r("CORRELATION_Z", CORRELATION_Z),
    ]
    .concat()
}

only_f64! {
#[cfg(test)]
mod tests {
    use super::*;

    /// `common_period` of `fx` and `fy` [Hz], both driven, with the
    /// scene period of the slower.
    fn common(fx: f64, fy: f64) -> u32 {
        let lowest = fx.min(fy);
        let frequency = Vec2::new(fx, fy);
        common_period(frequency, frequency * (1.0 / lowest), [true, true])
    }

    /// Frequencies as decimals give their exact common period, grid values
    /// (from + i step) included; ratios without one give 0; short periods
    /// come from the ratio whatever the decimals.
    #[test]
    fn common_periods_from_the_frequencies_as_written() {
        let step = (39.9 - 5.1) / 15.0;
        let grid = |i: f64| 5.1 + i * step;
        let cases = [
            (21.34, 23.66, 1067),
            (grid(7.0), grid(8.0), 1067),
            (5.1, 7.42, 255),
            (grid(0.0), grid(1.0), 255),
            (37.58, 39.9, 1879),
            (10.0, 14.0, 5),
            (10.0, 10.0 * 4.0 / 3.0, 3),
            (10.0, 10.003, 10_000),
            (6.006519, 29.34, 0),
            (10.0, 10.0 * 2f64.sqrt(), 0),
            (25.98, 25.98 * 0.96 * 2f64.sqrt(), 0),
            (9.99991, 10.0, 0),
        ];
        for (fx, fy, expected) in cases {
            assert_eq!(common(fx, fy), expected, "{fx} Hz and {fy} Hz");
            assert_eq!(common(fy, fx), expected, "{fy} Hz and {fx} Hz");
        }
        // An undriven axis does not count.
        let f = Vec2::new(21.34, 23.66);
        assert_eq!(decimal_common_period(f, [true, false]), 1);
        assert_eq!(decimal_common_period(f, [false, false]), 0);
    }
}
}
