//! Sweeps: runs every instance of a scene on a backend, chunk by chunk, and
//! hands finished chunks to a sink (the HDF5 writer) so memory stays bounded
//! whatever the instance count.
//!
//! Every instance is integrated independently and deterministically, so the
//! results are the same bit for bit for any thread count and chunk size
//! (on a GPU in f64, up to the shader's difference from the CPU on the
//! instances of a batch's CPU tail: `gpu::BatchOptions::cpu_tail`).

use std::collections::HashMap;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::{Result, bail};
use rayon::prelude::*;

use crate::backend::Backend;
use crate::cpu::integrate::{STATUS_OK, Settings};
use crate::measurement::keeps_values;
use crate::status::Status;

pub use crate::cpu::integrate::constants::STATUS_UNCONVERGED;

/// How far a step may move under a 100 times tighter tolerance before
/// `--verify` calls the instance unconverged [m per drive cycle]: the
/// project's accuracy bar of 0.001 um (MODEL.md).
pub const VERIFY_ALLOWANCE_M: f64 = 1e-9;

/// How much tighter than the scene's the tolerance of a `--verify` rerun
/// is.
pub const VERIFY_TIGHTENING: f64 = 100.0;
use crate::model::{AXES, Instance, InstanceKey};
use crate::motion::Motion;

/// Baseline outcomes kept from one chunk for the next, at most: about
/// 200 MiB at 208 bytes an entry. The bound is checked between chunks, so a
/// chunk's own distinct baselines come on top (two per instance at most,
/// 2,000 on a 1000 x 1000 map).
const MAX_REMEMBERED_BASELINES: usize = 1 << 20;

/// A map from a 64-bit digest of an instance's key to its job, with a fast
/// multiply-rotate hash (the keys are parameter bits, not attacker-chosen):
/// 16 bytes an entry, so a million instances stay in cache where full keys
/// and std's SipHash made de-duplicating them cost a second.
type DigestMap = HashMap<u64, usize, std::hash::BuildHasherDefault<KeyHasher>>;

/// FxHash's word mixing (as in rustc): rotate, xor, multiply per word.
#[derive(Default)]
struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(word));
        }
    }

    fn write_u64(&mut self, word: u64) {
        self.0 = (self.0.rotate_left(5) ^ word).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }

    fn finish(&self) -> u64 {
        self.0
    }
}

/// A 64-bit digest of an instance's key.
fn digest(key: &InstanceKey) -> u64 {
    use std::hash::Hasher;
    let mut h = KeyHasher::default();
    for &word in key {
        h.write_u64(word);
    }
    // A final avalanche, so the map's low bits depend on every word.
    let x = h.finish();
    (x ^ (x >> 29)).wrapping_mul(0xbf58_476d_1ce4_e5b9) ^ (x >> 32)
}

/// Where a chunk's baseline comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
enum JobRef {
    /// Job `j` of this chunk.
    Run(usize),
    /// An earlier chunk ran it.
    Done,
}

/// The distinct integrations of a chunk: every main instance and every
/// baseline is run once, however often it occurs (a V_x x V_y map of N x N
/// instances has 2 N distinct baselines, not 2 N^2).
struct Jobs {
    jobs: Vec<Instance>,
    /// The job of each main instance.
    main_job: Vec<usize>,
    /// The job of each main instance's baselines.
    baseline_job: Vec<[JobRef; AXES]>,
}

/// Digest buckets the de-duplication of [`Jobs::new`] spreads over the
/// threads: enough for every core to have several, few enough that each is
/// thousands of integrations long on a large chunk.
const DEDUP_BUCKETS: usize = 256;

