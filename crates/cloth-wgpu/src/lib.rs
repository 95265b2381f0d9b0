//! # cloth-wgpu
//!
//! The WGSL compute backend of the cloth workbench: [`WgpuBackend`] implements
//! [`cloth_gpu::GpuBackend`], so [`WgpuSimulator`] (`cloth_gpu::GpuSimulator<WgpuBackend>`) runs
//! the shared plan with the kernels of `shaders/wgsl/`, every parameter reaching them through a
//! bind group, and one `advance` recorded into one compute pass and one submission.
//!
//! The simulator can run on its own device ([`cloth_gpu::GpuSimulator::with_tuning`]) or on one
//! the caller already has ([`WgpuBackend::on`], e.g. eframe's), and exposes its position buffer
//! ([`cloth_gpu::GpuSimulator::position_buffer`]) so the cloth can be drawn straight from the
//! simulation.

#![warn(missing_docs)]

mod backend;
mod context;

pub use backend::{WgpuBackend, WgpuKernel, WgpuSimulator};
pub use context::{GpuContext, device_requirements, list_adapters};

/// WGSL source of the force-based substep kernel: `layout.wgsl`, `colliders.wgsl` (the
/// colliders' signed distances), `common.wgsl` (effect constants and force model),
/// `self_collision.wgsl`, `self_partners.wgsl`, `cloth_step.wgsl`.
pub const STEP_SHADER: &str = concat!(
    include_str!("../../../shaders/wgsl/layout.wgsl"),
    include_str!("../../../shaders/wgsl/colliders.wgsl"),
    include_str!("../../../shaders/wgsl/common.wgsl"),
    include_str!("../../../shaders/wgsl/self_collision.wgsl"),
    include_str!("../../../shaders/wgsl/self_partners.wgsl"),
    include_str!("../../../shaders/wgsl/cloth_step.wgsl")
);

/// WGSL source of the passes that rebuild self-collision's spatial hash: `layout.wgsl`,
/// `self_collision.wgsl`, `self_hash.wgsl`.
pub const SELF_HASH_SHADER: &str = concat!(
    include_str!("../../../shaders/wgsl/layout.wgsl"),
    include_str!("../../../shaders/wgsl/self_collision.wgsl"),
    include_str!("../../../shaders/wgsl/self_hash.wgsl")
);

/// WGSL source of the tiled kernel that fuses several semi-implicit Euler substeps in one
/// dispatch, without its tile's constants ([`tiled_shader_source`] prepends them).
pub const TILED_STEP_SHADER: &str = concat!(
    include_str!("../../../shaders/wgsl/layout.wgsl"),
    include_str!("../../../shaders/wgsl/colliders.wgsl"),
    include_str!("../../../shaders/wgsl/common.wgsl"),
    include_str!("../../../shaders/wgsl/cloth_step_tiled.wgsl")
);

/// The tiled kernel's source for `tile`: its constants (`TILE_WIDTH`, `TILE_HEIGHT`,
/// `FUSED_SUBSTEPS`) followed by [`TILED_STEP_SHADER`]. (Constants rather than overrides: they
/// size the workgroup's arrays.)
pub fn tiled_shader_source(tile: &cloth_gpu::TileConfig) -> String {
    format!(
        "const TILE_WIDTH: u32 = {}u;\nconst TILE_HEIGHT: u32 = {}u;\nconst FUSED_SUBSTEPS: u32 = {}u;\n{TILED_STEP_SHADER}",
        tile.width, tile.height, tile.substeps
    )
}

/// WGSL source of the XPBD passes: `layout.wgsl`, `colliders.wgsl`, `common.wgsl`,
/// `self_collision.wgsl`, `self_partners.wgsl`, `xpbd.wgsl`.
pub const XPBD_SHADER: &str = concat!(
    include_str!("../../../shaders/wgsl/layout.wgsl"),
    include_str!("../../../shaders/wgsl/colliders.wgsl"),
    include_str!("../../../shaders/wgsl/common.wgsl"),
    include_str!("../../../shaders/wgsl/self_collision.wgsl"),
    include_str!("../../../shaders/wgsl/self_partners.wgsl"),
    include_str!("../../../shaders/wgsl/xpbd.wgsl")
);

/// WGSL source of the Vertex Block Descent passes: `layout.wgsl`, `colliders.wgsl`,
/// `common.wgsl`, `self_collision.wgsl`, `self_partners.wgsl`, `workgroup_sum.wgsl`, `vbd.wgsl`.
pub const VBD_SHADER: &str = concat!(
    include_str!("../../../shaders/wgsl/layout.wgsl"),
    include_str!("../../../shaders/wgsl/colliders.wgsl"),
    include_str!("../../../shaders/wgsl/common.wgsl"),
    include_str!("../../../shaders/wgsl/self_collision.wgsl"),
    include_str!("../../../shaders/wgsl/self_partners.wgsl"),
    include_str!("../../../shaders/wgsl/workgroup_sum.wgsl"),
    include_str!("../../../shaders/wgsl/vbd.wgsl")
);

/// WGSL source of the backward-Euler passes: `layout.wgsl`, `colliders.wgsl`, `common.wgsl`,
/// `self_collision.wgsl`, `self_partners.wgsl`, `workgroup_sum.wgsl`, `implicit.wgsl`.
pub const IMPLICIT_SHADER: &str = concat!(
    include_str!("../../../shaders/wgsl/layout.wgsl"),
    include_str!("../../../shaders/wgsl/colliders.wgsl"),
    include_str!("../../../shaders/wgsl/common.wgsl"),
    include_str!("../../../shaders/wgsl/self_collision.wgsl"),
    include_str!("../../../shaders/wgsl/self_partners.wgsl"),
    include_str!("../../../shaders/wgsl/workgroup_sum.wgsl"),
    include_str!("../../../shaders/wgsl/implicit.wgsl")
);

/// WGSL source of the copy kernel that measures the memory bandwidth (`copy.wgsl`).
pub const COPY_SHADER: &str = include_str!("../../../shaders/wgsl/copy.wgsl");

/// Backend name used by the tools.
pub const BACKEND_NAME: &str = "wgpu";
