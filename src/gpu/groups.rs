//! Replicas on the device (`crate::replicas`): a batch with fewer
//! instances than lanes runs each splittable instance as a group of
//! replica jobs, each on a lane of its own, in either precision. A replica runs to the ladder
//! level it waits at (`measured` 2, counted finished by the shader), a
//! cycle split's piece to its end;
//! between dispatches the host reads the groups whose replicas all
//! stopped, and each group does what [`Group::step`] says, the rule the
//! CPU's groups follow too: its jobs go back to the queue and the lanes
//! that hold none take them (`entry.wgsl`, `take_idle`), or it stops with
//! the merged estimate, or it gives up the split and the instance runs
//! again alone after the batch, labelled multistable where its replicas
//! disagreed. The batch's other instances run alongside, as in any batch.
//! Once the queue is empty and the groups left hold few jobs
//! ([`Groups::tail_of`]), the CPU continues f64 groups from their states
//! (`replicas::cpu::continue_replicas`) and the batch's own unfinished
//! instances too, as any batch's tail; f32 groups run to their ends on the
//! device (the CPU cannot continue an f32 state, and starting a replica
//! over would lose what its group shares).

use std::marker::PhantomData;

use super::runner::Runner;
use super::slices::Between;
use super::*;
use crate::laws::floor::measure::VERDICT_RUNNING;
use crate::laws::status::STATUS_OK;
use crate::laws::{Replica, Replicas};
use crate::model::motion::Motion;
use crate::replicas::{Group, Member, Step};

/// A batch's jobs: its instances that run alone, in order, then every
/// group's replicas, group after group.
pub(super) struct Split {
    jobs: Vec<(Instance, Replica)>,
    /// The batch index of each job that runs alone (the first jobs).
    alone: Vec<usize>,
    groups: Vec<GpuGroup>,
}

impl Split {
    /// The jobs of `instances` where `count` replicas per instance are
    /// free (`replicas::count_queued`), or `None` where no instance splits.
    pub(super) fn of(instances: &[Instance], settings: &Settings, count: u32) -> Option<Split> {
        let splits: Vec<Option<Replica>> = instances
            .iter()
            .map(|inst| crate::replicas::split_of(inst, settings, count))
            .collect();
        if splits.iter().all(Option::is_none) {
            return None;
        }
        let alone: Vec<usize> = (0..instances.len())
            .filter(|&k| splits[k].is_none())
            .collect();
        let mut jobs: Vec<(Instance, Replica)> = alone
            .iter()
            .map(|&k| (instances[k], Replica::NONE))
            .collect();
        let mut groups = Vec::new();
        for (k, split) in splits.iter().enumerate() {
            let Some(split) = split else { continue };
            let group = Group::new(&instances[k], settings, *split);
            let first = jobs.len();
            jobs.extend(group.replicas());
            groups.push(GpuGroup {
                index: k,
                inst: instances[k],
                group,
                first,
                done: None,
            });
        }
        Some(Split {
            jobs,
            alone,
            groups,
        })
    }
}

/// One instance's replicas in a batch.
struct GpuGroup {
    /// The instance's index in the batch.
    index: usize,
    inst: Instance,
    group: Group,
    /// Its first job; its replicas are the next `group.count()` jobs.
    first: usize,
    done: Option<Done>,
}

/// How a group ended, with the steps its replicas took.
#[derive(Clone, Copy)]
enum Done {
    Merged(Measured, u32),
    Alone { multistable: bool, steps: u32 },
}

/// A batch's groups in precision `L`, stepped between its dispatches.
struct Groups<L> {
    groups: Vec<GpuGroup>,
    /// The first replica job: replicas run from here to the batch's end.
    first: usize,
    /// The finished count of the last look, after what it queued again: a
    /// dispatch that finished nothing more changed no group.
    seen: Option<u64>,
    /// The jobs the CPU takes over once no more of them are left
    /// ([`Groups::tail_of`]), 0 for none.
    tail: u64,
    layout: PhantomData<L>,
}