impl Jobs {
    /// Every integration the chunk asks for is an item: the mains in order,
    /// then each main's baselines, axis by axis. An item is a job where it
    /// is the first of its kind; jobs keep the order of their first items.
    /// Digests, the comparison of whole keys where digests meet, and the
    /// search for first items run in parallel (items are spread over
    /// [`DEDUP_BUCKETS`] by digest, and each bucket is searched in item
    /// order); only the numbering of the jobs is a sequential pass.
    fn new(mains: &[Instance], baselines: bool, done: &BaselineMemo) -> Jobs {
        let n = mains.len();
        let total = if baselines { n * (1 + AXES) } else { n };
        let item = |i: usize| -> Instance {
            if i < n {
                mains[i]
            } else {
                mains[(i - n) / AXES].baseline((i - n) % AXES)
            }
        };
        // Each item's digest, and whether an earlier chunk ran it (only
        // baselines are remembered between chunks).
        let (digests, earlier): (Vec<u64>, Vec<bool>) = (0..total)
            .into_par_iter()
            .map(|i| {
                let inst = item(i);
                let d = digest(&inst.key());
                (d, i >= n && done.get(&inst, d).is_some())
            })
            .unzip();
        let bucket = |d: u64| (d >> 56) as usize % DEDUP_BUCKETS;
        let mut buckets: Vec<Vec<usize>> = vec![Vec::new(); DEDUP_BUCKETS];
        for i in (0..total).filter(|&i| !earlier[i]) {
            buckets[bucket(digests[i])].push(i);
        }
        // The first item of each item's kind: itself, or an earlier item
        // with the same key. Two different keys with one digest (never
        // seen) both run: a duplicate integration is harmless.
        let firsts: Vec<Vec<(usize, usize)>> = buckets
            .par_iter()
            .map(|items| {
                let mut seen = DigestMap::with_capacity_and_hasher(items.len(), Default::default());
                items
                    .iter()
                    .map(|&i| {
                        use std::collections::hash_map::Entry;
                        match seen.entry(digests[i]) {
                            Entry::Occupied(e) if item(*e.get()).key() == item(i).key() => {
                                (i, *e.get())
                            }
                            Entry::Occupied(_) => (i, i),
                            Entry::Vacant(e) => (i, *e.insert(i)),
                        }
                    })
                    .collect()
            })
            .collect();
        let mut first = vec![usize::MAX; total];
        for (i, f) in firsts.into_iter().flatten() {
            first[i] = f;
        }
        // Jobs numbered in the order of their first items.
        let first_items: Vec<usize> = (0..total)
            .into_par_iter()
            .filter(|&i| !earlier[i] && first[i] == i)
            .collect();
        let jobs: Vec<Instance> = first_items.par_iter().map(|&i| item(i)).collect();
        let mut job_of_first = vec![usize::MAX; total];
        for (j, &i) in first_items.iter().enumerate() {
            job_of_first[i] = j;
        }
        // Each item's job (`usize::MAX`: an earlier chunk ran it); the
        // mains come first.
        let mut main_job: Vec<usize> = (0..total)
            .into_par_iter()
            .map(|i| match earlier[i] {
                true => usize::MAX,
                false => job_of_first[first[i]],
            })
            .collect();
        let baseline_job = main_job
            .split_off(n)
            .par_chunks(AXES)
            .map(|refs| {
                std::array::from_fn(|axis| match refs[axis] {
                    usize::MAX => JobRef::Done,
                    j => JobRef::Run(j),
                })
            })
            .collect();
        Jobs {
            jobs,
            main_job,
            baseline_job,
        }
    }
}

/// Every distinct integration that `instances` (and, with `baselines`,
/// their 1-DOF baselines) ask for, each once, in first-seen order: what a
/// sweep of them integrates, for studies and benchmarks of whole scenes.
pub fn distinct_integrations(instances: &[Instance], baselines: bool) -> Vec<Instance> {
    Jobs::new(instances, baselines, &BaselineMemo::default()).jobs
}

/// Baseline outcomes of earlier chunks, by digest (with the instance key, to
/// tell digests apart). A caller that runs several sweeps of one scene
/// (the waves of `crate::refine`) keeps one across them with
/// [`run_with_memo`], so each baseline runs once.
#[derive(Default)]
pub struct BaselineMemo(
    HashMap<u64, (InstanceKey, Outcome), std::hash::BuildHasherDefault<KeyHasher>>,
);

impl BaselineMemo {
    fn get(&self, inst: &Instance, d: u64) -> Option<Outcome> {
        self.get_by_key(&inst.key(), d)
    }

    /// The outcome remembered for the instance of `key` (digest `d`).
    fn get_by_key(&self, key: &InstanceKey, d: u64) -> Option<Outcome> {
        self.0
            .get(&d)
            .filter(|(known, _)| known == key)
            .map(|(_, outcome)| *outcome)
    }

    fn insert(&mut self, inst: &Instance, outcome: Outcome) {
        let key = inst.key();
        self.0.insert(digest(&key), (key, outcome));
    }
}

