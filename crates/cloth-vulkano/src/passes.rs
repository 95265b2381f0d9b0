//! The dispatches of one substep for each integrator: specialized pipelines, descriptor sets,
//! workgroup counts.
//!
//! | integrator | passes per substep |
//! |---|---|
//! | semi-implicit Euler | 1: `cloth_step.comp`, `STAGE = 0`; or, fused, `cloth_step_tiled.comp` for `FUSED_SUBSTEPS` at once |
//! | velocity Verlet | 2: `STAGE = 1` (kick and drift), `STAGE = 2` (second kick) |
//! | RK4 | 4: `STAGE = 3..=6`, one per stage (state `k` → S → `1 − k` → S → `1 − k`) |
//! | XPBD | `xpbd.comp`: predict; `XPBD_ITERATIONS` × (one per non-empty colour + spheres); finish |
//!
//! Every pass of a substep reads the state buffer `k` that is current and leaves the new state in
//! buffer `1 − k`; each pass has one descriptor set per `k`. Semi-implicit Euler also has a tiled
//! pass ([`TiledPass`], `cloth_core::tiling`) that advances several substeps in one dispatch, from
//! `k` to `1 − k` likewise; the substeps left over run one at a time. Where it does not tile,
//! semi-implicit Euler runs the substeps inside one submission on its packed state
//! ([`PackedPasses`], `cloth_core::layout::PackedState`).

use std::sync::Arc;

use cloth_core::coloring::COLOR_COUNT;
use cloth_core::integrator::XPBD_ITERATIONS;
use cloth_core::layout::{GpuBuffers, GpuColorRange, GpuSimParams, GpuSphere};
use cloth_core::{Effect, Integrator, Scene, SimError};
use vulkano::buffer::Subbuffer;
use vulkano::descriptor_set::allocator::StandardDescriptorSetAllocator;
use vulkano::descriptor_set::layout::DescriptorType;
use vulkano::descriptor_set::{DescriptorBufferInfo, DescriptorSet, WriteDescriptorSet};
use vulkano::device::Device;
use vulkano::pipeline::compute::ComputePipelineCreateInfo;
use vulkano::pipeline::layout::PipelineDescriptorSetLayoutCreateInfo;
use vulkano::pipeline::{ComputePipeline, PipelineLayout, PipelineShaderStageCreateInfo};
use vulkano::shader::{ShaderModule, ShaderModuleCreateInfo, SpecializationConstant};

use cloth_core::tiling::{DeviceLimits, TileConfig, Tiling};

use crate::{BACKEND_NAME, STEP_SPIRV, TILED_STEP_SPIRV, XPBD_SPIRV};

/// Invocations per workgroup by default (specialization constant [`WORKGROUP_SIZE_CONSTANT_ID`];
/// see `cloth_core::layout::workgroup_size` for the `CLOTH_WORKGROUP_SIZE` knob).
pub const WORKGROUP_SIZE: u32 = cloth_core::layout::DEFAULT_WORKGROUP_SIZE;

/// The workgroup size in use (checked when the simulator is created).
pub(crate) fn workgroup_size() -> u32 {
    cloth_core::layout::workgroup_size().unwrap_or(WORKGROUP_SIZE)
}
/// Specialization-constant id of the workgroup size; ids `0..` are the effects, in
/// `cloth_core::Effect::ALL` order.
pub const WORKGROUP_SIZE_CONSTANT_ID: u32 = 100;
/// Specialization-constant id of the pass a pipeline runs: `STAGE` in `cloth_step.comp` (0 Euler,
/// 1 and 2 the Verlet halves), `XPBD_PASS` in `xpbd.comp`.
pub const STAGE_CONSTANT_ID: u32 = 101;
/// Specialization-constant ids of the tiled kernel's `TILE_WIDTH` and `TILE_HEIGHT` (its
/// workgroup's size), `TILE_CELLS` and `FUSED_SUBSTEPS` (`cloth_step_tiled.comp`).
pub const TILE_CONSTANT_IDS: [u32; 4] = [102, 103, 104, 106];
/// Specialization-constant id of `BLOCK_WIDTH` in `cloth_step.comp`
/// (`cloth_core::layout::block_width`).
pub const BLOCK_WIDTH_CONSTANT_ID: u32 = 107;
/// Specialization-constant ids of `PACKED_IN` and `PACKED_OUT` in `cloth_step.comp`
/// (`cloth_core::layout::PackedState`).
pub const PACKED_CONSTANT_IDS: [u32; 2] = [108, 109];
/// Specialization-constant id of `REVERSED_ORDER` in `cloth_step.comp`
/// (`cloth_core::layout::alternates_order`).
pub const REVERSED_ORDER_CONSTANT_ID: u32 = 110;
/// Binding of XPBD's colour range, a dynamic uniform buffer.
const COLOR_RANGE_BINDING: u32 = 10;

