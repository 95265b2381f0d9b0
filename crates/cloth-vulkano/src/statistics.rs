//! What the driver's compiler made of each kernel: registers, shared memory, spills and the like,
//! as the driver reports them through `VK_KHR_pipeline_executable_properties`. A diagnostic for
//! tuning (occupancy is registers and shared memory), asked for with
//! `GpuTuning::pipeline_statistics` and printed to standard error as each pipeline is built.

use std::sync::Arc;

use ash::vk;
use vulkano::VulkanObject;
use vulkano::device::Device;
use vulkano::pipeline::PipelineLayout;
use vulkano::shader::{ShaderModule, SpecializationConstant};

/// Why no statistics came back.
#[derive(Debug, thiserror::Error)]
pub(crate) enum StatisticsError {
    #[error("specialization constant {0} is neither a bool nor a u32, which this diagnostic does not pass")]
    Constant(u32),
    #[error("the driver answered {0:?}")]
    Vulkan(vk::Result),
}

/// The driver's statistics of the compute pipeline of `module`'s `main` under `layout` and the
/// specialization `constants`, one `name = value` line each. vulkano has no flag to capture them
/// (`CAPTURE_STATISTICS` is not exposed), so this builds a twin of the pipeline through the raw
/// Vulkan calls, with the flag, and destroys it after.
///
/// # Errors
/// [`StatisticsError`]: a constant is of a type this does not pass, or the driver failed a call.
/// The device must have been opened with the extension and its feature.
pub(crate) fn of(
    device: &Arc<Device>,
    module: &ShaderModule,
    layout: &PipelineLayout,
    constants: &[(u32, SpecializationConstant)],
) -> Result<Vec<String>, StatisticsError> {
    let mut data: Vec<u8> = Vec::new();
    let mut entries: Vec<vk::SpecializationMapEntry> = Vec::new();
    for (id, constant) in constants {
        let value = match *constant {
            SpecializationConstant::Bool(on) => u32::from(on),
            SpecializationConstant::U32(value) => value,
            _ => return Err(StatisticsError::Constant(*id)),
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
    // SAFETY: valid device, module and layout handles (the module's `main` and these constants
    // were validated by vulkano building the same pipeline first); the create info and what it
    // points to outlive the call; the pipeline is destroyed below and never used otherwise.
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
        return Err(StatisticsError::Vulkan(result));
    }
    let lines = statistics(device, pipeline);
    // SAFETY: the pipeline was created above on this device and is not in use.
    unsafe { (v1_0.destroy_pipeline)(device.handle(), pipeline, std::ptr::null()) };
    lines
}

/// The statistics of executable 0 (a compute pipeline's only one) of `pipeline`, built with
/// `CAPTURE_STATISTICS` on `device`, which has the extension and its feature.
fn statistics(device: &Device, pipeline: vk::Pipeline) -> Result<Vec<String>, StatisticsError> {
    let fns = &device.fns().khr_pipeline_executable_properties;
    let info = vk::PipelineExecutableInfoKHR::default().pipeline(pipeline).executable_index(0);
    let mut count = 0u32;
    // SAFETY: a valid device and pipeline; the first call only counts the statistics.
    let result = unsafe {
        (fns.get_pipeline_executable_statistics_khr)(device.handle(), &info, &mut count, std::ptr::null_mut())
    };
    if result != vk::Result::SUCCESS {
        return Err(StatisticsError::Vulkan(result));
    }
    let mut statistics = vec![vk::PipelineExecutableStatisticKHR::default(); count as usize];
    // SAFETY: `statistics` holds `count` initialised structures of the right type.
    let result = unsafe {
        (fns.get_pipeline_executable_statistics_khr)(device.handle(), &info, &mut count, statistics.as_mut_ptr())
    };
    if result != vk::Result::SUCCESS && result != vk::Result::INCOMPLETE {
        return Err(StatisticsError::Vulkan(result));
    }
    Ok(statistics
        .iter()
        .take(count as usize)
        .map(|s| {
            let name = s.name_as_c_str().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|_| "?".into());
            // SAFETY: the union member read is the one `format` names.
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
        .collect())
}
