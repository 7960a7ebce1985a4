//! A group of replicas on the CPU's threads: every replica runs on a
//! thread of its own (rayon) to the ladder level it waits at, the group
//! merges ([`Group::step`]), and all go on or stop; where the group gives
//! up the split, the instance runs as one run of its own. In f64, the
//! reference.

use rayon::prelude::*;

use super::{Group, Member, Step};
use crate::laws::law::Resumable;
use crate::laws::status::STATUS_OK;
use crate::laws::{Law, Replica, Settings};
use crate::measurement::{Measured, reduce, reduce_variation};
use crate::model::motion::Motion;
use crate::model::{AXES, Instance};

/// What a group's run gave: the instance's values and the replicas that
/// made them (1 where it ran alone), the steps every replica took, and the
/// largest disagreement of its merges ([`Group::disagreement`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroupRun {
    pub measured: Measured,
    /// The backward travel's values where the settings ask for them
    /// (`Settings::backward`; `measurement::reduce_variation`): the
    /// slider's total variation per axis and its standard error.
    pub variation: Option<([f64; AXES], [f64; AXES])>,
    pub replicas: u32,
    pub steps: u32,
    pub disagreement: f64,
}

/// Runs `inst` split as `split` says (`super::split`; see the module docs
/// of `crate::replicas`), or `None` once `stop` asks (within about a
/// millisecond per replica).
pub fn run_group(
    inst: &Instance,
    settings: &Settings,
    split: Replica,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<GroupRun> {
    let group = Group::new(inst, settings, split);
    run_replicas(inst, settings, &group, &group.replicas(), stop)
}

/// [`run_group`] with the replicas' instances given (`group.replicas()`
/// unless a test plants one on another attractor).
pub fn run_replicas(
    inst: &Instance,
    settings: &Settings,
    group: &Group,
    replicas: &[(Instance, Replica)],
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<GroupRun> {
    let started: Vec<Resumable> = replicas
        .iter()
        .map(|&(replica, r)| Resumable::start(&replica, settings, r))
        .collect();
    drive_group(inst, settings, group, replicas, started, stop)
}

/// [`run_replicas`] from where the replicas stand (`runs`, in replica
/// order): running, or waiting for their group's merge. A GPU batch hands
/// its last groups over so (`gpu::groups`, with `Resumable::of_run`): the
/// shader mirrors the CPU's integrator step for step in f64, so a group
/// ends as it would have on the device, merges and all.
pub fn continue_replicas(
    inst: &Instance,
    settings: &Settings,
    group: &Group,
    replicas: &[(Instance, Replica)],
    runs: Vec<Resumable>,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<GroupRun> {
    drive_group(inst, settings, group, replicas, runs, stop)
}

/// Runs the replicas to their waits on the threads, merges, and goes on
/// until the group merges or gives up the split (then the instance runs
/// alone, with its own law's integrator).
fn drive_group(
    inst: &Instance,
    settings: &Settings,
    group: &Group,
    replicas: &[(Instance, Replica)],
    mut runs: Vec<Resumable>,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<GroupRun> {
    let count = group.count();
    let instances: Vec<Instance> = replicas.iter().map(|(replica, _)| *replica).collect();
    let mut disagreement: f64 = 0.0;
    loop {
        let advanced = runs
            .par_iter_mut()
            .with_max_len(1)
            .map(|run| run.advance(stop))
            .all(|going| going);
        if !advanced {
            return None;
        }
        let members: Vec<Member> = runs
            .iter()
            .zip(&instances)
            .map(|(run, replica)| Member::of(replica, &run.run()).following(run.variation()))
            .collect();
        let steps = runs.iter().map(|run| run.run().record.steps).sum::<u32>();
        if let Some(d) = group.disagreement(&members) {
            disagreement = disagreement.max(d);
        }
        match group.step(&members) {
            Step::Merged(measured) => {
                return Some(GroupRun {
                    measured,
                    variation: group.followed(&members),
                    replicas: count,
                    steps,
                    disagreement,
                });
            }
            Step::Continue => {
                for run in &mut runs {
                    run.release();
                }
            }
            // Every replica ran to its wait or end: a wait is for all.
            Step::Wait => unreachable!("every replica on the CPU runs to its wait"),
            Step::Alone { multistable } => {
                let (alone, variation) = if settings.backward {
                    let (run, v) = Law::run_with_variation_until(inst, settings, stop)?;
                    (run, Some(reduce_variation(inst, &run, &v)))
                } else {
                    (crate::laws::run_until(inst, settings, stop)?, None)
                };
                let mut measured = reduce(inst, &alone);
                // Only a finished run has a kind of motion (docs/output.md).
                if multistable && measured.status == STATUS_OK {
                    measured.motion = Motion::Multistable;
                }
                return Some(GroupRun {
                    measured,
                    variation,
                    replicas: 1,
                    steps: steps.saturating_add(alone.record.steps),
                    disagreement,
                });
            }
        }
    }
}