pub(crate) type State = Subbuffer<[[f32; 4]]>;

/// The buffers every integrator's passes bind, and the allocators to make more.
pub(crate) struct StateBuffers {
    pub params: Subbuffer<GpuSimParams>,
    pub spheres: Subbuffer<[GpuSphere]>,
    pub positions: [State; 2],
    pub velocities: [State; 2],
    pub max_penetration: Subbuffer<[u32]>,
}

/// One dispatch of a substep.
pub(crate) struct Pass {
    /// Index into [`SubstepPlan::pipelines`].
    pub pipeline: usize,
    /// The descriptor set when state buffer `k` is current.
    pub sets: [Arc<DescriptorSet>; 2],
    /// Workgroups along x, y, z.
    pub workgroups: [u32; 3],
    /// The dynamic offset of the layout's dynamic uniform, when it has one.
    pub dynamic_offset: Option<u32>,
}

/// The dispatches of one substep, in order, and the buffers only they use (kept alive here;
/// the initial contents are copied in by the caller).
pub(crate) struct SubstepPlan {
    pub pipelines: Vec<Arc<ComputePipeline>>,
    pub passes: Vec<Pass>,
    /// The pass that advances several semi-implicit Euler substeps at once, if any.
    pub tiled: Option<TiledPass>,
    /// Semi-implicit Euler's passes on its packed state, if it has them.
    pub packed: Option<PackedPasses>,
    /// `(buffer, bytes)` to upload before the first substep.
    pub uploads: Vec<(Subbuffer<[u8]>, Vec<u8>)>,
}

impl SubstepPlan {
    /// The packed passes, where they run: only where the tiled kernel does not.
    pub fn active_packed(&self) -> Option<&PackedPasses> {
        self.packed.as_ref().filter(|_| self.tiled.is_none())
    }

    /// Bytes a vertex of the state the substeps hand each other (`Simulator::substep_state_bytes`).
    pub fn state_bytes(&self) -> u32 {
        cloth_core::layout::PackedState::substep_bytes(self.active_packed().is_some())
    }
}

/// Semi-implicit Euler's substeps on its packed state (`cloth_core::layout::PackedState`): a
/// submission of `n ≥ 2` substeps runs `first` (the `vec4` state `k` → packed state 0), `n − 2`
/// times `middle` (packed `m` → packed `1 − m`) and `last` (packed `m` → the `vec4` state
/// `1 − k`), so the `vec4` state flips once a submission.
pub(crate) struct PackedPasses {
    /// The pipeline of `first`.
    pub first_pipeline: Arc<ComputePipeline>,
    /// The pipelines of `middle` and `last` by the order the substep takes the grid's blocks
    /// in: `[forward, backward]` (the same pipeline twice unless
    /// `cloth_core::layout::alternates_order`); substep `s` of a submission goes backward when
    /// `s` is odd.
    pub middle_pipelines: [Arc<ComputePipeline>; 2],
    /// The same for `last` (substep `n − 1` of a submission of `n`).
    pub last_pipelines: [Arc<ComputePipeline>; 2],
    /// `first`'s descriptor set when the `vec4` state `k` is current.
    pub first: [Arc<DescriptorSet>; 2],
    /// `middle`'s descriptor set reading packed state `m`.
    pub middle: [Arc<DescriptorSet>; 2],
    /// `last`'s descriptor set when the `vec4` state `k` is current, reading packed state `m`:
    /// `last[k][m]`.
    pub last: [[Arc<DescriptorSet>; 2]; 2],
    /// Workgroups along x, y, z (those of the per-substep kernel).
    pub workgroups: [u32; 3],
}

