//! Adapters: which wgpu can open, how they are ranked (hardware before
//! software, f64 before none), what `pidm info` reports of them, and the
//! private runtime directory some Vulkan loaders need.

use super::*;

/// One adapter as wgpu enumerates it.
#[derive(Clone, Debug, PartialEq)]
pub struct AdapterSummary {
    pub name: String,
    pub device_type: String,
    pub backend: String,
    /// The driver and its version, as the adapter reports them.
    pub driver: String,
    /// True when the adapter offers `SHADER_F64`.
    pub f64: bool,
    /// True when the adapter keeps compiled pipelines in a cache wgpu can
    /// save (`PIPELINE_CACHE`).
    pub pipeline_cache: bool,
    pub max_storage_buffer_binding_size: u64,
    pub max_buffer_size: u64,
    pub max_compute_workgroups_per_dimension: u32,
}

/// Every adapter on the given backends (the instance's other settings come
/// from wgpu's environment variables).
pub(super) fn adapters_on(backends: wgpu::Backends) -> Vec<wgpu::Adapter> {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle().with_env();
    desc.backends = backends;
    pollster::block_on(wgpu::Instance::new(desc).enumerate_adapters(backends))
}

/// Every adapter wgpu can open, on the backends `WGPU_BACKEND` names or on
/// all.
pub(super) fn adapters() -> Vec<wgpu::Adapter> {
    adapters_on(wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all()))
}

pub(super) fn summary(adapter: &wgpu::Adapter) -> AdapterSummary {
    let info = adapter.get_info();
    let limits = adapter.limits();
    AdapterSummary {
        name: info.name.clone(),
        device_type: format!("{:?}", info.device_type),
        backend: format!("{:?}", info.backend),
        driver: driver_of(&info),
        f64: adapter.features().contains(wgpu::Features::SHADER_F64),
        pipeline_cache: adapter.features().contains(wgpu::Features::PIPELINE_CACHE),
        max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
        max_buffer_size: limits.max_buffer_size,
        max_compute_workgroups_per_dimension: limits.max_compute_workgroups_per_dimension,
    }
}

/// "NVIDIA 580.159.04": the driver's name and version.
pub(super) fn driver_of(info: &wgpu::AdapterInfo) -> String {
    match (info.driver.is_empty(), info.driver_info.is_empty()) {
        (false, false) => format!("{} {}", info.driver, info.driver_info),
        (false, true) => info.driver.clone(),
        (true, false) => info.driver_info.clone(),
        (true, true) => "unknown driver".to_string(),
    }
}

/// Every adapter wgpu enumerates (honouring `WGPU_BACKEND`).
pub fn list_adapters() -> Vec<AdapterSummary> {
    adapters().iter().map(summary).collect()
}

/// Whether an adapter runs one precision and trusts it: `Ok` once its
/// pipeline compiled and passed the self-test against the CPU, else why
/// not (no `SHADER_F64`, no compute shaders, a device, compile or
/// self-test failure).
#[derive(Clone, Debug, PartialEq)]
pub struct PrecisionCheck {
    pub precision: Precision,
    pub trusted: Result<(), String>,
}

impl PrecisionCheck {
    /// "f64 yes (self-test passed)" or "f32 no (...)".
    pub fn describe(&self) -> String {
        match &self.trusted {
            Ok(()) => format!("{} yes (self-test passed)", self.precision),
            Err(why) => format!("{} no ({why})", self.precision),
        }
    }
}

/// Every adapter wgpu enumerates with, per precision, whether it runs and
/// passes its self-test: opens a device on each and compiles and self-tests
/// each precision it offers (seconds per adapter when the pipeline is not
/// cached).
pub fn check_adapters() -> Vec<(AdapterSummary, Vec<PrecisionCheck>)> {
    adapters()
        .iter()
        .map(|adapter| {
            let summary = summary(adapter);
            let compute = adapter
                .get_downlevel_capabilities()
                .flags
                .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS);
            let ctx = if compute {
                GpuContext::from_adapter(adapter).map_err(|e| e.to_string())
            } else {
                Err("no compute shaders".to_string())
            };
            let checks = [Precision::F32, Precision::F64]
                .into_iter()
                .map(|precision| {
                    let trusted = match &ctx {
                        Err(why) => Err(why.clone()),
                        Ok(_) if precision == Precision::F64 && !summary.f64 => {
                            Err("no SHADER_F64".to_string())
                        }
                        Ok(ctx) => match ctx.prepare(precision) {
                            Ok(_) => Ok(()),
                            Err(GpuError::SelfTest { message, .. }) => {
                                Err(format!("self-test failed: {message}"))
                            }
                            Err(e) => Err(e.to_string()),
                        },
                    };
                    PrecisionCheck { precision, trusted }
                })
                .collect();
            (summary, checks)
        })
        .collect()
}

/// A private runtime folder for this process when `XDG_RUNTIME_DIR` is
/// unset or invalid (not a folder of this user's that only it may enter),
/// to set before wgpu looks for adapters: Mesa's GL driver otherwise prints
/// "error: XDG_RUNTIME_DIR is invalid or not set in the environment", which
/// a user of pidm can do nothing about. `None` when the variable is valid
/// or no such folder can be made. The folder, `pidm-runtime-<uid>-<pid>`
/// in the temporary folder with mode 0700, is new and empty: the caller
/// removes it when the process ends ([`std::fs::remove_dir`] leaves it if
/// a driver put something there).
pub fn private_runtime_dir() -> Option<std::path::PathBuf> {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt};
    // SAFETY: getuid cannot fail and touches no memory.
    let uid = unsafe { libc::getuid() };
    let private = |path: &std::path::Path| {
        std::fs::symlink_metadata(path)
            .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.mode() & 0o077 == 0)
    };
    if let Some(dir) = std::env::var_os("XDG_RUNTIME_DIR").filter(|d| !d.is_empty())
        && private(std::path::Path::new(&dir))
    {
        return None;
    }
    let dir = std::env::temp_dir().join(format!("pidm-runtime-{uid}-{}", std::process::id()));
    std::fs::DirBuilder::new().mode(0o700).create(&dir).ok()?;
    private(&dir).then_some(dir)
}

/// True for adapters that run on the CPU (lavapipe, llvmpipe, SwiftShader,
/// WARP).
pub(super) fn is_software(info: &wgpu::AdapterInfo) -> bool {
    let name = info.name.to_lowercase();
    info.device_type == wgpu::DeviceType::Cpu
        || ["llvmpipe", "lavapipe", "swiftshader", "softpipe", "warp"]
            .iter()
            .any(|n| name.contains(n))
}

/// True for adapters whose shader loops stop silently after 65,535
/// iterations (Mesa's llvmpipe, behind lavapipe and its GL driver).
pub(super) fn has_loop_limiter(info: &wgpu::AdapterInfo) -> bool {
    let name = info.name.to_lowercase();
    name.contains("llvmpipe") || name.contains("lavapipe")
}

/// Preference among usable adapters: discrete, integrated, virtual, other,
/// software; f64 support breaks ties.
pub(super) fn rank(adapter: &wgpu::Adapter) -> (u32, bool) {
    let info = adapter.get_info();
    let kind = if is_software(&info) {
        0
    } else {
        match info.device_type {
            wgpu::DeviceType::DiscreteGpu => 4,
            wgpu::DeviceType::IntegratedGpu => 3,
            wgpu::DeviceType::VirtualGpu => 2,
            _ => 1,
        }
    };
    (
        kind,
        adapter.features().contains(wgpu::Features::SHADER_F64),
    )
}
