//! ACO's registers of one hand-edited shader, for finding where a lane's
//! registers go (issue 57): compile a copy of a variant `pidm info --shader
//! DIR` wrote, reduced or restructured, as pidm compiles its pipelines.
//!
//!     cargo build --release --bin pidm --example isa
//!     target/release/examples/isa DIR/f64-hardware-window.wgsl [ENTRY]
//!
//! ENTRY defaults to `advance_slice`; the figures are navi31's and
//! navi21's, as `pidm info --shader` prints them.

use pidm::gpu::isa;
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(file) = args.first() else {
        anyhow::bail!("usage: isa FILE.wgsl [ENTRY]");
    };
    let entry = args.get(1).map_or("advance_slice", |s| s.as_str());
    let src = std::fs::read_to_string(file)?;
    let mut module = naga::front::wgsl::parse_str(&src)
        .map_err(|e| anyhow::anyhow!("{}", e.emit_to_string(&src)))?;
    module.entry_points.retain(|e| e.name == entry);
    let precision = pidm::laws::Precision::F64;
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        pidm::gpu::prelude::capabilities(precision),
    )
    .validate(&module)
    .map_err(|e| anyhow::anyhow!("{}", e.emit_to_string(&src)))?;
    let pipeline = isa::Pipeline {
        name: file.clone(),
        words: pidm::gpu::spirv::module_spirv(&module, &info, precision)?,
        entry: entry.to_string(),
        bindings: isa::bindings(&module),
    };
    // The pidm binary beside this example's folder runs the probe.
    let exe: PathBuf = std::env::current_exe()?
        .parent()
        .and_then(|p| p.parent())
        .map(|p| p.join("pidm"))
        .ok_or_else(|| anyhow::anyhow!("no pidm binary beside the example"))?;
    let mut stats = Vec::new();
    for family in isa::Family::ALL {
        stats.extend(isa::measure(&exe, family, std::slice::from_ref(&pipeline))?);
    }
    print!("{}", isa::table(&stats));
    Ok(())
}
