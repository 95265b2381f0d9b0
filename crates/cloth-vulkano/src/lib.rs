//! # cloth-vulkano
//!
//! The GLSL/SPIR-V compute backend of the cloth workbench. [`VulkanoSimulator`] implements
//! [`cloth_core::Simulator`] with the compute shader `shaders/glsl/cloth_step.comp` (shared code
//! in `layout.glsl` and `forces.glsl`), compiled to SPIR-V by `glslc` at build time. Effects the
//! scene leaves out, and the workgroup size, are Vulkan specialization constants; every parameter
//! reaches the shader through one descriptor set; one `advance` is one command buffer, one
//! submission, and no wait.

#![warn(missing_docs)]

mod context;
mod simulator;

pub use context::{VulkanContext, list_devices};
pub use simulator::{VulkanoSimulator, WORKGROUP_SIZE_CONSTANT_ID};

/// SPIR-V of the substep kernel, compiled from `shaders/glsl/cloth_step.comp` by `build.rs`.
pub const STEP_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/cloth_step.spv"));

/// Backend name used by the tools.
pub const BACKEND_NAME: &str = "vulkano";
