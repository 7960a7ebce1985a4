//! From the command line's choice to a backend, said in one line on
//! stderr.

use anyhow::{Context, Result, bail};

use super::cost::{self, Estimate, Plan};
use super::{Backend, CpuBackend, GpuBackend, Precision, cost_book};
use crate::gpu::{GpuContext, Parts};
use crate::laws::{Law, Settings};
use crate::model::Instance;

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

/// What `--backend auto` weighs a run by.
#[derive(Clone, Debug)]
pub struct Workload {
    /// The distinct integrations the run computes (an upper bound will do).
    pub integrations: u64,
    /// The integrations auto's probe picks from: the run's distinct
    /// integrations, or a sample of them (`crate::run::estimate::integrations`).
    pub candidates: Vec<Instance>,
    pub settings: Settings,
    /// Whether the run searches stall loads (its probes carry a load).
    pub stall: bool,
    /// The scene's friction law: whether f32 and `--backend auto`'s cost
    /// model apply to it.
    pub law: Law,
}

impl Workload {
    /// The shader's parts the run uses, from its candidates, and a load
    /// wherever a stall search will set one: the pipeline a GPU prepares
    /// before any work (each batch takes one with the parts its own
    /// instances use).
    pub fn parts(&self) -> Parts {
        let mut parts = Parts::of(&self.candidates, &self.settings);
        parts.load |= self.stall;
        parts
    }
}

/// The backend chosen, and what a finished run on a hardware GPU measures
/// of it for later `auto` decisions ([`Selected::record`]).
pub struct Selected {
    backend: Box<dyn Backend>,
    measure: Option<Measure>,
}

/// What is known of a GPU run before it runs: the adapter's fixed costs,
/// and the run's core-seconds on the CPU path where auto probed it.
struct Measure {
    adapter: String,
    precision: Precision,
    open_s: f64,
    ready_s: f64,
    core_s: Option<f64>,
}

impl Selected {
    pub fn backend(&self) -> &dyn Backend {
        self.backend.as_ref()
    }

    /// After a complete run on a hardware GPU whose pipeline came from
    /// pidm's cache (a compile is a one-time cost, not the adapter's):
    /// records the adapter's fixed costs and, where auto probed the run and
    /// `integration_s` is the GPU's integrating time for the integrations
    /// probed (not a resumed, refined or stall run's), its throughput
    /// ([`cost_book`]). Does nothing for other backends.
    pub fn record(&self, integration_s: Option<f64>) {
        let Some(m) = &self.measure else {
            return;
        };
        let cores = match (m.core_s, integration_s) {
            (Some(core_s), Some(s)) if s >= cost_book::MIN_INTEGRATING_S => Some(core_s / s),
            _ => None,
        };
        cost_book::record(cost_book::Entry {
            adapter: m.adapter.clone(),
            precision: m.precision,
            open_s: m.open_s,
            ready_s: m.ready_s,
            cores,
        });
    }
}

/// What to record of a GPU backend once its run finishes: `None` on a
/// software adapter, or where the pipeline was compiled rather than taken
/// from pidm's cache.
fn measure_of(gpu: &GpuBackend, core_s: Option<f64>) -> Option<Measure> {
    let ctx = gpu.context();
    if !ctx.is_hardware() || !ctx.pipeline_from_cache() {
        return None;
    }
    let p = gpu.preparation()?;
    Some(Measure {
        adapter: ctx.describe(),
        precision: gpu.precision(),
        open_s: p.open_s,
        ready_s: p.pipeline_s + p.self_test_s,
        core_s,
    })
}

