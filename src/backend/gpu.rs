//! The GPU path as a [`Backend`] of the sweep driver.

use anyhow::{Result, bail};

use super::{Backend, Hardware, Precision, Staged};
use crate::gpu::LugreGpu;
use crate::gpu::{BatchOptions, GpuContext, GpuOutcome, Parts, run_batch_packed};
use crate::laws::status::STATUS_GRAZE;
use crate::laws::{Law, Replica, Settings};
use crate::measurement::Outcome;
use crate::model::Instance;
use rayon::prelude::*;

/// The WGSL shader on one adapter at one precision.
pub struct GpuBackend {
    ctx: GpuContext,
    precision: Precision,
    /// The parts of the pipeline prepared up front (batches that need
    /// others prepare theirs when they come).
    parts: Parts,
    options: BatchOptions,
}

impl GpuBackend {
    /// Compiles and self-tests the pipeline (see [`GpuContext::prepare`]),
    /// so a driver that cannot run the shader is found before any work;
    /// fails with a clear message when f64 is asked of an adapter without
    /// `SHADER_F64`.
    pub fn new(ctx: GpuContext, precision: Precision) -> Result<GpuBackend> {
        GpuBackend::for_parts(ctx, precision, Parts::ALL)
    }

    /// [`GpuBackend::new`] with a pipeline of only `parts` prepared up
    /// front: what a run's instances use (`Workload::parts`).
    pub fn for_parts(ctx: GpuContext, precision: Precision, parts: Parts) -> Result<GpuBackend> {
        if precision == Precision::F64 && !ctx.supports_f64() {
            bail!(
                "--precision f64: adapter {} does not support 64-bit floats in shaders \
                 (SHADER_F64); use --precision f32 or --backend cpu",
                ctx.describe()
            );
        }
        ctx.prepare_parts(precision, parts)?;
        Ok(GpuBackend {
            ctx,
            precision,
            parts,
            options: BatchOptions::default(),
        })
    }

    /// [`GpuBackend::new`] with batches run with `options` (tests force
    /// small batches and a CPU tail with them).
    pub fn with_options(
        ctx: GpuContext,
        precision: Precision,
        options: BatchOptions,
    ) -> Result<GpuBackend> {
        Ok(GpuBackend {
            options,
            ..GpuBackend::new(ctx, precision)?
        })
    }

    /// "GPU ready in 0.21 s (...)": what opening the device, creating the
    /// pipeline and its self-test cost.
    pub fn readiness(&self) -> String {
        match self.ctx.prepare_parts(self.precision, self.parts) {
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
        self.ctx
            .prepare_parts(self.precision, self.parts)
            .ok()
            .map(|(_, p)| p)
    }
}

impl Backend for GpuBackend {
    fn describe(&self) -> String {
        format!("gpu: {}", self.ctx.describe())
    }

    fn precision(&self) -> Precision {
        self.precision
    }

    /// One batch of the device's ([`crate::gpu::chunk_instances`]): the
    /// queue's lanes four times over, 1,048,576 on hardware within the
    /// device's limits, so lanes refill for most of a chunk.
    fn chunk_size(&self) -> usize {
        crate::gpu::chunk_instances(&self.ctx, self.precision)
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
        self.run_staged(instances, settings, Staged::default(), done)
    }

    fn stage(&self, instances: &[Instance], settings: &Settings) -> Staged {
        // Only Karnopp's lanes take coefficients packed ahead; LuGre's host
        // sets up each batch itself.
        match instances.first().map(Law::of_instance) {
            Some(Law::Karnopp) => {
                Staged(Some(crate::gpu::pack(instances, settings, self.precision)))
            }
            _ => Staged::default(),
        }
    }

