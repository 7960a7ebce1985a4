//! What a real GPU compiler makes of every pipeline a batch creates, with
//! no GPU (issue 57): Mesa's RADV opens an AMD GPU that is not there
//! (`RADV_FORCE_FAMILY`, its null device), compiles each pipeline with
//! ACO, AMD's production shader compiler, and reports the statistics of
//! `VK_KHR_pipeline_executable_properties`: VGPRs asked and allocated,
//! spills, scratch, subgroups per SIMD, instructions.
//!
//! A thread that needs more registers than the hardware gives it spills to
//! scratch (AMD) or local memory (NVIDIA: at most 255 registers a thread),
//! off-chip, at every access: the figure that decides whether a lane runs
//! at the GPU's speed. The SPIR-V measured is the one pidm hands the
//! driver (`spirv::module_spirv`), the batch's entry point alone.
//!
//! The probe is a child process (`pidm isa-probe JOBS.json`, `probe.rs`)
//! with the newer RADV's folder on `LD_LIBRARY_PATH` and its ICD file in
//! `VK_ICD_FILENAMES`, so the process that runs batches keeps the system's
//! Vulkan (lavapipe). `.ci/radv.sh` unpacks that RADV into
//! [`radv_dir`]; without it [`measure`] says how to get it.

mod budgets;
pub mod probe;

pub use budgets::{BUDGETS, Budget, Limit, verdicts};

use crate::gpu::GpuError;
use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The AMD families measured: RDNA3 and RDNA2, both with f64 in shaders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Family {
    Navi31,
    Navi21,
}

impl Family {
    pub const ALL: [Family; 2] = [Family::Navi31, Family::Navi21];

    /// RADV's name for it (`RADV_FORCE_FAMILY`).
    pub fn as_str(self) -> &'static str {
        match self {
            Family::Navi31 => "navi31",
            Family::Navi21 => "navi21",
        }
    }
}

/// One compute pipeline of a batch: its name, the SPIR-V of its entry
/// point and the resources it binds.
#[derive(Clone, Debug)]
pub struct Pipeline {
    /// "f64-hardware-window", "lugre-f64-hardware".
    pub name: String,
    pub words: Vec<u32>,
    pub entry: String,
    pub bindings: Vec<Binding>,
}

/// One resource binding of a pipeline, as the descriptor set layout
/// declares it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Binding {
    pub group: u32,
    pub binding: u32,
    /// A uniform buffer (else a storage buffer).
    pub uniform: bool,
}

/// The resource bindings the module's entry points may use: every global
/// with a binding, uniform or storage.
pub fn bindings(module: &naga::Module) -> Vec<Binding> {
    module
        .global_variables
        .iter()
        .filter_map(|(_, g)| {
            let b = g.binding.as_ref()?;
            Some(Binding {
                group: b.group,
                binding: b.binding,
                uniform: g.space == naga::AddressSpace::Uniform,
            })
        })
        .collect()
}

/// Every compute pipeline a batch creates on a hardware adapter: Karnopp's
/// variants (two precisions, every combination of parts, and f64's with
/// the backward travel) and LuGre's.
pub fn batch_pipelines() -> Result<Vec<Pipeline>, GpuError> {
    use crate::gpu::footprint::variant_name;
    use crate::gpu::shader::{ENTRY_POINT, Variant, parse_and_validate};
    use crate::gpu::spirv::module_spirv;
    let mut out = Vec::new();
    for v in Variant::every() {
        if v.loop_limiter {
            continue;
        }
        let precision = v.precision;
        {
            let (module, info) = parse_and_validate(v)?;
            out.push(Pipeline {
                name: variant_name(v),
                words: module_spirv(&module, &info, precision)?,
                entry: ENTRY_POINT.to_string(),
                bindings: bindings(&module),
            });
        }
    }
    for (name, module, words, entry) in crate::gpu::law_hardware_lanes()? {
        out.push(Pipeline {
            name,
            words,
            entry,
            bindings: bindings(&module),
        });
    }
    Ok(out)
}

