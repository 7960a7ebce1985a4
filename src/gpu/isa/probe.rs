//! The child side of [`super::measure`]: `pidm isa-probe JOBS.json` opens
//! the first Vulkan device (RADV's null device, as the parent's environment
//! picks it), creates each job's compute pipeline with
//! `VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR` and prints the driver's
//! statistics as JSON on stdout. Nothing is dispatched: a null device only
//! compiles.

use super::Binding;
use anyhow::{Context, Result, bail};
use ash::vk;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::ffi::{CStr, CString};
use std::path::PathBuf;

/// The hidden subcommand that runs [`run`].
pub const SUBCOMMAND: &str = "isa-probe";

/// One pipeline to compile.
#[derive(Serialize, Deserialize)]
pub struct Job {
    pub name: String,
    pub spirv: PathBuf,
    pub entry: String,
    pub bindings: Vec<Binding>,
}

/// What the child prints.
#[derive(Serialize, Deserialize)]
pub struct Report {
    pub device: String,
    pub pipelines: Vec<Compiled>,
}

#[derive(Serialize, Deserialize)]
pub struct Compiled {
    pub name: String,
    pub executables: Vec<Executable>,
}

#[derive(Serialize, Deserialize)]
pub struct Executable {
    pub name: String,
    pub subgroup_size: u32,
    pub statistics: BTreeMap<String, f64>,
}

/// Compiles every job of `jobs_file` and prints the [`Report`].
pub fn run(jobs_file: &std::path::Path) -> Result<()> {
    let jobs: Vec<Job> = serde_json::from_slice(
        &std::fs::read(jobs_file).with_context(|| format!("reading {}", jobs_file.display()))?,
    )?;
    // SAFETY: the Vulkan calls below follow the specification's valid
    // usage: every handle is created before use and outlives its users;
    // the process ends right after.
    let report = unsafe { compile_all(&jobs)? };
    println!("{}", serde_json::to_string(&report)?);
    Ok(())
}

unsafe fn compile_all(jobs: &[Job]) -> Result<Report> {
    let entry = unsafe { ash::Entry::load() }.context("loading the Vulkan loader")?;
    let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_2);
    let instance = unsafe {
        entry.create_instance(
            &vk::InstanceCreateInfo::default().application_info(&app),
            None,
        )
    }
    .context("creating a Vulkan instance")?;
    let pd = *unsafe { instance.enumerate_physical_devices()? }
        .first()
        .context("no Vulkan device")?;
    let props = unsafe { instance.get_physical_device_properties(pd) };
    let device_name = props
        .device_name_as_c_str()
        .map(|c| c.to_string_lossy().into_owned())
        .unwrap_or_default();
    let has_statistics = {
        let mut e = vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR::default();
        let mut f = vk::PhysicalDeviceFeatures2::default().push_next(&mut e);
        unsafe { instance.get_physical_device_features2(pd, &mut f) };
        e.pipeline_executable_info != 0
    };
    if !has_statistics {
        bail!("{device_name} offers no pipeline executable statistics");
    }
    // Every feature the device has (f64 and int64 among them), and the
    // executables' statistics.
    let mut v12 = vk::PhysicalDeviceVulkan12Features::default();
    let mut v11 = vk::PhysicalDeviceVulkan11Features::default();
    let mut features = vk::PhysicalDeviceFeatures2::default()
        .push_next(&mut v12)
        .push_next(&mut v11);
    unsafe { instance.get_physical_device_features2(pd, &mut features) };
    if features.features.shader_float64 == 0 {
        bail!("{device_name} has no f64 in shaders");
    }
    let mut executables = vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR::default()
        .pipeline_executable_info(true);
    let mut features = features.push_next(&mut executables);
    let priorities = [1.0f32];
    let queues = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(0)
        .queue_priorities(&priorities)];
    let extensions = [ash::khr::pipeline_executable_properties::NAME.as_ptr()];
    let info = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queues)
        .enabled_extension_names(&extensions)
        .push_next(&mut features);
    let device = unsafe { instance.create_device(pd, &info, None) }
        .with_context(|| format!("opening {device_name}"))?;
    let stats = ash::khr::pipeline_executable_properties::Device::new(&instance, &device);
    let mut pipelines = Vec::new();
    for job in jobs {
        let compiled = unsafe { compile(&device, &stats, job) }
            .with_context(|| format!("compiling {} on {device_name}", job.name))?;
        pipelines.push(compiled);
    }
    Ok(Report {
        device: device_name,
        pipelines,
    })
}

