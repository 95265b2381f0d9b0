//! # cloth-vulkano
//!
//! The GLSL/SPIR-V compute backend of the cloth workbench: [`VulkanoBackend`] implements
//! [`cloth_gpu::GpuBackend`], so [`VulkanoSimulator`] (`cloth_gpu::GpuSimulator<VulkanoBackend>`)
//! runs the shared plan with the kernels of `shaders/glsl/` (`cloth_step.comp`,
//! `cloth_step_tiled.comp`, `xpbd.comp`, `vbd.comp`, `implicit.comp`, sharing `effects.glsl`, `layout.glsl`, `forces.glsl` and
//! `grid.glsl`), compiled to SPIR-V by `glslc` at build time. The plan's pipeline constants are
//! Vulkan specialization constants; every parameter reaches the kernels through one descriptor
//! set; one `advance` is one command buffer, recorded with one memory barrier between dispatches
//! instead of vulkano's automatic tracking (`raw.rs` says why), one submission, and no wait.

#![warn(missing_docs)]

mod backend;
mod context;
mod raw;
mod statistics;

pub use backend::{VulkanoBackend, VulkanoKernel, VulkanoSimulator};
pub use context::{VulkanContext, list_devices};

/// SPIR-V of the force-based substep kernel, compiled from `shaders/glsl/cloth_step.comp`.
pub const STEP_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/cloth_step.spv"));

/// SPIR-V of the tiled kernel that fuses several semi-implicit Euler substeps in one dispatch,
/// compiled from `shaders/glsl/cloth_step_tiled.comp`.
pub const TILED_STEP_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/cloth_step_tiled.spv"));

/// SPIR-V of the XPBD passes, compiled from `shaders/glsl/xpbd.comp`.
pub const XPBD_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/xpbd.spv"));
/// SPIR-V of the Vertex Block Descent passes, compiled from `shaders/glsl/vbd.comp`.
pub const VBD_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/vbd.spv"));
/// SPIR-V of the backward-Euler passes, compiled from `shaders/glsl/implicit.comp`.
pub const IMPLICIT_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/implicit.spv"));

/// SPIR-V of the passes that rebuild self-collision's spatial hash, from `shaders/glsl/self_hash.comp`.
pub const SELF_HASH_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/self_hash.spv"));

/// SPIR-V of the copy kernel that measures the memory bandwidth, from `shaders/glsl/copy.comp`.
pub const COPY_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/copy.spv"));

/// Backend name used by the tools.
pub const BACKEND_NAME: &str = "vulkano";
