//! Replicas (issue 39): one slow steady measurement split over several
//! lanes or threads that would otherwise wait, so that a map smaller than
//! the machine still fills it and ends with its median instance rather than
//! its slowest.
//!
//! A quasi-periodic motion's step is the mean over its attractor, and the
//! phase ladder (`laws::floor::phase`) estimates it by a trapezoid rule
//! over the faster drive's phase, whatever order the phases came in. So an
//! instance whose ladder is on ([`splittable`]) runs as R replicas: replica
//! r is the instance with its faster drive's phase advanced by r rho / R
//! cycles ([`replica_instance`]), started from rest like the instance and
//! settled for as many periods. Period k of replica r then starts at the
//! phase of period R k + r of a virtual run whose faster drive advances by
//! rho / R a period, and each replica adds its slider positions to the
//! virtual run's trapezoid windows with that run's weights
//! (`phase::window_coefficient`): the replicas' sums add up to the virtual
//! run's, R times the phases for the same chain length. At each level of
//! the ladder that may stop the run, every replica waits while its group
//! adds the replicas' sums and judges them as one run's ([`group`]); the
//! merged window stops all, or all go on.
//!
//! An instance whose drives repeat after a common period q and that no
//! phase split takes (its ladder off, or no virtual run even enough: near
//! a resonance, where the run alone waits for the recurrence test at
//! `settle` plus q periods) makes a *cycle split* instead
//! ([`cycle_split`]): R pieces of q, each from rest at the drives' phases
//! of its first period, joined end to start by the recurrence test's
//! tolerances into one periodic motion (`group::Group::step`).
//!
//! Replicas that disagree beyond their errors (coexisting attractors) are
//! never merged: the instance then runs again as one run of its own, and
//! the map keeps that run labelled `multistable`. A group that cannot merge
//! for another reason (a replica failed, found its motion periodic or
//! converged by batch means) runs the instance as one run too, unlabelled.
//!
//! Measured (CPU mirror, Table 1 at 10 and 10 sqrt 2 Hz, 100 V): replicas
//! from rest at other phases land on the one run's attractor (the trapezoid
//! of 20,000 periods from four phases agrees to 2e-6 um), and 8 replicas
//! of 170 periods each estimate the step within 1e-4 um of it, as one run
//! of 1,360 periods does.

pub mod cpu;
pub mod group;

pub use group::{Group, Member, Step};

use crate::laws::floor::Setup;
use crate::laws::floor::phase;
use crate::laws::{Law, Replica, Settings};
use crate::model::{Instance, Measure};

pub use crate::laws::settings::Replicas;

/// The most replicas `simulation.replicas = "auto"` makes of one instance:
/// 8 cuts a chain to about an eighth plus its settling, where the lanes or
/// threads are there; beyond, the replicas' settling and the merges cost
/// more than the shorter chains save on the instances measured.
pub const MAX_AUTO: u32 = 8;

/// Whether `inst`'s steady measurement can be split: a steady measurement
/// whose phase ladder has a level whose phases resolve enough for its run
/// alone (two driven axes at frequencies with no common period of at
/// most 680 scene periods; `phase::Ladder::resolving`), whether or not
/// they bunch: a group's replicas interleave between a near resonance's
/// clusters, and its virtual run is judged for bunching on its own
/// ([`split`]). A periodic motion the recurrence test finds early is not
/// split: nothing would be gained. Nor is a run no level resolves (near a
/// resonance of few clusters): its replicas' coarse estimates were
/// measured to disagree as if attractors coexisted (7.13 / 23.858 Hz); a
/// cycle split takes those that repeat.
pub fn splittable(inst: &Instance, settings: &Settings) -> bool {
    if !matches!(inst.measure, Measure::Steady { .. }) || !Law::of_instance(inst).splits_by_phase()
    {
        return false;
    }
    let c = Setup::new(inst, settings, Replica::NONE);
    let rho = faster_drive(inst).1;
    let driven = inst.axes.each_ref().map(|a| a.is_driven());
    let on = phase::ladder_on(driven, rho, c.common_period);
    let horizon = inst.cycles.saturating_sub(inst.settle);
    phase::ladder(rho, on, c.common_period, horizon).resolving != 0
}

/// Whether `inst` may split at all, by a phase split ([`splittable`]) or a
/// cycle split ([`cycle_split`]) into up to [`MAX_AUTO`] pieces: what a
/// cost estimate asks (`crate::backend::probe`).
pub fn may_split(inst: &Instance, settings: &Settings) -> bool {
    splittable(inst, settings) || cycle_split(inst, settings, MAX_AUTO).is_some()
}

