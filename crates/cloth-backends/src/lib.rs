//! # cloth-backends
//!
//! The backends compiled into the workbench, by name: what `cloth backends` lists, what
//! `--backend NAME` picks, and what the inspector offers; and what the apps share besides: the
//! benchmarks' measurements (`throughput`, `effect_cost`, `timing`) and how they write files
//! (`output`, which is `cloth_core::output`).

#![warn(missing_docs)]

pub mod effect_cost;
pub use cloth_core::output;
pub mod throughput;
pub mod timing;

use cloth_core::{CpuSimulator, CpuSimulatorF64, Scene, SimError, Simulator};
pub use cloth_gpu::bandwidth::CopyBandwidth;
use cloth_gpu::{GpuSimulator, GpuTuning};

/// Creates a simulator for a scene; a GPU backend lays its work out as the tuning says and
/// opens the adapter it names (the CPU backends have nothing to tune).
pub type Factory = fn(&Scene, &GpuTuning) -> Result<Box<dyn Simulator>, SimError>;

/// Measures the copy bandwidth of the device a tuning names ([`cloth_gpu::bandwidth`]).
pub type BandwidthProbe = fn(&GpuTuning) -> Result<CopyBandwidth, SimError>;

/// A backend the CLI can run.
pub struct Backend {
    /// Name used with `--backend`.
    pub name: &'static str,
    /// One line saying what it is.
    pub description: &'static str,
    /// Creates a simulator.
    pub create: Factory,
    /// Lists the adapters this backend can use here, or says why none.
    pub adapters: fn() -> Result<Vec<String>, String>,
    /// Measures the device's copy bandwidth, the memory ceiling of a substep (GPU backends).
    pub copy_bandwidth: Option<BandwidthProbe>,
}

fn cpu<S: Simulator + 'static>(scene: &Scene, _tuning: &GpuTuning) -> Result<Box<dyn Simulator>, SimError> {
    Ok(Box::new(S::new(scene)?))
}

fn gpu<B: cloth_gpu::GpuBackend + 'static>(scene: &Scene, tuning: &GpuTuning) -> Result<Box<dyn Simulator>, SimError> {
    Ok(Box::new(GpuSimulator::<B>::with_tuning(scene, tuning)?))
}

fn cpu_adapters() -> Result<Vec<String>, String> {
    Ok(vec![format!("CPU ({} threads)", std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1))])
}

/// Every backend compiled in, the default first.
pub fn all() -> Vec<Backend> {
    vec![
        Backend {
            name: "cpu",
            description: "CPU reference stepper in f32 (the oracle GPU results are compared with)",
            create: cpu::<CpuSimulator>,
            adapters: cpu_adapters,
            copy_bandwidth: None,
        },
        Backend {
            name: "cpu-f64",
            description: "CPU reference stepper in f64 (high-precision oracle)",
            create: cpu::<CpuSimulatorF64>,
            adapters: cpu_adapters,
            copy_bandwidth: None,
        },
        Backend {
            name: cloth_wgpu::BACKEND_NAME,
            description: "WGSL compute shaders through wgpu (Vulkan, Metal or DX12; lavapipe included)",
            create: gpu::<cloth_wgpu::WgpuBackend>,
            adapters: cloth_wgpu::list_adapters,
            copy_bandwidth: Some(cloth_gpu::bandwidth::copy_bandwidth::<cloth_wgpu::WgpuBackend>),
        },
        Backend {
            name: cloth_vulkano::BACKEND_NAME,
            description: "GLSL compute shaders compiled to SPIR-V, through vulkano (Vulkan; lavapipe included)",
            create: gpu::<cloth_vulkano::VulkanoBackend>,
            adapters: cloth_vulkano::list_devices,
            copy_bandwidth: Some(cloth_gpu::bandwidth::copy_bandwidth::<cloth_vulkano::VulkanoBackend>),
        },
    ]
}

/// Looks a backend up by name.
///
/// # Errors
/// A message listing the backends of this build when there is none of that name.
pub fn find(name: &str) -> Result<Backend, String> {
    let all = all();
    let names: Vec<&str> = all.iter().map(|b| b.name).collect();
    all.into_iter()
        .find(|b| b.name == name)
        .ok_or_else(|| format!("unknown backend '{name}': this build has {}", names.join(", ")))
}

/// Where Mesa's Vulkan drivers find a runtime directory when `current` (the value of
/// `XDG_RUNTIME_DIR`) is not one: a private folder (mode 0700) of this user in the temporary
/// directory, created if missing. Without one, creating a wgpu instance on a machine without a
/// display session prints "error: XDG_RUNTIME_DIR is invalid or not set" though nothing is
/// wrong. `None` when `current` is a folder already, or when none can be made.
pub fn private_runtime_dir(current: Option<&std::ffi::OsStr>) -> Option<std::path::PathBuf> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    if current.is_some_and(|dir| std::path::Path::new(dir).is_dir()) {
        return None;
    }
    let uid = std::fs::metadata("/proc/self").map(|m| m.uid()).unwrap_or(0);
    let dir = std::env::temp_dir().join(format!("cloth-runtime-{uid}"));
    std::fs::create_dir_all(&dir).ok()?;
    let owned = std::fs::metadata(&dir).is_ok_and(|m| m.uid() == uid);
    (owned && std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).is_ok()).then_some(dir)
}
