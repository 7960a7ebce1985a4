//! `--backend auto`'s cost model: the run's estimated time on the CPU path
//! against its estimated time on a GPU, and the plan that follows from
//! them. Plain values and pure functions; [`super::select`] runs the probe
//! and opens the device, [`super::cost_book`] keeps the GPU costs measured
//! on this machine.
//!
//! - **CPU**: the probe `pidm check` runs ([`crate::backend::probe`]) measures
//!   the core-seconds of an integration; times the run's distinct
//!   integrations, over the CPU threads (the cores the probe's threads
//!   had), that is the run's integration time on the CPU path
//!   ([`crate::backend::probe::cpu_sweep_s`]).
//! - **GPU**: fixed costs (opening the device, the pipeline from the
//!   cache, the self-test) plus the same core-seconds over the GPU's
//!   throughput in CPU-core equivalents. Both default to what
//!   results/gpu.md measured ([`GpuCosts::default`]) until a GPU run on
//!   this machine measures its own ([`super::cost_book`]).
//!
//! What both paths share (starting the process, reading the scene,
//! writing the file) is left out: it does not change which is faster.

use super::Precision;
use crate::backend::probe::{PROBE_MAX, Probe};

/// Fewest distinct integrations per CPU thread for which `--backend auto`
/// probes the run's cost and may open a GPU; below, the CPU path runs
/// without either. Random instances are the heaviest per instance that
/// results/gpu.md times, and at this many per thread (1,024 on 16 threads)
/// the H100 machine's 16 cores finished them in 0.41 s, before the GPU
/// (0.50 s in f64): a measured floor, not a proof (a scene of much longer
/// instances could pay on a GPU below it; `--backend gpu` runs it there).
pub const GPU_MIN_INTEGRATIONS_PER_THREAD: u64 = 64;

/// `--backend auto` probes at most one in this many of a run's distinct
/// integrations (and at most [`PROBE_MAX`]), so that the probe costs at
/// most about 3 % of the run on the CPU path.
pub const PROBE_SHARE: u64 = 32;

/// True when `--backend auto` should neither probe nor look for a GPU: the
/// run has too few integrations for one to pay (see
/// [`GPU_MIN_INTEGRATIONS_PER_THREAD`]).
pub fn too_few_for_gpu(integrations: u64, threads: usize) -> bool {
    integrations < min_integrations(threads)
}

/// The fewest integrations auto weighs a GPU for on `threads` threads.
pub fn min_integrations(threads: usize) -> u64 {
    GPU_MIN_INTEGRATIONS_PER_THREAD.saturating_mul(threads.max(1) as u64)
}

/// How many integrations auto's probe takes for a run of `integrations`.
pub fn probe_size(integrations: u64) -> usize {
    (integrations / PROBE_SHARE).clamp(1, PROBE_MAX as u64) as usize
}

/// Default time to find a hardware adapter and open its device [s]:
/// 0.13-0.18 s on the H100 of results/gpu.md ("Start-up").
pub const DEFAULT_OPEN_S: f64 = 0.15;

/// Default time to create the pipeline from pidm's cache and run the
/// self-test [s]: 0.01-0.03 s and 0.02-0.03 s on that H100, so that the
/// fixed costs come to 0.2 s.
pub const DEFAULT_READY_S: f64 = 0.05;

/// Default throughput of a GPU in CPU-core equivalents: on the H200 of
/// results/gpu.md ("The fifth on an H200") the 20,000 random instances of
/// `pidm random-scene --seed 7 --count 20000` took 2.95 s integrating on
/// 16 CPU cores and 1.51 s on the GPU in f64, 2.95 x 16 / 1.51 = 31 cores.
pub const DEFAULT_GPU_CORES: f64 = 31.0;

/// How much more a GPU's throughput falls than the CPU path's where a run
/// measures the backward travel (`output.backward`): the probe's
/// core-seconds already carry the CPU's share, the GPU's throughput is
/// divided by this. On the H200 of results/bench.md ("On an H200") random
/// 2,000 and 20,000 integrated 1.33-1.35x and 1.50x slower with it on the
/// GPU, 1.27x on 16 CPU cores: 1.50 / 1.27 = 1.18, rounded up.
pub const BACKWARD_GPU_SLOWDOWN: f64 = 1.2;

