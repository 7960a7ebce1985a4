//! The 1-DOF baselines remembered across chunks and sweeps
//! ([`BaselineMemo`]), and the baselines of a list of instances integrated
//! in one batch ([`baselines_of`]).

use std::collections::HashMap;

use anyhow::Result;
use rayon::prelude::*;

use super::dedup::{DigestMap, KeyHasher, digest};
use super::{Outcome, record};
use crate::backend::Backend;
use crate::laws::Settings;
use crate::model::{AXES, Instance, InstanceKey};

/// Baseline outcomes of earlier chunks, by digest (with the instance key, to
/// tell digests apart). A caller that runs several sweeps of one scene
/// (the waves of `crate::refine`) keeps one across them with
/// [`run_with_memo`](super::run_with_memo), so each baseline runs once.
#[derive(Default)]
pub struct BaselineMemo(
    pub(super) HashMap<u64, (InstanceKey, Outcome), std::hash::BuildHasherDefault<KeyHasher>>,
);

impl BaselineMemo {
    pub(super) fn get(&self, inst: &Instance, d: u64) -> Option<Outcome> {
        self.get_by_key(&inst.key(), d)
    }

    /// The outcome remembered for the instance of `key` (digest `d`).
    pub(super) fn get_by_key(&self, key: &InstanceKey, d: u64) -> Option<Outcome> {
        self.0
            .get(&d)
            .filter(|(known, _)| known == key)
            .map(|(_, outcome)| *outcome)
    }

    pub(super) fn insert(&mut self, inst: &Instance, outcome: Outcome) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn baseline_of_a_one_axis_instance_is_the_instance() {
        let mut inst = Instance::TABLE1;
        inst.axes[1].voltage = 0.0;
        assert_eq!(inst.baseline(0), inst);
        assert_ne!(inst.baseline(1), inst);
    }
}
