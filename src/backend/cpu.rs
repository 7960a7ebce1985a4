//! The rayon CPU path: every instance through [`run_one`], one per task,
//! in f64 (the reference) or in f32 (the f32 shader's mirror,
//! `pidm::laws::karnopp::single`).

use anyhow::{Result, bail};
use rayon::prelude::*;

use super::{Backend, Hardware, Precision};
use crate::interrupt::interrupt_requested;
use crate::laws::Law;
use crate::laws::floor::check;
use crate::laws::status::STATUS_GRAZE;
use crate::laws::{Replica, Settings};
use crate::measurement::{Outcome, reduce, reduce_variation};
use crate::model::Instance;
use crate::replicas;

/// The rayon CPU path: in f64 the reference.
pub struct CpuBackend {
    pool: rayon::ThreadPool,
    precision: Precision,
}

impl CpuBackend {
    /// A backend in f64 on `threads` threads, or on every core when `None`.
    pub fn new(threads: Option<usize>) -> Result<CpuBackend> {
        CpuBackend::with_precision(threads, Precision::F64)
    }

    /// A backend in `precision`: f64 is the reference; f32 is the f32
    /// shader's mirror, the same formulation in the same units, for
    /// checking the shader and for seeing what f32 does without a GPU.
    pub fn with_precision(threads: Option<usize>, precision: Precision) -> Result<CpuBackend> {
        let mut builder = rayon::ThreadPoolBuilder::new();
        if let Some(n) = threads {
            if n == 0 {
                bail!("--threads must be at least 1");
            }
            builder = builder.num_threads(n);
        }
        Ok(CpuBackend {
            pool: builder.build()?,
            precision,
        })
    }

    /// The threads a pool built from `--threads` gets: the flag's value, or
    /// every core.
    pub fn default_threads(threads: Option<usize>) -> usize {
        threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
    }

    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }
}

impl Backend for CpuBackend {
    fn describe(&self) -> String {
        let mirror = match self.precision {
            Precision::F64 => "",
            Precision::F32 => ", f32 mirror of the shader",
        };
        match self.threads() {
            1 => format!("cpu (rayon, 1 thread{mirror})"),
            n => format!("cpu (rayon, {n} threads{mirror})"),
        }
    }

    fn precision(&self) -> Precision {
        self.precision
    }

    fn chunk_size(&self) -> usize {
        4096.max(256 * self.threads())
    }

    fn hardware(&self) -> Hardware {
        Hardware::Cpu {
            threads: self.threads(),
        }
    }

    fn run(
        &self,
        instances: &[Instance],
        settings: &Settings,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Outcome>> {
        // Replicas on the threads a batch leaves idle (f64, the reference;
        // the f32 mirror runs every instance alone).
        let count = match self.precision {
            Precision::F64 => replicas::count(settings.replicas, self.threads(), instances.len()),
            Precision::F32 => 1,
        };
        Ok(self.pool.install(|| {
            let mut out: Vec<Outcome> = instances
                .par_iter()
                .with_max_len(1)
                .map(|inst| {
                    // After a stop request the remaining instances are
                    // skipped; the sweep then discards the whole chunk.
                    if interrupt_requested() {
                        return Outcome::default();
                    }
                    let out = match replicas::split_of(inst, settings, count) {
                        Some(split) => run_split(inst, settings, split),
                        None => run_one_in(inst, settings, self.precision),
                    };
                    done(1);
                    out
                })
                .collect();
            if self.precision == Precision::F32 && !interrupt_requested() {
                check_heaviest(instances, settings, &mut out);
            }
            out
        }))
    }
}

/// The f32 mirror's check of its heaviest window runs
/// ([`super::check`]): on the CPU a twin would cost about what the f64
/// reference costs, so the mirror always takes [`check::Route::Reference`]:
/// the checked runs carry the reference's value, as they do on a software
/// adapter.
fn check_heaviest(instances: &[Instance], settings: &Settings, out: &mut [Outcome]) {
    let candidates: Vec<(usize, u32)> = out
        .iter()
        .zip(instances)
        .enumerate()
        .filter(|(_, (o, inst))| check::is_candidate(inst, o.status, o.on_cpu))
        .map(|(k, (o, _))| (k, o.steps))
        .collect();
    let picked = check::heaviest(&candidates);
    let reference: Vec<Outcome> = picked
        .par_iter()
        .with_max_len(1)
        .map(|&k| Outcome {
            checked: true,
            ..run_one_in(&instances[k], settings, Precision::F64)
        })
        .collect();
    for (&k, outcome) in picked.iter().zip(reference) {
        out[k] = Outcome {
            on_cpu: true,
            ..outcome
        };
    }
}

/// Integrates one instance as a group of replicas on the CPU in f64
/// (`replicas::cpu`); stops as [`run_one`].
pub(super) fn run_split(inst: &Instance, settings: &Settings, split: Replica) -> Outcome {
    match replicas::cpu::run_group(inst, settings, split, &interrupt_requested) {
        Some(group) => {
            let (variation, variation_se) = group.variation.unwrap_or_default();
            Outcome {
                replicas: group.replicas,
                variation,
                variation_se,
                ..Outcome::of(&group.measured, group.steps, false)
            }
        }
        None => Outcome::default(),
    }
}

/// Integrates one instance on the CPU in f64 (the reference).
///
/// A stop request (`request_interrupt`) ends the integration within about
/// a millisecond; the outcome is then a default one that the sweep discards
/// with the rest of its chunk.
pub fn run_one(inst: &Instance, settings: &Settings) -> Outcome {
    run_one_in(inst, settings, Precision::F64)
}

/// Integrates one instance on the CPU in `precision` (f32 results are
/// reduced in f64 and SI units, as the GPU's are); stops as [`run_one`].
/// An f32 run that fails or meets a band graze is integrated again in f64,
/// as the f32 shader's are (`laws::karnopp::f32_needs_f64`), and marked `on_cpu`: the
/// mirror's backend gives what the f32 GPU path gives.
pub fn run_one_in(inst: &Instance, settings: &Settings, precision: Precision) -> Outcome {
    if settings.backward {
        return run_with_variation(inst, settings);
    }
    // The f32 status that sent the instance to f64, if one did.
    let Some((run, sent)) = Law::run_in_until(inst, settings, precision, interrupt_requested)
    else {
        return Outcome::default();
    };
    Outcome {
        graze: sent == Some(STATUS_GRAZE),
        ..Outcome::of(&reduce(inst, &run), run.record.steps, sent.is_some())
    }
}

/// Integrates one instance on the CPU in f64 keeping the slider's total
/// variation (`Settings::backward`, which only f64 on the CPU measures:
/// the scene's backend selection sees to that); stops as [`run_one`].
fn run_with_variation(inst: &Instance, settings: &Settings) -> Outcome {
    let Some((run, v)) = Law::run_with_variation_until(inst, settings, interrupt_requested) else {
        return Outcome::default();
    };
    let (variation, variation_se) = reduce_variation(inst, &run, &v);
    Outcome {
        variation,
        variation_se,
        ..Outcome::of(&reduce(inst, &run), run.record.steps, false)
    }
}
