//! `pidm run`: the backend chosen for the run's distinct integrations, the
//! scene run into its result file ([`crate::run::run_scene`]), and the
//! summary printed.

use std::path::PathBuf;

use anyhow::{Result, bail};

use super::format::plural;
use super::summary::print_summary;
use crate::backend::{BackendChoice, Hardware, Precision, Workload, select_backend};
use crate::laws::status::STATUS_NOT_STEADY;
use crate::laws::status::STATUS_OK;
use crate::model::Instance;
use crate::output::ShardInfo;
use crate::run::{RunScope, default_output, run_scene};
use crate::scene::Scene;

/// Options of `pidm run`.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    pub scene: PathBuf,
    pub out: Option<PathBuf>,
    pub threads: Option<usize>,
    pub backend: BackendChoice,
    pub precision: Option<Precision>,
    /// Print the per-instance table for scenes up to this many instances.
    pub table_limit: u64,
    /// Shard, resume and chunking.
    pub scope: RunScope,
}

/// `pidm run`: prints a short summary and returns the number of instances
/// that did not finish normally.
pub fn run(opts: &RunOptions) -> Result<u64> {
    // Ctrl-C and SIGTERM from here on stop the run through the checkpoint
    // (exit 130 or 143), not by ending the process mid-write.
    crate::run::install_interrupt_handler();
    let scene = Scene::load(&opts.scene)?;
    crate::profile::close_start();
    let selecting = crate::profile::span(crate::profile::Phase::Backend);
    let selected = select_backend(
        opts.backend,
        opts.precision,
        opts.threads,
        &workload(&scene, opts.scope),
    )?;
    drop(selecting);
    let backend = selected.backend();
    let out = match (&opts.out, opts.scope.shard) {
        (Some(out), _) => out.clone(),
        (None, Some(shard)) => shard.default_output(&scene.name),
        (None, None) => default_output(&scene),
    };
    if crate::output::claim::is_same_file(&out, &opts.scene) {
        bail!(
            "{} is the scene file itself; give another --out",
            out.display()
        );
    }
    eprintln!(
        "pidm: scene {:?}: {} {}{} on {}, {}, {}",
        scene.name,
        scene.instance_count(),
        plural(scene.instance_count(), "instance", "instances"),
        if scene.baselines {
            " (+ 1-DOF baselines)"
        } else {
            ""
        },
        backend.describe(),
        backend.precision(),
        scene.tolerance_text()
    );
    if let Some(shard) = opts.scope.shard {
        eprintln!(
            "pidm: shard {shard}: {} of the {} instances",
            ShardInfo::new(shard, scene.instance_count()).len(),
            scene.instance_count()
        );
    }
    let result = run_scene(&scene, backend, &out, opts.table_limit, opts.scope)?;
    crate::profile::time(crate::profile::Phase::Finish, || {
        print_summary(&scene, &result);
        // A hardware GPU's measured costs, for later `--backend auto` runs;
        // its throughput only where the integrations were the ones auto
        // estimated: all of them, in one pass.
        let as_estimated =
            result.from_checkpoint == 0 && result.refine.is_none() && result.stall.is_none();
        selected.record(as_estimated.then_some(result.summary.integration_s));
    });
    if crate::profile::enabled() {
        eprint!(
            "{}{}{}{}",
            crate::profile::table(),
            crate::laws::Law::iteration_lines(),
            crate::gpu::warps::table_lines(),
            crate::gpu::law_table_lines()
        );
    }
    // Closing a GPU device costs NVIDIA's driver 0.03-0.05 s, as long as
    // the whole integration of a 200 x 200 map. The output is complete and
    // closed here and the process ends right after this command, so the
    // device is left to the operating system, which frees it either way.
    if backend.hardware() == Hardware::Gpu {
        std::mem::forget(selected);
    }
    // "Not steady" instances finished normally and keep their estimates.
    let counts = &result.summary.status_counts;
    Ok(result.summary.instances - counts[STATUS_OK as usize] - counts[STATUS_NOT_STEADY as usize])
}

/// Largest run whose distinct integrations `pidm run` counts before
/// choosing a backend; larger runs count as their instances.
const COUNTED_RUN: u64 = 1 << 16;

/// What `--backend auto` weighs a run by: its distinct integrations (small
/// runs counted exactly, repeated instances and shared baselines once;
/// larger ones and shards by their instances, an upper bound), and the
/// integrations its probe picks from (those, or a sample of the scene's).
fn workload(scene: &Scene, scope: RunScope) -> Workload {
    let count = match scope.shard {
        Some(shard) => ShardInfo::new(shard, scene.instance_count()).len(),
        None => scene.instance_count(),
    };
    if scope.shard.is_some() || count > COUNTED_RUN {
        let (_, candidates) = crate::run::estimate::integrations(scene);
        return Workload {
            integrations: count,
            stall: scene.stall.is_some(),
            law: scene.law(),
            candidates,
            settings: scene.settings,
        };
    }
    let instances: Vec<Instance> = (0..count).map(|i| scene.instance(i)).collect();
    let candidates = crate::sweep::distinct_integrations(&instances, scene.baselines);
    Workload {
        integrations: candidates.len() as u64,
        stall: scene.stall.is_some(),
        law: scene.law(),
        candidates,
        settings: scene.settings,
    }
}
