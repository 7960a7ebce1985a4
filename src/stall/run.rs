//! A stall run into its result file: the output claimed by the caller's
//! [`OutputClaim`], the checkpoint created or replayed, wave 0 (the
//! scene's ordinary run, its maps written as any run's) and the waves of
//! the stall searches, each one batch of probes on the backend, every
//! record journalled; then the stall maps and the file finished.
//!
//! The journal holds the records of wave 0 at their flat indices and those
//! of wave `w`'s probes at `w * instances + index`. Resuming replays them
//! and reruns the searches: a search's probes depend only on its own
//! records, so they ask for the same loads, and the probes already
//! journalled are not integrated again. A shard runs the searches of its
//! own instances.

use std::collections::HashMap;
use std::ops::Range;
use std::time::Instant;

use anyhow::{Result, bail};

use super::search::{Search, StallRecord};
use crate::backend::Backend;
use crate::checkpoint::{self, Checkpoint};
use crate::measurement::status::STATUS_NO_STALL;
use crate::model::Instance;
use crate::output::{FileInfo, MapWriter, OutputClaim};
use crate::progress::{Progress, ProgressMode};
use crate::scene::{Scene, Stall};
use crate::scope::RunScope;
use crate::sweep::{self, BaselineMemo, Plan, Record, Summary};

/// The most waves a search may take after wave 0, which bounds the
/// journal's indices: the bracketing's probes and a bisection to the
/// resolution of f64 (53 halvings) with room to spare.
pub const MAX_WAVES: u64 = 128;

/// What a stall run did, for the summary.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// The stalled axis (0 = x).
    pub axis: usize,
    /// Waves after wave 0 (the longest search's).
    pub waves: u32,
    /// Probe integrations over all waves (this run's and the checkpoint's).
    pub probes: u64,
    /// Wall time of the waves' integrations [s].
    pub integration_s: f64,
    /// Instances per stall status code (index; the last gathers unknown
    /// codes).
    pub status_counts: [u64; 10],
    /// The stall load of the largest magnitude among instances with status
    /// 0 [N], and its flat index.
    pub best: Option<(f64, u64)>,
    /// The stall loads' range among instances with status 0 [N].
    pub range: Option<(f64, f64)>,
}

impl Report {
    fn add(&mut self, index: u64, r: &StallRecord) {
        self.status_counts[(r.status as usize).min(9)] += 1;
        if r.status != 0 {
            return;
        }
        let better = match self.best {
            None => true,
            Some((load, at)) => {
                r.load.abs() > load.abs() || (r.load.abs() == load.abs() && index < at)
            }
        };
        if better {
            self.best = Some((r.load, index));
        }
        self.range = Some(match self.range {
            None => (r.load, r.load),
            Some((lo, hi)) => (lo.min(r.load), hi.max(r.load)),
        });
    }

    /// Instances whose step keeps its direction under every load probed.
    pub fn no_stall(&self) -> u64 {
        self.status_counts[STATUS_NO_STALL as usize]
    }
}

/// What [`run`] produced.
pub struct Outcome {
    pub path: std::path::PathBuf,
    /// Over the main (unloaded) instances, the checkpoint's included.
    pub summary: Summary,
    pub wall_time_s: f64,
    pub total_wall_time_s: f64,
    /// The main records and the stall records, kept only for small scenes.
    pub records: Vec<Record>,
    pub stall: Vec<StallRecord>,
    pub from_checkpoint: u64,
    pub report: Report,
}

