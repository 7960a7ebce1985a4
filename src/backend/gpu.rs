//! The GPU path as a [`Backend`] of the sweep driver.

use anyhow::{Result, bail};

use super::{Backend, Hardware, Precision};
use crate::cpu::integrate::Settings;
use crate::cpu::integrate::constants::STATUS_GRAZE;
use crate::gpu::{GpuContext, run_batch};
use crate::measurement::Outcome;
use crate::model::Instance;

/// Instances per sweep chunk on the GPU: a million, enough to fill a large
/// GPU several times over (so the slowest instances of a chunk, which the
/// chunk waits for, are a small part of it), and about a second of work
/// between checkpoints.
const GPU_CHUNK: usize = 1 << 20;

/// The WGSL shader on one adapter at one precision.
pub struct GpuBackend {
    ctx: GpuContext,
    precision: Precision,
}

impl GpuBackend {
    /// Compiles and self-tests the pipeline (see [`GpuContext::prepare`]),
    /// so a driver that cannot run the shader is found before any work;
    /// fails with a clear message when f64 is asked of an adapter without
    /// `SHADER_F64`.
    pub fn new(ctx: GpuContext, precision: Precision) -> Result<GpuBackend> {
        if precision == Precision::F64 && !ctx.supports_f64() {
            bail!(
                "--precision f64: adapter {} does not support 64-bit floats in shaders \
                 (SHADER_F64); use --precision f32 or --backend cpu",
                ctx.describe()
            );
        }
        ctx.prepare(precision)?;
        Ok(GpuBackend { ctx, precision })
    }

    /// "GPU ready in 0.21 s (...)": what opening the device, creating the
    /// pipeline and its self-test cost.
    pub fn readiness(&self) -> String {
        match self.ctx.prepare_timed(self.precision) {
            Ok((_, p)) => format!(
                "GPU ready in {:.2} s (device {:.2} s of which drivers and adapters {:.2} s, \
                 pipeline {:.2} s{}, self-test {:.2} s)",
                p.open_s + p.pipeline_s + p.self_test_s,
                p.open_s,
                p.adapters_s,
                p.pipeline_s,
                match self.ctx.pipeline_cache_path() {
                    Some(path) => format!(" with the cache {}", path.display()),
                    None => String::new(),
                },
                p.self_test_s
            ),
            Err(e) => format!("GPU not ready: {e}"),
        }
    }

    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// What opening the device, creating the pipeline and its self-test
    /// cost (`None` where the pipeline is not ready).
    pub fn preparation(&self) -> Option<crate::gpu::Preparation> {
        self.ctx.prepare_timed(self.precision).ok().map(|(_, p)| p)
    }
}

impl Backend for GpuBackend {
    fn describe(&self) -> String {
        format!("gpu: {}", self.ctx.describe())
    }

    fn precision(&self) -> Precision {
        self.precision
    }

    fn chunk_size(&self) -> usize {
        GPU_CHUNK
    }

    fn hardware(&self) -> Hardware {
        Hardware::Gpu
    }

    fn run(
        &self,
        instances: &[Instance],
        settings: &Settings,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Outcome>> {
        let mut reported = 0;
        let outcomes = run_batch(
            &self.ctx,
            instances,
            settings,
            self.precision,
            &mut |finished, _total| {
                if finished > reported {
                    done(finished - reported);
                    reported = finished;
                }
            },
        )?;
        Ok(outcomes
            .into_iter()
            .map(|o| Outcome {
                displacement: o.displacement,
                span: o.span,
                se: o.se,
                periods: o.periods,
                lag: o.lag,
                status: o.status,
                motion: o.motion,
                steps: o.steps,
                on_cpu: o.cpu_fallback || o.finished_on_cpu,
                graze: o.cpu_fallback && o.shader_status == STATUS_GRAZE,
                checked: o.checked,
            })
            .collect())
    }
}
