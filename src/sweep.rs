//! Sweeps: runs every instance of a scene on a backend, chunk by chunk, and
//! hands finished chunks to a sink (the HDF5 writer) so memory stays bounded
//! whatever the instance count.
//!
//! Every instance is integrated independently and deterministically, so the
//! results are the same bit for bit for any thread count and chunk size.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use anyhow::{Result, bail};
use rayon::prelude::*;

use crate::cpu::integrate::{self, STATUS_OK, Settings};
use crate::model::{AXES, Instance};

/// Set when the user asks the run to stop (Ctrl-C); backends check it
/// between instances (CPU) and between time slices (GPU).
static INTERRUPT: AtomicBool = AtomicBool::new(false);

/// Asks every running backend to stop as soon as it can.
pub fn request_interrupt() {
    INTERRUPT.store(true, Ordering::Relaxed);
}

/// True once a stop was asked for.
pub fn interrupt_requested() -> bool {
    INTERRUPT.load(Ordering::Relaxed)
}

/// What a backend returns for one instance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outcome {
    /// Slider displacement over the measured periods [m]; zero unless the
    /// status is [`STATUS_OK`].
    pub displacement: [f64; AXES],
    pub status: u32,
    pub steps: u32,
}

/// One instance's entry in the maps, in SI units.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Record {
    /// Step per own drive cycle [m].
    pub step: [f64; AXES],
    /// Mean slider velocity [m/s].
    pub velocity: [f64; AXES],
    pub status: u32,
    pub steps: u32,
    /// 1-DOF steps with the other axis undriven [m] (zero when not asked).
    pub baseline_step: [f64; AXES],
    /// Worst status of the two baselines.
    pub baseline_status: u32,
}

/// A way of integrating many instances.
pub trait Backend: Sync {
    /// Names the hardware that ran, for the `backend` attribute.
    fn describe(&self) -> String;
    /// "f64" or "f32".
    fn precision(&self) -> &'static str;
    /// A good number of instances per chunk.
    fn chunk_size(&self) -> usize;
    /// The CPU threads the backend computes on, or `None` for the GPU.
    fn cpu_threads(&self) -> Option<usize>;
    /// Integrates the instances; `done(n)` reports n more finished ones.
    fn run(
        &self,
        instances: &[Instance],
        settings: &Settings,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Outcome>>;
}

/// The rayon CPU path in f64: the reference.
pub struct CpuBackend {
    pool: rayon::ThreadPool,
}

impl CpuBackend {
    /// A backend on `threads` threads, or on every core when `None`.
    pub fn new(threads: Option<usize>) -> Result<CpuBackend> {
        let mut builder = rayon::ThreadPoolBuilder::new();
        if let Some(n) = threads {
            if n == 0 {
                bail!("--threads must be at least 1");
            }
            builder = builder.num_threads(n);
        }
        Ok(CpuBackend {
            pool: builder.build()?,
        })
    }

    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }
}

/// Integrates one instance on the CPU.
pub fn run_one(inst: &Instance, settings: &Settings) -> Outcome {
    let st = integrate::run_instance(inst, settings);
    Outcome {
        displacement: integrate::displacement(inst, &st),
        status: st.status,
        steps: st.steps,
    }
}

impl Backend for CpuBackend {
    fn describe(&self) -> String {
        format!("cpu (rayon, {} threads)", self.threads())
    }

    fn precision(&self) -> &'static str {
        "f64"
    }

    fn chunk_size(&self) -> usize {
        4096.max(256 * self.threads())
    }

    fn cpu_threads(&self) -> Option<usize> {
        Some(self.threads())
    }

    fn run(
        &self,
        instances: &[Instance],
        settings: &Settings,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Outcome>> {
        Ok(self.pool.install(|| {
            instances
                .par_iter()
                .with_max_len(1)
                .map(|inst| {
                    // After a stop request the remaining instances are
                    // skipped; the sweep then discards the whole chunk.
                    if interrupt_requested() {
                        return Outcome::default();
                    }
                    let out = run_one(inst, settings);
                    done(1);
                    out
                })
                .collect()
        }))
    }
}