/// The replicas each splittable instance of a batch runs as: the scene's
/// count, or with `Auto` the `workers` (lanes or threads) per integration
/// of the batch (`jobs`, splittable or not), at most [`MAX_AUTO`], and 1
/// (no replicas) where there are as many integrations as workers.
pub fn count(setting: Replicas, workers: usize, jobs: usize) -> u32 {
    match setting {
        Replicas::Count(n) => n.max(1),
        Replicas::Auto => ((workers / jobs.max(1)).min(MAX_AUTO as usize) as u32).max(1),
    }
}

/// [`count`] for workers that take queued jobs as they free (the GPU's
/// lanes, `gpu::groups`): with `Auto`, the lanes per integration rounded
/// up where that queues at most a quarter of the lanes' worth of jobs
/// beyond the lanes (else rounded down, as [`count`]). The jobs left over
/// wait in the queue for the first lanes a replica frees at its group's
/// merge. Measured on `results/pipeline/twofreq6.toml` (36 instances on
/// lavapipe's 256 lanes, f64, 2 pairs): 8 replicas each took 52.6 s
/// against 61.6 s for 7 (results/replicas.md).
pub fn count_queued(setting: Replicas, lanes: usize, jobs: usize) -> u32 {
    let floor = count(setting, lanes, jobs);
    let up = lanes.div_ceil(jobs.max(1)).min(MAX_AUTO as usize);
    match setting {
        Replicas::Auto if 4 * up * jobs <= 5 * lanes => up.max(1) as u32,
        _ => floor,
    }
}

/// The index of the faster drive (the one whose cycles per scene period
/// are the most, as `Setup` takes it) and its advance per scene
/// period [cycles].
fn faster_drive(inst: &Instance) -> (usize, f64) {
    let period = inst.period();
    let cycles = inst.axes.map(|a| a.frequency * period);
    let fast = if cycles[1] > cycles[0] { 1 } else { 0 };
    (fast, cycles[fast].fract())
}

/// Replica `r` of `inst`: the instance with its faster drive's phase
/// advanced by `r.index` times the virtual run's step (module docs).
pub fn replica_instance(inst: &Instance, r: Replica) -> Instance {
    let mut out = *inst;
    if r.cycle > 0 {
        return cycle_piece(inst, r);
    }
    if r.index == 0 || r.count <= 1 {
        return out;
    }
    let (fast, rho) = faster_drive(inst);
    let shift = r.index as f64 * r.virtual_step(rho);
    let axis = &mut out.axes[fast];
    axis.phase = (axis.phase + shift).fract();
    out
}

/// Piece `r` of a cycle split of `inst` ([`cycle_split`]): the instance
/// with its faster drive advanced to its phase at the piece's start period
/// s (by s rho cycles; the slower drive completes whole cycles a scene
/// period), running `settle` plus the piece's periods.
fn cycle_piece(inst: &Instance, r: Replica) -> Instance {
    let mut out = *inst;
    let (start, length) = r.cycle_segment();
    let (fast, rho) = faster_drive(inst);
    let axis = &mut out.axes[fast];
    axis.phase = (axis.phase + (start as f64 * rho).fract()).fract();
    out.cycles = inst.settle + length;
    out
}

/// The fewest periods a cycle split's piece measures: shorter pieces save
/// less than their own settling (2 periods at the default `settle`, a
/// sixteenth of this) and their group's join cost.
pub const MIN_PIECE: u32 = 32;

/// The cycle split of `inst` into at most `count` pieces, if it has one
/// (`Replica::cycle`): a steady measurement of drives that repeat after a
/// common period q (`Setup::common_period`) that the run alone
/// could reach (`settle + q <= max_cycles`), cut into as many pieces as
/// `count` allows with at least [`MIN_PIECE`] periods (and `settle`) each,
/// none longer than the run alone's first chance to stop: the shortest
/// phase window that may stop it (at least `phase::MIN_WINDOW`), or q
/// where none may (its phases bunch up to q, `phase::MAX_BUNCHING`). A
/// motion that turns out not to repeat after q (the pieces do not join)
/// then costs its pieces no more than the run alone spends before it
/// could stop.
pub fn cycle_split(inst: &Instance, settings: &Settings, count: u32) -> Option<Replica> {
    if !matches!(inst.measure, Measure::Steady { .. }) || !Law::of_instance(inst).splits_by_cycle()
    {
        return None;
    }
    let c = Setup::new(inst, settings, Replica::NONE);
    let q = c.common_period;
    if q == 0 || inst.settle.saturating_add(q) > inst.cycles {
        return None;
    }
    let first_stop = match c.phase_levels {
        0 => q,
        levels => phase::ladder_length(levels.trailing_zeros()),
    };
    let pieces = count.min(q / MIN_PIECE.max(inst.settle).max(1));
    let split = Replica {
        index: 0,
        count: pieces,
        turns: 0,
        cycle: q,
    };
    let longest = phase::MIN_WINDOW.max(first_stop);
    (pieces >= 2 && q.div_ceil(pieces) <= longest).then_some(split)
}