/// One dispatch that advances [`TiledPass::substeps`] semi-implicit Euler substeps at once.
pub(crate) struct TiledPass {
    pub pipeline: Arc<ComputePipeline>,
    /// The descriptor set when state buffer `k` is current.
    pub sets: [Arc<DescriptorSet>; 2],
    /// Workgroups along x, y, z: one per output block.
    pub workgroups: [u32; 3],
    /// Substeps per dispatch.
    pub substeps: u32,
}

fn device_error(reason: impl std::fmt::Display) -> SimError {
    SimError::Device { backend: BACKEND_NAME, reason: reason.to_string() }
}

/// Workgroups for `items` invocations: along x up to the device's limit, the rest along y.
pub(crate) fn workgroups(items: u32, max_x: u32) -> [u32; 3] {
    let [x, y] = cloth_core::layout::spilled_workgroups(items, workgroup_size(), max_x);
    [x, y, 1]
}

/// A SPIR-V module whose pipelines share one layout (reflected from the module; XPBD's colour
/// range made dynamic).
struct Kernel {
    device: Arc<Device>,
    module: Arc<ShaderModule>,
    layout: Arc<PipelineLayout>,
    effects: Vec<(u32, SpecializationConstant)>,
}

impl Kernel {
    fn new(device: &Arc<Device>, scene: &Scene, spirv: &[u8], dynamic_binding: Option<u32>) -> Result<Self, SimError> {
        let words = vulkano::shader::spirv::bytes_to_words(spirv).map_err(device_error)?;
        // SAFETY: the SPIR-V comes from glslc, which emits valid modules for Vulkan 1.1.
        let module = unsafe { ShaderModule::new(device.clone(), ShaderModuleCreateInfo::new(&words)) }
            .map_err(|e| device_error(format!("loading the SPIR-V: {e}")))?;
        let effects: Vec<(u32, SpecializationConstant)> = scene
            .effects
            .shader_constants()
            .into_iter()
            .enumerate()
            .map(|(id, (_, on))| (id as u32, SpecializationConstant::Bool(on)))
            .chain([(WORKGROUP_SIZE_CONSTANT_ID, SpecializationConstant::U32(workgroup_size()))])
            .collect();
        let entry = module.entry_point("main").ok_or_else(|| device_error("the SPIR-V has no `main` entry point"))?;
        let mut info = PipelineDescriptorSetLayoutCreateInfo::from_stages([&PipelineShaderStageCreateInfo::new(entry)]);
        if let Some(binding) = dynamic_binding
            && let Some(b) = info.set_layouts.first_mut().and_then(|s| s.bindings.get_mut(&binding))
        {
            b.descriptor_type = DescriptorType::UniformBufferDynamic;
        }
        let layout = PipelineLayout::new(
            device.clone(),
            info.into_pipeline_layout_create_info(device.clone())
                .map_err(|e| device_error(format!("pipeline layout: {e:?}")))?,
        )
        .map_err(|e| device_error(format!("pipeline layout: {e}")))?;
        Ok(Self { device: device.clone(), module, layout, effects })
    }

    /// The pipeline with the scene's effects, the workgroup size and `XPBD_PASS = stage`.
    fn pipeline(&self, stage: u32) -> Result<Arc<ComputePipeline>, SimError> {
        self.pipeline_with([(STAGE_CONSTANT_ID, stage)])
    }

    /// The per-substep kernel's pipeline: `STAGE = stage`, and its block width.
    fn step_pipeline(&self, stage: u32, block_width: u32) -> Result<Arc<ComputePipeline>, SimError> {
        self.pipeline_with([(STAGE_CONSTANT_ID, stage), (BLOCK_WIDTH_CONSTANT_ID, block_width)])
    }