/// One instance's 1-DOF baselines, axis by axis: the baseline's step along
/// that axis [m per own drive cycle] and its status.
pub type BaselinePair = [(f64, u32); AXES];

/// The 1-DOF baselines of `instances`: for each instance and axis, the
/// baseline's step along that axis [m per own drive cycle] and its status.
/// Each distinct baseline is integrated once, in one batch, and those
/// `memo` holds are not integrated again (the new ones are added to it).
/// `None`, with nothing integrated, when more than `most` would have to be:
/// the adaptive refinement asks for the exact baselines of its inferred
/// points only where they are few (a V_x by V_y map has one per grid line
/// and axis).
pub fn baselines_of(
    instances: &[Instance],
    backend: &dyn Backend,
    settings: &Settings,
    memo: &mut BaselineMemo,
    most: usize,
) -> Result<Option<Vec<BaselinePair>>> {
    // Each baseline's key and digest once, in parallel, with what the memo
    // already holds.
    let looked_up: Vec<[(InstanceKey, u64, Option<Outcome>); AXES]> = {
        let memo = &*memo;
        instances
            .par_iter()
            .map(|inst| {
                std::array::from_fn(|axis| {
                    let key = inst.baseline(axis).key();
                    let d = digest(&key);
                    let known = memo.get_by_key(&key, d);
                    (key, d, known)
                })
            })
            .collect()
    };
    // The distinct baselines the memo lacks, in first-seen order.
    let mut jobs: Vec<Instance> = Vec::new();
    let mut keys: Vec<InstanceKey> = Vec::new();
    let mut seen = DigestMap::default();
    for (inst, axes) in instances.iter().zip(&looked_up) {
        for (axis, (key, d, known)) in axes.iter().enumerate() {
            if known.is_some() {
                continue;
            }
            if let Some(&j) = seen.get(d)
                && keys[j] == *key
            {
                continue;
            }
            // A digest shared by two keys: the later one is integrated on
            // its own (and found by key below).
            seen.insert(*d, jobs.len());
            jobs.push(inst.baseline(axis));
            keys.push(*key);
            if jobs.len() > most {
                return Ok(None);
            }
        }
    }
    let outcomes = if jobs.is_empty() {
        Vec::new()
    } else {
        backend.run(&jobs, settings, &|_| {})?
    };
    let fresh = |key: &InstanceKey, d: u64| -> Outcome {
        let j = match seen.get(&d) {
            Some(&j) if keys[j] == *key => j,
            _ => keys
                .iter()
                .position(|k| k == key)
                .expect("every baseline was integrated or remembered"),
        };
        outcomes[j]
    };
    let out = instances
        .par_iter()
        .zip(&looked_up)
        .map(|(inst, axes)| {
            std::array::from_fn(|axis| {
                let (key, d, known) = &axes[axis];
                let outcome = known.unwrap_or_else(|| fresh(key, *d));
                let rec = record(&inst.baseline(axis), &outcome);
                (rec.step[axis], rec.status)
            })
        })
        .collect();
    for (inst, outcome) in jobs.iter().zip(&outcomes) {
        memo.insert(inst, *outcome);
    }
    Ok(Some(out))
}

pub use crate::interrupt::{interrupt_requested, request_interrupt};

pub use crate::measurement::Outcome;

/// One instance's entry in the maps, in SI units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Record {
    /// Step per own drive cycle [m].
    pub step: [f64; AXES],
    /// Mean slider velocity [m/s].
    pub velocity: [f64; AXES],
    /// Standard error of each step [m per own drive cycle]: 0 for a window
    /// and a periodic motion.
    pub step_se: [f64; AXES],
    /// Scene periods integrated, settle included.
    pub periods: u32,
    /// Scene periods of the detected cycle, 0 when none.
    pub period_lag: u32,
    /// The kind of motion a steady measurement found: undetermined for a
    /// window, a failed or "not steady" run, and an inferred point of a
    /// refined map (`/maps/motion`).
    pub motion: Motion,
    pub status: u32,
    pub steps: u32,
    /// 1-DOF steps with the other axis undriven [m] (zero when not asked).
    pub baseline_step: [f64; AXES],
    /// Worst status of the two baselines.
    pub baseline_status: u32,
}

