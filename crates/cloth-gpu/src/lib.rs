//! # cloth-gpu
//!
//! What the GPU backends of the cloth workbench share, with no GPU API in it:
//!
//! * [`layout`]: the structs the host shares with the shaders, each defined once;
//! * [`tuning`]: [`GpuTuning`], every knob of the backends as one typed value;
//! * [`geometry`]: how the kernels cover the grid (blocks, packed state, tiles) and what a device
//!   allows;
//! * [`memory`]: the device memory a scene needs, checked before anything is allocated;
//! * [`plan`]: every buffer, kernel, pipeline and bind group of a simulation;
//! * [`schedule`]: the order of a frame's dispatches;
//! * [`simulator`]: [`GpuSimulator`], the `Simulator` of every backend, over [`GpuBackend`];
//! * [`bandwidth`]: the device's copy bandwidth, the ceiling of a memory-bound substep.
//!
//! A backend (`cloth-wgpu`, `cloth-vulkano`) implements [`GpuBackend`]: it turns the plan's
//! descriptions into its API's objects and records the dispatches of [`Schedule::frame_from`].

#![warn(missing_docs)]

pub mod bandwidth;
pub mod geometry;
pub mod layout;
pub mod memory;
pub mod plan;
pub mod schedule;
pub mod simulator;
pub mod tuning;

pub use geometry::{DeviceLimits, TileConfig};
pub use plan::Plan;
pub use schedule::{Dispatch, Schedule};
pub use simulator::{Frame, GpuBackend, GpuSimulator};
pub use tuning::{BlockOrder, CandidateListing, GpuTuning, Tiling};