    /// The pipeline with the scene's effects, the workgroup size and the given `u32` constants.
    fn pipeline_with(&self, values: impl IntoIterator<Item = (u32, u32)>) -> Result<Arc<ComputePipeline>, SimError> {
        let constants: Vec<(u32, SpecializationConstant)> = self
            .effects
            .iter()
            .cloned()
            .chain(values.into_iter().map(|(id, value)| (id, SpecializationConstant::U32(value))))
            .collect();
        let entry = self
            .module
            .specialize(constants.iter().cloned().collect())
            .map_err(|e| device_error(format!("specializing the shader: {e}")))?
            .entry_point("main")
            .ok_or_else(|| device_error("the SPIR-V has no `main` entry point"))?;
        let pipeline = ComputePipeline::new(
            self.device.clone(),
            None,
            ComputePipelineCreateInfo::stage_layout(PipelineShaderStageCreateInfo::new(entry), self.layout.clone()),
        )
        .map_err(|e| device_error(format!("compute pipeline: {e}")))?;
        if crate::statistics::wanted() {
            // The constants name the kernel: 101 the stage, 102-106 a tile, 107 the block width,
            // 108-109 whether it reads and writes the packed state.
            let named: Vec<(u32, u32)> = constants
                .iter()
                .filter_map(|(id, c)| match c {
                    SpecializationConstant::U32(value) if *id > WORKGROUP_SIZE_CONSTANT_ID => Some((*id, *value)),
                    _ => None,
                })
                .collect();
            match crate::statistics::of(&self.device, &self.module, &self.layout, &constants) {
                Ok(lines) => eprintln!("pipeline statistics (constants {named:?}): {}", lines.join(", ")),
                Err(e) => eprintln!("pipeline statistics (constants {named:?}): none: {e}"),
            }
        }
        Ok(pipeline)
    }

    fn set(
        &self,
        descriptors: &Arc<StandardDescriptorSetAllocator>,
        writes: impl IntoIterator<Item = WriteDescriptorSet>,
    ) -> Result<Arc<DescriptorSet>, SimError> {
        DescriptorSet::new(descriptors.clone(), self.layout.set_layouts()[0].clone(), writes, [])
            .map_err(|e| device_error(format!("descriptor set: {e}")))
    }
}

