//! From the command line's choice to a backend, said in one line on
//! stderr.

use anyhow::{Context, Result, bail};

use super::{Backend, CpuBackend, GpuBackend, Precision};
use crate::gpu::GpuContext;

/// Which integrator runs a scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum BackendChoice {
    /// A hardware GPU adapter when there is one, else the CPU path.
    #[default]
    Auto,
    /// The WGSL shader on any adapter, software ones (lavapipe) included.
    Gpu,
    /// The rayon CPU path in f64.
    Cpu,
}

/// Picks the backend and says which in one line on stderr.
pub fn select_backend(
    choice: BackendChoice,
    precision: Option<Precision>,
    threads: Option<usize>,
) -> Result<Box<dyn Backend>> {
    // f64 where the adapter has it: on the GPUs measured it costs no more
    // than f32 (the integrator waits on branches, not arithmetic) and it
    // follows the CPU reference to rounding.
    let gpu_precision = |ctx: &GpuContext| match precision {
        Some(p) => p,
        None if ctx.supports_f64() => Precision::F64,
        None => Precision::F32,
    };
    let backend: Box<dyn Backend> = match choice {
        BackendChoice::Cpu => {
            if precision == Some(Precision::F32) {
                bail!("--precision f32: the CPU path runs in f64 only");
            }
            Box::new(CpuBackend::new(threads)?)
        }
        BackendChoice::Gpu => {
            let ctx = GpuContext::new(true).context("--backend gpu")?;
            let precision = gpu_precision(&ctx);
            let gpu = GpuBackend::new(ctx, precision)?;
            eprintln!("pidm: {}", gpu.readiness());
            Box::new(gpu)
        }
        BackendChoice::Auto => match GpuContext::new(false) {
            Ok(ctx) => {
                let adapter = ctx.describe();
                let precision = gpu_precision(&ctx);
                match GpuBackend::new(ctx, precision) {
                    Ok(gpu) => {
                        eprintln!("pidm: {}", gpu.readiness());
                        Box::new(gpu)
                    }
                    Err(err) => {
                        eprintln!(
                            "pidm: the GPU path cannot run on {adapter}, using the CPU path \
                             ({err:#})"
                        );
                        Box::new(CpuBackend::new(threads)?)
                    }
                }
            }
            Err(err) => {
                eprintln!("pidm: no hardware GPU adapter, using the CPU path ({err})");
                Box::new(CpuBackend::new(threads)?)
            }
        },
    };
    eprintln!(
        "pidm: backend {} ({})",
        backend.describe(),
        backend.precision()
    );
    Ok(backend)
}