impl Record {
    /// Why a stored record cannot have been written by a run, if it cannot:
    /// every status must be a known code, every value finite, an instance
    /// that did not finish normally must have zeros in its map entries,
    /// and only an instance with status 0 has a kind of motion (any other
    /// status is undetermined; a motion code that does not exist is
    /// refused as it is read, by [`stored_motion`]). Readers of result
    /// files and checkpoints ask this of every record they take in.
    pub fn implausibility(&self) -> Option<String> {
        for (what, code) in [
            ("status", self.status),
            ("baseline status", self.baseline_status),
        ] {
            if Status::from_code(code).is_none() {
                return Some(format!("its {what} is {code}, which is no status code"));
            }
        }
        if self.status == crate::status::STATUS_NO_STALL {
            return Some(format!(
                "its status is {} ({}), which only a stall map holds",
                self.status,
                Status::describe(self.status)
            ));
        }
        if self.status != STATUS_OK && self.motion != Motion::Undetermined {
            return Some(format!(
                "its status is {} ({}) but its motion is {}, not {}",
                self.status,
                Status::describe(self.status),
                self.motion.name(),
                Motion::Undetermined.name()
            ));
        }
        let values = [
            ("step_x", self.step[0]),
            ("step_y", self.step[1]),
            ("velocity_x", self.velocity[0]),
            ("velocity_y", self.velocity[1]),
            ("step_x_se", self.step_se[0]),
            ("step_y_se", self.step_se[1]),
            ("baseline step_x", self.baseline_step[0]),
            ("baseline step_y", self.baseline_step[1]),
        ];
        if let Some((what, value)) = values.iter().find(|(_, v)| !v.is_finite()) {
            return Some(format!("its {what} is {value}"));
        }
        if let Some((what, value)) = values[4..6].iter().find(|(_, v)| *v < 0.0) {
            return Some(format!("its {what} is {value:e}, below 0"));
        }
        let failed = !keeps_values(self.status);
        let kept = values[..6].iter().find(|(_, v)| *v != 0.0);
        match kept {
            Some((what, value)) if failed => Some(format!(
                "its status is {} ({}) but its {what} is {value:e}, not 0",
                self.status,
                Status::describe(self.status)
            )),
            _ => None,
        }
    }
}

/// The kind of motion of a stored code (`/maps/motion`, a checkpoint's
/// record), or why it cannot be right, in the words of
/// [`Record::implausibility`]: a `Record` holds a [`Motion`], so a code
/// that is none is refused here, as it is read.
pub fn stored_motion(code: u8) -> Result<Motion, String> {
    Motion::from_code(code).ok_or_else(|| {
        format!(
            "its motion is {code}, which is no motion code (flag_values {:?})",
            Motion::flag_values()
        )
    })
}

pub use crate::backend::cpu::run_one;

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

/// Turns a displacement outcome into map entries.
pub fn record(inst: &Instance, out: &Outcome) -> Record {
    let mut rec = Record {
        status: out.status,
        steps: out.steps,
        step_se: out.se,
        periods: out.periods,
        period_lag: out.lag,
        motion: out.motion,
        ..Record::default()
    };
    for i in 0..AXES {
        let (velocity, step) = inst.measure_over(i, out.displacement[i], out.span);
        rec.velocity[i] = velocity;
        rec.step[i] = step;
    }
    rec
}

/// Totals over a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    pub instances: u64,
    /// Instances per status code (index = code; the last entry gathers
    /// unknown codes).
    pub status_counts: [u64; 8],
    /// Instances whose motion was found periodic (a steady measurement).
    pub periodic: u64,
    /// Instances per kind of motion (index = `Motion::code`).
    pub motion: [u64; Motion::ALL.len()],
    /// Largest standard error of a step among instances that keep values
    /// [m per own drive cycle].
    pub largest_se: f64,
    /// Scene periods integrated over all main instances, and the most of
    /// one instance.
    pub periods: u64,
    pub max_periods: u32,
    /// Integrator steps over all main instances.
    pub steps: u64,
    /// Integrations run, baselines included, each distinct one once.
    pub integrations: u64,
    /// Wall time spent integrating (in the backend) [s].
    pub integration_s: f64,
    /// Integrations an f32 or GPU backend ran on the CPU in f64 instead.
    pub on_cpu: u64,
    /// Of those, f32 runs that stopped at a band graze.
    pub grazes: u64,
    /// f32 window runs among the heaviest of their batch, checked
    /// (`backend::check`); those that carry the f64 reference's value are
    /// counted in `on_cpu` too.
    pub checked: u64,
    /// Of the checked, those that carry the f64 reference's value.
    pub checked_on_cpu: u64,
    /// Simulated time over all integrated instances, baselines included [s].
    pub simulated_s: f64,
    pub extreme_step: [f64; 2],
    /// Per axis, the instance with the most backward step and the one with
    /// the most forward step among those with status 0: (step [m per own
    /// drive cycle], flat index); the index is `u64::MAX` while none is.
    pub best: [[(f64, u64); 2]; AXES],
}

