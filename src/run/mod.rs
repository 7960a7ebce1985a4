//! A run of a scene into its result file: the output claimed, the
//! checkpoint created or replayed, the sweep driven chunk by chunk, the
//! file finished and renamed into place. `pidm run` (in `commands/run.rs`) and
//! every caller that wants a result file go through [`run_scene`].

pub mod estimate;
pub mod report;
pub mod shard;

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicI32, Ordering};
use std::time::Instant;

use anyhow::{Result, bail};

use crate::backend::{Backend, Hardware};
use crate::checkpoint::{self, Checkpoint};
use crate::output::{FileInfo, MapWriter, OutputClaim, ShardInfo};
use crate::progress::{Progress, ProgressMode};
use crate::scene::{MAP_MEMORY_BUDGET_BYTES, Scene};
use crate::sweep::{self, Plan, Record, Summary};

/// What a run produced.
pub struct RunResult {
    pub path: PathBuf,
    pub summary: Summary,
    /// This process's wall time [s].
    pub wall_time_s: f64,
    /// The wall time of every part of the run, this one and those before
    /// an interrupt (`--resume`) [s].
    pub total_wall_time_s: f64,
    pub backend: String,
    /// The records, kept only for small scenes (up to the table limit).
    pub records: Vec<Record>,
    /// Instances taken from the checkpoint of an interrupted run
    /// (`--resume`) rather than integrated by this one.
    pub from_checkpoint: u64,
    /// What the refinement did, for a scene with `[refine]`.
    pub refine: Option<crate::refine::Report>,
    /// What the stall searches found, for a scene with `[stall]`.
    pub stall: Option<crate::stall::Report>,
    /// The stall records, kept like `records` (a scene with `[stall]`).
    pub stall_records: Vec<crate::stall::StallRecord>,
}

/// The signal that stopped the run (SIGINT or SIGTERM), 0 while none did.
static STOP_SIGNAL: AtomicI32 = AtomicI32::new(0);

/// The handler of SIGINT and SIGTERM: it records the first signal and asks
/// running backends to stop. Only atomic stores, so it is
/// async-signal-safe.
extern "C" fn on_stop_signal(signal: libc::c_int) {
    let _ = STOP_SIGNAL.compare_exchange(0, signal, Ordering::SeqCst, Ordering::SeqCst);
    crate::sweep::request_interrupt();
}

/// Installs the SIGINT (Ctrl-C) and SIGTERM handler once: it asks running
/// backends to stop, and the sweep then ends without writing a result
/// file, its finished chunks kept in the checkpoint. [`stop_signal`] says
/// which signal it was, for the exit code (128 + the signal's number).
pub fn install_interrupt_handler() {
    static INSTALLED: std::sync::Once = std::sync::Once::new();
    INSTALLED.call_once(|| {
        for signal in [libc::SIGINT, libc::SIGTERM] {
            // SAFETY: a zeroed sigaction is valid (empty mask, no flags);
            // the handler only stores to atomics. A failure only means the
            // signal ends the process at once, which also leaves no output.
            unsafe {
                let mut action: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = on_stop_signal as extern "C" fn(libc::c_int) as usize;
                action.sa_flags = libc::SA_RESTART;
                libc::sigemptyset(&mut action.sa_mask);
                libc::sigaction(signal, &action, std::ptr::null_mut());
            }
        }
    });
}

/// The signal (SIGINT or SIGTERM) that asked the run to stop, if one did.
pub fn stop_signal() -> Option<i32> {
    match STOP_SIGNAL.load(Ordering::SeqCst) {
        0 => None,
        signal => Some(signal),
    }
}

/// Which integrator runs a scene's instances: every backend runs the 2-DOF
/// integrator, where an undriven axis stays exactly at rest.
pub fn variant(scene: &Scene) -> String {
    if scene.axis_ever_driven(1) {
        "2-DOF".into()
    } else {
        "2-DOF (axis y undriven everywhere, exactly at rest)".into()
    }
}

pub use crate::scope::RunScope;

/// Everything that must match for a checkpoint to be resumed: results are
/// bit-identical only on the same scene, version, precision and hardware
/// (the CPU path gives the same bits on any thread count).
fn run_identity(scene: &Scene, backend: &dyn Backend, scope: RunScope) -> String {
    let hardware = match backend.hardware() {
        Hardware::Cpu { .. } => "cpu".to_string(),
        Hardware::Gpu => backend.describe(),
    };
    format!(
        "pidm {}\nbackend {hardware}\nprecision {}\nshard {}\nverify {}\ninstances {}\nscene\n{}",
        env!("CARGO_PKG_VERSION"),
        backend.precision(),
        scope.shard.map_or("all".to_string(), |s| s.to_string()),
        scope.verify,
        scene.instance_count(),
        scene.text
    )
}