/// Runs `scene`'s instances in `all` (the whole scene or a shard's) with
/// their stall searches into `claim`'s output. `identity` names the run in
/// the checkpoint; records are kept for the caller when there are at most
/// `keep` instances.
#[allow(clippy::too_many_arguments)]
pub fn run(
    scene: &Scene,
    stall: Stall,
    backend: &dyn Backend,
    claim: &OutputClaim,
    info: &FileInfo,
    scope: RunScope,
    identity: &str,
    all: &[Range<u64>],
    keep: u64,
) -> Result<Outcome> {
    let count: u64 = all.iter().map(|r| r.end - r.start).sum();
    let checkpoint_path = claim.checkpoint_path();
    let (mut checkpoint, mut writer, mut journal) = if scope.resume {
        resume(scene, claim, info, identity, all)?
    } else {
        let (checkpoint, writer) = crate::profile::time(crate::profile::Phase::Open, || {
            crate::checkpoint::start(&checkpoint_path, identity, claim, info)
        })?;
        (checkpoint, writer, Journal::default())
    };
    // An instance counts twice: its unloaded run, and its stall search.
    let progress = Progress::new(
        scope
            .progress
            .unwrap_or_else(ProgressMode::default_for_stderr),
        journal.from_checkpoint,
        2 * count,
    );
    let started = Instant::now();
    let ctx = Searches {
        scene,
        stall,
        backend,
        scope,
        all,
        chunk: scope.chunk_size.unwrap_or_else(|| backend.chunk_size()),
        progress: &progress,
    };
    let mut report = Report {
        axis: stall.axis,
        ..Report::default()
    };
    let result = (|| -> Result<Vec<StallRecord>> {
        ctx.unloaded(&mut journal, &mut checkpoint, &mut writer)?;
        ctx.search(&mut journal, &mut checkpoint, &mut report)
    })();
    let _finishing = crate::profile::span(crate::profile::Phase::Finish);
    let stalls = progress.conclude(result, &checkpoint_path)?;
    let indices: Vec<u64> = all.iter().flat_map(|r| r.clone()).collect();
    for (&i, r) in indices.iter().zip(&stalls) {
        report.add(i, r);
    }
    let mut offset = 0;
    for range in all {
        let n = (range.end - range.start) as usize;
        writer.write_stall(
            range.start,
            &StallRecord::columns(&stalls[offset..offset + n]),
        )?;
        offset += n;
    }
    let wall_time_s = started.elapsed().as_secs_f64();
    if scope.shard.is_none() {
        crate::trajectory::record_and_write(writer.file(), scene)?;
    }
    let (path, parts) = checkpoint.finish(writer, wall_time_s)?;
    let small = count <= keep;
    Ok(Outcome {
        path,
        summary: journal.summary,
        wall_time_s,
        total_wall_time_s: parts.iter().sum(),
        records: if small {
            indices.iter().map(|i| journal.main[i]).collect()
        } else {
            Vec::new()
        },
        stall: if small { stalls } else { Vec::new() },
        from_checkpoint: journal.from_checkpoint,
        report,
    })
}

/// The records a stall run holds: wave 0's at their flat indices, the
/// probes' at `wave * instances + index`.
#[derive(Default)]
struct Journal {
    main: HashMap<u64, Record>,
    probes: HashMap<u64, Record>,
    /// Over the main (unloaded) instances.
    summary: Summary,
    /// Main records taken from the checkpoint of an interrupted run.
    from_checkpoint: u64,
}

/// Opens the output again and replays the checkpoint of an interrupted
/// stall run (`--resume`): its wave-0 records go to the writer again, its
/// probes wait for the searches that ask for them.
fn resume(
    scene: &Scene,
    claim: &OutputClaim,
    info: &FileInfo,
    identity: &str,
    all: &[Range<u64>],
) -> Result<(Checkpoint, MapWriter, Journal)> {
    let total = scene.instance_count();
    let count: u64 = all.iter().map(|r| r.end - r.start).sum();
    let ours = |i: u64| all.iter().any(|r| r.contains(&i));
    let checkpoint_path = claim.checkpoint_path();
    checkpoint::require(&checkpoint_path)?;
    let mut writer = MapWriter::create(claim, info)?;
    let mut journal = Journal::default();
    let (checkpoint, _) = Checkpoint::resume(&checkpoint_path, identity, &mut |start, got| {
        let n = got.len() as u64;
        let (wave, first) = (start / total.max(1), start % total.max(1));
        let fits = wave <= MAX_WAVES && first + n <= total && (first..first + n).all(&ours);
        if !fits {
            bail!(
                "the checkpoint {} holds instances {start}.. that this run does not \
                 compute; delete it to start over",
                checkpoint_path.display()
            );
        }
        if wave == 0 {
            writer.write(start, got)?;
        }
        for (k, r) in got.iter().enumerate() {
            let index = start + k as u64;
            if wave == 0 {
                if journal.main.insert(index, *r).is_none() {
                    journal.from_checkpoint += 1;
                    journal.summary.add(r, index);
                }
            } else {
                journal.probes.insert(index, *r);
            }
        }
        Ok(())
    })?;
    eprintln!(
        "pidm: resuming from {}: {} of {count} unloaded instances and {} stall \
         probes done; the stall searches are recomputed and go on from there",
        checkpoint_path.display(),
        journal.from_checkpoint,
        journal.probes.len()
    );
    Ok((checkpoint, writer, journal))
}

/// What the waves of a stall run share.
struct Searches<'a> {
    scene: &'a Scene,
    stall: Stall,
    backend: &'a dyn Backend,
    scope: RunScope,
    /// The instance ranges of this run (the scene's or a shard's).
    all: &'a [Range<u64>],
    /// Instances per chunk of wave 0.
    chunk: usize,
    progress: &'a Progress,
}