/// Where a figure of [`GpuCosts`] comes from: measured by earlier runs on
/// an adapter (the median of `runs`), or the default of results/gpu.md.
#[derive(Clone, Debug, PartialEq)]
pub struct Measured {
    /// The adapter, as `GpuContext::describe` names it.
    pub adapter: String,
    pub precision: Precision,
    pub runs: usize,
}

/// What a GPU costs a run: fixed costs and throughput.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuCosts {
    /// Finding the adapter and opening the device [s].
    pub open_s: f64,
    /// Creating the pipeline (from the cache) and the self-test [s].
    pub ready_s: f64,
    /// Throughput in CPU-core equivalents: the run's core-seconds on the
    /// CPU path over the GPU's integrating seconds.
    pub cores: f64,
    /// Where `open_s` and `ready_s` come from (`None`: the defaults).
    pub fixed_from: Option<Measured>,
    /// Where `cores` comes from (`None`: the default).
    pub cores_from: Option<Measured>,
    /// `cores` is for a run that measures the backward travel
    /// ([`GpuCosts::for_backward`]).
    pub backward: bool,
}

impl Default for GpuCosts {
    /// The costs of results/gpu.md's H100 and H200.
    fn default() -> GpuCosts {
        GpuCosts {
            open_s: DEFAULT_OPEN_S,
            ready_s: DEFAULT_READY_S,
            cores: DEFAULT_GPU_CORES,
            fixed_from: None,
            cores_from: None,
            backward: false,
        }
    }
}

impl GpuCosts {
    /// Opening the device, the pipeline and the self-test [s].
    pub fn fixed_s(&self) -> f64 {
        self.open_s + self.ready_s
    }

    /// The GPU's time for `core_s` core-seconds of the CPU path's work [s].
    pub fn work_s(&self, core_s: f64) -> f64 {
        core_s / self.cores.max(f64::MIN_POSITIVE)
    }

    /// The costs of a run that measures the backward travel: the
    /// throughput over [`BACKWARD_GPU_SLOWDOWN`] (the book keeps runs
    /// without it).
    pub fn for_backward(self) -> GpuCosts {
        if self.backward {
            return self;
        }
        GpuCosts {
            cores: self.cores / BACKWARD_GPU_SLOWDOWN,
            backward: true,
            ..self
        }
    }

    /// Where the figures come from, in words: "results/gpu.md's defaults,
    /// throughput 31 CPU cores", "measured on NVIDIA H100 (...) in f64:
    /// fixed costs the median of 5 runs, throughput 27 CPU cores the
    /// median of 3"; for the backward travel ", over 1.2 for the backward
    /// travel" after it.
    pub fn source(&self) -> String {
        let said = self.source_of_runs();
        if self.backward {
            format!(
                "{said}, over {BACKWARD_GPU_SLOWDOWN} for the backward travel (results/bench.md)"
            )
        } else {
            said
        }
    }

    fn source_of_runs(&self) -> String {
        // The throughput the runs measured, before `for_backward`.
        let throughput = if self.backward {
            self.cores * BACKWARD_GPU_SLOWDOWN
        } else {
            self.cores
        };
        let runs = |n: usize| format!("{n} {}", if n == 1 { "run" } else { "runs" });
        match (&self.fixed_from, &self.cores_from) {
            (None, None) => {
                format!("results/gpu.md's defaults, throughput {throughput:.0} CPU cores")
            }
            (Some(f), Some(c)) if f.adapter == c.adapter && f.precision == c.precision => {
                format!(
                    "measured on {} in {}: fixed costs the median of {}, throughput {:.0} CPU \
                     cores the median of {}",
                    f.adapter,
                    f.precision,
                    runs(f.runs),
                    throughput,
                    runs(c.runs)
                )
            }
            (fixed, cores) => {
                let fixed = match fixed {
                    Some(f) => format!(
                        "fixed costs measured on {} in {}, the median of {}",
                        f.adapter,
                        f.precision,
                        runs(f.runs)
                    ),
                    None => "results/gpu.md's fixed costs".to_string(),
                };
                let cores = match cores {
                    Some(c) => format!(
                        "throughput {:.0} CPU cores measured on {} in {}, the median of {}",
                        throughput,
                        c.adapter,
                        c.precision,
                        runs(c.runs)
                    ),
                    None => format!("results/gpu.md's throughput, {throughput:.0} CPU cores"),
                };
                format!("{fixed}; {cores}")
            }
        }
    }
}