/// Runs a scene on a backend into an HDF5 file, checkpointing each
/// finished chunk beside it. On an error or an interrupt the output file
/// is not written and the checkpoint stays for `--resume`.
///
/// The way of a scene's values: the scene's [`Plan`] of instances goes to
/// the mode (plain here, `refine::run` or `stall::run`), which hands it to
/// `sweep::run`, which hands chunks to the backend and its records to the
/// writer (`output::MapWriter`).
pub fn run_scene(
    scene: &Scene,
    backend: &dyn Backend,
    out: &Path,
    keep: u64,
    scope: RunScope,
) -> Result<RunResult> {
    scene.check_memory(MAP_MEMORY_BUDGET_BYTES)?;
    if scene.refine.is_some() && scope.shard.is_some() {
        bail!(
            "--shard: the scene has [refine], whose waves choose the points to integrate from \
             the whole map, so it cannot be split into shards; run it whole, or remove \
             [refine] to shard the uniform grid"
        );
    }
    let info = file_info(scene, backend, scope);
    // The claim comes before anything else touches the output, its
    // temporary file or its checkpoint: a second run of the same output is
    // refused here, without side effects.
    let claim = OutputClaim::acquire(out)?;
    let run = Opened {
        scene,
        backend,
        identity: run_identity(scene, backend, scope),
        claim,
        info,
        scope,
        keep,
    };
    install_interrupt_handler();
    if let Some(refine) = &scene.refine {
        run_refined(&run, refine)
    } else if let Some(stall) = scene.stall {
        run_stall(&run, stall)
    } else {
        run_plain(&run)
    }
}

/// A run whose output is claimed: what every mode starts from.
struct Opened<'a> {
    scene: &'a Scene,
    backend: &'a dyn Backend,
    /// What a checkpoint must match to be resumed ([`run_identity`]).
    identity: String,
    claim: OutputClaim,
    info: FileInfo,
    scope: RunScope,
    /// Records are kept in the result up to this many instances.
    keep: u64,
}

impl Opened<'_> {
    /// The instance ranges this run computes: its shard's, or all.
    fn ranges(&self) -> Vec<Range<u64>> {
        match &self.info.shard {
            Some(shard) => shard.ranges.clone(),
            None => Plan::everything(self.scene.instance_count()),
        }
    }
}

/// The result file's description of the run: the scene's, with the
/// backend, the precision, the shard and the verification tolerance.
fn file_info(scene: &Scene, backend: &dyn Backend, scope: RunScope) -> FileInfo {
    let mut info = scene.file_info(
        backend.describe(),
        backend.precision().to_string(),
        variant(scene),
    );
    info.shard = scope
        .shard
        .map(|spec| ShardInfo::new(spec, scene.instance_count()));
    if scope.verify {
        info.verify_tolerance = Some(scene.settings.tolerance / sweep::VERIFY_TIGHTENING);
    }
    info
}

/// A scene with `[refine]`: `refine::run`, level by level.
fn run_refined(run: &Opened, refine: &crate::scene::Refine) -> Result<RunResult> {
    let scope = crate::refine::Scope {
        resume: run.scope.resume,
        chunk_size: run.scope.chunk_size,
        verify: run.scope.verify,
        progress: run
            .scope
            .progress
            .unwrap_or_else(ProgressMode::default_for_stderr),
        keep: run.keep,
    };
    let refined = crate::refine::run::run(
        run.scene,
        refine,
        run.backend,
        &run.claim,
        &run.info,
        scope,
        &run.identity,
    )?;
    Ok(RunResult {
        path: refined.path,
        summary: refined.summary,
        wall_time_s: refined.wall_time_s,
        total_wall_time_s: refined.total_wall_time_s,
        backend: run.backend.describe(),
        records: refined.records,
        from_checkpoint: refined.from_checkpoint,
        refine: Some(refined.report),
        stall: None,
        stall_records: Vec::new(),
    })
}

/// A scene with `[stall]`: `stall::run`, one search per instance.
fn run_stall(run: &Opened, stall: crate::scene::Stall) -> Result<RunResult> {
    let stalled = crate::stall::run::run(
        run.scene,
        stall,
        run.backend,
        &run.claim,
        &run.info,
        run.scope,
        &run.identity,
        &run.ranges(),
        run.keep,
    )?;
    Ok(RunResult {
        path: stalled.path,
        summary: stalled.summary,
        wall_time_s: stalled.wall_time_s,
        total_wall_time_s: stalled.total_wall_time_s,
        backend: run.backend.describe(),
        records: stalled.records,
        from_checkpoint: stalled.from_checkpoint,
        refine: None,
        stall: Some(stalled.report),
        stall_records: stalled.stall,
    })
}

/// What a plain run holds before its sweep: the records of the chunks a
/// checkpoint held (`--resume`) and the instances still to compute.
struct Started {
    checkpoint: Checkpoint,
    writer: MapWriter,
    work: Vec<Range<u64>>,
    summary: Summary,
    kept: BTreeMap<u64, Record>,
    from_checkpoint: u64,
}