/// Turns a displacement outcome into map entries.
pub fn record(inst: &Instance, out: &Outcome) -> Record {
    let mut rec = Record {
        status: out.status,
        steps: out.steps,
        ..Record::default()
    };
    for i in 0..AXES {
        let (velocity, step) = inst.measure(i, out.displacement[i]);
        rec.velocity[i] = velocity;
        rec.step[i] = step;
    }
    rec
}

/// Totals over a sweep.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    pub instances: u64,
    /// Instances per status code (index = code; the last entry gathers
    /// unknown codes).
    pub status_counts: [u64; 6],
    /// Integrator steps over all main instances.
    pub steps: u64,
    /// Simulated time over all integrated instances, baselines included [s].
    pub simulated_s: f64,
    pub extreme_step: [f64; 2],
}

/// Everything a sweep needs to know about its instances.
pub struct Plan<'a> {
    pub count: u64,
    pub instance: &'a (dyn Fn(u64) -> Instance + Sync),
    pub settings: Settings,
    pub baselines: bool,
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
    let chunk = chunk.max(1) as u64;
    let mut summary = Summary {
        extreme_step: [f64::INFINITY, f64::NEG_INFINITY],
        ..Summary::default()
    };
    let mut start = 0;
    while start < plan.count {
        if interrupt_requested() {
            bail!(
                "interrupted after {start} of {} instances; nothing was written",
                plan.count
            );
        }
        let end = (start + chunk).min(plan.count);
        let mains: Vec<Instance> = (start..end).map(|i| (plan.instance)(i)).collect();
        // Jobs: the instances, then each baseline that differs from its
        // instance (a baseline of an instance whose other axis is undriven
        // is that instance).
        let mut jobs = mains.clone();
        let mut baseline_job = vec![[usize::MAX; AXES]; mains.len()];
        if plan.baselines {
            for (k, inst) in mains.iter().enumerate() {
                for (axis, job) in baseline_job[k].iter_mut().enumerate() {
                    let base = inst.baseline(axis);
                    *job = if base == *inst {
                        k
                    } else {
                        jobs.push(base);
                        jobs.len() - 1
                    };
                }
            }
        }
        // Progress counts main instances; baseline jobs add a proportional
        // share.
        let scale = mains.len() as f64 / jobs.len() as f64;
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
        let outcomes = backend.run(&jobs, &plan.settings, &done)?;
        if interrupt_requested() {
            bail!(
                "interrupted after {start} of {} instances; nothing was written",
                plan.count
            );
        }
        let left = mains.len() as u64 - reported.load(Ordering::Relaxed);
        if left > 0 {
            progress(left);
        }
        let mut records = Vec::with_capacity(mains.len());
        for (k, inst) in mains.iter().enumerate() {
            let mut rec = record(inst, &outcomes[k]);
            if plan.baselines {
                for (axis, &j) in baseline_job[k].iter().enumerate() {
                    let base = record(&jobs[j], &outcomes[j]);
                    rec.baseline_step[axis] = base.step[axis];
                    rec.baseline_status = rec.baseline_status.max(base.status);
                }
            }
            summary.instances += 1;
            summary.status_counts[(rec.status as usize).min(5)] += 1;
            summary.steps += rec.steps as u64;
            if rec.status == STATUS_OK {
                for axis in 0..AXES {
                    summary.extreme_step[0] = summary.extreme_step[0].min(rec.step[axis]);
                    summary.extreme_step[1] = summary.extreme_step[1].max(rec.step[axis]);
                }
            }
            records.push(rec);
        }
        summary.simulated_s += jobs.iter().map(Instance::duration).sum::<f64>();
        sink(start, &records)?;
        start = end;
    }
    Ok(summary)
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