unsafe fn compile(
    device: &ash::Device,
    stats: &ash::khr::pipeline_executable_properties::Device,
    job: &Job,
) -> Result<Compiled> {
    let bytes = std::fs::read(&job.spirv)?;
    let words: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let module = unsafe {
        device.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
    }?;
    let groups = job.bindings.iter().map(|b| b.group + 1).max().unwrap_or(0);
    let mut set_layouts = Vec::new();
    for group in 0..groups {
        let bindings: Vec<_> = job
            .bindings
            .iter()
            .filter(|b| b.group == group)
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.binding)
                    .descriptor_type(if b.uniform {
                        vk::DescriptorType::UNIFORM_BUFFER
                    } else {
                        vk::DescriptorType::STORAGE_BUFFER
                    })
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        set_layouts.push(unsafe {
            device.create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                None,
            )
        }?);
    }
    let layout = unsafe {
        device.create_pipeline_layout(
            &vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts),
            None,
        )
    }?;
    let entry = CString::new(job.entry.as_str())?;
    let stage = vk::PipelineShaderStageCreateInfo::default()
        .stage(vk::ShaderStageFlags::COMPUTE)
        .module(module)
        .name(&entry);
    let create = vk::ComputePipelineCreateInfo::default()
        .flags(vk::PipelineCreateFlags::CAPTURE_STATISTICS_KHR)
        .stage(stage)
        .layout(layout);
    let pipeline =
        unsafe { device.create_compute_pipelines(vk::PipelineCache::null(), &[create], None) }
            .map_err(|(_, e)| e)?[0];
    let properties = unsafe {
        stats.get_pipeline_executable_properties(&vk::PipelineInfoKHR::default().pipeline(pipeline))
    }?;
    let mut executables = Vec::new();
    for (k, p) in properties.iter().enumerate() {
        let info = vk::PipelineExecutableInfoKHR::default()
            .pipeline(pipeline)
            .executable_index(k as u32);
        let mut statistics = BTreeMap::new();
        for s in unsafe { stats.get_pipeline_executable_statistics(&info) }? {
            statistics.insert(text(&s.name), value(&s));
        }
        executables.push(Executable {
            name: text(&p.name),
            subgroup_size: p.subgroup_size,
            statistics,
        });
    }
    unsafe {
        device.destroy_pipeline(pipeline, None);
        device.destroy_pipeline_layout(layout, None);
        for l in set_layouts {
            device.destroy_descriptor_set_layout(l, None);
        }
        device.destroy_shader_module(module, None);
    }
    Ok(Compiled {
        name: job.name.clone(),
        executables,
    })
}

fn text(chars: &[std::ffi::c_char]) -> String {
    // The driver writes NUL-terminated strings within the array;
    // a missing NUL gives an empty name instead of reading past it.
    let bytes: Vec<u8> = chars.iter().map(|c| *c as u8).collect();
    CStr::from_bytes_until_nul(&bytes)
        .map(|c| c.to_string_lossy().into_owned())
        .unwrap_or_default()
}

fn value(s: &vk::PipelineExecutableStatisticKHR) -> f64 {
    // SAFETY: `format` says which member of the union the driver wrote.
    unsafe {
        match s.format {
            vk::PipelineExecutableStatisticFormatKHR::BOOL32 => s.value.b32 as f64,
            vk::PipelineExecutableStatisticFormatKHR::INT64 => s.value.i64 as f64,
            vk::PipelineExecutableStatisticFormatKHR::UINT64 => s.value.u64 as f64,
            _ => s.value.f64,
        }
    }
}
