//! Loading Vulkan, choosing a physical device, opening a device; validation messages.

use std::sync::{Arc, Mutex};

use cloth_core::SimError;
use vulkano::VulkanLibrary;
use vulkano::device::physical::{PhysicalDevice, PhysicalDeviceType};
use vulkano::device::{Device, DeviceCreateInfo, DeviceExtensions, DeviceFeatures, Queue, QueueCreateInfo, QueueFlags};
use vulkano::instance::debug::{
    DebugUtilsMessageSeverity, DebugUtilsMessageType, DebugUtilsMessengerCallback, DebugUtilsMessengerCreateInfo,
};
use vulkano::instance::{Instance, InstanceCreateFlags, InstanceCreateInfo, InstanceExtensions};

use cloth_gpu::geometry::{DeviceKind, choose_device};

use crate::BACKEND_NAME;

const VALIDATION_LAYER: &str = "VK_LAYER_KHRONOS_validation";

/// An open device with its compute queue.
pub struct VulkanContext {
    /// The device.
    pub device: Arc<Device>,
    /// A queue that supports compute.
    pub queue: Arc<Queue>,
    /// The physical device, in words.
    pub description: String,
    /// Whether the Khronos validation layer is enabled (debug builds, when it is installed).
    pub validation: bool,
    /// Validation messages (warnings and errors) received so far in this process (the instance,
    /// and so its messenger, is shared).
    pub messages: Arc<Mutex<Vec<String>>>,
}

fn unavailable(reason: impl Into<String>) -> SimError {
    SimError::Unavailable { backend: BACKEND_NAME, reason: reason.into() }
}

fn describe(p: &PhysicalDevice) -> String {
    let props = p.properties();
    let driver = props.driver_info.clone().unwrap_or_default();
    format!("{} ({:?}, Vulkan {}, {})", props.device_name, props.device_type, p.api_version(), driver.trim())
}

fn kind(t: PhysicalDeviceType) -> DeviceKind {
    match t {
        PhysicalDeviceType::DiscreteGpu => DeviceKind::DiscreteGpu,
        PhysicalDeviceType::IntegratedGpu => DeviceKind::IntegratedGpu,
        PhysicalDeviceType::VirtualGpu => DeviceKind::VirtualGpu,
        PhysicalDeviceType::Cpu => DeviceKind::Cpu,
        _ => DeviceKind::Other,
    }
}

fn load_library() -> Result<Arc<VulkanLibrary>, SimError> {
    VulkanLibrary::new().map_err(|e| {
        unavailable(format!(
            "cannot load the Vulkan loader ({e}); on Debian/Ubuntu install it with \
             `apt-get install libvulkan1 mesa-vulkan-drivers` (mesa-vulkan-drivers gives lavapipe, a CPU driver)"
        ))
    })
}

/// The process's one Vulkan instance, whether validation is on, and where its messages go.
struct SharedInstance {
    instance: Arc<Instance>,
    validation: bool,
    messages: Arc<Mutex<Vec<String>>>,
}

/// Creates the instance once per process and shares it (debug builds enable validation when
/// the layer is installed).
///
/// With NVIDIA's driver 580, creating and destroying instances repeatedly in one process makes
/// `vkCreateInstance` fail after about 20 cycles (wgpu and vulkano alike); one shared instance
/// avoids it, and saves its start-up cost.
fn shared_instance() -> Result<&'static SharedInstance, SimError> {
    static SHARED: std::sync::OnceLock<Result<SharedInstance, String>> = std::sync::OnceLock::new();
    SHARED
        .get_or_init(|| {
            let messages = Arc::new(Mutex::new(Vec::new()));
            create_instance(cfg!(debug_assertions), &messages)
                .map(|(instance, validation)| SharedInstance { instance, validation, messages })
                .map_err(|e| match e {
                    SimError::Unavailable { reason, .. } => reason,
                    other => other.to_string(),
                })
        })
        .as_ref()
        .map_err(|reason| unavailable(reason.clone()))
}

/// Creates an instance; with `validation`, enables the Khronos layer (if installed) and routes its
/// warnings and errors into `messages`. Returns whether the layer was enabled.
fn create_instance(validation: bool, messages: &Arc<Mutex<Vec<String>>>) -> Result<(Arc<Instance>, bool), SimError> {
    let library = load_library()?;
    let layer_installed = validation
        && library.layer_properties().map(|mut layers| layers.any(|l| l.name() == VALIDATION_LAYER)).unwrap_or(false);
    let mut info = InstanceCreateInfo {
        flags: InstanceCreateFlags::ENUMERATE_PORTABILITY,
        application_name: Some("cloth workbench".into()),
        ..Default::default()
    };
    if layer_installed {
        info.enabled_layers = vec![VALIDATION_LAYER.into()];
        info.enabled_extensions = InstanceExtensions { ext_debug_utils: true, ..InstanceExtensions::empty() };
        let sink = messages.clone();
        // SAFETY: the callback only formats the message and pushes it into a Vec; it makes no
        // Vulkan call.
        let callback = unsafe {
            DebugUtilsMessengerCallback::new(move |severity, _ty, data| {
                if let Ok(mut m) = sink.lock() {
                    m.push(format!("{severity:?}: {}", data.message));
                }
            })
        };
        info.debug_utils_messengers = vec![DebugUtilsMessengerCreateInfo {
            message_severity: DebugUtilsMessageSeverity::ERROR | DebugUtilsMessageSeverity::WARNING,
            message_type: DebugUtilsMessageType::GENERAL
                | DebugUtilsMessageType::VALIDATION
                | DebugUtilsMessageType::PERFORMANCE,
            ..DebugUtilsMessengerCreateInfo::user_callback(callback)
        }];
    }
    let instance =
        Instance::new(library, info).map_err(|e| unavailable(format!("cannot create a Vulkan instance: {e}")))?;
    Ok((instance, layer_installed))
}

