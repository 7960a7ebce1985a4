//! `pidm bench`: the simulated time per wall second of each backend on a
//! scene.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Result, bail};

use super::scenes::{DEFAULT_SCENE, load_scene, scene_integrations};
use crate::backend::{Backend, CpuBackend, GpuBackend, Hardware, Precision};
use crate::laws::status::STATUS_OK;
use crate::model::Instance;

/// `pidm bench`: simulated seconds per wall second per core on one thread
/// at the scene's accuracy, and the all-core figure; `path` `None` is the
/// built-in paper scene.
pub fn bench(path: Option<&Path>, min_seconds: f64) -> Result<()> {
    let default = PathBuf::from(DEFAULT_SCENE);
    let scene = load_scene(path.unwrap_or(&default))?;
    let count = scene.instance_count();
    if count > 100_000 {
        bail!("bench runs every instance repeatedly; {count} instances is too many");
    }
    let instances = scene_integrations(&scene);
    let simulated: f64 = instances.iter().map(Instance::duration).sum();
    println!(
        "bench: scene {:?}, {} integrations ({} simulated s per pass), {}",
        scene.name,
        instances.len(),
        simulated,
        scene.tolerance_text()
    );
    let mut backends: Vec<Box<dyn Backend>> = vec![
        Box::new(CpuBackend::new(Some(1))?),
        Box::new(CpuBackend::new(None)?),
    ];
    match crate::gpu::GpuContext::new(true) {
        // A law without f32 has an f64 shader only.
        Ok(ctx) if scene.law().no_f32().is_some() && ctx.supports_f64() => {
            backends.push(Box::new(GpuBackend::new(ctx, Precision::F64)?));
        }
        Ok(ctx) if scene.law().no_f32().is_some() => {
            println!("  gpu: not measured (no f64 on {})", ctx.describe())
        }
        Ok(ctx) => {
            let f64_ok = ctx.supports_f64();
            backends.push(Box::new(GpuBackend::new(ctx, Precision::F32)?));
            if f64_ok {
                let ctx = crate::gpu::GpuContext::new(true)?;
                backends.push(Box::new(GpuBackend::new(ctx, Precision::F64)?));
            }
        }
        Err(err) => println!("  gpu: not measured ({err})"),
    }
    // Instances per second of the all-core CPU path, to compare the GPU with.
    let mut cpu_rate = None;
    for backend in &backends {
        let mut passes = 0;
        // One warm-up pass (pipeline compilation on the GPU), then passes
        // until the time budget is used.
        backend.run(&instances, &scene.settings, &|_| {})?;
        let started = Instant::now();
        while started.elapsed().as_secs_f64() < min_seconds || passes == 0 {
            let out = backend.run(&instances, &scene.settings, &|_| {})?;
            if out.iter().any(|o| o.status != STATUS_OK) {
                bail!("an instance did not finish normally during the benchmark");
            }
            passes += 1;
        }
        let wall = started.elapsed().as_secs_f64();
        let rate = passes as f64 * simulated / wall;
        let per_core = match backend.hardware() {
            Hardware::Cpu { threads } => format!(" ({:.1} per core)", rate / threads as f64),
            Hardware::Gpu => String::new(),
        };
        let per_second = passes as f64 * instances.len() as f64 / wall;
        let versus = match (backend.hardware(), cpu_rate) {
            (Hardware::Cpu { .. }, _) => {
                cpu_rate = Some(per_second);
                String::new()
            }
            (Hardware::Gpu, Some(cpu)) => {
                format!(", {:.2} times the CPU path on every core", per_second / cpu)
            }
            (Hardware::Gpu, None) => String::new(),
        };
        println!(
            "  {} {}: {:.1} simulated s per wall s{per_core}, {:.1} instances per s{versus}, \
             {passes} passes in {wall:.2} s",
            backend.describe(),
            backend.precision(),
            rate,
            per_second
        );
    }
    Ok(())
}
