//! `pidm info`: the GPU adapters and what the backends would take.

use anyhow::Result;

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
