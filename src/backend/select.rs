//! From the command line's choice to a backend, said in one line on
//! stderr.

use anyhow::{Context, Result};

use super::{Backend, CpuBackend, GpuBackend, Precision};
use crate::gpu::GpuContext;

/// Which integrator runs a scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum BackendChoice {
    /// A hardware GPU adapter when there is one and the run is large enough
    /// for it to pay (in f64 where the adapter has it, else in f32), else
    /// the CPU path.
    #[default]
    Auto,
    /// The WGSL shader on any adapter, software ones (lavapipe) included.
    Gpu,
    /// The rayon CPU path: f64 (the reference), or with `--precision
    /// f32` the f32 shader's CPU mirror.
    Cpu,
}

/// Fewest distinct integrations per CPU thread for which `--backend auto`
/// opens a GPU. One step takes a GPU lane tens of times as long as a CPU
/// core, and opening the device costs about 0.2 s before any work: on the
/// H100 machine of results/gpu.md (16 threads) whole runs of up to 1,024
/// random instances, or up to 20,000 instances of the coupling map, end
/// sooner on the CPU, and 4,096 random instances take both about as long.
/// Below this many per thread the CPU wins or loses only fractions of a
/// second.
pub const GPU_MIN_INTEGRATIONS_PER_THREAD: u64 = 256;

/// True when `--backend auto` should not even look for a GPU: the run has
/// too few integrations for one to pay (see
/// [`GPU_MIN_INTEGRATIONS_PER_THREAD`]).
pub fn too_few_for_gpu(integrations: u64, threads: usize) -> bool {
    integrations < GPU_MIN_INTEGRATIONS_PER_THREAD.saturating_mul(threads.max(1) as u64)
}

/// What `--backend auto` knows of the hardware adapter it found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AdapterFacts {
    /// The adapter offers `SHADER_F64`.
    pub f64: bool,
}

/// Where `--backend auto` runs a scene large enough for a GPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AutoChoice {
    /// The GPU in this precision (its self-test may still refuse it).
    Gpu(Precision),
    /// The CPU path: the adapter cannot run the precision asked for.
    Cpu,
}

/// `--backend auto`'s choice on a hardware adapter (software ones, lavapipe,
/// are slower than the CPU path and never chosen): f64 where the adapter
/// has it, else f32; the precision asked for where the adapter runs it.
/// f32 misses 0.005 um + 1 % of the CPU's f64 step on fewer than 1 random
/// instance in 100,000 with its checks (1 of 327,000 on lavapipe, 2 of
/// 300,000 with twins on an H200: results/gpu.md "The heaviest fifth" and
/// "f32 on an H200"), fewer than the CPU's own f64 step
/// moves by that much when its tolerance is made 100 times tighter (1 in
/// 3,600): on the random scenes of results/gpu.md, f32 is as close to the
/// CPU's map as that map is to a converged one, and `--verify` finds both
/// kinds.
pub fn auto_choice(adapter: AdapterFacts, precision: Option<Precision>) -> AutoChoice {
    match precision {
        Some(Precision::F64) if !adapter.f64 => AutoChoice::Cpu,
        Some(p) => AutoChoice::Gpu(p),
        None if adapter.f64 => AutoChoice::Gpu(Precision::F64),
        None => AutoChoice::Gpu(Precision::F32),
    }
}