/// How far a virtual run's phases may be spaced less evenly than the
/// instance's own run's ([`phase::spread`]) for the split to be made by
/// `auto`: measured (Table 1 at 10 Hz against 10 (1 + sqrt 5) / 2 Hz, 8
/// replicas of 85 periods, against the trapezoid of 20,000 periods), the
/// virtual run of spread 2.08 estimated the step within 0.0002 um, as one
/// run of 680 periods does (0.0015 um); those of spread 5.2 were 0.014 and
/// 0.046 um off, and their error estimates missed it.
pub const SPREAD_SLACK: f64 = 1.2;

/// The spread below which a virtual run is always even enough: a run of
/// its own at a badly approximable ratio (the golden ratio: 1.88; sqrt 2:
/// 2.01; sqrt 3: 2.08).
pub const SPREAD_FLOOR: f64 = 2.2;

/// How `inst` is split into `count` replicas (>= 2), and the spread of
/// that virtual run (`Replica::turns`): among the virtual runs even enough
/// (`spread_limit`), the one whose ladder may stop soonest (its first
/// level that may stop a run: a level's quarters must resolve enough
/// phases, which a virtual step may deny the first levels; measured on
/// the 36 instances of `examples/replicas_validate.rs`, the first level
/// decides most of a replica's periods), then the most even; where none is
/// even enough, the most even. Spreads count every ladder window from
/// `MIN_WINDOW` on, also those longer than a common period whose ladder
/// stops short of them: counting only the windows used tightened the limit
/// for decimal frequencies, and the longest replica of 7.13 / 9.71 Hz grew
/// from 0.25 to 0.50 of the run alone (same accuracy; tried and not kept).
/// Also whether that virtual run has a level that may stop it at all.
pub fn best_turns(inst: &Instance, count: u32) -> (u32, f64, bool) {
    let (_, rho) = faster_drive(inst);
    let limit = spread_limit(rho);
    (0..count)
        .map(|turns| {
            let r = Replica {
                index: 0,
                count,
                turns,
                cycle: 0,
            };
            let first = virtual_levels(inst, count, turns).trailing_zeros();
            (turns, phase::spread(r.virtual_step(rho)), first)
        })
        .min_by(|a, b| {
            // Even enough first; among those, the soonest first level.
            let key = |c: &(u32, f64, u32)| (c.1 > limit, if c.1 > limit { 0 } else { c.2 });
            key(a).cmp(&key(b)).then(a.1.total_cmp(&b.1))
        })
        .map(|(turns, spread, first)| (turns, spread, first < phase::LEVELS as u32))
        .expect("count >= 2")
}

/// The ladder levels that may stop the virtual run of `count` replicas of
/// `inst` turned by `turns` (`Replica::turns`), over their periods
/// together: none where its phases bunch as a near resonance's
/// (`phase::MAX_BUNCHING`). (Its common period, q times `count`, is left
/// out: q > 680 where the ladder is on, so it bars no level this finds.)
fn virtual_levels(inst: &Instance, count: u32, turns: u32) -> u32 {
    let r = Replica {
        index: 0,
        count,
        turns,
        cycle: 0,
    };
    let horizon = inst
        .cycles
        .saturating_sub(inst.settle)
        .saturating_mul(count);
    phase::ladder(r.virtual_step(faster_drive(inst).1), true, 0, horizon).levels
}

/// The spread a virtual run may have for a faster drive that advances by
/// `rho` ([`SPREAD_SLACK`], [`SPREAD_FLOOR`]).
fn spread_limit(rho: f64) -> f64 {
    (SPREAD_SLACK * phase::spread(rho)).max(SPREAD_FLOOR)
}

/// How `inst` splits in a batch that leaves `count` workers per
/// integration ([`count`]) under `settings`, if it does: the one rule
/// both backends follow.
pub fn split_of(inst: &Instance, settings: &Settings, count: u32) -> Option<Replica> {
    if count < 2 {
        return None;
    }
    splittable(inst, settings)
        .then(|| split(inst, settings.replicas, count))
        .flatten()
        .or_else(|| cycle_split(inst, settings, count))
}

