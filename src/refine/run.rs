//! A refined run into its result file: the output claimed by the caller's
//! [`OutputClaim`], the checkpoint created or replayed, the waves run with
//! each batch a sweep of finest-grid indices (every finished chunk
//! journalled), the raster interpolated and the file finished.
//!
//! Resuming replays the journal's records into the store and reruns the
//! waves: they are deterministic given the records, so they ask for the
//! same points, and those already integrated are not integrated again.

use std::time::Instant;

use anyhow::{Result, bail};

use super::grid::FineGrid;
use super::interpolate;
use super::output;
use super::rule::Sample;
use super::waves::{self, LevelStats, Options};
use crate::backend::Backend;
use crate::checkpoint::Checkpoint;
use crate::model::Instance;
use crate::output::{FileInfo, MapWriter, OutputClaim};
use crate::progress::{Progress, ProgressMode};
use crate::scene::{Refine, Scene};
use crate::sweep::{self, BaselineMemo, Plan, Record, Summary};

/// How the caller runs the refinement (`crate::run::RunScope`'s part that
/// applies).
#[derive(Clone, Copy, Debug)]
pub struct Scope {
    pub resume: bool,
    pub chunk_size: Option<usize>,
    pub verify: bool,
    pub progress: ProgressMode,
    /// Keep the raster's records for the caller when the grid has at most
    /// this many points.
    pub keep: u64,
}

/// What a refined run did, for the summary.
#[derive(Clone, Debug)]
pub struct Report {
    /// Points of the finest grid.
    pub points: u64,
    /// Points integrated (this run and the checkpoint's).
    pub integrated: u64,
    /// Per level, from 0 (the coarse grid).
    pub levels: Vec<LevelStats>,
}

/// What [`run`] produced.
pub struct Outcome {
    pub path: std::path::PathBuf,
    /// Over the integrated points, the checkpoint's included.
    pub summary: Summary,
    pub wall_time_s: f64,
    pub total_wall_time_s: f64,
    /// The raster's records, kept only for small grids.
    pub records: Vec<Record>,
    pub from_checkpoint: u64,
    pub report: Report,
}

/// Runs a refined scene (its grid is the finest grid) into `claim`'s
/// output. `identity` names the run in the checkpoint.
pub fn run(
    scene: &Scene,
    refine: &Refine,
    backend: &dyn Backend,
    claim: &OutputClaim,
    info: &FileInfo,
    scope: Scope,
    identity: &str,
) -> Result<Outcome> {
    let grid = FineGrid::new(refine.coarse, refine.levels);
    let count = grid.len();
    if scene.instance_count() != count as u64 {
        bail!("internal: the refined scene's grid is not its finest grid");
    }
    let checkpoint_path = claim.checkpoint_path();
    let (mut checkpoint, mut writer, journal) = if scope.resume {
        resume(claim, info, identity, count)?
    } else {
        let (checkpoint, writer) = crate::profile::time(crate::profile::Phase::Open, || {
            crate::checkpoint::start(&checkpoint_path, identity, claim, info)
        })?;
        (checkpoint, writer, Journal::new(count))
    };
    let Journal {
        mut records,
        mut summary,
        from_checkpoint,
    } = journal;

    let baselines = scene.baselines;
    let known: Vec<Option<Sample>> = records
        .iter()
        .map(|r| r.as_ref().map(|r| Sample::of_record(r, baselines)))
        .collect();
    let instance = |i: u64| scene.instance(i);
    let chunk = scope.chunk_size.unwrap_or_else(|| backend.chunk_size());
    let mut memo = BaselineMemo::default();
    let started = Instant::now();
    let opts = Options::standard(refine.tolerance, baselines);
    // Records journalled since the last sync: the journal is synced once
    // per `chunk` records, as a uniform run syncs once per chunk, not once
    // per batch (a level's small batches would each pay a sync), and on an
    // interrupt or error; the last records are not synced at all, since the
    // finished file follows at once and the journal is removed.
    let mut unsynced = 0;
    // One progress over the finest grid: it counts the integrated points
    // and jumps to the whole grid when the waves are done (the rest is
    // interpolated then).
    let progress = Progress::new(scope.progress, from_checkpoint, count as u64);
    let mut integrate = |indices: &[u64]| -> Result<Vec<Sample>> {
        // One sweep per chunk, so that the chunk's scattered ranges (one
        // journal entry each) are written to the checkpoint together.
        for part in indices.chunks(chunk.max(1)) {
            let plan = Plan {
                work: crate::checkpoint::ranges_of(part),
                instance: &instance,
                settings: scene.settings,
                baselines,
                verify: scope.verify,
            };
            let result = sweep::run_with_memo(
                &plan,
                backend,
                part.len(),
                &|n| progress.inc(n),
                &mut |start, got| {
                    for (k, r) in got.iter().enumerate() {
                        records[start as usize + k] = Some(*r);
                    }
                    checkpoint.append_unsynced(start, got)
                },
                &mut memo,
            );
            let result = synced_every(&mut checkpoint, &mut unsynced, part.len(), chunk, result);
            summary.merge(&result?);
        }
        Ok(samples(&records, indices, baselines))
    };
    let refinement = progress.conclude(
        waves::refine(grid, &opts, known, &mut integrate),
        &checkpoint_path,
    )?;
    let (mut raster, inferred) = interpolate::raster(&refinement, &records);
    let integrated = inferred.iter().filter(|&&m| m == 0).count() as u64;
    let exact_baselines = baselines
        && inferred_baselines(
            scene,
            backend,
            &mut memo,
            &mut raster,
            &inferred,
            integrated,
        )?;
    let _finishing = crate::profile::span(crate::profile::Phase::Finish);
    writer.write(0, &raster)?;
    writer.write_inferred(&inferred)?;
    output::write_group(writer.file(), refine, &refinement, exact_baselines)?;
    let wall_time_s = started.elapsed().as_secs_f64();
    crate::trajectory::record_and_write(writer.file(), scene)?;
    let (path, parts) = checkpoint.finish(writer, wall_time_s)?;
    Ok(Outcome {
        path,
        summary,
        wall_time_s,
        total_wall_time_s: parts.iter().sum(),
        records: if count as u64 <= scope.keep {
            raster
        } else {
            Vec::new()
        },
        from_checkpoint,
        report: Report {
            points: count as u64,
            integrated,
            levels: refinement.stats,
        },
    })
}