/// Builds the passes of one substep of the scene's integrator. `device_local` allocates a
/// device buffer of the given usage and size.
pub(crate) fn plan(
    device: &Arc<Device>,
    scene: &Scene,
    data: &GpuBuffers,
    state: &StateBuffers,
    descriptors: &Arc<StandardDescriptorSetAllocator>,
    device_local: &dyn Fn(vulkano::buffer::BufferUsage, u64) -> Result<Subbuffer<[u8]>, SimError>,
) -> Result<SubstepPlan, SimError> {
    use vulkano::buffer::BufferUsage;
    let storage = BufferUsage::STORAGE_BUFFER | BufferUsage::TRANSFER_DST | BufferUsage::TRANSFER_SRC;
    let counts = device.physical_device().properties().max_compute_work_group_count;
    let max_x = counts[0];
    let vertices = workgroups(data.positions.len() as u32, max_x);
    // The per-substep kernel's workgroups each update a block of the grid (BLOCK_WIDTH).
    let [nx, ny] = scene.cloth.resolution;
    let block_grid = cloth_core::layout::BlockGrid::new(workgroup_size(), nx, ny, counts[0].min(counts[1]));
    let block_width = block_grid.width;
    let blocks = [block_grid.workgroups[0], block_grid.workgroups[1], 1];
    let [p, v] = [&state.positions, &state.velocities];
    let mut uploads: Vec<(Subbuffer<[u8]>, Vec<u8>)> = Vec::new();
    let mut buffer_with = |usage: BufferUsage, bytes: Vec<u8>| -> Result<Subbuffer<[u8]>, SimError> {
        let buffer = device_local(usage, bytes.len() as u64)?;
        uploads.push((buffer.clone(), bytes));
        Ok(buffer)
    };
    match scene.integrator {
        Integrator::SemiImplicitEuler | Integrator::VelocityVerlet | Integrator::RungeKutta4 => {
            let rk4 = scene.integrator == Integrator::RungeKutta4;
            // RK4's per-vertex start state and sums (a placeholder for the other integrators).
            let rk4_scratch = device_local(storage, if rk4 { 64 * data.positions.len() as u64 } else { 64 })?;
            // Semi-implicit Euler's packed states and pin bits (cloth_core::layout::PackedState);
            // 64-byte placeholders for the passes that do not use them (a read-only one, and one
            // for each written binding).
            let placeholders = [device_local(storage, 64)?, device_local(storage, 64)?, device_local(storage, 64)?];
            let euler = scene.integrator == Integrator::SemiImplicitEuler;
            let packed_buffers = if euler {
                let [xv_bytes, v_bytes] = cloth_core::layout::PackedState::buffer_bytes(data.positions.len() as u64);
                let pins = buffer_with(storage, bytemuck::cast_slice(&data.pin_bits).to_vec())?;
                Some((
                    [device_local(storage, xv_bytes)?, device_local(storage, xv_bytes)?],
                    [device_local(storage, v_bytes)?, device_local(storage, v_bytes)?],
                    pins,
                ))
            } else {
                None
            };
            let kernel = Kernel::new(device, scene, STEP_SPIRV, None)?;
            // The packed bindings 8-12: (x, v.x) in, (v.y, v.z) in, (x, v.x) out, (v.y, v.z) out,
            // pin bits.
            let unpacked: [&Subbuffer<[u8]>; 5] =
                [&placeholders[0], &placeholders[0], &placeholders[1], &placeholders[2], &placeholders[0]];
            let set_with = |[x_in, v_in, x_out, v_out]: [&State; 4], packed: [&Subbuffer<[u8]>; 5]| {
                kernel.set(
                    descriptors,
                    [
                        WriteDescriptorSet::buffer(0, state.params.clone()),
                        WriteDescriptorSet::buffer(1, state.spheres.clone()),
                        WriteDescriptorSet::buffer(2, x_in.clone()),
                        WriteDescriptorSet::buffer(3, v_in.clone()),
                        WriteDescriptorSet::buffer(4, x_out.clone()),
                        WriteDescriptorSet::buffer(5, v_out.clone()),
                        WriteDescriptorSet::buffer(6, state.max_penetration.clone()),
                        WriteDescriptorSet::buffer(7, rk4_scratch.clone()),
                        WriteDescriptorSet::buffer(8, packed[0].clone()),
                        WriteDescriptorSet::buffer(9, packed[1].clone()),
                        WriteDescriptorSet::buffer(10, packed[2].clone()),
                        WriteDescriptorSet::buffer(11, packed[3].clone()),
                        WriteDescriptorSet::buffer(12, packed[4].clone()),
                    ],
                )
            };
            let set = |buffers: [&State; 4]| set_with(buffers, unpacked);
            let pass = |pipeline: usize, sets: [Arc<DescriptorSet>; 2]| Pass {
                pipeline,
                sets,
                workgroups: blocks,
                dynamic_offset: None,
            };
            let state_bytes = std::mem::size_of_val(data.positions.as_slice()) as u64;
            match scene.integrator {
                Integrator::SemiImplicitEuler => {
                    let sets = [set([&p[0], &v[0], &p[1], &v[1]])?, set([&p[1], &v[1], &p[0], &v[0]])?];
                    let packed = match &packed_buffers {
                        Some((xv, pv, pins)) if cloth_core::layout::PackedState::checked_enabled(BACKEND_NAME)? => {
                            // Packed state m in, 1 - m out; the vec4 bindings the pass does not use
                            // hold state buffers it does not touch either.
                            let packed_io = |m: usize| [&xv[m], &pv[m], &xv[1 - m], &pv[1 - m], pins];
                            // Whether the substeps alternate the order of the blocks (the
                            // knob is checked at creation).
                            let vertices = data.positions.len() as u64;
                            let alternate =
                                block_width > 0 && cloth_core::layout::alternates_order(vertices).unwrap_or(false);
                            let pipeline = |packed_in: u32, packed_out: u32, reversed: bool| {
                                kernel.pipeline_with([
                                    (STAGE_CONSTANT_ID, 0),
                                    (BLOCK_WIDTH_CONSTANT_ID, block_width),
                                    (PACKED_CONSTANT_IDS[0], packed_in),
                                    (PACKED_CONSTANT_IDS[1], packed_out),
                                    (REVERSED_ORDER_CONSTANT_ID, u32::from(reversed)),
                                ])
                            };
                            let both = |packed_in: u32,
                                        packed_out: u32|
                             -> Result<[Arc<ComputePipeline>; 2], SimError> {
                                let forward = pipeline(packed_in, packed_out, false)?;
                                let backward =
                                    if alternate { pipeline(packed_in, packed_out, true)? } else { forward.clone() };
                                Ok([forward, backward])
                            };
                            let for_k = |k: usize, packed: [&Subbuffer<[u8]>; 5]| {
                                set_with([&p[k], &v[k], &p[1 - k], &v[1 - k]], packed)
                            };
                            Some(PackedPasses {
                                first_pipeline: pipeline(0, 1, false)?,
                                middle_pipelines: both(1, 1)?,
                                last_pipelines: both(1, 0)?,
                                // first writes packed state 0 (reading nothing packed: state 1
                                // sits in the input bindings).
                                first: [for_k(0, packed_io(1))?, for_k(1, packed_io(1))?],
                                middle: [for_k(0, packed_io(0))?, for_k(0, packed_io(1))?],
                                last: [
                                    [for_k(0, packed_io(0))?, for_k(0, packed_io(1))?],
                                    [for_k(1, packed_io(0))?, for_k(1, packed_io(1))?],
                                ],
                                workgroups: blocks,
                            })
                        }
                        _ => None,
                    };
                    Ok(SubstepPlan {
                        pipelines: vec![kernel.step_pipeline(0, block_width)?],
                        passes: vec![pass(0, sets)],
                        tiled: tiled_pass(device, scene, state, descriptors, Tiling::Auto)?,
                        packed,
                        uploads,
                    })
                }
                Integrator::VelocityVerlet => {
                    // Verlet's half-step velocities, and a sink for the positions its second kick
                    // does not write.
                    let v_half: State = device_local(storage, state_bytes)?.reinterpret();
                    let sink: State = device_local(storage, 16)?.reinterpret();
                    let first = [set([&p[0], &v[0], &p[1], &v_half])?, set([&p[1], &v[1], &p[0], &v_half])?];
                    let second = [set([&p[1], &v_half, &sink, &v[1]])?, set([&p[0], &v_half, &sink, &v[0]])?];
                    Ok(SubstepPlan {
                        pipelines: vec![kernel.step_pipeline(1, block_width)?, kernel.step_pipeline(2, block_width)?],
                        passes: vec![pass(0, first), pass(1, second)],
                        tiled: None,
                        packed: None,
                        uploads,
                    })
                }
                _ => {
                    // RK4's stage states alternate between a scratch state S and the output
                    // buffer 1 - k: k -> S -> 1-k -> S -> 1-k. S starts as the initial state so
                    // its w (free or pinned) is right from the first stage.
                    let s_x: State =
                        buffer_with(storage, bytemuck::cast_slice(&data.positions).to_vec())?.reinterpret();
                    let s_v: State =
                        buffer_with(storage, bytemuck::cast_slice(&data.velocities).to_vec())?.reinterpret();
                    let stage = |n: u32| -> Result<[Arc<DescriptorSet>; 2], SimError> {
                        let for_k = |k: usize| {
                            let (out_x, out_v) = (&p[1 - k], &v[1 - k]);
                            match n {
                                1 => set([&p[k], &v[k], &s_x, &s_v]),
                                3 => set([out_x, out_v, &s_x, &s_v]),
                                _ => set([&s_x, &s_v, out_x, out_v]),
                            }
                        };
                        Ok([for_k(0)?, for_k(1)?])
                    };
                    let mut passes = Vec::new();
                    let mut pipelines = Vec::new();
                    for n in 1..=4 {
                        pipelines.push(kernel.step_pipeline(2 + n, block_width)?);
                        passes.push(pass(n as usize - 1, stage(n)?));
                    }
                    Ok(SubstepPlan { pipelines, passes, tiled: None, packed: None, uploads })
                }
            }
        }
        Integrator::Xpbd => {
            let constraints = buffer_with(storage, bytemuck::cast_slice(&data.constraints).to_vec())?;
            let lambdas = buffer_with(storage, vec![0u8; 4 * data.constraints.len()])?;
            let corrections = buffer_with(storage, vec![0u8; 4 * data.positions.len()])?;
            let ranges =
                buffer_with(BufferUsage::UNIFORM_BUFFER | BufferUsage::TRANSFER_DST, data.color_ranges.clone())?;
            let kernel = Kernel::new(device, scene, XPBD_SPIRV, Some(COLOR_RANGE_BINDING))?;
            let set = |k: usize| {
                kernel.set(
                    descriptors,
                    [
                        WriteDescriptorSet::buffer(0, state.params.clone()),
                        WriteDescriptorSet::buffer(1, state.spheres.clone()),
                        WriteDescriptorSet::buffer(2, constraints.clone()),
                        WriteDescriptorSet::buffer(3, p[k].clone()),
                        WriteDescriptorSet::buffer(4, v[k].clone()),
                        WriteDescriptorSet::buffer(5, p[1 - k].clone()),
                        WriteDescriptorSet::buffer(6, v[1 - k].clone()),
                        WriteDescriptorSet::buffer(7, state.max_penetration.clone()),
                        WriteDescriptorSet::buffer(8, lambdas.clone()),
                        WriteDescriptorSet::buffer(9, corrections.clone()),
                        WriteDescriptorSet::buffer_with_range(
                            COLOR_RANGE_BINDING,
                            DescriptorBufferInfo {
                                buffer: ranges.clone(),
                                range: 0..size_of::<GpuColorRange>() as u64,
                            },
                        ),
                    ],
                )
            };
            let sets = [set(0)?, set(1)?];
            let pipelines = (0..4).map(|pass| kernel.pipeline(pass)).collect::<Result<Vec<_>, _>>()?;
            let pass = |pipeline: usize, workgroups: [u32; 3], offset: u32| Pass {
                pipeline,
                sets: sets.clone(),
                workgroups,
                dynamic_offset: Some(offset),
            };
            let mut passes = vec![pass(0, vertices, 0)];
            let contact = scene.effects.contains(Effect::SphereContact) && data.params.sphere_count > 0;
            for iteration in 0..XPBD_ITERATIONS {
                for color in 0..COLOR_COUNT {
                    let range = data.color_range(color, iteration);
                    if range.count > 0 {
                        passes.push(pass(1, workgroups(range.count, max_x), GpuColorRange::offset(color, iteration)));
                    }
                }
                if contact {
                    passes.push(pass(2, vertices, 0));
                }
            }
            passes.push(pass(3, vertices, 0));
            Ok(SubstepPlan { pipelines, passes, tiled: None, packed: None, uploads })
        }
    }
}

