//! The dispatches of one substep for each integrator: pipelines, bind groups, workgroup counts.
//!
//! | integrator | passes per substep |
//! |---|---|
//! | semi-implicit Euler | 1: `cloth_step.wgsl`, `STAGE = 0`; or, fused, `cloth_step_tiled.wgsl` for `FUSED_SUBSTEPS` at once |
//! | velocity Verlet | 2: `STAGE = 1` (kick and drift), `STAGE = 2` (second kick) |
//! | RK4 | 4: `STAGE = 3..=6`, one per stage (state `k` → S → `1 − k` → S → `1 − k`) |
//! | XPBD | `xpbd.wgsl`: predict; `XPBD_ITERATIONS` × (one per non-empty colour + spheres); finish |
//!
//! Every pass of a substep reads the state buffer `k` that is current and leaves the new state in
//! buffer `1 − k`; each pass has one bind group per `k`. Semi-implicit Euler also has a tiled pass
//! ([`TiledPass`], `cloth_core::tiling`) that advances several substeps in one dispatch, from `k`
//! to `1 − k` likewise; the substeps left over run one at a time. Where it does not tile,
//! semi-implicit Euler runs the substeps inside one submission on its packed state
//! ([`PackedPasses`], `cloth_core::layout::PackedState`).

use cloth_core::coloring::COLOR_COUNT;
use cloth_core::integrator::XPBD_ITERATIONS;
use cloth_core::layout::{GpuBuffers, GpuColorRange, GpuSimParams};
use cloth_core::{Effect, Integrator, Scene, SimError};
use wgpu::util::DeviceExt;

use cloth_core::tiling::{DeviceLimits, TileConfig, Tiling};

use crate::{BACKEND_NAME, STEP_SHADER, XPBD_SHADER};

/// Invocations per workgroup of every kernel by default (the WGSL `WORKGROUP_SIZE` override; see
/// `cloth_core::layout::workgroup_size` for the `CLOTH_WORKGROUP_SIZE` knob).
pub const WORKGROUP_SIZE: u32 = cloth_core::layout::DEFAULT_WORKGROUP_SIZE;

/// The workgroup size in use (checked when the simulator is created).
pub(crate) fn workgroup_size() -> u32 {
    cloth_core::layout::workgroup_size().unwrap_or(WORKGROUP_SIZE)
}

/// The buffers every integrator's passes bind.
pub(crate) struct StateBuffers {
    pub params: wgpu::Buffer,
    pub spheres: wgpu::Buffer,
    pub positions: [wgpu::Buffer; 2],
    pub velocities: [wgpu::Buffer; 2],
    pub max_penetration: wgpu::Buffer,
}

/// One dispatch of a substep.
pub(crate) struct Pass {
    /// Index into [`SubstepPlan::pipelines`].
    pub pipeline: usize,
    /// The bind group when state buffer `k` is current.
    pub groups: [wgpu::BindGroup; 2],
    /// Workgroups along x and y.
    pub workgroups: (u32, u32),
    /// The dynamic offset of the layout's dynamic uniform, when it has one.
    pub dynamic_offset: Option<u32>,
}

/// The dispatches of one substep, in order, and the tiled pass that fuses several, if any.
pub(crate) struct SubstepPlan {
    pub pipelines: Vec<wgpu::ComputePipeline>,
    pub passes: Vec<Pass>,
    pub tiled: Option<TiledPass>,
    /// Semi-implicit Euler's passes on its packed state, if it has them.
    pub packed: Option<PackedPasses>,
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
    pub first_pipeline: wgpu::ComputePipeline,
    /// The pipelines of `middle` and `last` by the order the substep takes the grid's blocks
    /// in: `[forward, backward]` (the same pipeline twice unless
    /// `cloth_core::layout::alternates_order`); substep `s` of a submission goes backward when
    /// `s` is odd.
    pub middle_pipelines: [wgpu::ComputePipeline; 2],
    /// The same for `last` (substep `n − 1` of a submission of `n`).
    pub last_pipelines: [wgpu::ComputePipeline; 2],
    /// `first`'s bind group when the `vec4` state `k` is current.
    pub first: [wgpu::BindGroup; 2],
    /// `middle`'s bind group reading packed state `m`.
    pub middle: [wgpu::BindGroup; 2],
    /// `last`'s bind group when the `vec4` state `k` is current, reading packed state `m`:
    /// `last[k][m]`.
    pub last: [[wgpu::BindGroup; 2]; 2],
    /// Workgroups along x and y (those of the per-substep kernel).
    pub workgroups: (u32, u32),
}

