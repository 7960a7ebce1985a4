//! The options of a batch: slice length, lanes, batch size, the CPU tail,
//! f32's check of its heaviest runs.

use super::*;

/// Tuning knobs of [`run_batch_with`]; [`Default`] is what [`run_batch`]
/// uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatchOptions {
    /// Iterations of `iterate` per dispatch.
    pub slice_iterations: u32,
    /// Largest number of instances per dispatch batch, on top of the
    /// device's limits (tests force small batches with it).
    pub max_batch: Option<usize>,
    /// Read every steady instance's whole accumulators back, not only the
    /// heads and the accumulators that the reductions need
    /// ([`readback`]); tests compare the two.
    pub whole_accumulators: bool,
    /// Passes the shader's loop-limiter probe makes; at least
    /// [`layout::PROBE_PASSES`]. Tests raise it beyond 65,535 so that on
    /// llvmpipe no iteration can complete its probe, which exercises the
    /// fallback of [`STATUS_LOOP_LIMIT`] instances to the CPU.
    pub probe_passes: u32,
    /// Lanes working through a batch at once after its first dispatch, at
    /// most; `None`: the adapter's ([`super::lanes_for`]; through
    /// [`execute_gpu_inner`], which does not see the adapter, a hardware
    /// one's). Tests use few, so lanes take several instances each.
    pub lanes: Option<usize>,
    /// Iterations of a batch's first dispatch, which starts every instance
    /// on a lane of its own and ranks the rest ([`super::warps`]).
    pub probe_iterations: u32,
    /// The order of the queue after the first dispatch.
    pub order: Order,
    /// Pack the busy lanes into fewer workgroups once the queue is empty
    /// (`PIDM_GPU_COMPACT=0` leaves them where they are, for measuring
    /// what packing is worth).
    pub compact: bool,
    /// Hand the slow tail of a batch to the CPU: in rounds of a cap on an
    /// instance's steps (`super::rounds`: once a round ends with at most
    /// this many parked, twice it by default), a replica batch's once
    /// every job has started and at most this many are unfinished; the GPU stops and the CPU finishes
    /// those, in parallel: from where the GPU left them in f64
    /// (the shader mirrors the CPU step for step, so no work is lost), from
    /// their start in f32 (the f32 mirror could continue an f32 state, but
    /// the slow tail is where f32 is least sure of itself, and the f64
    /// reference costs the CPU no more), so those f32 instances carry the CPU's
    /// f64 values and the run's summary counts them among the integrations
    /// that ran on the CPU. `None` is the default of
    /// [`BatchOptions::tail_size`] for batches of at least
    /// [`CPU_TAIL_MIN_BATCH`] instances in either precision, and nothing for
    /// a smaller one; `Some(0)` never hands over. A GPU lane takes tens of microseconds a step, a CPU core about
    /// one: once few instances are left, the GPU runs them at one lane's
    /// speed each while the CPU's threads would be faster, and an instance a
    /// hundred times longer than its batch's others (a sliding mode on the
    /// rim of the band) would hold the whole batch. Which instances form
    /// the tail depends on the batch, so a map split into other batches
    /// (chunks, shards, a resumed run) differs on them by the GPU's
    /// difference from the CPU: rounding or the tolerance's scatter in f64,
    /// f32's own error in f32 (within 0.005 um + 1 % of the f64 step on the
    /// random scenes of results/gpu.md since issue 19).
    pub cpu_tail: Option<usize>,
    /// How an f32 batch checks its heaviest window runs
    /// ([`crate::laws::floor::check`]); f64 batches are not checked.
    pub check: F32Check,
}

/// How an f32 batch checks its heaviest window runs
/// ([`crate::laws::floor::check`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum F32Check {
    /// [`Route::Reference`] on a software adapter (its "GPU" is the CPU's
    /// own cores, where native f64 code takes about a third of the
    /// shader's time per step), [`Route::Twins`] on any other. A batch run
    /// through [`execute_gpu_inner`], which does not see the adapter,
    /// takes twins.
    Auto,
    /// Always this route.
    Route(Route),
    /// No check: the self-test's (it judges the shader alone), and for
    /// measurements (`PIDM_F32_CHECK=off`).
    Off,
}

