//! The probe: a few of a run's integrations on the CPU path, each to its
//! end or to [`PROBE_PERIODS`] periods, timed, and what their cost says
//! of the whole run's ([`cpu_sweep_s`]). `pidm check`'s estimate
//! ([`crate::run::estimate`]) and `--backend auto`'s choice
//! ([`crate::backend::cost`]) both stand on it; it knows instances, not
//! scenes or sweeps.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use crate::laws::Settings;
use crate::laws::status::STATUS_NOT_STEADY;
use crate::laws::{Law, run_until};
use crate::model::{Instance, Measure};

/// At most this many integrations are probed.
pub const PROBE_MAX: usize = 256;

/// The probe starts no integration after this many seconds.
pub const PROBE_BUDGET_S: f64 = 0.4;

/// A probed integration still running after this many seconds is cut off
/// and charged the nominal rate instead.
pub const PROBE_CUTOFF_S: f64 = 1.0;

/// A probed integration runs at most this many scene periods; beyond, its
/// cost is scaled up to its `cycles`.
pub const PROBE_PERIODS: u32 = 200;

/// Simulated seconds per wall second per core charged to a probed
/// integration cut off after [`PROBE_CUTOFF_S`] (and to none else): the
/// paper scene's rate on the 2-core build machine, a lower rate than most
/// scenes reach.
pub const NOMINAL_SIMULATED_PER_CORE: f64 = 300.0;

/// A probe shorter than this [s] does not measure how many cores its
/// threads had.
const MEASURABLE_S: f64 = 0.02;

/// The wall time of a run's `integrations` on the CPU path [s], from the
/// probe: its cost per integration times the integrations, over the cores
/// the probe's threads had (fewer than the threads where other work shares
/// the machine), and no more cores than integrations; a probe of every
/// integration, each to its end, was the run itself, and its wall time is
/// the estimate. `pidm check` and `--backend auto` both estimate so.
///
/// A scene whose steady measurements split into replicas
/// (`crate::replicas`) spreads its integrations over the threads they
/// leave idle: a chain of replicas costs about the integration's
/// core-seconds over its replicas (each settles on its own, its share
/// of the periods is a little more than its fraction).
pub fn cpu_sweep_s(integrations: u64, probe: &Probe) -> f64 {
    let core_seconds = probe.mean_core_s * integrations as f64;
    let replicas = match probe.splittable {
        true => crate::replicas::count(probe.replicas, probe.threads, integrations as usize),
        false => 1,
    } as f64;
    let spread = match replicas > 1.0 {
        true => (integrations as f64 * replicas).clamp(1.0, probe.threads.max(1) as f64),
        false => (integrations as f64).clamp(1.0, probe.parallelism.max(1.0)),
    };
    let whole = probe.integrations as u64 == integrations
        && probe.scaled + probe.cut == 0
        && replicas == 1.0;
    if whole {
        probe.wall_s
    } else {
        core_seconds / spread
    }
}

/// What the probe measured.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Probe {
    /// Integrations probed.
    pub integrations: usize,
    /// Of them, those that would run past [`PROBE_PERIODS`] periods and
    /// were scaled up to their `cycles`.
    pub scaled: usize,
    /// Of them, those cut off after [`PROBE_CUTOFF_S`].
    pub cut: usize,
    /// Mean scene periods a probed integration ran (scaled ones counted at
    /// their `cycles`).
    pub mean_periods: f64,
    /// Mean cost of a probed integration [core-seconds], scaled ones at
    /// their `cycles`.
    pub mean_core_s: f64,
    /// Wall time the probe took [s].
    pub wall_s: f64,
    /// The cores the probe's threads had on average: the time they spent
    /// integrating over its wall time, at least 1 (less than the threads
    /// where other work shares the machine).
    pub parallelism: f64,
    /// The probe's threads, the scene's replicas setting, and whether a
    /// probed integration splits into replicas (`crate::replicas`).
    pub threads: usize,
    pub replicas: crate::laws::Replicas,
    pub splittable: bool,
}

/// One probed integration.
struct Probed {
    /// What it is charged [core-seconds]: its cost to the end of the run.
    cost: f64,
    /// What it took [s].
    wall: f64,
    /// Scene periods it runs (charged ones at their `cycles`).
    periods: f64,
    /// Scaled up from [`PROBE_PERIODS`] to its `cycles`.
    scaled: bool,
    /// Cut off after [`PROBE_CUTOFF_S`].
    cut: bool,
}