/// The tile semi-implicit Euler uses for a grid of `vertices` on `device` as `tiling` asks
/// (`cloth_core::tiling`: the largest default tile the device's shared memory and invocations
/// allow), or none: every substep is then its own dispatch, as exact.
pub(crate) fn usable_tile(device: &Arc<Device>, tiling: Tiling, vertices: u32) -> Result<Option<TileConfig>, SimError> {
    let properties = device.physical_device().properties();
    let [x, y, _] = properties.max_compute_work_group_size;
    let limits = DeviceLimits {
        invocations: properties.max_compute_work_group_invocations.min(x * y),
        workgroup_memory: properties.max_compute_shared_memory_size,
        cpu: properties.device_type == vulkano::device::physical::PhysicalDeviceType::Cpu,
    };
    cloth_core::tiling::checked_tile_config(BACKEND_NAME, tiling, vertices, limits)
}

/// The tiled pass of semi-implicit Euler (`cloth_step_tiled.comp`) as `tiling` asks, if the scene
/// integrates with semi-implicit Euler and the device can run it.
pub(crate) fn tiled_pass(
    device: &Arc<Device>,
    scene: &Scene,
    state: &StateBuffers,
    descriptors: &Arc<StandardDescriptorSetAllocator>,
    tiling: Tiling,
) -> Result<Option<TiledPass>, SimError> {
    if scene.integrator != Integrator::SemiImplicitEuler {
        return Ok(None);
    }
    let [nx, ny] = scene.cloth.resolution;
    let Some(tile) = usable_tile(device, tiling, nx * ny)? else {
        return Ok(None);
    };
    let kernel = Kernel::new(device, scene, TILED_STEP_SPIRV, None)?;
    let [p, v] = [&state.positions, &state.velocities];
    let set = |k: usize| {
        kernel.set(
            descriptors,
            [
                WriteDescriptorSet::buffer(0, state.params.clone()),
                WriteDescriptorSet::buffer(1, state.spheres.clone()),
                WriteDescriptorSet::buffer(2, p[k].clone()),
                WriteDescriptorSet::buffer(3, v[k].clone()),
                WriteDescriptorSet::buffer(4, p[1 - k].clone()),
                WriteDescriptorSet::buffer(5, v[1 - k].clone()),
                WriteDescriptorSet::buffer(6, state.max_penetration.clone()),
            ],
        )
    };
    let values = [tile.width, tile.height, tile.cells(), tile.substeps];
    let (x, y) = tile.workgroups(nx, ny);
    Ok(Some(TiledPass {
        pipeline: kernel.pipeline_with(TILE_CONSTANT_IDS.into_iter().zip(values))?,
        sets: [set(0)?, set(1)?],
        workgroups: [x, y, 1],
        substeps: tile.substeps,
    }))
}