impl Default for Summary {
    fn default() -> Summary {
        Summary {
            instances: 0,
            status_counts: [0; 8],
            periodic: 0,
            motion: [0; Motion::ALL.len()],
            largest_se: 0.0,
            periods: 0,
            max_periods: 0,
            steps: 0,
            integrations: 0,
            integration_s: 0.0,
            on_cpu: 0,
            grazes: 0,
            checked: 0,
            checked_on_cpu: 0,
            simulated_s: 0.0,
            extreme_step: [f64::INFINITY, f64::NEG_INFINITY],
            best: [[(f64::INFINITY, u64::MAX), (f64::NEG_INFINITY, u64::MAX)]; AXES],
        }
    }
}

impl Summary {
    /// Adds the totals of another part of the same run.
    pub fn merge(&mut self, other: &Summary) {
        self.instances += other.instances;
        for (a, b) in self.status_counts.iter_mut().zip(other.status_counts) {
            *a += b;
        }
        self.steps += other.steps;
        self.periodic += other.periodic;
        for (a, b) in self.motion.iter_mut().zip(other.motion) {
            *a += b;
        }
        self.largest_se = self.largest_se.max(other.largest_se);
        self.periods += other.periods;
        self.max_periods = self.max_periods.max(other.max_periods);
        self.integrations += other.integrations;
        self.integration_s += other.integration_s;
        self.on_cpu += other.on_cpu;
        self.grazes += other.grazes;
        self.checked += other.checked;
        self.checked_on_cpu += other.checked_on_cpu;
        self.simulated_s += other.simulated_s;
        self.extreme_step[0] = self.extreme_step[0].min(other.extreme_step[0]);
        self.extreme_step[1] = self.extreme_step[1].max(other.extreme_step[1]);
        for axis in 0..AXES {
            let [low, high] = other.best[axis];
            self.offer(axis, low.0, low.1);
            self.offer(axis, high.0, high.1);
        }
    }

    /// Takes a step of instance `index` on `axis` as the most backward or
    /// forward one when it is (the lower index wins a tie, whatever the
    /// order instances come in).
    fn offer(&mut self, axis: usize, step: f64, index: u64) {
        if index == u64::MAX || !step.is_finite() {
            return;
        }
        let [low, high] = &mut self.best[axis];
        if step < low.0 || (step == low.0 && index < low.1) {
            *low = (step, index);
        }
        if step > high.0 || (step == high.0 && index < high.1) {
            *high = (step, index);
        }
    }