/// The cost of one integration, probed, or `None` when the probe's budget
/// was spent before it started.
fn probe_one(
    inst: &Instance,
    settings: &Settings,
    started: Instant,
    cut: &AtomicBool,
) -> Option<Probed> {
    if started.elapsed().as_secs_f64() > PROBE_BUDGET_S {
        return None;
    }
    let capped = Instance {
        cycles: inst.cycles.min(PROBE_PERIODS.max(inst.settle + 1)),
        ..*inst
    };
    let begin = Instant::now();
    let stop = || cut.load(Ordering::Relaxed);
    // The run the sweep will make: with the backward travel where asked.
    let run = if settings.backward {
        Law::run_with_variation_until(&capped, settings, stop).map(|(run, _)| run)
    } else {
        run_until(&capped, settings, stop)
    };
    let wall = begin.elapsed().as_secs_f64();
    let Some(run) = run else {
        // Cut off: charged at the nominal rate, and at least what it took.
        let nominal = inst.duration() / NOMINAL_SIMULATED_PER_CORE;
        return Some(Probed {
            cost: nominal.max(wall),
            wall,
            periods: inst.cycles as f64,
            scaled: false,
            cut: true,
        });
    };
    let measured = crate::measurement::reduce(&capped, &run);
    let periods = measured.periods.max(1) as f64;
    let ran_out = capped.cycles < inst.cycles
        && match capped.measure {
            Measure::Window => true,
            Measure::Steady { .. } => measured.status == STATUS_NOT_STEADY,
        };
    let scale = if ran_out {
        inst.cycles as f64 / periods
    } else {
        1.0
    };
    Some(Probed {
        cost: wall * scale,
        wall,
        periods: periods * scale,
        scaled: ran_out,
        cut: false,
    })
}

/// Probes the cost of at most `max` of `candidates` (a run's distinct
/// integrations, or a sample of them: [`crate::run::estimate::integrations`]) on the CPU path
/// with a pool of `threads` threads, within [`PROBE_BUDGET_S`]. `pidm
/// check` probes [`PROBE_MAX`]; `--backend auto` fewer for a small run, so
/// that the probe stays a small part of it.
pub fn probe_instances(
    candidates: &[Instance],
    settings: &Settings,
    threads: usize,
    max: usize,
) -> Probe {
    let max = max.max(1);
    let k = candidates.len().min(max);
    // Every candidate when there are few; else spread by the golden ratio,
    // so that the ones probed before the budget ran out (any stretch of
    // the list, as the threads split it) are spread over the whole scene.
    let picked: Vec<Instance> = if candidates.len() <= max {
        candidates.to_vec()
    } else {
        let golden = 0.5 * (5f64.sqrt() - 1.0);
        (0..k)
            .map(|j| {
                let at = (0.5 + j as f64 * golden).fract() * candidates.len() as f64;
                candidates[(at as usize).min(candidates.len() - 1)]
            })
            .collect()
    };
    let cut = Arc::new(AtomicBool::new(false));
    // The watchdog cuts the probe off at its limit, and wakes as soon as
    // the probe drops `done` (a probe of a cheap scene takes milliseconds:
    // it must not wait for a polling interval).
    let (done, finished) = std::sync::mpsc::channel::<()>();
    let watchdog = {
        let cut = Arc::clone(&cut);
        std::thread::spawn(move || {
            let limit = Duration::from_secs_f64(PROBE_BUDGET_S + PROBE_CUTOFF_S);
            if let Err(std::sync::mpsc::RecvTimeoutError::Timeout) = finished.recv_timeout(limit) {
                cut.store(true, Ordering::Relaxed);
            }
        })
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build();
    // The threads started before the clock: a run's pool is warm too.
    if let Ok(pool) = &pool {
        pool.broadcast(|_| ());
    }
    let started = Instant::now();
    let run = || -> Vec<Probed> {
        picked
            .par_iter()
            .with_max_len(1)
            .filter_map(|inst| probe_one(inst, settings, started, &cut))
            .collect()
    };
    let results = match pool {
        Ok(pool) => pool.install(run),
        Err(_) => run(),
    };
    let wall_s = started.elapsed().as_secs_f64();
    drop(done);
    let _ = watchdog.join();
    let n = results.len().max(1) as f64;
    let busy: f64 = results.iter().map(|r| r.wall).sum();
    Probe {
        integrations: results.len(),
        scaled: results.iter().filter(|r| r.scaled).count(),
        cut: results.iter().filter(|r| r.cut).count(),
        mean_periods: results.iter().map(|r| r.periods).sum::<f64>() / n,
        mean_core_s: results.iter().map(|r| r.cost).sum::<f64>() / n,
        wall_s,
        // A probe shorter than this is mostly the pool's own overhead and
        // tells nothing of how busy the cores are: it counts them all.
        parallelism: if wall_s < MEASURABLE_S {
            threads.max(1) as f64
        } else {
            (busy / wall_s).clamp(1.0, threads.max(1) as f64)
        },
        threads: threads.max(1),
        replicas: settings.replicas,
        splittable: picked
            .iter()
            .any(|inst| crate::replicas::may_split(inst, settings)),
    }
}