    fn run_staged(
        &self,
        instances: &[Instance],
        settings: &Settings,
        staged: Staged,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Outcome>> {
        // A scene has one law, and so does each of its batches.
        let law = instances.first().map_or(Law::default(), Law::of_instance);
        if instances.iter().any(|i| Law::of_instance(i) != law) {
            bail!("a batch mixes friction laws; a scene has one law");
        }
        if let Some(why) = law.no_f32()
            && self.precision != Precision::F64
        {
            bail!("--precision f32: {why}");
        }
        if law == Law::Lugre {
            return self.groups_on_cpu(instances, settings, done, |alone| {
                self.run_lugre(alone, settings, done)
            });
        }
        if settings.backward {
            // Karnopp's device groups merge steps only, not the backward
            // travel: the instances that split run their groups on the
            // CPU, the rest on the device (packed anew where some split).
            let all = instances.len();
            return self.groups_on_cpu(instances, settings, done, |alone| {
                let staged = staged.0.as_ref().filter(|_| alone.len() == all);
                self.run_karnopp(alone, settings, staged, done)
            });
        }
        self.run_karnopp(instances, settings, staged.0.as_ref(), done)
    }
}

impl GpuBackend {
    /// A batch of Karnopp instances on Karnopp's shader.
    fn run_karnopp(
        &self,
        instances: &[Instance],
        settings: &Settings,
        packed: Option<&crate::gpu::Packed>,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Outcome>> {
        let mut reported = 0;
        let outcomes = run_batch_packed(
            &self.ctx,
            instances,
            packed,
            settings,
            self.precision,
            &self.options,
            &mut |finished, _total| {
                if finished > reported {
                    done(finished - reported);
                    reported = finished;
                }
            },
        )?;
        Ok(outcomes.into_iter().map(GpuOutcome::into_outcome).collect())
    }

    /// A batch whose instances that split into replicas
    /// (`simulation.replicas`) run their groups on the CPU's threads in
    /// f64, the reference (marked on_cpu), and the rest on the device
    /// (`device`, given them in order): LuGre's lanes run no group merges,
    /// and Karnopp's merge no backward travel. The groups are counted as
    /// the CPU path counts them, so that their outcomes are its own.
    fn groups_on_cpu(
        &self,
        instances: &[Instance],
        settings: &Settings,
        done: &(dyn Fn(u64) + Sync),
        device: impl FnOnce(&[Instance]) -> Result<Vec<Outcome>>,
    ) -> Result<Vec<Outcome>> {
        let count = crate::replicas::count(
            settings.replicas,
            rayon::current_num_threads(),
            instances.len(),
        );
        let splits: Vec<Option<Replica>> = instances
            .iter()
            .map(|inst| crate::replicas::split_of(inst, settings, count))
            .collect();
        let alone: Vec<Instance> = instances
            .iter()
            .zip(&splits)
            .filter(|(_, split)| split.is_none())
            .map(|(inst, _)| *inst)
            .collect();
        let on_device = if alone.is_empty() {
            Vec::new()
        } else {
            device(&alone)?
        };
        let mut on_device = on_device.into_iter();
        let grouped: Vec<Option<Outcome>> = instances
            .par_iter()
            .zip(&splits)
            .map(|(inst, split)| {
                split.map(|split| {
                    let out = super::cpu::run_split(inst, settings, split);
                    done(1);
                    Outcome {
                        on_cpu: true,
                        ..out
                    }
                })
            })
            .collect();
        Ok(grouped
            .into_iter()
            .map(|group| group.unwrap_or_else(|| on_device.next().expect("one per instance alone")))
            .collect())
    }

    /// A batch of LuGre instances that run alone (a scene's friction is
    /// one law for all) on the LuGre shader (`crate::gpu::lugre`), in f64.
    fn run_lugre(
        &self,
        alone: &[Instance],
        settings: &Settings,
        done: &(dyn Fn(u64) + Sync),
    ) -> Result<Vec<Outcome>> {
        let mut gpu = LugreGpu::for_instances(&self.ctx, alone, settings)?;
        gpu.cpu_tail = self.options.cpu_tail;
        Ok(gpu
            .outcomes_until(alone, settings, crate::interrupt::interrupt_requested, done)?
            .into_iter()
            .map(GpuOutcome::into_outcome)
            .collect())
    }
}

impl GpuOutcome {
    /// The sweep's [`Outcome`] of a GPU outcome: on the CPU where the CPU
    /// finished or redid it, a graze where an f32 graze sent it there.
    pub fn into_outcome(self) -> Outcome {
        let o = self;
        Outcome {
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
            replicas: o.replicas,
            variation: o.variation,
            variation_se: o.variation_se,
        }
    }
}
