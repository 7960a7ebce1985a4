//! `pidm info`: the GPU adapters and what the backends would take; `pidm
//! info --shader DIR`: the integrator shader's variants and what a lane of
//! each carries (issue 47).

use anyhow::{Context, Result};
use std::path::Path;

/// `pidm info`: every GPU adapter wgpu finds, with type, backend, limits
/// and f64 support, which precisions it runs and trusts (each compiled and
/// self-tested against the CPU), and which one `--backend auto` and `gpu`
/// would take.
pub fn info() -> Result<()> {
    let adapters = crate::gpu::check_adapters();
    println!(
        "WGPU_BACKEND={}",
        std::env::var("WGPU_BACKEND").unwrap_or_else(|_| "(unset: all)".into())
    );
    if adapters.is_empty() {
        println!("no GPU adapters found");
    }
    for (a, checks) in &adapters {
        println!(
            "- {} ({}, {}, {}): f64 {}, pipeline cache {}, max storage binding {} MiB, \
             max buffer {} MiB, max workgroups per dimension {}",
            a.name,
            a.device_type,
            a.backend,
            a.driver,
            if a.f64 { "yes" } else { "no" },
            if a.pipeline_cache { "yes" } else { "no" },
            a.max_storage_buffer_binding_size >> 20,
            a.max_buffer_size >> 20,
            a.max_compute_workgroups_per_dimension
        );
        let checks: Vec<String> = checks.iter().map(|c| c.describe()).collect();
        println!("  runs and trusts: {}", checks.join(", "));
    }
    for (label, software) in [
        ("--backend auto (a run large enough for a GPU)", false),
        ("--backend gpu", true),
    ] {
        match crate::gpu::GpuContext::new(software) {
            Ok(ctx) if !software && !ctx.supports_f64() => println!(
                "{label}: {} in f32 (it has no f64 in shaders)",
                ctx.describe()
            ),
            Ok(ctx) => println!("{label}: {}", ctx.describe()),
            Err(err) => println!(
                "{label}: {}",
                if software {
                    format!("fails: {err}")
                } else {
                    format!("the CPU path ({err})")
                }
            ),
        }
    }
    println!(
        "cpu: {} threads",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    Ok(())
}

/// Random instances of the emulated-operation probe (seed 11, as the
/// random 2,000 of `results/`), two periods each.
const PROBE_INSTANCES: usize = 64;

/// `pidm info --shader DIR`: every Karnopp pipeline variant's WGSL written
/// into `dir` (one file each, named by [`crate::gpu::footprint::variant_name`])
/// and a table of their footprints, then the emulated f64 operations per
/// slip trial of the f64 pipeline on a probe batch.
pub fn shader_info(dir: &Path) -> Result<()> {
    use crate::gpu::footprint::{self, write_sources};
    use crate::gpu::spirv::{Footprint, SPIRV_OPT_ARGS};
    let variants = crate::gpu::shader::Variant::every();
    let mut names = write_sources(dir, &variants)
        .with_context(|| format!("writing the shader variants into {}", dir.display()))?;
    names.extend(
        crate::gpu::write_law_sources(dir)
            .with_context(|| format!("writing the laws' shaders into {}", dir.display()))?,
    );
    println!(
        "{} shader variants written into {} (hardware: no loop limiter; limiter: llvmpipe's)",
        names.len(),
        dir.display()
    );
    println!(
        "{:<38} {:>12} {:>14} {:>13} {:>9}",
        "variant", "indexed [B]", "variables [B]", "instructions", "inlined"
    );
    let mut measured = true;
    let mut row = |name: &str, f: Footprint| {
        let show = |x: Option<usize>| x.map_or("-".to_string(), |n| n.to_string());
        measured &= f.indexed.is_some();
        println!(
            "{:<38} {:>12} {:>14} {:>13} {:>9}",
            name,
            show(f.indexed_bytes()),
            f.declared_bytes,
            show(f.instructions),
            f.inlined
        );
    };
    for v in &variants {
        row(&footprint::variant_name(*v), footprint::measure(*v)?);
    }
    // The laws' own pipelines, as a hardware adapter and llvmpipe compile
    // them.
    for (name, f) in crate::gpu::law_footprints()? {
        row(&name, f);
    }
    println!(
        "indexed: private arrays an access chain indexes at run time after `spirv-opt {}` \
         (local memory on NVIDIA, at every access); variables: function variables of naga's \
         SPIR-V, what the driver receives; instructions: after spirv-opt, which inlines \
         everything and folds; inlined: naga's SPIR-V with every call inlined before any \
         folding, what a driver that inlines first works through (lavapipe's pipeline \
         creation scales with it)",
        SPIRV_OPT_ARGS.join(" ")
    );
    if !measured {
        println!(
            "(spirv-opt was not found: install Debian's spirv-tools for the indexed arrays and \
             instructions)"
        );
    }
    registers()?;
    probe_emulated()
}

/// Every statistic the system's own Vulkan device lists for each hardware
/// pipeline (NVIDIA's register count on a lent device), or a line saying
/// why not (lavapipe lists none).
fn native_statistics(exe: &Path, pipelines: &[crate::gpu::isa::Pipeline]) {
    match crate::gpu::isa::measure_native(exe, pipelines) {
        Err(err) => println!(
            "driver statistics: none from the system's Vulkan device ({})",
            format!("{err:#}").replace('\n', " ")
        ),
        Ok(report) => {
            println!(
                "driver statistics on {} per hardware pipeline",
                report.device
            );
            for p in &report.pipelines {
                for e in &p.executables {
                    let stats: Vec<String> = e
                        .statistics
                        .iter()
                        .map(|(k, v)| format!("{k} {v}"))
                        .collect();
                    println!("  {} [{}]: {}", p.name, e.name, stats.join(", "));
                }
            }
        }
    }
}

/// ACO's registers of every pipeline a hardware batch creates, on RADV's
/// null navi31 and navi21 (`gpu::isa`), against issue 57's budgets; a line
/// saying why not where the newer RADV is not unpacked.
pub fn registers() -> Result<()> {
    use crate::gpu::isa;
    let pipelines = isa::batch_pipelines()?;
    let exe = std::env::current_exe().context("finding pidm's own binary for the probe")?;
    native_statistics(&exe, &pipelines);
    if !isa::radv_available() {
        println!(
            "registers: no Mesa 25 RADV in {} (`bash .ci/radv.sh` as root unpacks it)",
            isa::radv_dir().display()
        );
        return Ok(());
    }
    let mut stats = Vec::new();
    for family in isa::Family::ALL {
        stats.extend(isa::measure(&exe, family, &pipelines)?);
    }
    println!("\nregisters: ACO (Mesa's RADV on a null device) per hardware pipeline");
    print!("{}", isa::table(&stats));
    println!(
        "VGPRs: allocated per thread (asked: before spilling); spilled: VGPRs (sgpr sp: SGPRs) \
         spilled to scratch; scratch: bytes per wave; subgroups: waves per SIMD"
    );
    for b in isa::BUDGETS {
        let verdicts: Vec<_> = isa::verdicts(&stats)
            .into_iter()
            .filter(|(v, _, _)| v.prefix == b.prefix && v.limit == b.limit)
            .collect();
        let broken: Vec<_> = verdicts.iter().filter(|(_, _, kept)| !kept).collect();
        match broken
            .iter()
            .max_by_key(|(_, s, _)| (s.spilled_vgprs, s.vgprs))
        {
            None => println!("budget {}: kept by all {}", b.describe(), verdicts.len()),
            Some((_, worst, _)) => println!(
                "budget {}: broken by {} of {} (worst {} on {}: {} VGPRs, {} spilled)",
                b.describe(),
                broken.len(),
                verdicts.len(),
                worst.pipeline,
                worst.family.as_str(),
                worst.vgprs,
                worst.spilled_vgprs
            ),
        }
    }
    Ok(())
}

/// The f64 pipeline's emulated divisions and roots per slip trial on
/// [`PROBE_INSTANCES`] random instances, on the adapter `--backend gpu`
/// takes (the software one included); a line saying why not where there
/// is none or it has no f64.
fn probe_emulated() -> Result<()> {
    use crate::backend::Precision;
    let ctx = match crate::gpu::GpuContext::new(true) {
        Ok(ctx) if ctx.supports_f64() => ctx,
        Ok(ctx) => {
            println!(
                "emulated f64 operations: not probed ({} has no f64)",
                ctx.describe()
            );
            return Ok(());
        }
        Err(e) => {
            println!("emulated f64 operations: not probed (no GPU adapter: {e})");
            return Ok(());
        }
    };
    let instances = crate::model::random::random_instances(11, PROBE_INSTANCES, 2, 1);
    crate::profile::enable();
    {
        let _integrating = crate::profile::span(crate::profile::Phase::Integrate);
        crate::gpu::run_batch(
            &ctx,
            &instances,
            &crate::laws::Settings::default(),
            Precision::F64,
            &mut |_, _| {},
        )?;
    }
    match crate::gpu::warps::emulated_per_slip_trial() {
        Some((emulated, per_trial)) => println!(
            "emulated f64 divisions and roots on {PROBE_INSTANCES} random instances (seed 11, 2 \
             periods) on {}: {emulated}, {per_trial:.1} per slip trial (every kind of \
             iteration's counted)",
            ctx.describe()
        ),
        None => println!("emulated f64 operations: the probe took no slip trial"),
    }
    Ok(())
}
