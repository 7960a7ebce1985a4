//! The rayon CPU path in f64: every instance through
//! [`run_one`], one per task.

use anyhow::{Result, bail};
use rayon::prelude::*;

use super::{Backend, Hardware, Precision};
use crate::cpu::integrate;
use crate::cpu::integrate::Settings;
use crate::interrupt::interrupt_requested;
use crate::measurement::{Outcome, reduce};
use crate::model::Instance;

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
        match self.threads() {
            1 => "cpu (rayon, 1 thread)".to_owned(),
            n => format!("cpu (rayon, {n} threads)"),
        }
    }

    fn precision(&self) -> Precision {
        Precision::F64
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

/// Integrates one instance on the CPU.
///
/// A stop request ([`request_interrupt`]) ends the integration within about
/// a millisecond; the outcome is then a default one that the sweep discards
/// with the rest of its chunk.
pub fn run_one(inst: &Instance, settings: &Settings) -> Outcome {
    let Some(run) = integrate::run_instance_until(inst, settings, interrupt_requested) else {
        return Outcome::default();
    };
    Outcome::of(&reduce(inst, &run), run.state.steps, false)
}
