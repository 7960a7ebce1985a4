//! The chunk loop: a [`Plan`]'s instances run chunk by chunk, each
//! chunk's distinct integrations once (`--verify` reruns them tighter),
//! records made and handed to the sink, and baselines remembered for the
//! chunks after it.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::Result;
use rayon::prelude::*;

use super::dedup::{JobRef, Jobs, digest};
use super::{
    BaselineMemo, Outcome, Record, STATUS_UNCONVERGED, Summary, interrupt_requested, record,
};
use crate::backend::{Backend, Staged};
use crate::laws::Settings;
use crate::laws::status::STATUS_OK;
use crate::model::{AXES, Instance};
use crate::profile::{self, Phase};

/// How far a step may move under a 100 times tighter tolerance before
/// `--verify` calls the instance unconverged [m per drive cycle]: the
/// project's accuracy bar of 0.001 um (docs/model.md).
pub const VERIFY_ALLOWANCE_M: f64 = 1e-9;

/// How much tighter than the scene's the tolerance of a `--verify` rerun
/// is.
pub const VERIFY_TIGHTENING: f64 = 100.0;

/// Baseline outcomes kept from one chunk for the next, at most: about
/// 200 MiB at 208 bytes an entry. The bound is checked between chunks, so a
/// chunk's own distinct baselines come on top (two per instance at most,
/// 2,000 on a 1000 x 1000 map).
const MAX_REMEMBERED_BASELINES: usize = 1 << 20;

/// Where a sweep's finished chunks go, `sink(first_index, records)`: the
/// HDF5 writer and the checkpoint, on the pipeline's writer thread.
pub type Sink<'a> = dyn FnMut(u64, &[Record]) -> Result<()> + Send + 'a;

/// Marks `outcome` unconverged when its tighter rerun `check` finished and
/// moved a step by more than the allowance. A check that did not finish
/// (a tighter tolerance can underflow, status 3) leaves the outcome as it
/// is: it neither confirms nor refutes it.
fn verify(inst: &Instance, outcome: &mut Outcome, check: &Outcome) {
    if outcome.status != STATUS_OK || check.status != STATUS_OK {
        return;
    }
    let moved = (0..AXES).any(|i| {
        let a = outcome.step(inst, i);
        let b = check.step(inst, i);
        (a - b).abs() > VERIFY_ALLOWANCE_M
    });
    if moved {
        *outcome = Outcome {
            status: STATUS_UNCONVERGED,
            steps: outcome.steps,
            periods: outcome.periods,
            on_cpu: outcome.on_cpu,
            graze: outcome.graze,
            checked: outcome.checked,
            ..Outcome::default()
        };
    }
}

/// Everything a sweep needs to know about its instances.
pub struct Plan<'a> {
    /// The flat instance indices to run: disjoint ranges in ascending
    /// order (all of `0..count` for a whole run; fewer for a shard or a
    /// resumed run).
    pub work: Vec<Range<u64>>,
    pub instance: &'a (dyn Fn(u64) -> Instance + Sync),
    pub settings: Settings,
    pub baselines: bool,
    /// Rerun every integration with a [`VERIFY_TIGHTENING`] times tighter
    /// tolerance and mark the instances whose steps move by more than
    /// [`VERIFY_ALLOWANCE_M`] with [`STATUS_UNCONVERGED`].
    pub verify: bool,
}

impl Plan<'_> {
    /// The work list of a whole run of `count` instances.
    #[allow(clippy::single_range_in_vec_init)]
    pub fn everything(count: u64) -> Vec<Range<u64>> {
        if count == 0 {
            Vec::new()
        } else {
            vec![0..count]
        }
    }

    /// How many instances the plan runs.
    pub fn count(&self) -> u64 {
        self.work.iter().map(|r| r.end - r.start).sum()
    }
}