    /// Counts one finished instance, flat index `index` (its simulated time is added apart,
    /// because baselines add to it too).
    pub fn add(&mut self, rec: &Record, index: u64) {
        self.instances += 1;
        self.status_counts[(rec.status as usize).min(7)] += 1;
        self.steps += rec.steps as u64;
        self.periodic += (rec.period_lag > 0) as u64;
        self.motion[rec.motion.code() as usize] += 1;
        if keeps_values(rec.status) {
            self.largest_se = self.largest_se.max(rec.step_se[0]).max(rec.step_se[1]);
        }
        self.periods += rec.periods as u64;
        self.max_periods = self.max_periods.max(rec.periods);
        if rec.status == STATUS_OK {
            for axis in 0..AXES {
                self.extreme_step[0] = self.extreme_step[0].min(rec.step[axis]);
                self.extreme_step[1] = self.extreme_step[1].max(rec.step[axis]);
                self.offer(axis, rec.step[axis], index);
            }
        }
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
/// when an interrupt is requested ([`request_interrupt`]) the sweep ends
/// with an error and hands nothing more to the sink.
pub fn run(
    plan: &Plan,
    backend: &dyn Backend,
    chunk: usize,
    progress: &(dyn Fn(u64) + Sync),
    sink: &mut dyn FnMut(u64, &[Record]) -> Result<()>,
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
/// `baselines_done` (and this sweep's added to it).
pub fn run_with_memo(
    plan: &Plan,
    backend: &dyn Backend,
    chunk: usize,
    progress: &(dyn Fn(u64) + Sync),
    sink: &mut dyn FnMut(u64, &[Record]) -> Result<()>,
    baselines_done: &mut BaselineMemo,
) -> Result<Summary> {
    let total = plan.count();
    let mut summary = Summary::default();
    let mut finished_before = 0;
    for segments in chunks(&plan.work, chunk.max(1) as u64) {
        if interrupt_requested() {
            bail!("interrupted after {finished_before} of {total} instances");
        }
        let indices: Vec<u64> = segments.iter().flat_map(|r| r.clone()).collect();
        let mains: Vec<Instance> = indices.par_iter().map(|&i| (plan.instance)(i)).collect();
        let jobs = Jobs::new(&mains, plan.baselines, baselines_done);
        let Jobs {
            jobs,
            main_job,
            baseline_job,
        } = jobs;
        // Progress counts main instances; the other jobs add a proportional
        // share.
        let scale = mains.len() as f64 / jobs.len().max(1) as f64;
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
            backend.run(&jobs, &plan.settings, &done)?
        };
        if plan.verify && !interrupt_requested() {
            let tight = Settings {
                tolerance: plan.settings.tolerance / VERIFY_TIGHTENING,
                ..plan.settings
            };
            let checks = backend.run(&jobs, &tight, &|_| {})?;
            for ((job, outcome), check) in jobs.iter().zip(outcomes.iter_mut()).zip(&checks) {
                verify(job, outcome, check);
            }
        }
        summary.integration_s += started.elapsed().as_secs_f64();
        if interrupt_requested() {
            bail!("interrupted after {finished_before} of {total} instances");
        }
        let left = mains.len() as u64 - reported.load(Ordering::Relaxed);
        if left > 0 {
            progress(left);
        }
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
                            JobRef::Done => baselines_done
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
            if baselines_done.0.len() > MAX_REMEMBERED_BASELINES {
                baselines_done.0.clear();
            }
            for (inst, refs) in mains.iter().zip(&baseline_job) {
                for (axis, job) in refs.iter().enumerate() {
                    if let JobRef::Run(j) = *job {
                        baselines_done.insert(&inst.baseline(axis), outcomes[j]);
                    }
                }
            }
        }
        let mut offset = 0;
        for segment in &segments {
            let n = (segment.end - segment.start) as usize;
            sink(segment.start, &records[offset..offset + n])?;
            offset += n;
        }
        finished_before += mains.len() as u64;
    }
    Ok(summary)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What [`Jobs::new`] must equal: a plain first-seen de-duplication
    /// on whole keys, one item after another. Returns the jobs' keys, each
    /// main's job and each baseline's job (`None`: an earlier chunk ran it).
    #[allow(clippy::type_complexity)]
    fn plain_jobs(
        mains: &[Instance],
        baselines: bool,
        done: &BaselineMemo,
    ) -> (Vec<InstanceKey>, Vec<usize>, Vec<[Option<usize>; AXES]>) {
        let mut keys: Vec<InstanceKey> = Vec::new();
        let mut job = |inst: &Instance| match keys.iter().position(|k| *k == inst.key()) {
            Some(j) => j,
            None => {
                keys.push(inst.key());
                keys.len() - 1
            }
        };
        let main_job: Vec<usize> = mains.iter().map(&mut job).collect();
        let mut baseline_job = Vec::new();
        if baselines {
            for m in mains {
                baseline_job.push(std::array::from_fn(|axis| {
                    let b = m.baseline(axis);
                    match done.get(&b, digest(&b.key())) {
                        Some(_) => None,
                        None => Some(job(&b)),
                    }
                }));
            }
        }
        (keys, main_job, baseline_job)
    }

    #[test]
    fn jobs_are_the_first_seen_distinct_integrations() {
        // A scrambled grid with repeats, 1-DOF instances (their x baseline
        // is themselves) and baselines an earlier chunk ran.
        let mut mains = Vec::new();
        for k in 0..700u64 {
            let mut inst = Instance::TABLE1;
            inst.axes[0].voltage = [0.0, 40.0, 80.0, 120.0][(k * 7 % 4) as usize];
            inst.axes[1].voltage = [0.0, 50.0, 100.0][(k * 5 % 3) as usize];
            inst.axes[0].frequency = 10.0 + (k * 13 % 97) as f64;
            mains.push(inst);
        }
        let mut done = BaselineMemo::default();
        for m in mains.iter().step_by(11) {
            done.insert(&m.baseline(1), Outcome::default());
        }
        for (baselines, memo) in [
            (false, BaselineMemo::default()),
            (true, BaselineMemo::default()),
            (true, done),
        ] {
            let jobs = Jobs::new(&mains, baselines, &memo);
            let (keys, main_job, baseline_job) = plain_jobs(&mains, baselines, &memo);
            let got: Vec<InstanceKey> = jobs.jobs.iter().map(Instance::key).collect();
            assert_eq!(got, keys, "baselines {baselines}");
            assert_eq!(jobs.main_job, main_job);
            let got: Vec<[Option<usize>; AXES]> = jobs
                .baseline_job
                .iter()
                .map(|refs| {
                    refs.map(|r| match r {
                        JobRef::Run(j) => Some(j),
                        JobRef::Done => None,
                    })
                })
                .collect();
            assert_eq!(got, baseline_job);
        }
    }

    #[test]
    fn baseline_of_a_one_axis_instance_is_the_instance() {
        let mut inst = Instance::TABLE1;
        inst.axes[1].voltage = 0.0;
        assert_eq!(inst.baseline(0), inst);
        assert_ne!(inst.baseline(1), inst);
    }

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

    /// Code 8 (no stall load) is the stall search's, held in
    /// `/maps/stall_status_*` only: a map record carrying it cannot be
    /// right.
    #[test]
    fn a_stall_status_is_no_map_status() {
        let rec = Record {
            status: crate::status::STATUS_NO_STALL,
            ..Record::default()
        };
        let why = rec.implausibility().expect("refused");
        assert!(why.contains("which only a stall map holds"), "{why}");
    }

    #[test]
    fn only_a_finished_record_has_a_kind_of_motion() {
        let ok = Record {
            step: [1e-7, -2e-7],
            motion: Motion::Periodic,
            ..Record::default()
        };
        assert_eq!(ok.implausibility(), None);
        // A window, an inferred point: status 0 and undetermined.
        assert_eq!(Record::default().implausibility(), None);
        // "Not steady" keeps its estimate but has no kind of motion.
        let not_steady = Record {
            status: crate::cpu::integrate::constants::STATUS_NOT_STEADY,
            ..ok
        };
        let why = not_steady.implausibility().expect("refused");
        assert!(
            why.starts_with("its status is 6 (not steady")
                && why.ends_with("but its motion is periodic, not undetermined"),
            "{why}"
        );
        let failed = Record {
            status: 1,
            motion: Motion::Irregular,
            ..Record::default()
        };
        let why = failed.implausibility().expect("refused");
        assert!(why.contains("its motion is irregular"), "{why}");
        let failed = Record {
            motion: Motion::Undetermined,
            ..failed
        };
        assert_eq!(failed.implausibility(), None);
        // Stored codes: every kind, and no other.
        for motion in Motion::ALL {
            assert_eq!(stored_motion(motion.code()), Ok(motion));
        }
        let why = stored_motion(4).unwrap_err();
        assert_eq!(
            why,
            "its motion is 4, which is no motion code (flag_values [0, 1, 2, 3])"
        );
    }

    #[test]
    fn the_summary_counts_every_kind_of_motion() {
        let mut a = Summary::default();
        for (k, motion) in [Motion::Periodic, Motion::Irregular, Motion::Periodic]
            .into_iter()
            .enumerate()
        {
            let rec = Record {
                motion,
                ..Record::default()
            };
            a.add(&rec, k as u64);
        }
        let mut b = Summary::default();
        b.add(&Record::default(), 3);
        b.merge(&a);
        assert_eq!(a.motion, [0, 2, 0, 1]);
        assert_eq!(b.motion, [1, 2, 0, 1]);
    }
}
