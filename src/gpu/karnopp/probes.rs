//! The probes the tests run on a device for Karnopp's lanes: a batch's
//! first dispatch alone, its states as the CPU mirror of each precision
//! holds them, and what each lane counted (as `gpu::lugre::probes` is
//! LuGre's).

use super::layout;
use crate::gpu::runner::Runner;
use crate::gpu::*;

/// The shader's state of every instance after `iterations` iterations of
/// the integrator (one dispatch, each instance on a lane of its own), as
/// the CPU mirror of precision `L` holds it: for tests that pin the shader
/// to its mirror step by step. On lavapipe `iterations` must stay small
/// enough (hundreds) for the loop limiter never to undo one.
pub(in crate::gpu) fn states_after<L: Layout>(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    iterations: u32,
) -> Result<Vec<L::Mirror>, GpuError> {
    let ((states, _, _), _) = first_dispatch::<L>(ctx, instances, settings, iterations)?;
    Ok(states.iter().map(L::mirror).collect())
}

/// What each lane did in a batch's first dispatch of `iterations`
/// iterations, where instance k runs on lane k (`gpu::warps`): for tests
/// that hold the lanes' counts against the CPU mirror's iterations.
pub fn f64_tallies_after(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    iterations: u32,
) -> Result<Vec<layout::control::Tally>, GpuError> {
    Ok(first_dispatch::<Double>(ctx, instances, settings, iterations)?.1)
}

/// A batch's first dispatch alone, of `iterations` iterations.
fn first_dispatch<L: Layout>(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    iterations: u32,
) -> Result<(Readback<L>, Vec<layout::control::Tally>), GpuError> {
    let options = BatchOptions {
        slice_iterations: iterations.max(1),
        probe_iterations: iterations.max(1),
        lanes: Some(instances.len().max(1)),
        cpu_tail: Some(0),
        ..BatchOptions::default()
    };
    let out = {
        let _turn = ctx.busy.lock().unwrap_or_else(|e| e.into_inner());
        let runner = Runner::on(ctx, settings, &options);
        let mut coefficients = runner.coefficients::<L>(instances, None);
        let (pipeline, variant) = runner.pipeline::<L>(L::PRECISION, &coefficients)?;
        let segments = segment_binding::<L>(ctx.device(), variant, instances, &mut coefficients);
        let extra = segment_entries(&segments);
        runner.slices::<L>(
            Work {
                instances,
                coefficients: &coefficients,
                states: None,
            },
            Kernel::with_segments(&pipeline, variant, &extra),
            &mut |_| {},
            Some(1),
            None,
        )?
    };
    ctx.check_health()?;
    Ok((out.readback, out.probe_tallies))
}

/// `states_after` in f32: the states of the f32 shader as its CPU mirror
/// (`pidm::laws::karnopp::single`) holds them.
pub fn f32_states_after(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    iterations: u32,
) -> Result<Vec<crate::laws::karnopp::single::integrate::State>, GpuError> {
    states_after::<Single>(ctx, instances, settings, iterations)
}

/// `states_after` in f64: the states of the f64 shader as the CPU
/// reference holds them.
pub fn f64_states_after(
    ctx: &GpuContext,
    instances: &[Instance],
    settings: &Settings,
    iterations: u32,
) -> Result<Vec<crate::laws::karnopp::integrate::State>, GpuError> {
    states_after::<Double>(ctx, instances, settings, iterations)
}