/// The split of a splittable `inst` for a `count` from [`count`]: with
/// `Replicas::Count`, `count` replicas on their most even virtual run;
/// with `Auto`, the most replicas up to `count` whose most even virtual run
/// is spaced within [`SPREAD_SLACK`] of the instance's own (or
/// [`SPREAD_FLOOR`]); `None` (run alone) where `count` is 1 or no count
/// is even enough.
pub fn split(inst: &Instance, setting: Replicas, count: u32) -> Option<Replica> {
    let replica = |(count, turns)| Replica {
        index: 0,
        count,
        turns,
        cycle: 0,
    };
    if count < 2 {
        return None;
    }
    // A virtual run no ladder level may stop would only run on.
    if let Replicas::Count(_) = setting {
        let (turns, _, stops) = best_turns(inst, count);
        return stops.then(|| replica((count, turns)));
    }
    let (_, rho) = faster_drive(inst);
    let limit = spread_limit(rho);
    (2..=count).rev().find_map(|n| {
        let (turns, spread, stops) = best_turns(inst, n);
        (spread <= limit && stops).then(|| replica((n, turns)))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_frequency(fy: f64) -> Instance {
        let mut inst = Instance::TABLE1;
        inst.axes[1].frequency = fy;
        inst.axes[1].voltage = 100.0;
        inst.cycles = 2000;
        inst.measure = Measure::Steady {
            step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
        };
        inst
    }

    #[test]
    fn quasi_periodic_measurements_split_and_periodic_ones_do_not() {
        let settings = Settings::default();
        assert!(splittable(&two_frequency(10.0 * 2f64.sqrt()), &settings));
        // 10 against 14 Hz repeats after 5 periods: the recurrence test's.
        assert!(!splittable(&two_frequency(14.0), &settings));
        let mut window = two_frequency(10.0 * 2f64.sqrt());
        window.measure = Measure::Window;
        assert!(!splittable(&window, &settings));
    }

    #[test]
    fn auto_fills_the_idle_workers_up_to_the_cap() {
        let check = |setting, workers, jobs, expected| {
            assert_eq!(
                count(setting, workers, jobs),
                expected,
                "{setting:?} {workers} {jobs}"
            );
        };
        check(Replicas::Auto, 2, 1, 2);
        check(Replicas::Auto, 16, 1, MAX_AUTO);
        check(Replicas::Auto, 256, 36, 7);
        check(Replicas::Auto, 2, 36, 1);
        check(Replicas::Count(5), 2, 36, 5);
        check(Replicas::Count(0), 2, 1, 1);
    }

    /// Lanes that take queued jobs round the share up where at most a
    /// quarter of the lanes' worth waits: 36 instances on 256 lanes make 8
    /// each (288 jobs), 200 make 1 (2 would queue 144), 110 make 2 (3
    /// would queue 74 > 64).
    #[test]
    fn queued_lanes_round_the_share_up() {
        let check = |setting, lanes, jobs, expected| {
            assert_eq!(
                count_queued(setting, lanes, jobs),
                expected,
                "{setting:?} {lanes} {jobs}"
            );
        };
        check(Replicas::Auto, 256, 36, 8);
        check(Replicas::Auto, 256, 200, 1);
        check(Replicas::Auto, 256, 110, 2);
        check(Replicas::Auto, 256, 100, 3);
        check(Replicas::Auto, 256, 1, MAX_AUTO);
        check(Replicas::Auto, 256, 300, 1);
        check(Replicas::Count(4), 256, 36, 4);
        check(Replicas::Count(1), 256, 1, 1);
    }

    /// Replica r's faster drive starts r (rho + m) / R cycles later, so
    /// its period k starts at the virtual run's period R k + r.
    #[test]
    fn a_replica_advances_the_faster_drive() {
        let inst = two_frequency(10.0 * 2f64.sqrt());
        let rho = 2f64.sqrt() - 1.0;
        let r = |index| Replica {
            index,
            count: 8,
            turns: 4,
            cycle: 0,
        };
        let third = replica_instance(&inst, r(3));
        assert!((third.axes[1].phase - (3.0 * (rho + 4.0) / 8.0).fract()).abs() < 1e-15);
        assert_eq!(third.axes[0], inst.axes[0]);
        assert_eq!(replica_instance(&inst, Replica::NONE), inst);
    }
}

#[cfg(test)]
mod cycle_tests {
    use super::*;

    fn periodic(fy: f64, cycles: u32) -> Instance {
        let mut inst = Instance::TABLE1;
        inst.axes[0].frequency = 7.13;
        inst.axes[1].frequency = fy;
        inst.axes[1].voltage = 100.0;
        inst.cycles = cycles;
        inst.measure = Measure::Steady {
            step_tolerance: Measure::DEFAULT_STEP_TOLERANCE,
        };
        inst
    }

    /// 7.13 against 23.858 Hz repeats after 3,565 periods, near 9 / 26:
    /// no window of its ladder resolves enough phases to stop a run (its
    /// phases bunch in 26 clusters), so no phase split; 8 workers make
    /// a cycle split into 8 pieces that tile the common period; 4 make
    /// pieces of 891-892 periods, longer than 680 but shorter than the run
    /// alone's first chance to stop (q itself), and too few `max_cycles`
    /// for the run alone's recurrence leave it alone.
    #[test]
    fn a_long_common_period_is_cut_into_pieces() {
        let settings = Settings {
            replicas: Replicas::Auto,
            ..Settings::default()
        };
        let inst = periodic(23.858, 20_000);
        assert!(!splittable(&inst, &settings));
        let eight = split_of(&inst, &settings, 8).unwrap();
        assert_eq!((eight.count, eight.cycle), (8, 3565));
        let pieces: Vec<(u32, u32)> = (0..8)
            .map(|index| Replica { index, ..eight }.cycle_segment())
            .collect();
        assert_eq!(pieces[0], (0, 445));
        assert_eq!(pieces[7], (3119, 446));
        assert!(pieces.windows(2).all(|w| w[0].0 + w[0].1 == w[1].0));
        assert_eq!(pieces.iter().map(|p| p.1).sum::<u32>(), 3565);
        let four = split_of(&inst, &settings, 4).unwrap();
        assert_eq!((four.count, four.cycle), (4, 3565));
        assert_eq!(Replica { index: 3, ..four }.cycle_segment(), (2673, 892));
        assert_eq!(split_of(&periodic(23.858, 3000), &settings, 8), None);
    }

    /// Piece r is the instance with its faster drive at its phase of
    /// period s_r and `settle` plus its periods to run; the slower drive
    /// is untouched.
    #[test]
    fn a_piece_starts_at_its_period_of_the_run() {
        let inst = periodic(23.858, 20_000);
        let split = cycle_split(&inst, &Settings::default(), 8).unwrap();
        let third = replica_instance(&inst, Replica { index: 3, ..split });
        let (start, length) = Replica { index: 3, ..split }.cycle_segment();
        let rho = (23.858f64 / 7.13).fract();
        let expected = (start as f64 * rho).fract();
        assert!((third.axes[1].phase - expected).abs() < 1e-9, "{third:?}");
        assert_eq!(third.axes[0], inst.axes[0]);
        assert_eq!(third.cycles, inst.settle + length);
    }

    /// A short common period is not cut (10 against 14 Hz: 5 periods), nor
    /// is a window.
    #[test]
    fn short_common_periods_and_windows_are_not_cut() {
        let settings = Settings::default();
        let mut short = periodic(14.0, 2000);
        short.axes[0].frequency = 10.0;
        assert_eq!(cycle_split(&short, &settings, 8), None);
        let mut window = periodic(23.858, 20_000);
        window.measure = Measure::Window;
        assert_eq!(cycle_split(&window, &settings, 8), None);
    }
}

#[cfg(test)]
mod split_tests {
    use super::*;

    /// Of the eight virtual runs of 8 replicas at the golden ratio, the
    /// most even (m = 6, spread 2.03) is taken; auto takes 8 there, and
    /// at 4 replicas, whose best is 2.82 against the run's own 1.88, fewer.
    #[test]
    fn the_split_takes_the_most_even_virtual_run() {
        let mut inst = Instance::TABLE1;
        inst.axes[1].frequency = 10.0 * (1.0 + 5f64.sqrt()) / 2.0;
        inst.axes[1].voltage = 100.0;
        let (turns, spread, stops) = best_turns(&inst, 8);
        assert_eq!(turns, 6);
        assert!(stops);
        assert!((spread - 2.03).abs() < 0.01, "{spread}");
        let eight = split(&inst, Replicas::Auto, 8).unwrap();
        assert_eq!((eight.count, eight.turns), (8, 6));
        let four = split(&inst, Replicas::Auto, 4).unwrap();
        assert!(four.count < 4, "{four:?}");
        let asked = split(&inst, Replicas::Count(4), 4).unwrap();
        assert_eq!(asked.count, 4);
        assert_eq!(split(&inst, Replicas::Auto, 1), None);
    }
}