/// Opens a plain run's output and checkpoint: a fresh one, or (`--resume`)
/// the journal of an interrupted run, whose chunks go to the writer again.
fn start_plain(run: &Opened, all: Vec<Range<u64>>, keep_records: bool) -> Result<Started> {
    let checkpoint_path = run.claim.checkpoint_path();
    if !run.scope.resume {
        let (checkpoint, writer) =
            checkpoint::start(&checkpoint_path, &run.identity, &run.claim, &run.info)?;
        return Ok(Started {
            checkpoint,
            writer,
            work: all,
            summary: Summary::default(),
            kept: BTreeMap::new(),
            from_checkpoint: 0,
        });
    }
    checkpoint::require(&checkpoint_path)?;
    let mut writer = MapWriter::create(&run.claim, &run.info)?;
    let mut summary = Summary::default();
    let mut kept = BTreeMap::new();
    let mut from_checkpoint = 0;
    let (checkpoint, done) =
        Checkpoint::resume(&checkpoint_path, &run.identity, &mut |start, records| {
            let end = start.checked_add(records.len() as u64);
            if !all
                .iter()
                .any(|r| r.start <= start && end.is_some_and(|e| e <= r.end))
            {
                bail!(
                    "the checkpoint {} holds instances {start}.. that this run does not \
                     compute; delete it to start over",
                    checkpoint_path.display()
                );
            }
            writer.write(start, records)?;
            from_checkpoint += records.len() as u64;
            for (k, r) in records.iter().enumerate() {
                summary.add(r, start + k as u64);
                if keep_records {
                    kept.insert(start + k as u64, *r);
                }
            }
            Ok(())
        })?;
    let work = checkpoint::missing(&all, &done);
    let count: u64 = all.iter().map(|r| r.end - r.start).sum();
    let left: u64 = work.iter().map(|r| r.end - r.start).sum();
    eprintln!(
        "pidm: resuming from {}: {} of {count} instances done, {left} to compute",
        checkpoint_path.display(),
        count - left
    );
    Ok(Started {
        checkpoint,
        writer,
        work,
        summary,
        kept,
        from_checkpoint,
    })
}

/// A plain scene: every instance of the run's ranges swept once, chunk by
/// chunk, into the writer and the checkpoint.
fn run_plain(run: &Opened) -> Result<RunResult> {
    let (scene, backend, scope) = (run.scene, run.backend, run.scope);
    let all = run.ranges();
    let count: u64 = all.iter().map(|r| r.end - r.start).sum();
    let keep_records = count <= run.keep;
    let opening = crate::profile::span(crate::profile::Phase::Open);
    let Started {
        mut checkpoint,
        mut writer,
        work,
        mut summary,
        mut kept,
        from_checkpoint,
    } = start_plain(run, all, keep_records)?;
    drop(opening);
    let instance = |i: u64| scene.instance(i);
    let plan = Plan {
        work,
        instance: &instance,
        settings: scene.settings,
        baselines: scene.baselines,
        verify: scope.verify,
    };
    let progress = Progress::new(
        scope
            .progress
            .unwrap_or_else(ProgressMode::default_for_stderr),
        count - plan.count(),
        count,
    );
    let started = Instant::now();
    let to_compute = plan.count();
    let mut computed = 0;
    let result = sweep::run(
        &plan,
        backend,
        scope.chunk_size.unwrap_or_else(|| backend.chunk_size()),
        &|n| progress.inc(n),
        &mut |start, records| {
            if keep_records {
                for (k, r) in records.iter().enumerate() {
                    kept.insert(start + k as u64, *r);
                }
            }
            writer.write(start, records)?;
            computed += records.len() as u64;
            // The last records go into the output file alone: it is
            // finished right after (trajectories, closing) and the journal
            // removed, so writing and syncing them there too (a third of a
            // second for a million) would only spare recomputing them after
            // a failure in those last moments.
            if computed < to_compute {
                checkpoint.append(start, records)?;
            }
            Ok(())
        },
    );
    let new = progress.conclude(result, &run.claim.checkpoint_path())?;
    let _finishing = crate::profile::span(crate::profile::Phase::Finish);
    summary.merge(&new);
    let wall_time_s = started.elapsed().as_secs_f64();
    // Trajectories belong to the whole scene: a shard leaves them to
    // `pidm merge`, which records them once (they are deterministic f64 CPU
    // runs, so the merged file equals a single run's).
    if scope.shard.is_none() {
        crate::trajectory::record_and_write(writer.file(), scene)?;
    }
    let (path, parts) = checkpoint.finish(writer, wall_time_s)?;
    Ok(RunResult {
        path,
        summary,
        wall_time_s,
        total_wall_time_s: parts.iter().sum(),
        backend: backend.describe(),
        records: kept.into_values().collect(),
        from_checkpoint,
        refine: None,
        stall: None,
        stall_records: Vec::new(),
    })
}

/// Default output path: `results/<name>.h5`.
pub fn default_output(scene: &Scene) -> PathBuf {
    PathBuf::from("results").join(format!("{}.h5", scene.name))
}