/// Picks the backend and says which in one line on stderr. `work` is what
/// `auto` weighs: the run's distinct integrations against the CPU's
/// threads, and where there are enough for a GPU to pay, a probe of their
/// cost ([`cost`]).
pub fn select_backend(
    choice: BackendChoice,
    precision: Option<Precision>,
    threads: Option<usize>,
    work: &Workload,
) -> Result<Selected> {
    let cpu = |threads: Option<usize>| -> Result<Selected> {
        finish(Box::new(CpuBackend::new(threads)?), None)
    };
    if let Some(why) = work.law.no_f32()
        && precision == Some(Precision::F32)
    {
        bail!("--precision f32: {why}");
    }
    let mut precision = precision;
    if work.settings.backward {
        if precision == Some(Precision::F32) {
            bail!(
                "--precision f32: {}; run it in f64",
                crate::laws::settings::BACKWARD_F64_ONLY
            );
        }
        if choice == BackendChoice::Auto {
            // Weighed as any run, in f64 (`GpuCosts::for_backward`).
            precision = Some(Precision::F64);
        }
    }
    if let Some(why) = work.law.auto_on_cpu()
        && choice == BackendChoice::Auto
    {
        // The cost model and its book do not weigh this law's scenes.
        eprintln!("pidm: --backend auto: the CPU path in f64 ({why})");
        return cpu(threads);
    }
    match choice {
        BackendChoice::Cpu => finish(
            Box::new(CpuBackend::with_precision(
                threads,
                precision.unwrap_or(Precision::F64),
            )?),
            None,
        ),
        BackendChoice::Gpu => {
            let ctx = GpuContext::new(true).context("--backend gpu")?;
            // f64 where the adapter has it: on the GPUs measured it costs no
            // more than f32 (the integrator waits on branches, not
            // arithmetic) and it follows the CPU reference to rounding.
            let precision = match precision {
                Some(p) => p,
                None if ctx.supports_f64() => Precision::F64,
                None => Precision::F32,
            };
            if work.settings.backward && precision == Precision::F32 {
                bail!(
                    "--backend gpu: adapter {} has no 64-bit floats in shaders (SHADER_F64); {}; \
                     run it with --backend cpu",
                    ctx.describe(),
                    crate::laws::settings::BACKWARD_F64_ONLY
                );
            }
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
            let gpu = GpuBackend::for_parts(ctx, precision, work.parts())?;
            eprintln!("pidm: {}", gpu.readiness());
            let measure = measure_of(&gpu, None);
            finish(Box::new(gpu), measure)
        }
        BackendChoice::Auto => auto(precision, threads, work, cpu),
    }
}

/// `--backend auto`: the plan ([`cost::plan`]) before anything is opened,
/// then, where a GPU may pay, the hardware adapter's own costs.
fn auto(
    precision: Option<Precision>,
    threads: Option<usize>,
    work: &Workload,
    cpu: impl Fn(Option<usize>) -> Result<Selected>,
) -> Result<Selected> {
    let cpu_threads = CpuBackend::default_threads(threads);
    let mut book = None;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let plan = cost::plan(
        work.integrations,
        cpu_threads,
        cores,
        precision,
        || {
            let loaded = cost_book::load();
            let known = known_costs(&loaded, precision, &work.settings);
            book = Some(loaded);
            known
        },
        |k| {
            crate::backend::probe::probe_instances(&work.candidates, &work.settings, cpu_threads, k)
        },
    );
    let estimate = match plan {
        Plan::TooFew {
            integrations,
            threads,
        } => {
            eprintln!(
                "pidm: {integrations} {} too few for a GPU to beat {threads} CPU {} (it needs {} \
                 or more); using the CPU path (--backend gpu uses the GPU anyway)",
                if integrations == 1 {
                    "integration is"
                } else {
                    "integrations are"
                },
                if threads == 1 { "thread" } else { "threads" },
                cost::min_integrations(threads)
            );
            return cpu(Some(threads));
        }
        Plan::Cpu(estimate) => {
            eprintln!("pidm: {}", estimate.say("a GPU", false));
            return cpu(Some(cpu_threads));
        }
        Plan::LookForGpu(estimate) => estimate,
    };
    // What auto weighed before looking, said too where no GPU is found.
    let weighed = estimate.as_ref().map_or(String::new(), |e| {
        format!("auto: {}; but ", e.weighed("a GPU"))
    });
    let ctx = match GpuContext::new(false) {
        Ok(ctx) => ctx,
        Err(err @ crate::gpu::GpuError::OnlySoftware { .. }) => {
            eprintln!(
                "pidm: {weighed}{err}: using the CPU path (--backend gpu runs lavapipe anyway)"
            );
            return cpu(threads);
        }
        Err(err) => {
            eprintln!("pidm: {weighed}no hardware GPU adapter, using the CPU path ({err})");
            return cpu(threads);
        }
    };
    let adapter = ctx.describe();
    let facts = AdapterFacts {
        f64: ctx.supports_f64(),
    };
    let precision = match auto_choice(facts, precision) {
        AutoChoice::Gpu(p) => p,
        AutoChoice::Cpu => {
            eprintln!(
                "pidm: {adapter} has no 64-bit floats in shaders; using the CPU path in f64 ({})",
                why_f64(&work.settings)
            );
            // Closing a device costs NVIDIA's driver 0.03-0.05 s; the
            // operating system frees it at exit either way.
            std::mem::forget(ctx);
            return cpu(threads);
        }
    };
    // The adapter's own costs, with the device open already.
    if let Some(estimate) = &estimate {
        let book = book.unwrap_or_else(cost_book::load);
        let estimate = Estimate {
            cpu: estimate.cpu.clone(),
            gpu: backward_costs(book.costs(&adapter, precision), &work.settings),
        };
        eprintln!("pidm: {}", estimate.say(&adapter, true));
        if estimate.cpu_wins(true) {
            std::mem::forget(ctx);
            return cpu(Some(estimate.cpu.threads));
        }
    }
    if precision == Precision::F32 && !facts.f64 {
        eprintln!(
            "pidm: {adapter} has no 64-bit floats in shaders; running the GPU in f32 \
             (self-tested against the CPU; on random scenes within 0.005 um + 1 % \
             of the CPU's f64 step on all but about 1 instance in 18,000: \
             results/gpu.md; --backend cpu runs f64)"
        );
    }
    match GpuBackend::for_parts(ctx, precision, work.parts()) {
        Ok(gpu) => {
            eprintln!("pidm: {}", gpu.readiness());
            // The book keeps the throughput of runs without the backward
            // travel (`GpuCosts::for_backward` scales it).
            let core_s = estimate
                .filter(|_| !work.settings.backward)
                .map(|e| e.cpu.core_s);
            let measure = measure_of(&gpu, core_s);
            finish(Box::new(gpu), measure)
        }
        Err(err) => {
            eprintln!("pidm: the GPU path cannot run on {adapter}, using the CPU path ({err:#})");
            cpu(threads)
        }
    }
}