/// The name of LuGre's hardware pipeline in the tables.
pub use crate::gpu::LAW_PIPELINE_NAME as LUGRE_NAME;

/// ACO's statistics of one pipeline's compute executable, the figures a
/// budget reads, and every statistic the driver listed.
#[derive(Clone, Debug, PartialEq)]
pub struct Statistics {
    pub pipeline: String,
    pub family: Family,
    /// VGPRs allocated to a thread (ACO's "VGPRs": at most 256 on RDNA).
    pub vgprs: u64,
    /// VGPRs the program asked for before spilling ("Pre-Sched VGPRs" where
    /// the driver lists it).
    pub vgprs_asked: Option<u64>,
    pub spilled_vgprs: u64,
    pub spilled_sgprs: u64,
    /// Scratch memory per wave [bytes].
    pub scratch: u64,
    pub subgroups_per_simd: u64,
    pub instructions: Option<u64>,
    /// Every statistic, by the driver's name.
    pub all: BTreeMap<String, f64>,
}

impl Statistics {
    fn from_driver(pipeline: &str, family: Family, all: BTreeMap<String, f64>) -> Result<Self> {
        let get = |name: &str| -> Result<u64> {
            all.get(name)
                .map(|v| *v as u64)
                .with_context(|| format!("RADV listed no \"{name}\" for {pipeline}"))
        };
        Ok(Statistics {
            pipeline: pipeline.to_string(),
            family,
            vgprs: get("VGPRs")?,
            vgprs_asked: all.get("Pre-Sched VGPRs").map(|v| *v as u64),
            spilled_vgprs: get("Spilled VGPRs")?,
            spilled_sgprs: get("Spilled SGPRs")?,
            scratch: get("Scratch size")?,
            subgroups_per_simd: get("Subgroups per SIMD")?,
            instructions: all.get("Instructions").map(|v| *v as u64),
            all,
        })
    }
}

/// Where `.ci/radv.sh` unpacks the newer RADV: `PIDM_RADV`, else
/// /opt/mesa-backports (the folder `../shared/gpu/isa/setup.sh` uses).
pub fn radv_dir() -> PathBuf {
    std::env::var_os("PIDM_RADV")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/opt/mesa-backports"))
}

/// Whether the newer RADV is unpacked (its ICD file and driver present).
pub fn radv_available() -> bool {
    let dir = radv_dir();
    dir.join("radeon.json").is_file() && driver_lib_dir(&dir).join("libvulkan_radeon.so").is_file()
}

fn driver_lib_dir(dir: &Path) -> PathBuf {
    dir.join("root/usr/lib/x86_64-linux-gnu")
}

/// ACO's statistics of every pipeline on `family`'s null device, compiled
/// by `probe_exe isa-probe` (the pidm binary) in a child process.
pub fn measure(
    probe_exe: &Path,
    family: Family,
    pipelines: &[Pipeline],
) -> Result<Vec<Statistics>> {
    let dir = radv_dir();
    if !radv_available() {
        bail!(
            "no RADV of Mesa 25 in {} (run `bash .ci/radv.sh` as root, or set PIDM_RADV to the \
             folder it unpacked)",
            dir.display()
        );
    }
    let report = probe(probe_exe, Some((&dir, family)), pipelines)?;
    if !report.device.contains(&family.as_str().to_uppercase()) {
        bail!(
            "the RADV probe opened \"{}\", not a {} null device",
            report.device,
            family.as_str()
        );
    }
    report
        .pipelines
        .into_iter()
        .map(|p| {
            let exe = p
                .executables
                .into_iter()
                .next()
                .with_context(|| format!("RADV reported no executable for {}", p.name))?;
            Statistics::from_driver(&p.name, family, exe.statistics)
        })
        .collect()
}

