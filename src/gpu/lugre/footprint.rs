//! What a LuGre lane carries, read from the SPIR-V a driver compiles for
//! a batch (as `gpu::karnopp::footprint` reads a Karnopp variant's).

use super::shader::{Arithmetic, Form, parse_and_validate, source, validate};
use crate::gpu::GpuError;
use crate::laws::Precision;

/// A LuGre pipeline's shape: its workgroup size, its arithmetic, and
/// what it drives and measures ([`Form`]).
pub type Shape = (u32, Arithmetic, Form);

/// What a lane of the LuGre integrator carries (as `gpu::footprint` reads
/// a Karnopp variant's): its entry point's, not the tests'.
pub fn footprint(shape: Shape) -> Result<crate::gpu::spirv::Footprint, GpuError> {
    let (_, words) = lane_spirv(shape)?;
    Ok(crate::gpu::spirv::measure_spirv(&words))
}

/// The module of the integrator's entry point alone and the SPIR-V naga
/// writes for it with the options pidm's pipelines use: what a driver
/// compiles for a LuGre batch (the tests' entry points, the functions and
/// the mirror's probes, carry arrays of their own no run touches).
pub fn lane_spirv(
    (workgroup_size, arithmetic, form): Shape,
) -> Result<(naga::Module, Vec<u32>), GpuError> {
    let (mut module, _) = parse_and_validate(workgroup_size, arithmetic, form)?;
    module.entry_points.retain(|e| e.name == super::ENTRY_POINT);
    let info = validate(&module, &source(workgroup_size, arithmetic, form))?;
    let words = crate::gpu::spirv::module_spirv(&module, &info, Precision::F64)?;
    Ok((module, words))
}

/// The name of LuGre's hardware pipeline in `pidm info`'s tables and the
/// register budgets (`crate::gpu::isa`); its waveform and backward
/// variants' add "-waveform" and "-backward", under the same budgets.
pub const PIPELINE_NAME: &str = "lugre-f64-hardware";

/// LuGre's pipelines as `pidm info --shader` lists them: the hardware's
/// (no loop limiter) and llvmpipe's, each a sawtooth's, a waveform's and
/// a backward one's, with its file name, its table row's name and its
/// shape.
const LISTED: [(&str, &str, Shape); 6] = [
    (
        "lugre-f64-hardware.wgsl",
        "lugre f64 (hardware)",
        (
            super::HARDWARE_WORKGROUP_SIZE,
            Arithmetic::Fused,
            Form::Sawtooth,
        ),
    ),
    (
        "lugre-f64-limiter.wgsl",
        "lugre f64 (llvmpipe)",
        (
            super::SOFTWARE_WORKGROUP_SIZE,
            Arithmetic::Native,
            Form::Sawtooth,
        ),
    ),
    (
        "lugre-f64-hardware-waveform.wgsl",
        "lugre f64 waveform (hardware)",
        (
            super::HARDWARE_WORKGROUP_SIZE,
            Arithmetic::Fused,
            Form::Waveform,
        ),
    ),
    (
        "lugre-f64-limiter-waveform.wgsl",
        "lugre f64 waveform (llvmpipe)",
        (
            super::SOFTWARE_WORKGROUP_SIZE,
            Arithmetic::Native,
            Form::Waveform,
        ),
    ),
    (
        "lugre-f64-hardware-backward.wgsl",
        "lugre f64 backward (hardware)",
        (
            super::HARDWARE_WORKGROUP_SIZE,
            Arithmetic::Fused,
            Form::Backward,
        ),
    ),
    (
        "lugre-f64-limiter-backward.wgsl",
        "lugre f64 backward (llvmpipe)",
        (
            super::SOFTWARE_WORKGROUP_SIZE,
            Arithmetic::Native,
            Form::Backward,
        ),
    ),
];

/// Writes the pipelines' WGSL into `dir`; their file names.
pub fn write_sources(dir: &std::path::Path) -> std::io::Result<Vec<String>> {
    let mut names = Vec::new();
    for (file, _, (size, arithmetic, form)) in LISTED {
        std::fs::write(dir.join(file), source(size, arithmetic, form))?;
        names.push(file.to_string());
    }
    Ok(names)
}

/// The pipelines' footprints, named as `pidm info`'s table lists them.
pub fn footprints() -> Result<Vec<(String, crate::gpu::spirv::Footprint)>, GpuError> {
    LISTED
        .iter()
        .map(|&(_, row, shape)| Ok((row.to_string(), footprint(shape)?)))
        .collect()
}

/// The hardware pipelines as a driver receives them, for their register
/// statistics (`crate::gpu::isa`): each one's name, module, SPIR-V and
/// entry point, the sawtooth's, the waveform's, then the backward one's.
#[allow(clippy::type_complexity)]
pub fn hardware_lanes() -> Result<Vec<(String, naga::Module, Vec<u32>, String)>, GpuError> {
    [
        (PIPELINE_NAME.to_string(), Form::Sawtooth),
        (format!("{PIPELINE_NAME}-waveform"), Form::Waveform),
        (format!("{PIPELINE_NAME}-backward"), Form::Backward),
    ]
    .into_iter()
    .map(|(name, form)| {
        let shape = (super::HARDWARE_WORKGROUP_SIZE, Arithmetic::Fused, form);
        let (module, words) = lane_spirv(shape)?;
        Ok((name, module, words, super::ENTRY_POINT.to_string()))
    })
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::lugre::{HARDWARE_WORKGROUP_SIZE, SOFTWARE_WORKGROUP_SIZE};

    /// Every LuGre variant's lane indexes no private array at run time (local
    /// memory on NVIDIA), as the Karnopp variants' (`gpu::footprint`):
    /// 4,976 B before the loops' bodies were called with literal indices
    /// and the vector sums written out. Needs `spirv-opt`: under `CI` its
    /// absence fails the test, elsewhere it is said and skipped.
    #[test]
    fn the_lane_indexes_no_private_array_at_run_time() {
        if !crate::gpu::spirv::spirv_opt_available() {
            assert!(
                std::env::var_os("CI").is_none(),
                "spirv-opt is missing (Debian's spirv-tools)"
            );
            eprintln!("notice: spirv-opt not found; the LuGre footprint is not checked");
            return;
        }
        for shape in Form::ALL.into_iter().flat_map(|form| {
            [
                (SOFTWARE_WORKGROUP_SIZE, Arithmetic::Native, form),
                (HARDWARE_WORKGROUP_SIZE, Arithmetic::Fused, form),
            ]
        }) {
            let arithmetic = shape;
            let f = footprint(shape).unwrap();
            let indexed = f.indexed.clone().expect("spirv-opt ran");
            assert!(indexed.is_empty(), "{arithmetic:?}: {indexed:?}");
            assert!(f.instructions.unwrap() > 1000, "{f:?}");
        }
    }
}