/// One dispatch that advances [`TiledPass::substeps`] semi-implicit Euler substeps at once.
pub(crate) struct TiledPass {
    pub pipeline: wgpu::ComputePipeline,
    /// The bind group when state buffer `k` is current.
    pub groups: [wgpu::BindGroup; 2],
    /// Workgroups along x and y: one per output block.
    pub workgroups: (u32, u32),
    /// Substeps per dispatch.
    pub substeps: u32,
}

/// What a binding of a kernel's bind group layout holds.
#[derive(Clone, Copy)]
enum Binding {
    /// A uniform block of `size` bytes; `dynamic` when selected by a dynamic offset.
    Uniform { size: u64, dynamic: bool },
    /// A storage buffer.
    Storage { read_only: bool },
}

fn bind_group_layout(device: &wgpu::Device, label: &str, bindings: &[Binding]) -> wgpu::BindGroupLayout {
    let entries: Vec<wgpu::BindGroupLayoutEntry> = bindings
        .iter()
        .enumerate()
        .map(|(binding, b)| wgpu::BindGroupLayoutEntry {
            binding: binding as u32,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: match *b {
                Binding::Uniform { size, dynamic } => wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: dynamic,
                    min_binding_size: wgpu::BufferSize::new(size),
                },
                Binding::Storage { read_only } => wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
            },
            count: None,
        })
        .collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries })
}

/// Workgroups for `items` invocations: along x up to the device's limit, the rest along y.
pub(crate) fn workgroups(items: u32, max_x: u32) -> (u32, u32) {
    let [x, y] = cloth_core::layout::spilled_workgroups(items, workgroup_size(), max_x);
    (x, y)
}

/// The bindings 0-6 of both force kernels (`cloth_step.wgsl`, `cloth_step_tiled.wgsl`): the
/// parameters, the spheres, the state read and written, the deepest penetration.
const STATE_BINDINGS: [Binding; 7] = [
    Binding::Uniform { size: size_of::<GpuSimParams>() as u64, dynamic: false },
    Binding::Storage { read_only: true },  // spheres
    Binding::Storage { read_only: true },  // positions in
    Binding::Storage { read_only: true },  // velocities in
    Binding::Storage { read_only: false }, // positions out
    Binding::Storage { read_only: false }, // velocities out
    Binding::Storage { read_only: false }, // deepest penetration
];

/// A compiled kernel: its module's pipelines share one bind group layout.
struct Kernel<'a> {
    device: &'a wgpu::Device,
    scene: &'a Scene,
    module: wgpu::ShaderModule,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    entry_point: &'static str,
    bindings: Vec<Binding>,
}

impl<'a> Kernel<'a> {
    fn new(
        device: &'a wgpu::Device,
        scene: &'a Scene,
        name: &'static str,
        source: &str,
        entry_point: &'static str,
        bindings: &[Binding],
    ) -> Self {
        let descriptor = wgpu::ShaderModuleDescriptor {
            label: Some(name),
            source: wgpu::ShaderSource::Wgsl(source.to_owned().into()),
        };
        // SAFETY: the kernels run without wgpu's runtime checks (index clamping and loop
        // bounding; 1.6-2.7% of the H100's frame at 1024² and 2048², docs/performance.md), as the
        // vulkano backend runs its SPIR-V. Every index they form is in bounds given what the host
        // guarantees: `vertex_count = nx · ny` is the length of every state buffer, and a vertex
        // index comes from grid coordinates checked against `nx`, `ny` (or is an offset of at
        // most two rows and columns from a vertex two or more from every edge); `sphere_count`
        // is at most the sphere buffer's length (a change of sphere count rebuilds the simulator,
        // `Scene::rebuild_reason`); XPBD's constraints have `a`, `b` below the vertex count and
        // `kind` at most 2, and its colour ranges lie inside the constraint buffer (both built by
        // cloth-core); RK4's stages run only with the full per-vertex scratch bound; the tiled
        // kernel reads only tile cells it wrote, at most two cells a substep from its own.
        // Every loop is bounded: over the spheres and over the fused substeps (a constant).
        let module = unsafe { device.create_shader_module_trusted(descriptor, wgpu::ShaderRuntimeChecks::unchecked()) };
        let layout = bind_group_layout(device, &format!("{name} bind group layout"), bindings);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(&format!("{name} pipeline layout")),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        Self { device, scene, module, layout, pipeline_layout, entry_point, bindings: bindings.to_vec() }
    }

