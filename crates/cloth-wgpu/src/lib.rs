//! # cloth-wgpu
//!
//! The WGSL compute backend of the cloth workbench. [`WgpuSimulator`] implements
//! [`cloth_core::Simulator`]: every force of the brief is computed by the compute shader
//! `shaders/wgsl/cloth_step.wgsl`, every parameter reaches it through a bind group, and one
//! call to `advance` records all its substeps into one command submission.
//!
//! The simulator can run on its own device ([`WgpuSimulator::with_options`]) or on a device
//! the caller already has ([`WgpuSimulator::on_device`]), e.g. eframe's, and exposes its
//! position buffer ([`WgpuSimulator::position_buffer`]) so the cloth can be drawn straight from
//! the simulation.

#![warn(missing_docs)]

mod bandwidth;
mod context;
mod passes;
mod simulator;
mod timer;

pub use bandwidth::{CopyBandwidth, copy_bandwidth};
pub use context::{AdapterChoice, GpuContext, device_requirements, list_adapters};
pub use simulator::WgpuSimulator;

/// WGSL source of the force-based substep kernel (`shaders/wgsl/common.wgsl` followed by
/// `cloth_step.wgsl`): semi-implicit Euler and velocity Verlet.
pub const STEP_SHADER: &str =
    concat!(include_str!("../../../shaders/wgsl/common.wgsl"), include_str!("../../../shaders/wgsl/cloth_step.wgsl"));

/// WGSL source of the tiled kernel that fuses several semi-implicit Euler substeps in one
/// dispatch (`shaders/wgsl/common.wgsl` followed by `cloth_step_tiled.wgsl`); the backend prepends
/// the tile's constants ([`tiled_shader_source`]).
pub const TILED_STEP_SHADER: &str = concat!(
    include_str!("../../../shaders/wgsl/common.wgsl"),
    include_str!("../../../shaders/wgsl/cloth_step_tiled.wgsl")
);

/// The tiled kernel's source for `tile`: its constants (`TILE_WIDTH`, `TILE_HEIGHT`,
/// `FUSED_SUBSTEPS`, from `cloth_core::tiling::TileConfig`) followed by [`TILED_STEP_SHADER`].
/// (Constants rather than pipeline overrides: WGSL sizes workgroup arrays and the workgroup by
/// constants everywhere naga reads it.)
pub fn tiled_shader_source(tile: &cloth_core::tiling::TileConfig) -> String {
    format!(
        "const TILE_WIDTH: u32 = {}u;\nconst TILE_HEIGHT: u32 = {}u;\nconst FUSED_SUBSTEPS: u32 = {}u;\n{TILED_STEP_SHADER}",
        tile.width, tile.height, tile.substeps
    )
}

/// WGSL source of the XPBD passes (`shaders/wgsl/common.wgsl` followed by `xpbd.wgsl`).
pub const XPBD_SHADER: &str =
    concat!(include_str!("../../../shaders/wgsl/common.wgsl"), include_str!("../../../shaders/wgsl/xpbd.wgsl"));

/// Backend name used by the tools.
pub const BACKEND_NAME: &str = "wgpu";