impl<L> Groups<L> {
    /// The jobs of a split batch of `jobs` that the CPU takes over with
    /// `options` on `threads` threads: `BatchOptions::cpu_tail` where set,
    /// else [`CPU_TAIL_PER_THREAD`] per thread, at most a quarter of the
    /// batch. The last groups' replicas are long chains on few lanes: on
    /// lavapipe the map's last groups of `results/pipeline/twofreq6.toml`
    /// ran a fifth of its time on one workgroup, at about 190 iterations a
    /// lane per dispatch (its loop limiter), where a CPU thread runs one
    /// replica several times as fast (results/replicas.md).
    fn tail_of(options: &BatchOptions, jobs: usize, threads: usize) -> u64 {
        match options.cpu_tail {
            Some(tail) => tail as u64,
            None => (CPU_TAIL_PER_THREAD * threads).min(jobs / 4) as u64,
        }
    }

    /// The jobs of the groups that have not ended.
    fn undone_jobs(&self) -> u64 {
        self.groups
            .iter()
            .filter(|g| g.done.is_none())
            .map(|g| g.group.count() as u64)
            .sum()
    }
}

impl<L: Layout> Between for Groups<L> {
    fn after(
        &mut self,
        runner: &Runner,
        states: &wgpu::Buffer,
        measures: &wgpu::Buffer,
        finished: u64,
    ) -> Result<Vec<u32>, GpuError> {
        if self.seen == Some(finished) || self.groups.iter().all(|g| g.done.is_some()) {
            return Ok(Vec::new());
        }
        let replicas = self
            .groups
            .last()
            .map_or(0, |g| g.first + g.group.count() as usize - self.first);
        let all: Vec<L::State> = read(runner, states, self.first, replicas)?;
        let mut again = Vec::new();
        for g in self.groups.iter_mut().filter(|g| g.done.is_none()) {
            let count = g.group.count() as usize;
            let own = &all[g.first - self.first..][..count];
            // As `Group::step` reads them.
            let group = &g.group;
            let ended = |s: &L::State| {
                let (status, measured, period) = L::progress(s);
                group.gives_up(status, measured, period)
            };
            let running = |(r, s): (usize, &L::State)| {
                let (status, measured, period) = L::progress(s);
                group.runs(r as u32, status, measured, period)
            };
            let steps = own.iter().fold(0u32, |n, s| n.saturating_add(L::steps(s)));
            if own.iter().any(ended) {
                // The split is given up: the replicas still running stop.
                for (j, s) in (g.first..).zip(own.iter().enumerate()) {
                    if running(s) {
                        write_u32(runner, states, state_field::<L>(j), 1);
                    }
                }
                g.done = Some(Done::Alone {
                    multistable: false,
                    steps,
                });
                continue;
            }
            if own.iter().enumerate().any(running) {
                continue;
            }
            let taken: Vec<L::Measure> = read(runner, measures, g.first, count)?;
            let members: Vec<Member> = own
                .iter()
                .zip(&taken)
                .zip(group.replicas())
                .map(|((s, m), (replica, _))| Member::of(&replica, &L::group_run(s, m).ended()))
                .collect();
            match g.group.step(&members) {
                Step::Wait => {}
                Step::Continue => {
                    for j in g.first..g.first + count {
                        write_u32(runner, states, state_field::<L>(j), 0);
                        write_u32(runner, measures, verdict_field::<L>(j), VERDICT_RUNNING);
                        again.push(j as u32);
                    }
                }
                Step::Merged(measured) => g.done = Some(Done::Merged(measured, steps)),
                Step::Alone { multistable } => g.done = Some(Done::Alone { multistable, steps }),
            }
        }
        self.seen = Some(finished - again.len() as u64);
        Ok(again)
    }