/// The records of a refined run's finest grid so far (`None`: not
/// integrated yet), with the summary of those taken from a checkpoint.
struct Journal {
    records: Vec<Option<Record>>,
    summary: Summary,
    from_checkpoint: u64,
}

impl Journal {
    /// Nothing integrated yet on a finest grid of `count` points.
    fn new(count: usize) -> Journal {
        Journal {
            records: vec![None; count],
            summary: Summary::default(),
            from_checkpoint: 0,
        }
    }
}

/// Opens the output again and replays the checkpoint of an interrupted
/// refined run (`--resume`) on a finest grid of `count` points.
fn resume(
    claim: &OutputClaim,
    info: &FileInfo,
    identity: &str,
    count: usize,
) -> Result<(Checkpoint, MapWriter, Journal)> {
    let checkpoint_path = claim.checkpoint_path();
    crate::checkpoint::require(&checkpoint_path)?;
    let writer = MapWriter::create(claim, info)?;
    let mut journal = Journal::new(count);
    let (checkpoint, _) = Checkpoint::resume(&checkpoint_path, identity, &mut |start, got| {
        let end = start.checked_add(got.len() as u64);
        if end.is_none_or(|e| e > count as u64) {
            bail!(
                "the checkpoint {} holds instances {start}.. that this run does not \
                 compute; delete it to start over",
                checkpoint_path.display()
            );
        }
        for (k, r) in got.iter().enumerate() {
            let index = start + k as u64;
            if journal.records[index as usize].replace(*r).is_none() {
                journal.from_checkpoint += 1;
                journal.summary.add(r, index);
            }
        }
        Ok(())
    })?;
    eprintln!(
        "pidm: resuming from {}: {} of the finest grid's {count} points \
         integrated; the waves are recomputed and go on from there",
        checkpoint_path.display(),
        journal.from_checkpoint
    );
    Ok((checkpoint, writer, journal))
}

/// The inferred points' 1-DOF baselines, integrated where they are few (at
/// most a tenth of the `integrated` points: a V_x by V_y map has one per
/// grid line and axis), so that their coupling regimes compare the
/// interpolated 2-DOF step with the exact 1-DOF one; interpolated
/// otherwise (a baseline that depends on both axes). True where they were
/// integrated into `raster`.
fn inferred_baselines(
    scene: &Scene,
    backend: &dyn Backend,
    memo: &mut BaselineMemo,
    raster: &mut [Record],
    inferred: &[u8],
    integrated: u64,
) -> Result<bool> {
    let points: Vec<usize> = (0..raster.len()).filter(|&k| inferred[k] == 1).collect();
    let instances: Vec<Instance> = points.iter().map(|&k| scene.instance(k as u64)).collect();
    let most = (integrated / 10) as usize;
    Ok(
        match sweep::baselines_of(&instances, backend, &scene.settings, memo, most)? {
            Some(found) => {
                for (&k, axes) in points.iter().zip(found) {
                    raster[k].baseline_step = axes.map(|(step, _)| step);
                    raster[k].baseline_status = axes[0].1.max(axes[1].1);
                }
                true
            }
            None => false,
        },
    )
}

/// The journal synced once `unsynced` (grown by `n`) reaches `chunk`
/// records, and after an interrupt or error (what finished before it is
/// kept); `result` passed on.
fn synced_every(
    checkpoint: &mut Checkpoint,
    unsynced: &mut usize,
    n: usize,
    chunk: usize,
    result: Result<Summary>,
) -> Result<Summary> {
    *unsynced += n;
    match result {
        Ok(s) if *unsynced < chunk => Ok(s),
        Ok(s) => {
            *unsynced = 0;
            checkpoint.sync().map(|()| s)
        }
        Err(e) => {
            let _ = checkpoint.sync();
            Err(e)
        }
    }
}

/// The samples the waves judge, of the swept points `indices`.
fn samples(records: &[Option<Record>], indices: &[u64], baselines: bool) -> Vec<Sample> {
    indices
        .iter()
        .map(|&i| {
            Sample::of_record(
                records[i as usize]
                    .as_ref()
                    .expect("a swept point has its record"),
                baselines,
            )
        })
        .collect()
}