    /// The pipeline with the scene's effects, the workgroup size and the kernel's own
    /// `(constant, value)`s (its stage, its block width).
    fn pipeline(&self, label: &str, own: &[(&str, u32)]) -> wgpu::ComputePipeline {
        let mut constants: Vec<(&str, f64)> = self
            .scene
            .effects
            .shader_constants()
            .into_iter()
            .map(|(name, on)| (name, if on { 1.0 } else { 0.0 }))
            .collect();
        constants.push(("WORKGROUP_SIZE", workgroup_size() as f64));
        constants.extend(own.iter().map(|&(name, value)| (name, value as f64)));
        self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&self.pipeline_layout),
            module: &self.module,
            entry_point: Some(self.entry_point),
            // No zero-initialized workgroup memory: every kernel reads only cells it has written.
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        })
    }

    fn bind_group(&self, label: &str, buffers: &[&wgpu::Buffer]) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .zip(&self.bindings)
            .enumerate()
            .map(|(binding, (buffer, kind))| wgpu::BindGroupEntry {
                binding: binding as u32,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer,
                    offset: 0,
                    // A dynamic uniform binds one block at a time; everything else whole.
                    size: match *kind {
                        Binding::Uniform { size, dynamic: true } => wgpu::BufferSize::new(size),
                        _ => None,
                    },
                }),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &self.layout,
            entries: &entries,
        })
    }
}

