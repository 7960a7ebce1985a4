//! What the CPU takes over from a batch: the heaviest runs f32's check
//! picks, and one instance integrated on the CPU from its start or from the
//! state the f64 shader left.

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

/// One instance integrated on the CPU, which the shader mirrors, as a GPU
/// outcome (the caller marks why it ran there): from its start, or from a
/// run the f64 shader left unfinished.
pub(super) fn on_cpu(inst: &Instance, settings: &Settings, from: Option<Run>) -> GpuOutcome {
    let run = match from {
        Some(run) => {
            crate::laws::karnopp::integrate::continue_instance_until(inst, settings, run, || false)
                .expect("never asked to stop")
        }
        None => run_instance(inst, settings),
    };
    GpuOutcome::of(&reduce(inst, &run), run.state.steps)
}
