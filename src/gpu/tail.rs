//! What the CPU takes over from a batch: the heaviest runs f32's check
//! picks (the law's `on_cpu` integrates each).

use super::*;

/// An instance the CPU integrates in f64 after the device's batches: why
/// ([`GpuOutcome::shader_status`], [`GpuOutcome::checked`]).
pub(super) struct CpuJob {
    pub(super) index: usize,
    pub(super) shader_status: u32,
    pub(super) checked: bool,
}

/// f32 window runs the device finished itself with status ok, as (index,
/// steps): those [`check::heaviest`] chooses from.
pub(super) fn heaviest_candidates(instances: &[Instance], out: &[GpuOutcome]) -> Vec<(usize, u32)> {
    out.iter()
        .zip(instances)
        .enumerate()
        .filter(|(_, (o, inst))| {
            check::is_candidate(inst, o.status, o.cpu_fallback || o.finished_on_cpu)
        })
        .map(|(k, (o, _))| (k, o.steps))
        .collect()
}
