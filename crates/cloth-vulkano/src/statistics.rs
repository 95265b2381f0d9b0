//! What the driver's compiler made of each kernel: registers, shared memory, spills and the like,
//! as the driver reports them through `VK_KHR_pipeline_executable_properties`. A diagnostic for
//! tuning (occupancy is registers and shared memory), asked for with `CLOTH_PIPELINE_STATS=1` and
//! printed to stderr as each pipeline is built.

use std::ffi::CStr;
use std::sync::Arc;

use vulkano::VulkanObject;
use vulkano::device::Device;
use vulkano::pipeline::PipelineLayout;
use vulkano::shader::{ShaderModule, SpecializationConstant};

/// Whether `CLOTH_PIPELINE_STATS=1` asks for the statistics.
pub(crate) fn wanted() -> bool {
    std::env::var("CLOTH_PIPELINE_STATS").is_ok_and(|v| v.trim() == "1")
}

/// Whether `device` was opened with the extension and feature the statistics need.
pub(crate) fn available(device: &Device) -> bool {
    device.enabled_extensions().khr_pipeline_executable_properties && device.enabled_features().pipeline_executable_info
}

/// The driver's statistics of the compute pipeline of `module`'s `main` under `layout` and the
/// specialization `constants`, one line each, `name = value`; empty when the driver reports
/// none. vulkano has no flag to capture them (`CAPTURE_STATISTICS` is not exposed), so this builds
/// a twin of the pipeline through the raw Vulkan calls, with the flag, and drops it after.
pub(crate) fn of(
    device: &Arc<Device>,
    module: &ShaderModule,
    layout: &PipelineLayout,
    constants: &[(u32, SpecializationConstant)],
) -> Vec<String> {
    use ash::vk;
    let mut data: Vec<u8> = Vec::new();
    let mut entries: Vec<vk::SpecializationMapEntry> = Vec::new();
    for (id, constant) in constants {
        let value = match *constant {
            SpecializationConstant::Bool(on) => u32::from(on),
            SpecializationConstant::U32(value) => value,
            _ => continue,
        };
        entries.push(vk::SpecializationMapEntry { constant_id: *id, offset: data.len() as u32, size: 4 });
        data.extend_from_slice(&value.to_ne_bytes());
    }
    let specialization = vk::SpecializationInfo::default().map_entries(&entries).data(&data);
    let stage = vk::PipelineShaderStageCreateInfo::default()
        .stage(vk::ShaderStageFlags::COMPUTE)
        .module(module.handle())
        .name(c"main")
        .specialization_info(&specialization);
    let info = vk::ComputePipelineCreateInfo::default()
        .flags(vk::PipelineCreateFlags::CAPTURE_STATISTICS_KHR)
        .stage(stage)
        .layout(layout.handle());
    let mut pipeline = vk::Pipeline::null();
    let v1_0 = &device.fns().v1_0;
    // SAFETY: valid device, module and layout handles; the create info and what it points to
    // outlive the call; the pipeline is destroyed below and never used otherwise.
    let result = unsafe {
        (v1_0.create_compute_pipelines)(
            device.handle(),
            vk::PipelineCache::null(),
            1,
            &info,
            std::ptr::null(),
            &mut pipeline,
        )
    };
    if result != vk::Result::SUCCESS {
        return vec![format!("(the driver did not build the pipeline: {result:?})")];
    }
    let lines = statistics(device, pipeline);
    // SAFETY: the pipeline was created above on this device and is not in use.
    unsafe { (v1_0.destroy_pipeline)(device.handle(), pipeline, std::ptr::null()) };
    lines
}

fn statistics(device: &Device, pipeline: ash::vk::Pipeline) -> Vec<String> {
    use ash::vk;
    let fns = &device.fns().khr_pipeline_executable_properties;
    let info = vk::PipelineExecutableInfoKHR::default().pipeline(pipeline).executable_index(0);
    let mut count = 0u32;
    // SAFETY: a valid device and pipeline; the first call only counts the statistics.
    let result = unsafe {
        (fns.get_pipeline_executable_statistics_khr)(device.handle(), &info, &mut count, std::ptr::null_mut())
    };
    if result != vk::Result::SUCCESS || count == 0 {
        return Vec::new();
    }
    let mut statistics = vec![vk::PipelineExecutableStatisticKHR::default(); count as usize];
    // SAFETY: `statistics` holds `count` initialised structures of the right type.
    let result = unsafe {
        (fns.get_pipeline_executable_statistics_khr)(device.handle(), &info, &mut count, statistics.as_mut_ptr())
    };
    if result != vk::Result::SUCCESS && result != vk::Result::INCOMPLETE {
        return Vec::new();
    }
    statistics
        .iter()
        .take(count as usize)
        .map(|s| {
            // SAFETY: the driver writes NUL-terminated names; the union member read is the one
            // `format` names.
            let name = unsafe { CStr::from_ptr(s.name.as_ptr()) }.to_string_lossy();
            let value = unsafe {
                match s.format {
                    vk::PipelineExecutableStatisticFormatKHR::BOOL32 => (s.value.b32 != 0).to_string(),
                    vk::PipelineExecutableStatisticFormatKHR::INT64 => s.value.i64.to_string(),
                    vk::PipelineExecutableStatisticFormatKHR::UINT64 => s.value.u64.to_string(),
                    _ => s.value.f64.to_string(),
                }
            };
            format!("{name} = {value}")
        })
        .collect()
}
