//! # cloth-vulkano
//!
//! The GLSL/SPIR-V compute backend of the cloth workbench. [`VulkanoSimulator`] implements
//! [`cloth_core::Simulator`] with the compute shaders `shaders/glsl/cloth_step.comp` (force-based
//! integrators) and `xpbd.comp` (XPBD), sharing `effects.glsl`, `layout.glsl` and `forces.glsl`,
//! compiled to SPIR-V by `glslc` at build time. Effects the scene leaves out, and the workgroup
//! size, are Vulkan specialization constants; every parameter reaches the shader through one
//! descriptor set; one `advance` is one command buffer, recorded with one memory barrier between
//! dispatches instead of vulkano's automatic tracking (`raw.rs` says why), one submission, and no
//! wait.

#![warn(missing_docs)]

mod context;
mod passes;
mod raw;
mod simulator;
mod statistics;
mod timer;

pub use context::{VulkanContext, list_devices};
pub use passes::{STAGE_CONSTANT_ID, TILE_CONSTANT_IDS, WORKGROUP_SIZE, WORKGROUP_SIZE_CONSTANT_ID};
pub use simulator::VulkanoSimulator;

/// SPIR-V of the force-based substep kernel (semi-implicit Euler, velocity Verlet), compiled from
/// `shaders/glsl/cloth_step.comp` by `build.rs`.
pub const STEP_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/cloth_step.spv"));

/// SPIR-V of the tiled kernel that fuses several semi-implicit Euler substeps in one dispatch
/// (`cloth_core::tiling`), compiled from `shaders/glsl/cloth_step_tiled.comp` by `build.rs`.
pub const TILED_STEP_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/cloth_step_tiled.spv"));

/// SPIR-V of the XPBD passes, compiled from `shaders/glsl/xpbd.comp` by `build.rs`.
pub const XPBD_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/xpbd.spv"));

/// Backend name used by the tools.
pub const BACKEND_NAME: &str = "vulkano";