/// Builds the passes of one substep of the scene's integrator (`cpu`: the device is a CPU
/// implementation, for the tiling policy).
pub(crate) fn plan(
    device: &wgpu::Device,
    scene: &Scene,
    data: &GpuBuffers,
    state: &StateBuffers,
    cpu: bool,
) -> Result<SubstepPlan, SimError> {
    let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC;
    let init = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
    };
    // The force kernel binds 12 storage buffers, XPBD's 9 (the WebGPU default allows 8; every
    // Vulkan device we know allows more, and the context requests what the adapter offers).
    let storage_needed = if scene.integrator == Integrator::Xpbd { 9 } else { 12 };
    if device.limits().max_storage_buffers_per_shader_stage < storage_needed {
        return Err(SimError::Unsupported {
            backend: BACKEND_NAME,
            what: format!(
                "devices that allow fewer than {storage_needed} storage buffers per shader stage (this one allows {})",
                device.limits().max_storage_buffers_per_shader_stage
            ),
            fix: "use the vulkano or cpu backend".into(),
        });
    }
    let max_x = device.limits().max_compute_workgroups_per_dimension;
    let vertices = workgroups(data.positions.len() as u32, max_x);
    // The per-substep kernel's workgroups each update a block of the grid (BLOCK_WIDTH).
    let [nx, ny] = scene.cloth.resolution;
    let block_grid = cloth_core::layout::BlockGrid::new(workgroup_size(), nx, ny, max_x);
    let block_width = block_grid.width;
    let blocks = (block_grid.workgroups[0], block_grid.workgroups[1]);
    let [p, v] = [&state.positions, &state.velocities];
    let name = ["A", "B"];
    match scene.integrator {
        Integrator::SemiImplicitEuler | Integrator::VelocityVerlet | Integrator::RungeKutta4 => {
            let rk4 = scene.integrator == Integrator::RungeKutta4;
            // RK4's per-vertex start state and sums (a placeholder for the other integrators).
            let scratch_bytes = if rk4 { 64 * data.positions.len() } else { 64 };
            let rk4_scratch = init("cloth RK4 scratch", &vec![0u8; scratch_bytes], storage);
            // Semi-implicit Euler's packed states and pin bits (cloth_core::layout::PackedState);
            // 64-byte placeholders for the passes that do not use them (a read-only one, and one
            // for each written binding: a binding must not alias another of the same dispatch).
            let placeholders = ["read", "(x, v.x) out", "(v.y, v.z) out"]
                .map(|what| init(&format!("cloth packed-state placeholder, {what}"), &[0u8; 64], storage));
            let packed_buffers = (scene.integrator == Integrator::SemiImplicitEuler).then(|| {
                let [xv_bytes, v_bytes] = cloth_core::layout::PackedState::buffer_bytes(data.positions.len() as u64);
                let empty = |label: String, size: u64| {
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some(&label),
                        size,
                        usage: storage,
                        mapped_at_creation: false,
                    })
                };
                (
                    name.map(|n| empty(format!("cloth packed (x, v.x) {n}"), xv_bytes)),
                    name.map(|n| empty(format!("cloth packed (v.y, v.z) and time {n}"), v_bytes)),
                    init("cloth pin bits", bytemuck::cast_slice(&data.pin_bits), storage),
                )
            });
            let kernel = Kernel::new(
                device,
                scene,
                "cloth_step.wgsl",
                STEP_SHADER,
                "substep",
                &[
                    STATE_BINDINGS.as_slice(),
                    &[
                        Binding::Storage { read_only: false }, // RK4 scratch
                        Binding::Storage { read_only: true },  // packed (x, v.x) in
                        Binding::Storage { read_only: true },  // packed (v.y, v.z) in
                        Binding::Storage { read_only: false }, // packed (x, v.x) out
                        Binding::Storage { read_only: false }, // packed (v.y, v.z) out
                        Binding::Storage { read_only: true },  // pin bits
                    ],
                ]
                .concat(),
            );
            // The packed bindings 8-12: (x, v.x) in, (v.y, v.z) in, (x, v.x) out, (v.y, v.z) out,
            // pin bits.
            let unpacked: [&wgpu::Buffer; 5] =
                [&placeholders[0], &placeholders[0], &placeholders[1], &placeholders[2], &placeholders[0]];
            let group_with =
                |label: String, [x_in, v_in, x_out, v_out]: [&wgpu::Buffer; 4], packed: [&wgpu::Buffer; 5]| {
                    kernel.bind_group(
                        &label,
                        &[
                            &state.params,
                            &state.spheres,
                            x_in,
                            v_in,
                            x_out,
                            v_out,
                            &state.max_penetration,
                            &rk4_scratch,
                            packed[0],
                            packed[1],
                            packed[2],
                            packed[3],
                            packed[4],
                        ],
                    )
                };
            let group = |label: String, buffers: [&wgpu::Buffer; 4]| group_with(label, buffers, unpacked);
            let pass = |pipeline: usize, groups: [wgpu::BindGroup; 2]| Pass {
                pipeline,
                groups,
                workgroups: blocks,
                dynamic_offset: None,
            };
            match scene.integrator {
                Integrator::SemiImplicitEuler => {
                    let groups = [0, 1].map(|k| {
                        group(
                            format!("cloth substep {} -> {}", name[k], name[1 - k]),
                            [&p[k], &v[k], &p[1 - k], &v[1 - k]],
                        )
                    });
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
                            let pipeline = |label: &str, packed_in: u32, packed_out: u32, reversed: bool| {
                                kernel.pipeline(
                                    label,
                                    &[
                                        ("STAGE", 0),
                                        ("BLOCK_WIDTH", block_width),
                                        ("PACKED_IN", packed_in),
                                        ("PACKED_OUT", packed_out),
                                        ("REVERSED_ORDER", u32::from(reversed)),
                                    ],
                                )
                            };
                            let both = |label: &str, packed_in: u32, packed_out: u32| {
                                let forward = pipeline(label, packed_in, packed_out, false);
                                let backward = if alternate {
                                    pipeline(&format!("{label}, blocks backward"), packed_in, packed_out, true)
                                } else {
                                    forward.clone()
                                };
                                [forward, backward]
                            };
                            let for_k = |label: String, k: usize, packed: [&wgpu::Buffer; 5]| {
                                group_with(label, [&p[k], &v[k], &p[1 - k], &v[1 - k]], packed)
                            };
                            Some(PackedPasses {
                                first_pipeline: pipeline("cloth Euler substep pipeline, vec4 -> packed", 0, 1, false),
                                middle_pipelines: both("cloth Euler substep pipeline, packed -> packed", 1, 1),
                                last_pipelines: both("cloth Euler substep pipeline, packed -> vec4", 1, 0),
                                // first writes packed state A (reading nothing packed: B sits in
                                // the input bindings).
                                first: [0, 1].map(|k| {
                                    for_k(format!("cloth packed substep {} -> packed A", name[k]), k, packed_io(1))
                                }),
                                middle: [0, 1].map(|m| {
                                    for_k(
                                        format!("cloth packed substep packed {} -> packed {}", name[m], name[1 - m]),
                                        0,
                                        packed_io(m),
                                    )
                                }),
                                last: [0, 1].map(|k| {
                                    [0, 1].map(|m| {
                                        for_k(
                                            format!("cloth packed substep packed {} -> {}", name[m], name[1 - k]),
                                            k,
                                            packed_io(m),
                                        )
                                    })
                                }),
                                workgroups: blocks,
                            })
                        }
                        _ => None,
                    };
                    Ok(SubstepPlan {
                        pipelines: vec![
                            kernel.pipeline(
                                "cloth Euler substep pipeline",
                                &[("STAGE", 0), ("BLOCK_WIDTH", block_width)],
                            ),
                        ],
                        passes: vec![pass(0, groups)],
                        tiled: tiled_pass(device, scene, state, Tiling::Auto, cpu)?,
                        packed,
                    })
                }
                Integrator::VelocityVerlet => {
                    // Verlet's half-step velocities, and a sink for the positions its second
                    // kick does not write (a binding must not alias another of the same dispatch).
                    let v_half =
                        init("cloth velocities (Verlet half step)", bytemuck::cast_slice(&data.velocities), storage);
                    let sink = init("cloth positions sink (Verlet second kick)", &[0u8; 16], storage);
                    let first = [0, 1].map(|k| {
                        group(
                            format!("cloth Verlet kick and drift {} -> {}", name[k], name[1 - k]),
                            [&p[k], &v[k], &p[1 - k], &v_half],
                        )
                    });
                    let second = [0, 1].map(|k| {
                        group(
                            format!("cloth Verlet second kick -> {}", name[1 - k]),
                            [&p[1 - k], &v_half, &sink, &v[1 - k]],
                        )
                    });
                    Ok(SubstepPlan {
                        pipelines: vec![
                            kernel.pipeline(
                                "cloth Verlet kick and drift pipeline",
                                &[("STAGE", 1), ("BLOCK_WIDTH", block_width)],
                            ),
                            kernel.pipeline(
                                "cloth Verlet second kick pipeline",
                                &[("STAGE", 2), ("BLOCK_WIDTH", block_width)],
                            ),
                        ],
                        passes: vec![pass(0, first), pass(1, second)],
                        tiled: None,
                        packed: None,
                    })
                }
                _ => {
                    // RK4's stage states alternate between a scratch state S and the output
                    // buffer 1 - k: k -> S -> 1-k -> S -> 1-k.
                    let s_x = init("cloth RK4 stage positions", bytemuck::cast_slice(&data.positions), storage);
                    let s_v = init("cloth RK4 stage velocities", bytemuck::cast_slice(&data.velocities), storage);
                    let stage = |n: u32| {
                        [0, 1].map(|k| {
                            let (out_x, out_v) = (&p[1 - k], &v[1 - k]);
                            let buffers = match n {
                                1 => [&p[k], &v[k], &s_x, &s_v],
                                2 => [&s_x, &s_v, out_x, out_v],
                                3 => [out_x, out_v, &s_x, &s_v],
                                _ => [&s_x, &s_v, out_x, out_v],
                            };
                            group(format!("cloth RK4 stage {n} (state {})", name[k]), buffers)
                        })
                    };
                    Ok(SubstepPlan {
                        pipelines: (1..=4)
                            .map(|n| {
                                kernel.pipeline(
                                    &format!("cloth RK4 stage {n} pipeline"),
                                    &[("STAGE", 2 + n), ("BLOCK_WIDTH", block_width)],
                                )
                            })
                            .collect(),
                        passes: (1..=4).map(|n| pass(n as usize - 1, stage(n))).collect(),
                        tiled: None,
                        packed: None,
                    })
                }
            }
        }
        Integrator::Xpbd => {
            let constraints = init("cloth XPBD constraints", bytemuck::cast_slice(&data.constraints), storage);
            let lambdas = init("cloth XPBD multipliers", &vec![0u8; 4 * data.constraints.len()], storage);
            let corrections = init("cloth XPBD normal corrections", &vec![0u8; 4 * data.positions.len()], storage);
            let ranges = init(
                "cloth XPBD colour ranges",
                &data.color_ranges,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            );
            let kernel = Kernel::new(
                device,
                scene,
                "xpbd.wgsl",
                XPBD_SHADER,
                "xpbd",
                &[
                    Binding::Uniform { size: size_of::<GpuSimParams>() as u64, dynamic: false },
                    Binding::Storage { read_only: true },  // spheres
                    Binding::Storage { read_only: true },  // constraints
                    Binding::Storage { read_only: true },  // positions in
                    Binding::Storage { read_only: true },  // velocities in
                    Binding::Storage { read_only: false }, // positions out
                    Binding::Storage { read_only: false }, // velocities out
                    Binding::Storage { read_only: false }, // deepest penetration
                    Binding::Storage { read_only: false }, // multipliers
                    Binding::Storage { read_only: false }, // normal corrections
                    Binding::Uniform { size: size_of::<GpuColorRange>() as u64, dynamic: true },
                ],
            );
            let groups = [0, 1].map(|k| {
                kernel.bind_group(
                    &format!("cloth XPBD {} -> {}", name[k], name[1 - k]),
                    &[
                        &state.params,
                        &state.spheres,
                        &constraints,
                        &p[k],
                        &v[k],
                        &p[1 - k],
                        &v[1 - k],
                        &state.max_penetration,
                        &lambdas,
                        &corrections,
                        &ranges,
                    ],
                )
            });
            let pipelines = ["predict", "project one colour", "project the spheres", "finish"]
                .iter()
                .enumerate()
                .map(|(pass, what)| {
                    kernel.pipeline(&format!("cloth XPBD {what} pipeline"), &[("XPBD_PASS", pass as u32)])
                })
                .collect();
            let pass = |pipeline: usize, workgroups: (u32, u32), offset: u32| Pass {
                pipeline,
                groups: groups.clone(),
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
            Ok(SubstepPlan { pipelines, passes, tiled: None, packed: None })
        }
    }
}

