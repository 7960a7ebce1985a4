//! `pidm check`'s cost estimate: a short probe that integrates a few
//! instances of the scene on the CPU path and scales their measured cost
//! to the whole run.
//!
//! A nominal rate (simulated seconds per wall second) misjudges a scene by
//! orders of magnitude: the cost of a simulated second grows with the
//! drive frequency and the stage's stiffness, and a steady measurement
//! usually stops long before its `max_cycles`, so the simulated time is
//! only an upper bound. The probe measures instead: it integrates up to
//! [`PROBE_MAX`] of the scene's distinct integrations, evenly spread over
//! it, on every core for at most about [`PROBE_BUDGET_S`] seconds, each
//! one to its end (so a steady one stops where the run would), but at
//! most [`PROBE_PERIODS`] periods: one that would run longer is charged
//! its cost per period times its `cycles` (`max_cycles`), and the
//! estimate is then an upper bound. The probe's cost per integration,
//! times the run's distinct integrations, over the cores the probe's
//! threads had, is the estimate; a probe of every integration of a small
//! scene was the run itself, and its wall time is the estimate.

use crate::backend::Workload;
use crate::model::{AXES, Instance, Measure};
use crate::scene::Scene;
use crate::sweep::distinct_integrations;

pub use crate::backend::probe::{
    NOMINAL_SIMULATED_PER_CORE, PROBE_BUDGET_S, PROBE_CUTOFF_S, PROBE_MAX, PROBE_PERIODS, Probe,
    cpu_sweep_s, probe_instances,
};

/// What recording one trajectory sample costs [s]: per sampled run (the
/// instance, and each 1-DOF baseline beside it), integration and writing
/// together. Measured with `sweeps/paper.toml` on the 2-core build
/// machine: 5 trajectories with baselines, 20,000 samples per run, 0.08 s.
pub const TRAJECTORY_S_PER_SAMPLE: f64 = 3e-7;

/// What a run costs besides its integrations [s]: starting the process,
/// creating and closing the result file (a one-instance run takes 0.01 s
/// on the 2-core build machine).
pub const RUN_OVERHEAD_S: f64 = 0.01;

/// The cost of recording a scene's trajectories [s]: each runs as long as
/// its instance (a steady one for the probe's mean periods, at most its
/// `max_cycles`), sampled `trajectory_samples_per_cycle` times a period,
/// with its 1-DOF baselines beside it when the scene has them.
pub fn trajectories_s(scene: &Scene, probe: &Probe) -> f64 {
    let runs = if scene.baselines { 1 + AXES } else { 1 } as f64;
    scene
        .trajectories
        .iter()
        .map(|t| {
            let inst = scene.instance(t.index);
            let periods = match inst.measure {
                Measure::Window => inst.cycles as f64,
                Measure::Steady { .. } => probe.mean_periods.clamp(1.0, inst.cycles as f64),
            };
            periods * scene.trajectory_samples_per_cycle as f64 * runs * TRAJECTORY_S_PER_SAMPLE
        })
        .sum()
}

/// Scenes with more instances than this are probed on a sample of evenly
/// spaced instances and their baselines rather than on every distinct
/// integration.
const COUNTED: u64 = 1 << 16;

/// The integrations a run computes (exact up to `COUNTED` instances,
/// else the instances and the distinct baselines of a sample), and the
/// candidates the probe picks from (every distinct integration, or those
/// of the sample).
pub fn integrations(scene: &Scene) -> (u64, Vec<Instance>) {
    let count = scene.instance_count();
    if count <= COUNTED {
        let instances: Vec<Instance> = (0..count).map(|i| scene.instance(i)).collect();
        let all = distinct_integrations(&instances, scene.baselines);
        return (all.len() as u64, all);
    }
    let sample: Vec<Instance> = (0..1024u64)
        .map(|k| scene.instance(k * count / 1024 + count / 2048))
        .collect();
    let mut baselines = std::collections::HashSet::new();
    if scene.baselines {
        for inst in &sample {
            for axis in 0..AXES {
                let base = inst.baseline(axis);
                if base != *inst {
                    baselines.insert(base.key());
                }
            }
        }
    }
    let candidates = distinct_integrations(&sample, scene.baselines);
    (count + baselines.len() as u64, candidates)
}

/// Probes the scene's cost on the CPU path (see the module documentation)
/// with a pool of `threads` threads. Returns the distinct integrations of
/// the run and what the probe measured.
pub fn probe(scene: &Scene, threads: usize) -> (u64, Probe) {
    let (count, candidates) = integrations(scene);
    let probe = probe_instances(&candidates, &scene.settings, threads, PROBE_MAX);
    (count, probe)
}

/// What `--backend auto` weighs a whole scene by: its integrations and the
/// candidates of its probe.
pub fn workload(scene: &Scene) -> Workload {
    let (integrations, candidates) = integrations(scene);
    Workload {
        integrations,
        stall: scene.stall.is_some(),
        law: scene.law(),
        candidates,
        settings: scene.settings,
    }
}