/// Every statistic the system's own first Vulkan device lists for each
/// pipeline (NVIDIA's "Register Count" and local memory on a lent
/// device), compiled by `probe_exe isa-probe` in a child with the
/// environment as it is: the device's name and the report.
pub fn measure_native(probe_exe: &Path, pipelines: &[Pipeline]) -> Result<probe::Report> {
    probe(probe_exe, None, pipelines)
}

/// Runs the probe child on `pipelines`, on RADV's null `family` from the
/// folder given, else on the system's first device.
fn probe(
    probe_exe: &Path,
    radv: Option<(&Path, Family)>,
    pipelines: &[Pipeline],
) -> Result<probe::Report> {
    let work = crate::gpu::spirv::tempfile_dir()
        .context("creating a temporary folder for the probe's jobs")?;
    let result = probe_in(&work, radv, probe_exe, pipelines);
    let _ = std::fs::remove_dir_all(&work);
    result
}

fn probe_in(
    work: &Path,
    radv: Option<(&Path, Family)>,
    probe_exe: &Path,
    pipelines: &[Pipeline],
) -> Result<probe::Report> {
    let mut jobs = Vec::new();
    for (k, p) in pipelines.iter().enumerate() {
        let file = work.join(format!("{k}.spv"));
        let bytes: Vec<u8> = p.words.iter().flat_map(|w| w.to_le_bytes()).collect();
        std::fs::write(&file, bytes)?;
        jobs.push(probe::Job {
            name: p.name.clone(),
            spirv: file,
            entry: p.entry.clone(),
            bindings: p.bindings.clone(),
        });
    }
    let jobs_file = work.join("jobs.json");
    std::fs::write(&jobs_file, serde_json::to_vec(&jobs)?)?;
    let mut child = Command::new(probe_exe);
    child.arg(probe::SUBCOMMAND).arg(&jobs_file);
    if let Some((radv, family)) = radv {
        child
            .env("LD_LIBRARY_PATH", driver_lib_dir(radv))
            .env("VK_ICD_FILENAMES", radv.join("radeon.json"))
            .env("VK_DRIVER_FILES", radv.join("radeon.json"))
            .env("RADV_FORCE_FAMILY", family.as_str())
            .env(
                "XDG_RUNTIME_DIR",
                std::env::var_os("XDG_RUNTIME_DIR").unwrap_or_else(|| std::env::temp_dir().into()),
            );
    }
    let device = radv.map_or("the system's Vulkan device", |(_, f)| f.as_str());
    let out = child
        .output()
        .with_context(|| format!("starting {} {}", probe_exe.display(), probe::SUBCOMMAND))?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let said: Vec<&str> = stderr
            .lines()
            .filter(|l| !l.contains("pci bus info"))
            .collect();
        bail!(
            "the pipeline statistics probe on {device} failed ({}): {}",
            out.status,
            said.join("\n")
        );
    }
    serde_json::from_slice(&out.stdout).context("reading the statistics probe's report")
}

/// The statistics as a table: one row per pipeline and family.
pub fn table(stats: &[Statistics]) -> String {
    let mut out = format!(
        "{:<34} {:>7} {:>6} {:>6} {:>8} {:>8} {:>9} {:>10} {:>7}\n",
        "pipeline",
        "family",
        "VGPRs",
        "asked",
        "spilled",
        "sgpr sp",
        "scratch",
        "subgroups",
        "instr"
    );
    let show = |x: Option<u64>| x.map_or("-".to_string(), |n| n.to_string());
    for s in stats {
        out += &format!(
            "{:<34} {:>7} {:>6} {:>6} {:>8} {:>8} {:>9} {:>10} {:>7}\n",
            s.pipeline,
            s.family.as_str(),
            s.vgprs,
            show(s.vgprs_asked),
            s.spilled_vgprs,
            s.spilled_sgprs,
            s.scratch,
            s.subgroups_per_simd,
            show(s.instructions)
        );
    }
    out
}