/// The tile semi-implicit Euler uses for a grid of `vertices` on `device` as `tiling` asks
/// (`cloth_core::tiling`: the largest default tile the device's workgroup memory and invocations
/// allow), or none: every substep is then its own dispatch, as exact.
pub(crate) fn usable_tile(
    device: &wgpu::Device,
    tiling: Tiling,
    vertices: u32,
    cpu: bool,
) -> Result<Option<TileConfig>, SimError> {
    let limits = device.limits();
    let invocations = limits
        .max_compute_invocations_per_workgroup
        .min(limits.max_compute_workgroup_size_x * limits.max_compute_workgroup_size_y);
    let device_limits = DeviceLimits { invocations, workgroup_memory: limits.max_compute_workgroup_storage_size, cpu };
    cloth_core::tiling::checked_tile_config(BACKEND_NAME, tiling, vertices, device_limits)
}

/// The tiled pass of semi-implicit Euler (`cloth_step_tiled.wgsl`) as `tiling` asks, if the scene
/// integrates with semi-implicit Euler and the device can run it.
pub(crate) fn tiled_pass(
    device: &wgpu::Device,
    scene: &Scene,
    state: &StateBuffers,
    tiling: Tiling,
    cpu: bool,
) -> Result<Option<TiledPass>, SimError> {
    if scene.integrator != Integrator::SemiImplicitEuler {
        return Ok(None);
    }
    let [nx, ny] = scene.cloth.resolution;
    let Some(tile) = usable_tile(device, tiling, nx * ny, cpu)? else {
        return Ok(None);
    };
    let source = crate::tiled_shader_source(&tile);
    let kernel = Kernel::new(device, scene, "cloth_step_tiled.wgsl", &source, "substeps", &STATE_BINDINGS);
    let [p, v] = [&state.positions, &state.velocities];
    let groups = [0, 1].map(|k| {
        kernel.bind_group(
            &format!("cloth tiled substeps {} -> {}", ["A", "B"][k], ["A", "B"][1 - k]),
            &[&state.params, &state.spheres, &p[k], &v[k], &p[1 - k], &v[1 - k], &state.max_penetration],
        )
    });
    Ok(Some(TiledPass {
        pipeline: kernel.pipeline("cloth tiled Euler substeps pipeline", &[]),
        groups,
        workgroups: tile.workgroups(nx, ny),
        substeps: tile.substeps,
    }))
}