/// The run on the CPU path, estimated from the probe.
#[derive(Clone, Debug, PartialEq)]
pub struct CpuEstimate {
    /// The run's integration time on the CPU path [s].
    pub seconds: f64,
    /// The run's work [core-seconds of the CPU path].
    pub core_s: f64,
    /// The CPU path's threads.
    pub threads: usize,
}

impl CpuEstimate {
    /// The estimate for `integrations` on `threads` threads from a probe
    /// run with those threads on a machine of `cores` cores. More threads
    /// than cores share them, and each probed integration's wall time then
    /// counts the others' turns too: its core-seconds are its wall time
    /// times cores over threads.
    pub fn from_probe(
        integrations: u64,
        probe: &Probe,
        threads: usize,
        cores: usize,
    ) -> CpuEstimate {
        let shared = (cores.max(1) as f64 / threads.max(1) as f64).min(1.0);
        CpuEstimate {
            seconds: crate::backend::probe::cpu_sweep_s(integrations, probe),
            core_s: probe.mean_core_s * integrations as f64 * shared,
            threads,
        }
    }
}

/// Both paths' estimates for one run.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    pub cpu: CpuEstimate,
    pub gpu: GpuCosts,
}

impl Estimate {
    /// The GPU's work on the run [s].
    pub fn gpu_work_s(&self) -> f64 {
        self.gpu.work_s(self.cpu.core_s)
    }

    /// The GPU's whole time on the run, fixed costs included [s].
    pub fn gpu_s(&self) -> f64 {
        self.gpu.fixed_s() + self.gpu_work_s()
    }

    /// Whether the CPU path is estimated to end no later than the GPU; with
    /// `opened`, the device is open already and only the rest of the fixed
    /// costs counts. A tie goes to the CPU, which opens nothing.
    pub fn cpu_wins(&self, opened: bool) -> bool {
        let fixed = if opened {
            self.gpu.ready_s
        } else {
            self.gpu.fixed_s()
        };
        self.cpu.seconds <= fixed + self.gpu_work_s()
    }

    /// What auto weighed: "estimated 0.05 s on 16 CPU threads against
    /// 0.20 s + 0.01 s on `gpu` (where the GPU's costs come from)".
    pub fn weighed(&self, gpu: &str) -> String {
        let threads = self.cpu.threads;
        format!(
            "estimated {} on {threads} CPU {} against {:.2} s + {} on {gpu} ({})",
            seconds(self.cpu.seconds),
            if threads == 1 { "thread" } else { "threads" },
            self.gpu.fixed_s(),
            seconds(self.gpu_work_s()),
            self.gpu.source()
        )
    }

    /// auto's line on stderr: what it weighed ([`Estimate::weighed`]) and
    /// the verdict: "auto: estimated ...; using the CPU path".
    pub fn say(&self, gpu: &str, opened: bool) -> String {
        let cpu_wins = self.cpu_wins(opened);
        let verdict = if cpu_wins {
            "using the CPU path (--backend gpu uses the GPU anyway)".to_string()
        } else if opened && self.cpu.seconds <= self.gpu_s() {
            format!(
                "using the GPU, whose device is open already ({:.2} s of its fixed costs to go)",
                self.gpu.ready_s
            )
        } else {
            "using the GPU".to_string()
        };
        format!("auto: {}; {verdict}", self.weighed(gpu))
    }
}

/// Seconds as auto says them: "12.3 s", "0.05 s", "4.2 ms".
fn seconds(s: f64) -> String {
    if s >= 10.0 {
        format!("{s:.1} s")
    } else if s >= 0.01 {
        format!("{s:.2} s")
    } else {
        format!("{:.1} ms", s * 1e3)
    }
}