/// Splits the work list into chunks of at most `chunk` instances, each a
/// list of contiguous segments.
fn chunks(work: &[Range<u64>], chunk: u64) -> Vec<Vec<Range<u64>>> {
    let mut out = Vec::new();
    let mut current: Vec<Range<u64>> = Vec::new();
    let mut filled = 0;
    for range in work {
        let mut start = range.start;
        while start < range.end {
            let take = (chunk - filled).min(range.end - start);
            current.push(start..start + take);
            filled += take;
            start += take;
            if filled == chunk {
                out.push(std::mem::take(&mut current));
                filled = 0;
            }
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// Runs every instance of the plan in chunks, in index order, calling
/// `sink(first_index, records)` for each finished chunk. `progress(n)` is
/// called as instances finish (baselines count as part of their instance);
/// when an interrupt is requested ([`request_interrupt`](super::request_interrupt)) the sweep ends
/// with an error and hands nothing more to the sink.
pub fn run(
    plan: &Plan,
    backend: &dyn Backend,
    chunk: usize,
    progress: &(dyn Fn(u64) + Sync),
    sink: &mut Sink,
) -> Result<Summary> {
    run_with_memo(
        plan,
        backend,
        chunk,
        progress,
        sink,
        &mut BaselineMemo::default(),
    )
}

/// [`run`], with the baselines of earlier sweeps of the same scene in
/// `baselines_done` (and this sweep's added to it). Chunks run in a
/// pipeline ([`pipelining`]).
pub fn run_with_memo(
    plan: &Plan,
    backend: &dyn Backend,
    chunk: usize,
    progress: &(dyn Fn(u64) + Sync),
    sink: &mut Sink,
    baselines_done: &mut BaselineMemo,
) -> Result<Summary> {
    run_chunks(
        plan,
        backend,
        chunk,
        progress,
        sink,
        baselines_done,
        pipelining(),
    )
}

/// Whether sweeps overlap their chunks: the backend integrates chunk k on
/// a thread of its own while this thread writes chunk k-1's records and
/// expands chunk k+1's instances. On by default; `PIDM_PIPELINE=0` runs
/// the chunks one after another, for measuring what the overlap saves.
/// The results are the same either way, bit for bit: every chunk hands
/// the backend the same jobs (tested).
pub fn pipelining() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| crate::knob::knob("PIDM_PIPELINE", 1u8, |n| *n <= 1, "0 or 1") == 1)
}

/// A chunk ready for the backend: its instances and distinct jobs.
struct Prepared {
    segments: Vec<Range<u64>>,
    indices: Vec<u64>,
    mains: Vec<Instance>,
    jobs: Jobs,
    /// The baselines this chunk runs that the memo will remember after
    /// it, keys only: the next chunk, expanded before this one's outcomes
    /// are in, counts them as run.
    pending: BaselineMemo,
    /// The backend's work done ahead ([`Backend::stage`]), taken by the
    /// run.
    staged: Staged,
}

/// A chunk's integrations: outcomes in job order.
struct Integrated {
    outcomes: Vec<Outcome>,
    seconds: f64,
    /// Instances `progress` was told of.
    reported: u64,
}

/// Expands a chunk's instances into jobs, and stages them on `backend`
/// where chunks overlap; `known` says which baselines earlier chunks run.
fn prepare(
    plan: &Plan,
    backend: Option<&dyn Backend>,
    segments: Vec<Range<u64>>,
    known: &(dyn Fn(&Instance, u64) -> bool + Sync),
) -> Prepared {
    let _span = profile::span(Phase::Expand);
    let indices: Vec<u64> = segments.iter().flat_map(|r| r.clone()).collect();
    let mains: Vec<Instance> = indices.par_iter().map(|&i| (plan.instance)(i)).collect();
    let jobs = Jobs::new_known(&mains, plan.baselines, known);
    let mut pending = BaselineMemo::default();
    if plan.baselines {
        for (inst, refs) in mains.iter().zip(&jobs.baseline_job) {
            for (axis, job) in refs.iter().enumerate() {
                if let JobRef::Run(_) = *job {
                    pending.insert(&inst.baseline(axis), Outcome::default());
                }
            }
        }
    }
    let staged = match backend {
        Some(backend) if !jobs.jobs.is_empty() => backend.stage(&jobs.jobs, &plan.settings),
        _ => Staged::default(),
    };
    Prepared {
        segments,
        indices,
        mains,
        jobs,
        pending,
        staged,
    }
}

/// Runs a chunk's jobs on the backend (and `--verify`'s tighter reruns).
fn integrate(
    plan: &Plan,
    backend: &dyn Backend,
    chunk: &Prepared,
    staged: Staged,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Integrated> {
    let _span = profile::span(Phase::Integrate);
    let jobs = &chunk.jobs.jobs;
    // Progress counts main instances; the other jobs add a proportional
    // share.
    let scale = chunk.mains.len() as f64 / jobs.len().max(1) as f64;
    let finished = AtomicU64::new(0);
    let reported = AtomicU64::new(0);
    let done = |n: u64| {
        let total = finished.fetch_add(n, Ordering::Relaxed) + n;
        let target = (total as f64 * scale) as u64;
        let before = reported.fetch_max(target, Ordering::Relaxed);
        if target > before {
            progress(target - before);
        }
    };
    let started = std::time::Instant::now();
    let mut outcomes = if jobs.is_empty() {
        Vec::new()
    } else {
        backend.run_staged(jobs, &plan.settings, staged, &done)?
    };
    if plan.verify && !interrupt_requested() {
        let tight = Settings {
            tolerance: plan.settings.tolerance / VERIFY_TIGHTENING,
            ..plan.settings
        };
        let checks = backend.run(jobs, &tight, &|_| {})?;
        for ((job, outcome), check) in jobs.iter().zip(outcomes.iter_mut()).zip(&checks) {
            verify(job, outcome, check);
        }
    }
    Ok(Integrated {
        outcomes,
        seconds: started.elapsed().as_secs_f64(),
        reported: reported.load(Ordering::Relaxed),
    })
}

/// A chunk's records on their way to the sink: its segments of flat
/// indices and their records, in order.
type Written = (Vec<Range<u64>>, Vec<Record>);

/// Where finished chunks go: the sink itself, called on the driver thread
/// (chunks one after another), or the writer thread's queue.
enum Out<'a, 's> {
    Direct(&'a mut Sink<'s>),
    Queue(&'a std::sync::mpsc::SyncSender<Written>),
}

/// Hands a chunk's records to the sink, segment by segment.
fn write(sink: &mut Sink<'_>, (segments, records): &Written) -> Result<u64> {
    let _span = profile::span(Phase::Write);
    let mut offset = 0;
    for segment in segments {
        let n = (segment.end - segment.start) as usize;
        sink(segment.start, &records[offset..offset + n])?;
        offset += n;
    }
    Ok(offset as u64)
}

/// What the driver thread keeps across chunks.
struct Driver<'p> {
    plan: &'p Plan<'p>,
    progress: &'p (dyn Fn(u64) + Sync),
    memo: &'p mut BaselineMemo,
    summary: Summary,
    /// Instances handed to the sink so far.
    written: &'p AtomicU64,
    total: u64,
}

/// The error of a sweep stopped by an interrupt after `written` of
/// `total` instances.
fn interrupted(written: &AtomicU64, total: u64) -> anyhow::Error {
    anyhow::anyhow!(
        "interrupted after {} of {total} instances",
        written.load(Ordering::Relaxed)
    )
}

/// The driver's error where the writer thread stopped taking chunks (its
/// own error says why).
#[derive(Debug, thiserror::Error)]
#[error("the writer thread stopped")]
struct WriterGone;

impl Driver<'_> {
    fn interrupted(&self) -> anyhow::Error {
        interrupted(self.written, self.total)
    }

    /// Whether the memo forgets what it holds before it takes the next
    /// chunk's baselines (it is bounded).
    fn memo_full(&self) -> bool {
        self.memo.0.len() > MAX_REMEMBERED_BASELINES
    }

    /// Records of an integrated chunk, into the summary, the memo and
    /// `out`. Nothing goes out once an interrupt is requested.
    fn finish(&mut self, chunk: Prepared, integrated: Integrated, out: &mut Out) -> Result<()> {
        let plan = self.plan;
        if interrupt_requested() {
            return Err(self.interrupted());
        }
        let Prepared {
            segments,
            indices,
            mains,
            jobs:
                Jobs {
                    jobs,
                    main_job,
                    baseline_job,
                },
            pending: _,
            staged: _,
        } = chunk;
        let Integrated {
            outcomes,
            seconds,
            reported,
        } = integrated;
        let left = mains.len() as u64 - reported;
        if left > 0 {
            (self.progress)(left);
        }
        let records_span = profile::span(Phase::Records);
        let summary = &mut self.summary;
        summary.integration_s += seconds;
        let memo = &*self.memo;
        let records: Vec<Record> = mains
            .par_iter()
            .enumerate()
            .map(|(k, inst)| {
                let mut rec = record(inst, &outcomes[main_job[k]]);
                if plan.baselines {
                    for (axis, job) in baseline_job[k].iter().enumerate() {
                        let base_inst = inst.baseline(axis);
                        let base = match *job {
                            JobRef::Run(j) => outcomes[j],
                            JobRef::Done => memo
                                .get(&base_inst, digest(&base_inst.key()))
                                .expect("a baseline marked done was remembered"),
                        };
                        let base = record(&base_inst, &base);
                        rec.baseline_step[axis] = base.step[axis];
                        rec.baseline_status = rec.baseline_status.max(base.status);
                    }
                }
                rec
            })
            .collect();
        for (rec, &index) in records.iter().zip(&indices) {
            summary.add(rec, index);
        }
        summary.simulated_s += jobs
            .iter()
            .zip(&outcomes)
            .map(|(inst, out)| out.periods as f64 * inst.period())
            .sum::<f64>();
        summary.integrations += jobs.len() as u64;
        summary.on_cpu += outcomes.iter().filter(|o| o.on_cpu).count() as u64;
        summary.grazes += outcomes.iter().filter(|o| o.graze).count() as u64;
        summary.checked += outcomes.iter().filter(|o| o.checked).count() as u64;
        summary.checked_on_cpu += outcomes.iter().filter(|o| o.checked && o.on_cpu).count() as u64;
        // Keep this chunk's baselines for the chunks after it (a grid's
        // baselines repeat along every other axis), within a bound.
        if plan.baselines {
            if self.memo_full() {
                self.memo.0.clear();
            }
            for (inst, refs) in mains.iter().zip(&baseline_job) {
                for (axis, job) in refs.iter().enumerate() {
                    if let JobRef::Run(j) = *job {
                        self.memo.insert(&inst.baseline(axis), outcomes[j]);
                    }
                }
            }
        }
        drop(records_span);
        let chunk = (segments, records);
        match out {
            Out::Direct(sink) => {
                let n = profile::time(Phase::WaitWriter, || write(&mut **sink, &chunk))?;
                self.written.fetch_add(n, Ordering::Relaxed);
            }
            Out::Queue(queue) => {
                let _waiting = profile::span(Phase::WaitWriter);
                queue.send(chunk).map_err(|_| WriterGone)?;
            }
        }
        Ok(())
    }

    /// The chunk loop of [`run_chunks`] on the driver thread.
    fn drive(
        &mut self,
        backend: &dyn Backend,
        chunk: usize,
        overlap: bool,
        out: &mut Out,
    ) -> Result<()> {
        let plan = self.plan;
        let progress = self.progress;
        // Staging ahead pays only where it runs beside another chunk.
        let stage = overlap.then_some(backend);
        let mut segments = chunks(&plan.work, chunk.max(1) as u64).into_iter();
        let mut next = segments.next().map(|s| {
            let memo = &*self.memo;
            prepare(plan, stage, s, &|inst, d| memo.get(inst, d).is_some())
        });
        // The chunk integrated last, still to finish.
        let mut finishing: Option<(Prepared, Integrated)> = None;
        while let Some(mut current) = next.take() {
            if interrupt_requested() {
                return Err(self.interrupted());
            }
            if !overlap {
                let staged = std::mem::take(&mut current.staged);
                let integrated = profile::time(Phase::Wait, || {
                    integrate(plan, backend, &current, staged, progress)
                })?;
                self.finish(current, integrated, out)?;
                next = segments.next().map(|s| {
                    let memo = &*self.memo;
                    prepare(plan, stage, s, &|inst, d| memo.get(inst, d).is_some())
                });
                continue;
            }
            let pending = std::mem::take(&mut current.pending);
            let staged = std::mem::take(&mut current.staged);
            let previous = finishing.take();
            let (integrated, driven) = std::thread::scope(|scope| {
                let integrating =
                    scope.spawn(|| integrate(plan, backend, &current, staged, progress));
                let driven = (|| -> Result<Option<Prepared>> {
                    if let Some((chunk, integrated)) = previous {
                        self.finish(chunk, integrated, out)?;
                    }
                    let forget = self.memo_full();
                    let memo = &*self.memo;
                    let known = |inst: &Instance, d: u64| {
                        (!forget && memo.get(inst, d).is_some()) || pending.get(inst, d).is_some()
                    };
                    Ok(segments
                        .next()
                        .map(|s| prepare(plan, Some(backend), s, &known)))
                })();
                (wait_for(integrating, Phase::Wait), driven)
            });
            next = driven?;
            finishing = Some((current, integrated?));
        }
        if let Some((chunk, integrated)) = finishing.take() {
            self.finish(chunk, integrated, out)?;
        }
        Ok(())
    }
}

/// Joins a thread of the pipeline, timing the wait as `phase`; its panic
/// goes on in this thread.
fn wait_for<T>(thread: std::thread::ScopedJoinHandle<'_, T>, phase: Phase) -> T {
    let _waiting = profile::span(phase);
    thread
        .join()
        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
}

/// The chunk loop. With `overlap` three threads share the work: the
/// backend integrates chunk k on one, a writer hands chunk k-1's records
/// to the sink (the HDF5 file and the checkpoint) on another, and this
/// one, the driver, makes chunk k-1's records and expands chunk k+1's
/// instances. Without, each chunk is expanded, integrated, recorded and
/// written before the next. Both hand the backend the same jobs: chunk
/// k+1 is expanded knowing the baselines the memo will hold after chunk k
/// (its own, or none where it is full, and chunk k's), so the records are
/// the same bit for bit. Once an interrupt is requested nothing more goes
/// to the sink, and the sweep ends with an error.
pub fn run_chunks(
    plan: &Plan,
    backend: &dyn Backend,
    chunk: usize,
    progress: &(dyn Fn(u64) + Sync),
    sink: &mut Sink,
    baselines_done: &mut BaselineMemo,
    overlap: bool,
) -> Result<Summary> {
    let written = AtomicU64::new(0);
    let total = plan.count();
    let mut driver = Driver {
        plan,
        progress,
        memo: baselines_done,
        summary: Summary::default(),
        written: &written,
        total,
    };
    if !overlap {
        driver.drive(backend, chunk, false, &mut Out::Direct(sink))?;
        return Ok(driver.summary);
    }
    let (queue, chunks_written) = std::sync::mpsc::sync_channel::<Written>(1);
    let (driven, wrote) = std::thread::scope(|scope| {
        let writer = scope.spawn(|| -> Result<()> {
            for chunk in chunks_written {
                if interrupt_requested() {
                    return Err(interrupted(&written, total));
                }
                let n = write(&mut *sink, &chunk)?;
                written.fetch_add(n, Ordering::Relaxed);
            }
            Ok(())
        });
        let driven = driver.drive(backend, chunk, true, &mut Out::Queue(&queue));
        drop(queue);
        (driven, wait_for(writer, Phase::WaitWriter))
    });
    match (driven, wrote) {
        // The writer's error is why the driver could not go on.
        (Err(e), Err(w)) if e.is::<WriterGone>() => Err(w),
        (Err(e), _) => Err(e),
        (Ok(()), Err(w)) => Err(w),
        (Ok(()), Ok(())) => Ok(driver.summary),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn verify_marks_only_finished_runs_that_a_finished_check_moves() {
        let inst = Instance::TABLE1;
        // Displacements over the measured periods [m]; 8 cycles of 10 Hz
        // are measured, so 8e-9 m is a step of 1e-9 m per cycle.
        let cycles = (inst.cycles - inst.settle) as f64;
        let outcome = |status: u32, x: f64| Outcome {
            displacement: [x * cycles, 0.0],
            span: cycles,
            status,
            steps: 1,
            periods: inst.cycles,
            ..Outcome::default()
        };
        let check = |run: Outcome, tighter: Outcome, want: u32| {
            let mut got = run;
            verify(&inst, &mut got, &tighter);
            assert_eq!(got.status, want, "{run:?} against {tighter:?}");
            if want == STATUS_UNCONVERGED {
                assert_eq!(got.displacement, [0.0; AXES]);
            } else {
                assert_eq!(got, run);
            }
        };
        let step = 1e-6;
        check(outcome(0, step), outcome(0, step + 0.5e-9), STATUS_OK);
        check(
            outcome(0, step),
            outcome(0, step + 2e-9),
            STATUS_UNCONVERGED,
        );
        check(
            outcome(0, step),
            outcome(0, step - 2e-9),
            STATUS_UNCONVERGED,
        );
        // A check that did not finish neither confirms nor refutes.
        check(outcome(0, step), outcome(3, 0.0), STATUS_OK);
        // A failed run keeps its own status.
        check(outcome(1, 0.0), outcome(0, step), 1);
    }

    #[test]
    fn chunks_cover_the_work_in_order_and_respect_the_size() {
        let work = vec![0..5, 7..8, 10..17];
        for size in [1, 2, 3, 5, 100] {
            let chunks = chunks(&work, size);
            let flat: Vec<u64> = chunks.iter().flatten().flat_map(|r| r.clone()).collect();
            assert_eq!(flat, [0, 1, 2, 3, 4, 7, 10, 11, 12, 13, 14, 15, 16]);
            for chunk in &chunks {
                let n: u64 = chunk.iter().map(|r| r.end - r.start).sum();
                assert!(n <= size && n > 0, "size {size}: {chunk:?}");
                // A segment never spans two work ranges.
                for seg in chunk {
                    assert!(
                        work.iter()
                            .any(|w| w.start <= seg.start && seg.end <= w.end)
                    );
                }
            }
        }
    }
}
