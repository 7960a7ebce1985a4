//! The de-duplication of a chunk's integrations: every main instance and
//! every baseline a chunk asks for runs once ([`Jobs`]), found by a 64-bit
//! digest of the instance's key and, where digests meet, the whole key.

use std::collections::HashMap;

use rayon::prelude::*;

use super::BaselineMemo;
use crate::model::{AXES, Instance, InstanceKey};

/// A map from a 64-bit digest of an instance's key to its job, with a fast
/// multiply-rotate hash (the keys are parameter bits, not attacker-chosen):
/// 16 bytes an entry, so a million instances stay in cache where full keys
/// and std's SipHash made de-duplicating them cost a second.
pub(super) type DigestMap = HashMap<u64, usize, std::hash::BuildHasherDefault<KeyHasher>>;

/// FxHash's word mixing (as in rustc): rotate, xor, multiply per word.
#[derive(Default)]
pub(super) struct KeyHasher(u64);

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
pub(super) fn digest(key: &InstanceKey) -> u64 {
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
pub(super) enum JobRef {
    /// Job `j` of this chunk.
    Run(usize),
    /// An earlier chunk ran it.
    Done,
}

/// The distinct integrations of a chunk: every main instance and every
/// baseline is run once, however often it occurs (a V_x x V_y map of N x N
/// instances has 2 N distinct baselines, not 2 N^2).
pub(super) struct Jobs {
    pub(super) jobs: Vec<Instance>,
    /// The job of each main instance.
    pub(super) main_job: Vec<usize>,
    /// The job of each main instance's baselines.
    pub(super) baseline_job: Vec<[JobRef; AXES]>,
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
    pub(super) fn new(mains: &[Instance], baselines: bool, done: &BaselineMemo) -> Jobs {
        Jobs::new_known(mains, baselines, &|inst, d| done.get(inst, d).is_some())
    }

    /// [`Jobs::new`] where `known(baseline, digest)` says whether an
    /// earlier chunk runs the baseline (the pipeline asks this before that
    /// chunk's outcomes are in the memo).
    pub(super) fn new_known(
        mains: &[Instance],
        baselines: bool,
        known: &(dyn Fn(&Instance, u64) -> bool + Sync),
    ) -> Jobs {
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
                (d, i >= n && known(&inst, d))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::Outcome;

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
}