/// What `--backend auto` does before it opens anything.
#[derive(Clone, Debug, PartialEq)]
pub enum Plan {
    /// Too few integrations to weigh a GPU for: the CPU path, unprobed.
    TooFew { integrations: u64, threads: usize },
    /// The CPU path wins against the cheapest GPU this machine has
    /// measured (or the default): no device is opened.
    Cpu(Estimate),
    /// Look for a hardware GPU, which the cheapest GPU known is estimated
    /// to pay; where one opens, weigh its own costs against the CPU path's
    /// estimate (`None`: not weighed, as with an explicit `--precision
    /// f32`, which auto runs on a GPU where it can).
    LookForGpu(Option<Estimate>),
}

/// auto's plan for a run of `integrations` distinct integrations on
/// `threads` CPU threads of a machine of `cores` cores: below the floor the
/// CPU path, unprobed; with an
/// explicit `--precision f32` a GPU, unprobed (as before costs were
/// weighed: the CPU path runs f64); else the probe (`probe(k)` probes `k`
/// integrations on `threads` threads) weighed against the cheapest for
/// this run of the GPUs `known()` returns (those measured on this machine,
/// or the default).
pub fn plan(
    integrations: u64,
    threads: usize,
    cores: usize,
    precision: Option<Precision>,
    known: impl FnOnce() -> Vec<GpuCosts>,
    probe: impl FnOnce(usize) -> Probe,
) -> Plan {
    if precision == Some(Precision::F32) {
        return Plan::LookForGpu(None);
    }
    if too_few_for_gpu(integrations, threads) {
        return Plan::TooFew {
            integrations,
            threads: threads.max(1),
        };
    }
    let probe = probe(probe_size(integrations));
    let cpu = CpuEstimate::from_probe(integrations, &probe, threads.max(1), cores);
    let cheapest = known()
        .into_iter()
        .map(|gpu| Estimate {
            cpu: cpu.clone(),
            gpu,
        })
        .min_by(|a, b| a.gpu_s().total_cmp(&b.gpu_s()))
        .unwrap_or(Estimate {
            cpu,
            gpu: GpuCosts::default(),
        });
    if cheapest.cpu_wins(false) {
        Plan::Cpu(cheapest)
    } else {
        Plan::LookForGpu(Some(cheapest))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the test's probe measured: `core_ms` per integration, on
    /// `threads` busy cores, or `None` where it must not run.
    #[derive(Clone, Copy)]
    struct Probed {
        core_ms: f64,
        threads: usize,
    }

    /// The plan's outcome in brief.
    #[derive(Debug, PartialEq)]
    enum Outcome {
        TooFew,
        Cpu,
        Gpu,
        GpuUnweighed,
    }

    /// One row: a run of `integrations` on `threads` threads with the
    /// precision asked for, a probe that measures `probed` (`None`: it
    /// must not run), the GPUs known; the plan, and (where it was weighed)
    /// the CPU estimate [s].
    fn check(
        integrations: u64,
        threads: usize,
        precision: Option<Precision>,
        probed: Option<Probed>,
        known: &[GpuCosts],
        expected: Outcome,
    ) -> Option<Estimate> {
        let probe = |k: usize| {
            let Some(p) = probed else {
                panic!("{integrations} on {threads} threads: probed, but must not be");
            };
            assert!(k as u64 <= integrations.max(1) && (1..=PROBE_MAX).contains(&k));
            Probe {
                integrations: k,
                mean_core_s: p.core_ms * 1e-3,
                parallelism: p.threads as f64,
                wall_s: 0.01,
                ..Probe::default()
            }
        };
        let plan = plan(
            integrations,
            threads,
            16,
            precision,
            || known.to_vec(),
            probe,
        );
        let (outcome, estimate) = match plan {
            Plan::TooFew { .. } => (Outcome::TooFew, None),
            Plan::Cpu(e) => (Outcome::Cpu, Some(e)),
            Plan::LookForGpu(Some(e)) => (Outcome::Gpu, Some(e)),
            Plan::LookForGpu(None) => (Outcome::GpuUnweighed, None),
        };
        assert_eq!(
            outcome, expected,
            "{integrations} integrations, {threads} threads, {precision:?}"
        );
        estimate
    }

    fn measured(open_s: f64, ready_s: f64, cores: f64) -> GpuCosts {
        let m = Measured {
            adapter: "NVIDIA H100 80GB HBM3 (Vulkan, DiscreteGpu)".into(),
            precision: Precision::F64,
            runs: 3,
        };
        GpuCosts {
            open_s,
            ready_s,
            cores,
            fixed_from: Some(m.clone()),
            cores_from: Some(m),
            backward: false,
        }
    }

    #[test]
    fn auto_plans_from_the_estimated_costs() {
        use Outcome::*;
        use Precision::{F32, F64};
        let default = [GpuCosts::default()];
        // The coupling map at 200 x 200, steady and periodic (40,400
        // integrations with its baselines): 20 us an integration on the
        // 16 cores of results/gpu.md's machines, 0.05 s in all.
        let periodic = Some(Probed {
            core_ms: 0.02,
            threads: 16,
        });
        // Random instances (4-period windows): 2.4 ms an integration on
        // the H200's cores (2.95 s for 20,000 on 16).
        let random = Some(Probed {
            core_ms: 2.4,
            threads: 16,
        });
        // Tiny runs neither probe nor open a GPU: sweeps/paper.toml's 12
        // integrations; just below the floor; f64 asked for.
        check(12, 16, None, None, &default, TooFew);
        check(12, 2, Some(F64), None, &default, TooFew);
        check(0, 1, None, None, &default, TooFew);
        check(1023, 16, None, None, &default, TooFew);
        // A thread count of zero counts as one.
        check(63, 0, None, None, &default, TooFew);
        // The periodic 200 x 200 map stays on 16 CPU threads: 0.05 s
        // against 0.2 s + 0.03 s.
        let e = check(40_400, 16, None, periodic, &default, Cpu).unwrap();
        assert!((e.cpu.seconds - 0.0505).abs() < 1e-9, "{e:?}");
        assert!(e.gpu_s() > 0.2 && e.gpu_s() < 0.23, "{e:?}");
        check(40_400, 16, Some(F64), periodic, &default, Cpu);
        // Random, 100,000: 15 s on 16 threads against 0.2 s + 7.7 s.
        let e = check(100_000, 16, None, random, &default, Gpu).unwrap();
        assert!((e.cpu.seconds - 15.0).abs() < 1e-6, "{e:?}");
        assert!((e.gpu_work_s() - 240.0 / 31.0).abs() < 1e-9, "{e:?}");
        check(100_000, 16, Some(F64), random, &default, Gpu);
        // At the floor auto probes: 1,024 random instances on 16 threads
        // take 0.15 s here, less than the GPU's 0.2 s of fixed costs.
        check(1024, 16, None, random, &default, Cpu);
        check(4096, 16, None, random, &default, Gpu);
        // An explicit f32 goes to a GPU unweighed, as before costs were
        // weighed (the CPU path would run f64).
        check(12, 16, Some(F32), None, &default, GpuUnweighed);
        check(100_000, 16, Some(F32), None, &default, GpuUnweighed);
        // The cheapest GPU measured decides: one that opens in 0.02 s and
        // integrates like 100 cores takes the 200 x 200 map; one measured
        // slower than the default leaves 4,096 random instances to the CPU.
        let fast = [measured(0.015, 0.005, 100.0)];
        check(40_400, 16, None, periodic, &fast, Gpu);
        let slow = [measured(0.3, 0.1, 8.0)];
        check(4096, 16, None, random, &slow, Cpu);
        check(
            4096,
            16,
            None,
            random,
            &[slow[0].clone(), fast[0].clone()],
            Gpu,
        );
    }

    #[test]
    fn threads_beyond_the_cores_share_them() {
        // 64 threads on 16 cores: each probed integration's wall time is
        // four times its core time.
        let probe = Probe {
            integrations: 256,
            mean_core_s: 8e-3,
            parallelism: 64.0,
            wall_s: 0.05,
            ..Probe::default()
        };
        let e = CpuEstimate::from_probe(100_000, &probe, 64, 16);
        assert!((e.seconds - 12.5).abs() < 1e-9, "{e:?}");
        assert!((e.core_s - 200.0).abs() < 1e-9, "{e:?}");
        let e = CpuEstimate::from_probe(100_000, &probe, 16, 64);
        assert!((e.core_s - 800.0).abs() < 1e-9, "{e:?}");
    }

    #[test]
    fn an_open_device_counts_only_the_rest_of_its_fixed_costs() {
        let estimate = |cpu_s: f64| Estimate {
            cpu: CpuEstimate {
                seconds: cpu_s,
                core_s: cpu_s * 16.0,
                threads: 16,
            },
            gpu: GpuCosts::default(),
        };
        // 0.15 s on 16 threads: 0.2 s + 0.077 s on a GPU, 0.05 s + 0.077 s
        // once it is open.
        let e = estimate(0.15);
        assert!(e.cpu_wins(false));
        assert!(!e.cpu_wins(true));
        let said = e.say("NVIDIA H100 (Vulkan, DiscreteGpu)", true);
        assert!(
            said.starts_with(
                "auto: estimated 0.15 s on 16 CPU threads against 0.20 s + 0.08 s on NVIDIA \
                 H100 (Vulkan, DiscreteGpu) (results/gpu.md's defaults, throughput 31 CPU \
                 cores); using the GPU, whose device is open already (0.05 s"
            ),
            "{said}"
        );
        let e = estimate(0.05);
        assert!(e.cpu_wins(true));
        assert!(
            e.say("the GPU", false)
                .ends_with("; using the CPU path (--backend gpu uses the GPU anyway)")
        );
        assert!(!estimate(20.0).cpu_wins(false));
    }

    #[test]
    fn the_source_of_the_costs_is_said() {
        assert_eq!(
            GpuCosts::default().source(),
            "results/gpu.md's defaults, throughput 31 CPU cores"
        );
        assert_eq!(
            measured(0.15, 0.04, 27.4).source(),
            "measured on NVIDIA H100 80GB HBM3 (Vulkan, DiscreteGpu) in f64: fixed costs the \
             median of 3 runs, throughput 27 CPU cores the median of 3 runs"
        );
        let mut fixed_only = measured(0.15, 0.04, DEFAULT_GPU_CORES);
        fixed_only.cores_from = None;
        assert_eq!(
            fixed_only.source(),
            "fixed costs measured on NVIDIA H100 80GB HBM3 (Vulkan, DiscreteGpu) in f64, the \
             median of 3 runs; results/gpu.md's throughput, 31 CPU cores"
        );
    }

    /// The backward travel slows the GPU's throughput by the H200's
    /// measured share, once, and says so; the time on the GPU grows by it.
    #[test]
    fn the_backward_travel_slows_the_gpu_by_its_measured_share() {
        let back = measured(0.15, 0.04, 27.4).for_backward();
        assert_eq!(back.cores, 27.4 / BACKWARD_GPU_SLOWDOWN);
        assert_eq!(back.clone().for_backward(), back, "applied once");
        assert_eq!(
            back.source(),
            "measured on NVIDIA H100 80GB HBM3 (Vulkan, DiscreteGpu) in f64: fixed costs the \
             median of 3 runs, throughput 27 CPU cores the median of 3 runs, over 1.2 for the \
             backward travel (results/bench.md)"
        );
        let estimate = |gpu: GpuCosts| Estimate {
            cpu: CpuEstimate {
                seconds: 1.0,
                core_s: 16.0,
                threads: 16,
            },
            gpu,
        };
        let plain = estimate(GpuCosts::default());
        let slowed = estimate(GpuCosts::default().for_backward());
        let ratio = slowed.gpu_work_s() / plain.gpu_work_s();
        assert!((ratio - BACKWARD_GPU_SLOWDOWN).abs() < 1e-12, "{ratio}");
        // 16 core-seconds: 0.52 s of work on the default GPU, 0.62 s with
        // the backward travel.
        assert!(!plain.cpu_wins(false) && !slowed.cpu_wins(false));
    }

    #[test]
    fn the_probe_stays_a_small_part_of_the_run() {
        assert_eq!(probe_size(0), 1);
        assert_eq!(probe_size(1024), 32);
        assert_eq!(probe_size(40_400), PROBE_MAX);
        assert_eq!(probe_size(u64::MAX), PROBE_MAX);
        assert_eq!(min_integrations(16), 1024);
        assert_eq!(min_integrations(0), 64);
    }
}