impl Searches<'_> {
    /// Wave 0: the scene's own run of what the journal lacks, written as
    /// any run's maps and journalled chunk by chunk.
    fn unloaded(
        &self,
        journal: &mut Journal,
        checkpoint: &mut Checkpoint,
        writer: &mut MapWriter,
    ) -> Result<()> {
        let scene = self.scene;
        let done: Vec<Range<u64>> = {
            let mut indices: Vec<u64> = journal.main.keys().copied().collect();
            indices.sort_unstable();
            checkpoint::ranges_of(&indices)
        };
        let work = checkpoint::missing(self.all, &done);
        let instance = |i: u64| scene.instance(i);
        let plan = Plan {
            work,
            instance: &instance,
            settings: scene.settings,
            baselines: scene.baselines,
            verify: self.scope.verify,
        };
        let mut memo = BaselineMemo::default();
        let main = &mut journal.main;
        let new = sweep::run_with_memo(
            &plan,
            self.backend,
            self.chunk,
            &|n| self.progress.inc(n),
            &mut |start, got| {
                writer.write(start, got)?;
                for (k, r) in got.iter().enumerate() {
                    main.insert(start + k as u64, *r);
                }
                // Unlike a plain run's last chunk, every chunk of wave 0
                // is journalled: the waves come after it.
                checkpoint.append(start, got)
            },
            &mut memo,
        )?;
        journal.summary.merge(&new);
        Ok(())
    }

    /// The searches, one per instance of ours in flat-index order, wave by
    /// wave until every one has ended.
    fn search(
        &self,
        journal: &mut Journal,
        checkpoint: &mut Checkpoint,
        report: &mut Report,
    ) -> Result<Vec<StallRecord>> {
        let indices: Vec<u64> = self.all.iter().flat_map(|r| r.clone()).collect();
        let mut searches: Vec<Search> = indices
            .iter()
            .map(|&i| {
                let rec = journal.main.get(&i).expect("wave 0 ran every instance");
                let inst = self.scene.instance(i);
                Search::new(
                    rec.step[self.stall.axis],
                    rec.status,
                    super::room(&inst, self.stall.axis),
                    self.stall.tolerance,
                )
            })
            .collect();
        let resolved =
            |searches: &[Search]| searches.iter().filter(|s| s.result().is_some()).count();
        let before = resolved(&searches) as u64;
        self.progress.inc(before);
        let (mut probes_asked, mut integration_s) = (0, 0.0);
        let waves = super::waves(&mut searches, &mut |wave, asked| {
            probes_asked += asked.len() as u64;
            let base = wave as u64 * self.scene.instance_count();
            let loads: HashMap<u64, f64> = asked
                .iter()
                .map(|&(k, load)| (base + indices[k], load))
                .collect();
            integration_s += self.probe_wave(base, &loads, &mut journal.probes, checkpoint)?;
            Ok(asked
                .iter()
                .map(|&(k, _)| {
                    let r = &journal.probes[&(base + indices[k])];
                    (r.step[self.stall.axis], r.status)
                })
                .collect())
        })?;
        self.progress.inc(resolved(&searches) as u64 - before);
        report.waves = waves;
        report.probes = probes_asked;
        report.integration_s = integration_s;
        Ok(searches
            .iter()
            .map(|s| s.result().expect("the waves end every search"))
            .collect())
    }

    /// Integrates one wave's probes that the journal lacks (journal index
    /// `j` = `base + instance`, at load `loads[j]` [N]) as one batch, each
    /// journalled; the wall time of the integration [s].
    fn probe_wave(
        &self,
        base: u64,
        loads: &HashMap<u64, f64>,
        probes: &mut HashMap<u64, Record>,
        checkpoint: &mut Checkpoint,
    ) -> Result<f64> {
        let mut missing: Vec<u64> = loads
            .keys()
            .copied()
            .filter(|j| !probes.contains_key(j))
            .collect();
        missing.sort_unstable();
        if missing.is_empty() {
            return Ok(0.0);
        }
        let probe = |j: u64| -> Instance {
            let mut inst = self.scene.instance(j - base);
            inst.mechanism.load[self.stall.axis] = loads[&j];
            inst
        };
        let plan = Plan {
            work: checkpoint::ranges_of(&missing),
            instance: &probe,
            settings: self.scene.settings,
            baselines: false,
            verify: self.scope.verify,
        };
        let wave_started = Instant::now();
        // One batch: the whole wave is one chunk.
        let result = sweep::run_with_memo(
            &plan,
            self.backend,
            missing.len(),
            &|_| {},
            &mut |start, got| {
                for (k, r) in got.iter().enumerate() {
                    probes.insert(start + k as u64, *r);
                }
                checkpoint.append_unsynced(start, got)
            },
            &mut BaselineMemo::default(),
        );
        // What finished before an interrupt or error is kept.
        let synced = checkpoint.sync();
        result?;
        synced?;
        Ok(wave_started.elapsed().as_secs_f64())
    }
}