/// Why auto runs f64 where an adapter has none: the backward travel, or
/// `--precision f64`.
fn why_f64(settings: &Settings) -> &'static str {
    if settings.backward {
        crate::laws::settings::BACKWARD_F64_ONLY
    } else {
        "--precision f64 needs them; leave --precision out to run the GPU in f32"
    }
}

/// The GPUs `book` knows that auto weighs for a run with `settings` in
/// `precision` (`None`: either; f64 where the run measures the backward
/// travel), their throughput slowed where it does ([`backward_costs`]).
pub fn known_costs(
    book: &cost_book::Book,
    precision: Option<Precision>,
    settings: &Settings,
) -> Vec<cost::GpuCosts> {
    let precision = precision.or(settings.backward.then_some(Precision::F64));
    book.known(precision)
        .into_iter()
        .map(|g| backward_costs(g, settings))
        .collect()
}

/// A GPU's costs for a run with `settings`: slower where it measures the
/// backward travel (`cost::GpuCosts::for_backward`).
fn backward_costs(costs: cost::GpuCosts, settings: &Settings) -> cost::GpuCosts {
    if settings.backward {
        costs.for_backward()
    } else {
        costs
    }
}

/// Says which backend runs, in one line on stderr.
fn finish(backend: Box<dyn Backend>, measure: Option<Measure>) -> Result<Selected> {
    eprintln!(
        "pidm: backend {} ({})",
        backend.describe(),
        backend.precision()
    );
    Ok(Selected { backend, measure })
}

/// Most `--threads` per core: the integration is bound by the CPU, so more
/// threads than cores only add overhead, and thousands of them take
/// seconds to start.
const MAX_THREADS_PER_CORE: usize = 4;

/// `--threads` may always be this many, on any machine: enough to run as
/// a 16-core machine would (tests and timings do), and quick to start.
const MIN_THREAD_LIMIT: usize = 64;

/// A `--threads` value: from 1 to `MAX_THREADS_PER_CORE` per core, or
/// `MIN_THREAD_LIMIT` where that is more.
pub fn thread_count(text: &str) -> Result<usize, String> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let limit = (MAX_THREADS_PER_CORE * cores).max(MIN_THREAD_LIMIT);
    match text.parse::<usize>() {
        Ok(0) => Err("expected at least 1 thread".into()),
        Ok(n) if n > limit => Err(format!(
            "{n} threads is too many: expected at most {limit} (the larger of \
             {MAX_THREADS_PER_CORE} per core on this machine's {cores} {} and \
             {MIN_THREAD_LIMIT}); the CPU path gains nothing from more threads than cores",
            if cores == 1 { "core" } else { "cores" }
        )),
        Ok(n) => Ok(n),
        Err(e) => Err(format!("{text:?} is not a whole number ({e})")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