    /// Once the groups not ended hold at most `tail` jobs, and at most
    /// `tail` jobs run: the CPU continues them from their states
    /// ([`Runner::batch_split`]).
    fn hand_over(&self, unfinished: u64) -> bool {
        self.tail > 0 && unfinished <= self.tail && self.undone_jobs() <= self.tail
    }
}

/// The byte offset of job `j`'s `State::measured`.
fn state_field<L: Layout>(j: usize) -> u64 {
    (j * size_of::<L::State>() + L::MEASURED_OFFSET) as u64
}

/// The byte offset of job `j`'s `Measure::verdict`.
fn verdict_field<L: Layout>(j: usize) -> u64 {
    (j * size_of::<L::Measure>() + L::VERDICT_OFFSET) as u64
}

fn write_u32(runner: &Runner, buffer: &wgpu::Buffer, offset: u64, value: u32) {
    runner
        .queue
        .write_buffer(buffer, offset, bytemuck::bytes_of(&value));
}

/// Entries `first..first + count` of an array of `T` in `buffer`.
fn read<T: bytemuck::Pod>(
    runner: &Runner,
    buffer: &wgpu::Buffer,
    first: usize,
    count: usize,
) -> Result<Vec<T>, GpuError> {
    let bytes = (count * size_of::<T>()) as u64;
    let staging = readback::mappable(runner.device, "replicas readback", bytes.max(4));
    let mut encoder = runner.device.create_command_encoder(&Default::default());
    let offset = (first * size_of::<T>()) as u64;
    encoder.copy_buffer_to_buffer(buffer, offset, &staging, 0, bytes);
    runner.queue.submit([encoder.finish()]);
    readback::with_mapped_prefix(runner.device, &staging, bytes, |bytes| {
        bytes
            .chunks_exact(size_of::<T>())
            .map(bytemuck::pod_read_unaligned)
            .collect()
    })
}

