//! The backends compiled into this binary, by name.

use cloth_core::{CpuSimulator, CpuSimulatorF64, Scene, SimError, Simulator};

/// A backend the CLI can run.
pub struct Backend {
    /// Name used with `--backend`.
    pub name: &'static str,
    /// One line saying what it is.
    pub description: &'static str,
    /// Creates a simulator for a scene.
    pub create: fn(&Scene) -> Result<Box<dyn Simulator>, SimError>,
    /// Lists the adapters this backend can use here, or says why none.
    pub adapters: fn() -> Result<Vec<String>, String>,
}

fn boxed<S: Simulator + 'static>(scene: &Scene) -> Result<Box<dyn Simulator>, SimError> {
    Ok(Box::new(S::new(scene)?))
}

fn cpu_adapters() -> Result<Vec<String>, String> {
    Ok(vec![format!("CPU ({} rayon threads)", rayon_threads())])
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
}

/// Every backend compiled in, the default first.
pub fn all() -> Vec<Backend> {
    vec![
        Backend {
            name: "cpu",
            description: "CPU reference stepper in f32 (the oracle GPU results are compared with)",
            create: boxed::<CpuSimulator>,
            adapters: cpu_adapters,
        },
        Backend {
            name: "cpu-f64",
            description: "CPU reference stepper in f64 (high-precision oracle)",
            create: boxed::<CpuSimulatorF64>,
            adapters: cpu_adapters,
        },
        Backend {
            name: cloth_wgpu::BACKEND_NAME,
            description: "WGSL compute shaders through wgpu (Vulkan, Metal or DX12; lavapipe included)",
            create: boxed::<cloth_wgpu::WgpuSimulator>,
            adapters: cloth_wgpu::list_adapters,
        },
    ]
}

/// Looks a backend up by name.
pub fn find(name: &str) -> anyhow::Result<Backend> {
    let all = all();
    let names: Vec<&str> = all.iter().map(|b| b.name).collect();
    all.into_iter()
        .find(|b| b.name == name)
        .ok_or_else(|| anyhow::anyhow!("unknown backend '{name}': this build has {}", names.join(", ")))
}