/// Picks the backend and says which in one line on stderr. `integrations`
/// is the number of distinct integrations the run will compute (an upper
/// bound will do), which `auto` weighs against the CPU's threads.
pub fn select_backend(
    choice: BackendChoice,
    precision: Option<Precision>,
    threads: Option<usize>,
    integrations: u64,
) -> Result<Box<dyn Backend>> {
    // f64 where the adapter has it: on the GPUs measured it costs no more
    // than f32 (the integrator waits on branches, not arithmetic) and it
    // follows the CPU reference to rounding.
    let gpu_precision = |ctx: &GpuContext| match precision {
        Some(p) => p,
        None if ctx.supports_f64() => Precision::F64,
        None => Precision::F32,
    };
    let cpu_threads = CpuBackend::default_threads(threads);
    let backend: Box<dyn Backend> = match choice {
        BackendChoice::Cpu => Box::new(CpuBackend::with_precision(
            threads,
            precision.unwrap_or(Precision::F64),
        )?),
        BackendChoice::Gpu => {
            let ctx = GpuContext::new(true).context("--backend gpu")?;
            let precision = gpu_precision(&ctx);
            if !ctx.is_hardware() {
                let name = ctx.describe();
                let kind = if name.contains("llvmpipe") {
                    " (lavapipe)"
                } else {
                    ""
                };
                eprintln!(
                    "pidm: no hardware GPU; the software adapter{kind} runs the shader, on the \
                     CPU: {name}"
                );
            }
            let gpu = GpuBackend::new(ctx, precision)?;
            eprintln!("pidm: {}", gpu.readiness());
            Box::new(gpu)
        }
        BackendChoice::Auto
            if precision != Some(Precision::F32) && too_few_for_gpu(integrations, cpu_threads) =>
        {
            let threads = cpu_threads;
            eprintln!(
                "pidm: {integrations} {} too few for a GPU to beat {threads} CPU {} (it needs {} \
                 or more); using the CPU path (--backend gpu uses the GPU anyway)",
                if integrations == 1 {
                    "integration is"
                } else {
                    "integrations are"
                },
                if threads == 1 { "thread" } else { "threads" },
                GPU_MIN_INTEGRATIONS_PER_THREAD * threads as u64
            );
            Box::new(CpuBackend::new(Some(threads))?)
        }
        BackendChoice::Auto => match GpuContext::new(false) {
            Ok(ctx) => {
                let adapter = ctx.describe();
                let facts = AdapterFacts {
                    f64: ctx.supports_f64(),
                };
                let precision = match auto_choice(facts, precision) {
                    AutoChoice::Gpu(p) => p,
                    AutoChoice::Cpu => {
                        eprintln!(
                            "pidm: {adapter} has no 64-bit floats in shaders; using the CPU \
                             path in f64 (--precision f64 needs them; leave --precision out \
                             to run the GPU in f32)"
                        );
                        return finish(Box::new(CpuBackend::new(threads)?));
                    }
                };
                if precision == Precision::F32 && !facts.f64 {
                    eprintln!(
                        "pidm: {adapter} has no 64-bit floats in shaders; running the GPU in f32 \
                         (self-tested against the CPU; on random scenes within 0.005 um + 1 % \
                         of the CPU's f64 step on all but about 1 instance in 18,000: \
                         results/gpu.md; --backend cpu runs f64)"
                    );
                }
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
            Err(err @ crate::gpu::GpuError::OnlySoftware { .. }) => {
                eprintln!("pidm: {err}: using the CPU path (--backend gpu runs lavapipe anyway)");
                Box::new(CpuBackend::new(threads)?)
            }
            Err(err) => {
                eprintln!("pidm: no hardware GPU adapter, using the CPU path ({err})");
                Box::new(CpuBackend::new(threads)?)
            }
        },
    };
    finish(backend)
}

/// Says which backend runs, in one line on stderr.
fn finish(backend: Box<dyn Backend>) -> Result<Box<dyn Backend>> {
    eprintln!(
        "pidm: backend {} ({})",
        backend.describe(),
        backend.precision()
    );
    Ok(backend)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One row: integrations, CPU threads, whether auto stays on the CPU.
    fn check(integrations: u64, threads: usize, cpu: bool) {
        assert_eq!(
            too_few_for_gpu(integrations, threads),
            cpu,
            "{integrations} integrations on {threads} threads"
        );
    }

    /// One row: whether the adapter has f64, the precision asked for, what
    /// auto runs.
    fn choose(f64: bool, asked: Option<Precision>, expected: AutoChoice) {
        assert_eq!(
            auto_choice(AdapterFacts { f64 }, asked),
            expected,
            "f64 {f64}, asked {asked:?}"
        );
    }

    #[test]
    fn auto_runs_f64_where_the_adapter_has_it_else_f32() {
        use AutoChoice::{Cpu, Gpu};
        use Precision::{F32, F64};
        choose(true, None, Gpu(F64));
        choose(false, None, Gpu(F32));
        choose(false, Some(F32), Gpu(F32));
        choose(true, Some(F32), Gpu(F32));
        choose(false, Some(F64), Cpu);
        choose(true, Some(F64), Gpu(F64));
    }

    #[test]
    fn auto_leaves_small_runs_to_the_cpu() {
        // sweeps/paper.toml: 12 integrations.
        check(12, 16, true);
        check(12, 2, true);
        check(0, 1, true);
        // The threshold itself opens the GPU.
        check(4095, 16, true);
        check(4096, 16, false);
        check(512, 2, false);
        // A 200 x 200 map.
        check(40_000, 16, false);
        // A thread count of zero counts as one.
        check(255, 0, true);
        check(256, 0, false);
    }
}