/// Physical devices with a compute queue (with the queue family index), their names and kinds.
type Devices = Vec<((Arc<PhysicalDevice>, u32), String, DeviceKind)>;

fn compute_devices(instance: &Arc<Instance>) -> Result<Devices, SimError> {
    Ok((instance.enumerate_physical_devices())
        .map_err(|e| unavailable(format!("cannot list Vulkan devices: {e}")))?
        .filter_map(|p| {
            let family =
                p.queue_family_properties().iter().position(|q| q.queue_flags.intersects(QueueFlags::COMPUTE))?;
            let (name, kind) = (p.properties().device_name.clone(), kind(p.properties().device_type));
            Some(((p, family as u32), name, kind))
        })
        .collect())
}

/// The Vulkan devices vulkano finds here, best first, in words.
///
/// # Errors
/// A sentence saying what to install when there is none.
pub fn list_devices() -> Result<Vec<String>, String> {
    let shared = shared_instance().map_err(|e| e.to_string())?;
    let mut devices = compute_devices(&shared.instance).map_err(|e| e.to_string())?;
    devices.sort_by_key(|d| d.2);
    if devices.is_empty() {
        return Err(no_device_reason());
    }
    Ok(devices.iter().map(|((p, _), _, _)| describe(p)).collect())
}

fn no_device_reason() -> String {
    "the Vulkan loader found no device with a compute queue; install a GPU driver, or Mesa's CPU \
     driver with `apt-get install mesa-vulkan-drivers`"
        .into()
}

impl VulkanContext {
    /// Opens the best device (a discrete GPU first, lavapipe last), or the first whose name
    /// contains `name_contains`, with `VK_KHR_pipeline_executable_properties` when `statistics`
    /// asks for it. In debug builds the Khronos validation layer is enabled when installed.
    ///
    /// # Errors
    /// [`SimError::Unavailable`] without a loader, without a device, or when none matches;
    /// [`SimError::Unsupported`] when the statistics are asked for and not offered.
    pub fn new(name_contains: Option<&str>, statistics: bool) -> Result<Self, SimError> {
        let shared = shared_instance()?;
        let (validation, messages) = (shared.validation, shared.messages.clone());
        let devices = compute_devices(&shared.instance)?;
        let (physical, family) = choose_device(devices, name_contains, &no_device_reason()).map_err(unavailable)?;
        let description = describe(&physical);
        // The compiler's statistics of each pipeline, where asked for (statistics.rs).
        let offered = physical.supported_extensions().khr_pipeline_executable_properties
            && physical.supported_features().pipeline_executable_info;
        if statistics && !offered {
            return Err(SimError::Unsupported {
                backend: BACKEND_NAME,
                what: format!("pipeline statistics (GpuTuning::pipeline_statistics) on {description}"),
                fix: "it does not offer VK_KHR_pipeline_executable_properties: turn them off".into(),
            });
        }
        let (device, mut queues) = Device::new(
            physical,
            DeviceCreateInfo {
                queue_create_infos: vec![QueueCreateInfo { queue_family_index: family, ..Default::default() }],
                enabled_extensions: DeviceExtensions {
                    khr_pipeline_executable_properties: statistics,
                    ..DeviceExtensions::empty()
                },
                enabled_features: DeviceFeatures { pipeline_executable_info: statistics, ..DeviceFeatures::empty() },
                ..Default::default()
            },
        )
        .map_err(|e| unavailable(format!("cannot open {description}: {e}")))?;
        let queue = queues.next().ok_or_else(|| unavailable("the device has no queue"))?;
        Ok(Self { device, queue, description, validation, messages })
    }

    /// Fails with the validation messages received so far, if any.
    ///
    /// # Errors
    /// [`SimError::Device`] listing the messages.
    pub fn check_validation(&self) -> Result<(), SimError> {
        let messages = self.messages.lock().map(|m| m.clone()).unwrap_or_default();
        if messages.is_empty() {
            Ok(())
        } else {
            Err(SimError::Device {
                backend: BACKEND_NAME,
                reason: format!("Vulkan validation: {}", messages.join("; ")),
            })
        }
    }
}