impl F32Check {
    /// The route of this choice on an adapter that `is_hardware` or not;
    /// `None` when off.
    pub fn route(self, is_hardware: bool) -> Option<Route> {
        match self {
            F32Check::Auto if is_hardware => Some(Route::Twins),
            F32Check::Auto => Some(Route::Reference),
            F32Check::Route(route) => Some(route),
            F32Check::Off => None,
        }
    }
}

/// How often progress is reported while the CPU integrates the checked runs
/// and fallbacks after the batches: often enough for a progress bar, and
/// the wait ends as soon as the pass does.
pub(super) const CPU_PASS_REPORT: std::time::Duration = std::time::Duration::from_millis(100);

/// The smallest batch whose slow tail goes to the CPU by default (smaller
/// ones, the self-test's and most tests', stay on the GPU to their end).
pub const CPU_TAIL_MIN_BATCH: usize = 1000;

/// Unfinished instances per CPU thread below which an f64 batch hands its
/// tail to the CPU: a core steps about twenty times as fast as a GPU lane,
/// so with fewer than about that many instances per thread left, the CPU
/// finishes them sooner than the GPU would.
pub const CPU_TAIL_PER_THREAD: usize = 16;

impl BatchOptions {
    /// The unfinished instances of a batch of `n` that the CPU takes over
    /// when it has `threads` threads (see [`BatchOptions::cpu_tail`]): by
    /// default, for batches of at least [`CPU_TAIL_MIN_BATCH`], 1 % of
    /// the batch or [`CPU_TAIL_PER_THREAD`] per thread, whichever is more,
    /// but never more than a quarter of the batch.
    pub fn tail_size(&self, _precision: Precision, n: usize, threads: usize) -> usize {
        tail_size(self.cpu_tail, n, threads)
    }
}

/// [`BatchOptions::tail_size`] for a batch of either law: `forced` where
/// given ([`BatchOptions::cpu_tail`]), else the default rule.
pub fn tail_size(forced: Option<usize>, n: usize, threads: usize) -> usize {
    match forced {
        Some(k) => k,
        None if n >= CPU_TAIL_MIN_BATCH => (n / 100).max(CPU_TAIL_PER_THREAD * threads).min(n / 4),
        None => 0,
    }
}

impl Default for BatchOptions {
    fn default() -> Self {
        BatchOptions {
            slice_iterations: slice_iterations(),
            max_batch: None,
            whole_accumulators: false,
            probe_passes: layout::PROBE_PASSES,
            lanes: None,
            probe_iterations: PROBE_ITERATIONS,
            order: order(),
            compact: compact(),
            cpu_tail: cpu_tail().0,
            check: f32_check(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The default tail is 1 % of a large f64 batch and nothing in f32,
    /// whose results would then depend on how a map is split into batches.
    #[test]
    fn only_large_f64_batches_hand_their_tail_to_the_cpu() {
        let default = BatchOptions::default();
        // (options, precision, batch, CPU threads, tail).
        let check = |options: &BatchOptions, precision, n, threads, expected| {
            assert_eq!(
                options.tail_size(precision, n, threads),
                expected,
                "{precision:?} {n} on {threads} threads"
            );
        };
        check(&default, Precision::F64, 999, 16, 0);
        // A quarter of the batch at most.
        check(&default, Precision::F64, 1000, 16, 250);
        // 16 per thread.
        check(&default, Precision::F64, 4096, 16, 256);
        check(&default, Precision::F64, 4096, 2, 40);
        // 1 % of a large batch.
        check(&default, Precision::F64, 250_000, 16, 2500);
        // f32 the same way (issue 19): its instances restart on the CPU.
        check(&default, Precision::F32, 250_000, 16, 2500);
        check(&default, Precision::F32, 999, 16, 0);
        let explicit = BatchOptions {
            cpu_tail: Some(3),
            ..default
        };
        check(&explicit, Precision::F32, 10, 16, 3);
        check(&explicit, Precision::F64, 10, 16, 3);
    }
}