impl Runner<'_> {
    /// A batch with replica groups (`split`): its jobs on the device, no
    /// CPU tail; the outcomes of its instances in order, each group's the
    /// merged estimate or its instance's own run, integrated again alone.
    pub(super) fn batch_split<L: Layout>(
        &self,
        instances: &[Instance],
        split: Split,
        progress: &mut dyn FnMut(u64),
    ) -> Result<Vec<GpuOutcome>, GpuError> {
        let n = instances.len();
        let Split {
            jobs,
            alone,
            groups,
        } = split;
        // f32 groups run to their ends on the device: the CPU cannot
        // continue their states (module docs).
        let continuable = L::PRECISION == Precision::F64;
        let mut groups = Groups::<L> {
            groups,
            first: alone.len(),
            seen: None,
            tail: match continuable {
                true => {
                    Groups::<L>::tail_of(self.options, jobs.len(), rayon::current_num_threads())
                }
                false => 0,
            },
            layout: PhantomData,
        };
        let options = BatchOptions {
            cpu_tail: Some(0),
            ..*self.options
        };
        let runner = self.with(self.settings, &options);
        let mut coefficients: Vec<L::Coefficients> = jobs
            .par_iter()
            .map(|(inst, r)| L::pack_replica(inst, self.settings, *r))
            .collect();
        let job_instances: Vec<Instance> = jobs.iter().map(|(inst, _)| *inst).collect();
        let (pipeline, variant) = runner.pipeline::<L>(L::PRECISION, &coefficients)?;
        let segments =
            segment_binding::<L>(self.device, variant, &job_instances, &mut coefficients);
        let extra = segment_entries(&segments);
        let total = job_instances.len() as u64;
        let mut job_progress = |done: u64| progress(done * n as u64 / total);
        let Sliced {
            readback: (states, measure_list, _),
            ..
        } = runner.slices::<L>(
            Work {
                instances: &job_instances,
                coefficients: &coefficients,
                states: None,
            },
            Kernel::with_segments(&pipeline, variant, &extra),
            &mut job_progress,
            None,
            Some(&mut groups),
        )?;
        drop(coefficients);
        let first = groups.first;
        let ran_alone = runner.outcomes::<L>(
            &job_instances[..first],
            &states[..first],
            (&measure_list[..first.min(measure_list.len())], &[]),
            Vec::new(),
        );
        let mut out: Vec<Option<GpuOutcome>> = vec![None; n];
        for (&k, outcome) in alone.iter().zip(ran_alone) {
            out[k] = Some(outcome);
        }
        self.on_cpu_merged_or_again::<L>(&groups.groups, (&states, &measure_list), &mut out)?;
        progress(n as u64);
        Ok(out
            .into_iter()
            .map(|o| o.expect("every instance has an outcome"))
            .collect())
    }

    /// Each group's outcome into `out`: its merged estimate; for the
    /// groups the device handed over (`done` none: the batch's tail, or a
    /// test's slice limit), the CPU's continuation of their replicas from
    /// the batch's `states` and accumulators; or its instance's own run (a batch of its
    /// own, replicas off), labelled multistable where its replicas
    /// disagreed.
    fn on_cpu_merged_or_again<L: Layout>(
        &self,
        groups: &[GpuGroup],
        (states, measures): (&[L::State], &[L::Measure]),
        out: &mut [Option<GpuOutcome>],
    ) -> Result<(), GpuError> {
        // Groups the device handed over: f64 ones continue on the CPU; an
        // f32 group (only a test's slice limit leaves one) runs again alone.
        let continuable = L::PRECISION == Precision::F64;
        let handed: Vec<&GpuGroup> = groups
            .iter()
            .filter(|g| g.done.is_none() && continuable)
            .collect();
        let _tail = crate::profile::span(crate::profile::Phase::CpuPart);
        let on_cpu: Vec<Option<crate::replicas::cpu::GroupRun>> = handed
            .par_iter()
            .with_max_len(1)
            .map(|g| {
                let replicas = g.group.replicas();
                let runs = (g.first..g.first + replicas.len())
                    .zip(&replicas)
                    .map(|(j, &(replica, r))| {
                        let run = L::continuable(&g.inst, &states[j], Some(&measures[j]))
                            .expect("an f64 state continues on the CPU");
                        crate::laws::law::Resumable::of_run(&replica, self.settings, r, run)
                    })
                    .collect();
                let stop = crate::interrupt::interrupt_requested;
                crate::replicas::cpu::continue_replicas(
                    &g.inst,
                    self.settings,
                    &g.group,
                    &replicas,
                    runs,
                    &stop,
                )
            })
            .collect();
        for (g, run) in handed.iter().zip(on_cpu) {
            let run = run.ok_or(GpuError::Interrupted)?;
            out[g.index] = Some(GpuOutcome {
                replicas: run.replicas,
                finished_on_cpu: true,
                ..GpuOutcome::of(&run.measured, run.steps)
            });
        }
        let mut again = Vec::new();
        for g in groups {
            match g.done {
                Some(Done::Merged(measured, steps)) => {
                    out[g.index] = Some(GpuOutcome {
                        replicas: g.group.count(),
                        ..GpuOutcome::of(&measured, steps)
                    });
                }
                Some(Done::Alone { multistable, steps }) => again.push((g, multistable, steps)),
                None if !continuable => again.push((g, false, 0)),
                None => {}
            }
        }
        if again.is_empty() {
            return Ok(());
        }
        let settings = Settings {
            replicas: Replicas::Count(1),
            ..*self.settings
        };
        let runner = self.with(&settings, self.options);
        let instances: Vec<Instance> = again.iter().map(|(g, _, _)| g.inst).collect();
        let runs = runner.batch::<L>(&instances, None, &mut |_| {})?;
        for ((g, multistable, steps), mut run) in again.into_iter().zip(runs) {
            run.steps = run.steps.saturating_add(steps);
            // Only a finished run has a kind of motion (docs/output.md).
            if multistable && run.status == STATUS_OK {
                run.motion = Motion::Multistable;
            }
            out[g.index] = Some(run);
        }
        Ok(())
    }
}
