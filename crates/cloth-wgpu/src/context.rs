//! Finding an adapter and opening a device.

use cloth_core::SimError;
use cloth_gpu::geometry::{DeviceKind, choose_device};

use crate::BACKEND_NAME;

/// A device and queue with a description of the adapter they come from.
#[derive(Clone, Debug)]
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter, in words: name, backend, type, driver.
    pub adapter_description: String,
    /// The adapter's type (semi-implicit Euler's tiled kernel is not used by default on a CPU:
    /// `cloth_gpu::Tiling::Auto`).
    pub device_type: wgpu::DeviceType,
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    let driver = if info.driver.is_empty() { String::new() } else { format!(", {} {}", info.driver, info.driver_info) };
    format!("{} ({:?}, {:?}{})", info.name, info.backend, info.device_type, driver.trim_end())
}

fn kind(device_type: wgpu::DeviceType) -> DeviceKind {
    match device_type {
        wgpu::DeviceType::DiscreteGpu => DeviceKind::DiscreteGpu,
        wgpu::DeviceType::IntegratedGpu => DeviceKind::IntegratedGpu,
        wgpu::DeviceType::VirtualGpu => DeviceKind::VirtualGpu,
        wgpu::DeviceType::Other => DeviceKind::Other,
        wgpu::DeviceType::Cpu => DeviceKind::Cpu,
    }
}

/// The process's one wgpu instance, on the backends that run compute shaders (Vulkan, Metal,
/// DX12; not GL).
///
/// Created once and shared: with NVIDIA's driver 580, creating and dropping instances repeatedly
/// in one process makes instance creation fail after about 20 cycles (wgpu and vulkano alike),
/// and an instance costs over a second to create there.
fn instance() -> &'static wgpu::Instance {
    static INSTANCE: std::sync::OnceLock<wgpu::Instance> = std::sync::OnceLock::new();
    INSTANCE.get_or_init(|| {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::PRIMARY;
        wgpu::Instance::new(desc)
    })
}

/// Adapters able to run compute shaders, their names and kinds.
fn compute_adapters() -> Vec<(wgpu::Adapter, String, DeviceKind)> {
    (pollster::block_on(instance().enumerate_adapters(wgpu::Backends::all())).into_iter())
        .filter(|a| a.get_downlevel_capabilities().flags.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS))
        .map(|a| {
            let info = a.get_info();
            (a, info.name, kind(info.device_type))
        })
        .collect()
}

/// The adapters wgpu finds here that can run the simulation, best first, in words.
///
/// # Errors
/// A sentence saying what to install when there is none.
pub fn list_adapters() -> Result<Vec<String>, String> {
    let mut adapters = compute_adapters();
    adapters.sort_by_key(|a| a.2);
    let list: Vec<String> = adapters.iter().map(|a| describe(&a.0.get_info())).collect();
    if list.is_empty() { Err(no_adapter_reason()) } else { Ok(list) }
}

fn no_adapter_reason() -> String {
    "wgpu found no Vulkan, Metal or DX12 adapter with compute shaders; on Debian/Ubuntu install \
     Mesa's software Vulkan driver (apt-get install mesa-vulkan-drivers libvulkan1) or a GPU driver"
        .into()
}

/// The features and limits the simulator asks of a device on `adapter`: the largest storage
/// buffers, workgroup grids and workgroup memory it offers, every storage buffer per stage it
/// offers (the force kernel binds up to 15, more than WebGPU's default of 8; the plan refuses a
/// device with fewer than a kernel needs), and timestamp queries where there are any (between
/// the dispatches of a pass too, for a frame's profile).
/// A host that opens the device itself (the inspector shares eframe's) requests these so the
/// simulator can run on it.
pub fn device_requirements(adapter: &wgpu::Adapter) -> (wgpu::Features, wgpu::Limits) {
    let offered = adapter.limits();
    let limits = wgpu::Limits {
        max_storage_buffer_binding_size: offered.max_storage_buffer_binding_size,
        max_buffer_size: offered.max_buffer_size,
        max_storage_buffers_per_shader_stage: offered.max_storage_buffers_per_shader_stage.max(8),
        max_compute_workgroups_per_dimension: offered.max_compute_workgroups_per_dimension,
        max_compute_invocations_per_workgroup: offered.max_compute_invocations_per_workgroup,
        max_compute_workgroup_size_x: offered.max_compute_workgroup_size_x,
        // The tiled Euler kernel keeps its tile in workgroup memory (cloth_gpu::geometry).
        max_compute_workgroup_storage_size: offered.max_compute_workgroup_storage_size,
        ..wgpu::Limits::default()
    };
    (adapter.features() & (wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES), limits)
}

impl GpuContext {
    /// Opens a device on the best adapter, or the first whose name contains `name_contains`
    /// (case-insensitive), with the largest storage buffers it offers.
    ///
    /// # Errors
    /// [`SimError::Unavailable`] when no adapter matches or the device cannot be opened.
    pub fn new(name_contains: Option<&str>) -> Result<Self, SimError> {
        let unavailable = |reason: String| SimError::Unavailable { backend: BACKEND_NAME, reason };
        let adapter = choose_device(compute_adapters(), name_contains, &no_adapter_reason()).map_err(unavailable)?;
        let (features, limits) = device_requirements(&adapter);
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("cloth device"),
            required_features: features,
            required_limits: limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| unavailable(format!("cannot open a device on {}: {e}", adapter.get_info().name)))?;
        let info = adapter.get_info();
        Ok(Self { device, queue, adapter_description: describe(&info), device_type: info.device_type })
    }
}
