//! The plan of a simulation on a GPU: every buffer, kernel, pipeline and bind group it needs and
//! the [`Schedule`] of its dispatches, for a scene, its integrator, a [`GpuTuning`] and what the
//! device allows. Written once: a backend creates the objects listed here, in order, and records
//! the dispatches the schedule gives.

use cloth_core::colliders::ColliderKind;
use cloth_core::coloring::{COLOR_COUNT, VERTEX_COLOR_COUNT};
use cloth_core::integrator::XPBD_ITERATIONS;
use cloth_core::solver::LINE_SEARCH_SLOPES;
use cloth_core::{ClothModel, Effect, Integrator, Scene, SimError};

use crate::geometry::{self, BlockGrid, DeviceLimits, TileConfig, spilled_workgroups};
use crate::layout::{
    COLOR_RANGE_STRIDE, GpuCgCounters, GpuCgStep, GpuCollider, GpuColorRange, GpuConstraint, GpuSelfControl,
    GpuSimParams, GpuVbdSweep, LISTING_BLOCK, LISTING_IN_LANES_BELOW, LISTING_VERTICES, MAX_COLLIDERS, MultigridLevels,
    REBUILD_PASSES, SelfHashTable,
};
use crate::schedule::{PackedPasses, Pass, Schedule, SelfCollisionChecks, TiledPass};
use crate::tuning::{CandidateListing, GpuTuning, invalid};

/// Index into [`Plan::buffers`].
pub type BufferId = usize;
/// Index into [`Plan::kernels`].
pub type KernelId = usize;
/// Index into [`Plan::pipelines`].
pub type PipelineId = usize;
/// Index into [`Plan::bind_groups`].
pub type BindGroupId = usize;

/// How a buffer is bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BufferUsage {
    /// A uniform block.
    Uniform,
    /// A storage buffer.
    Storage,
    /// A storage buffer a renderer on the same device may also draw from (vertex positions).
    StorageDrawable,
    /// A storage buffer that indirect dispatches also read their sizes from.
    StorageIndirect,
}

/// A buffer: its label, usage, size in bytes, and contents (`None`: zeros).
#[derive(Clone, Debug, PartialEq)]
pub struct BufferDesc {
    /// Label, for debuggers and validation messages.
    pub label: String,
    /// How it is bound.
    pub usage: BufferUsage,
    /// Size, bytes.
    pub size: u64,
    /// Initial contents, `size` bytes; `None`: zeros.
    pub contents: Option<Vec<u8>>,
}

/// What one binding of a kernel holds (binding `i` of set 0 is the `i`-th).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Binding {
    /// A uniform block of `size` bytes; `dynamic` when chosen by a dynamic offset.
    Uniform {
        /// Bytes of the block.
        size: u64,
        /// Whether a dynamic offset selects the block.
        dynamic: bool,
    },
    /// A storage buffer.
    Storage {
        /// Whether the kernel only reads it.
        read_only: bool,
    },
}

impl Binding {
    /// The bytes a bind group binds of its buffer from offset 0: a dynamic uniform one block at a
    /// time (the dynamic offset picks which), everything else whole (`None`).
    pub fn bound_bytes(self) -> Option<u64> {
        match self {
            Binding::Uniform { size, dynamic: true } => Some(size),
            _ => None,
        }
    }
}

/// A shader module of `shaders/`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shader {
    /// `cloth_step`: one substep of a force-based integrator (or one stage).
    Step,
    /// `cloth_step_tiled`: several semi-implicit Euler substeps of a tile in workgroup memory.
    Tiled(TileConfig),
    /// `xpbd`: XPBD's passes.
    Xpbd,
    /// `vbd`: Vertex Block Descent's passes.
    Vbd,
    /// `implicit`: backward Euler's passes (Newton iterations of conjugate gradients).
    Implicit,
    /// `copy`: the copy kernel that measures the memory bandwidth ([`crate::bandwidth`]).
    Copy,
    /// `self_hash`: self-collision's check and the passes that rebuild its spatial hash and
    /// candidate lists ([`HashPass`]).
    SelfHash,
}

/// A kernel: a shader module and the layout of its bindings, shared by its pipelines.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KernelDesc {
    /// The module.
    pub shader: Shader,
    /// Its bindings, in binding order.
    pub bindings: Vec<Binding>,
}

/// A pipeline constant of the kernels: WGSL `override` or a module constant, GLSL
/// specialization constant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Constant {
    /// An effect, compiled in (1) or out (0).
    Effect(Effect),
    /// A collider kind, compiled in (1: some collider of the scene has it) or out (0).
    Collider(ColliderKind),
    /// Invocations per workgroup.
    WorkgroupSize,
    /// `cloth_step`'s integration stage (0 Euler, 1-2 Verlet, 3-6 RK4).
    Stage,
    /// XPBD's pass (0 predict, 1 a colour, 2 the colliders, 3 finish, 4 the self-contacts).
    XpbdPass,
    /// VBD's pass (0 predict, 1 a colour's Newton steps, 2 finish).
    VbdPass,
    /// The vertex colour a VBD colour pass moves (0 to 4).
    VbdColor,
    /// Backward Euler's pass (`implicit.wgsl` lists them, 0 to 10).
    ImplicitPass,
    /// Vertices along `i` of a block, 0 for rows.
    BlockWidth,
    /// 1: the pipeline reads the packed state.
    PackedIn,
    /// 1: the pipeline writes the packed state.
    PackedOut,
    /// 1: the workgroups take the blocks backward.
    ReversedOrder,
    /// The tile's width, cells.
    TileWidth,
    /// The tile's height, cells.
    TileHeight,
    /// The tile's cells.
    TileCells,
    /// Substeps per tiled dispatch.
    FusedSubsteps,
    /// `self_hash`'s pass ([`HashPass`]).
    HashPass,
}

impl Constant {
    /// The constant's name in the shaders and its GLSL `constant_id` (the effects `0..` in
    /// `Effect::ALL` order, the collider kinds from [`COLLIDER_CONSTANT_IDS`], the others from
    /// 100).
    fn declared(self) -> (&'static str, u32) {
        match self {
            Constant::Effect(e) => {
                (e.shader_constant_name(), Effect::ALL.iter().position(|x| *x == e).unwrap_or(0) as u32)
            }
            Constant::Collider(k) => (k.shader_constant_name(), COLLIDER_CONSTANT_IDS + k.code()),
            Constant::WorkgroupSize => ("WORKGROUP_SIZE", 100),
            Constant::Stage => ("STAGE", 101),
            Constant::XpbdPass => ("XPBD_PASS", 101),
            Constant::VbdPass => ("VBD_PASS", 101),
            Constant::VbdColor => ("VBD_COLOR", 112),
            Constant::ImplicitPass => ("IMPLICIT_PASS", 101),
            Constant::TileWidth => ("TILE_WIDTH", 102),
            Constant::TileHeight => ("TILE_HEIGHT", 103),
            Constant::TileCells => ("TILE_CELLS", 104),
            Constant::FusedSubsteps => ("FUSED_SUBSTEPS", 106),
            Constant::BlockWidth => ("BLOCK_WIDTH", 107),
            Constant::PackedIn => ("PACKED_IN", 108),
            Constant::PackedOut => ("PACKED_OUT", 109),
            Constant::ReversedOrder => ("REVERSED_ORDER", 110),
            Constant::HashPass => ("HASH_PASS", 111),
        }
    }

    /// Whether the shaders declare it as a boolean (an effect or a collider kind; the others are
    /// unsigned integers).
    pub fn is_boolean(self) -> bool {
        matches!(self, Constant::Effect(_) | Constant::Collider(_))
    }

    /// The constant's name in the shaders.
    pub fn name(self) -> &'static str {
        self.declared().0
    }

    /// Its GLSL `constant_id`.
    pub fn spec_id(self) -> u32 {
        self.declared().1
    }

    /// Whether WGSL declares it as a module constant rather than an `override`: the tile's
    /// sizes, which size workgroup arrays (the backend writes them into the module's source).
    pub fn is_wgsl_module_constant(self) -> bool {
        matches!(self, Constant::TileWidth | Constant::TileHeight | Constant::TileCells | Constant::FusedSubsteps)
    }
}

/// The passes of `self_hash`, the value of its [`Constant::HashPass`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HashPass {
    /// Every vertex pushes itself onto its bucket's list.
    Insert = 0,
    /// Every vertex lists its candidates.
    Candidates = 1,
    /// The check: sizes the rebuild's dispatches, full when a rebuild is due, zero otherwise.
    Check = 2,
    /// The check that always rebuilds.
    ForcedCheck = 3,
    /// [`HashPass::Candidates`] on a grid of fewer than [`LISTING_IN_LANES_BELOW`] vertices:
    /// [`crate::layout::LISTING_LANES`] invocations a vertex.
    CandidatesInLanes = 4,
}

impl HashPass {
    /// The rebuild's passes for a cloth of `vertices` listed as `listing` asks, in order
    /// ([`REBUILD_PASSES`]).
    pub fn rebuild(vertices: usize, listing: CandidateListing) -> [HashPass; REBUILD_PASSES] {
        let lanes = match listing {
            CandidateListing::Auto => vertices < LISTING_IN_LANES_BELOW as usize,
            CandidateListing::Lanes => true,
            CandidateListing::OnePerVertex => false,
        };
        [HashPass::Insert, if lanes { HashPass::CandidatesInLanes } else { HashPass::Candidates }]
    }

    fn label(self) -> &'static str {
        match self {
            HashPass::Insert => "insert",
            HashPass::Candidates => "candidates",
            HashPass::CandidatesInLanes => "candidates in lanes",
            HashPass::Check => "check",
            HashPass::ForcedCheck => "forced check",
        }
    }
}

/// Invocations of a workgroup of `self_hash`, whatever the tuning's workgroup size.
pub const SELF_HASH_WORKGROUP: u32 = 256;

/// GLSL `constant_id` of the first collider kind's constant (`COLLIDER_SPHERE`; the others follow
/// in `ColliderKind::ALL` order).
pub const COLLIDER_CONSTANT_IDS: u32 = 20;

/// Whether the kernels built for `scene` evaluate collider kind `kind`: with `Contact`, when a
/// collider of the scene has it.
pub fn has_collider_kind(scene: &Scene, kind: ColliderKind) -> bool {
    scene.effects.contains(Effect::Contact) && scene.colliders.iter().any(|c| c.kind() == kind)
}

/// A pipeline: a kernel with its constants (the scene's effects, its collider kinds and the
/// workgroup size first).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PipelineDesc {
    /// The kernel.
    pub kernel: KernelId,
    /// What it does, in words (`Euler substep`, `self-collision check`): a row of a frame's
    /// profile ([`cloth_core::Simulator::profile_frame`]).
    pub name: String,
    /// Label of the device object.
    pub label: String,
    /// `(constant, value)`, booleans as 0 or 1.
    pub constants: Vec<(Constant, u32)>,
}

/// A bind group: a kernel's bindings filled with buffers, in binding order (a dynamic uniform
/// binds one block of its buffer, the others their whole buffer).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BindGroupDesc {
    /// The kernel whose layout it follows.
    pub kernel: KernelId,
    /// Label.
    pub label: String,
    /// One buffer a binding.
    pub buffers: Vec<BufferId>,
}

/// The buffers every plan has, which the simulator reads, writes and draws from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StateBuffers {
    /// [`GpuSimParams`].
    pub params: BufferId,
    /// [`GpuCollider`]s.
    pub colliders: BufferId,
    /// The mesh colliders' distance fields ([`GpuCollider::distance_fields_of`]), `f32` each.
    pub distance_fields: BufferId,
    /// Positions `vec4` (w 1 free, minus its pin group pinned), m, ping-pong.
    pub positions: [BufferId; 2],
    /// Velocities `vec4` (w the state's time), m/s, ping-pong.
    pub velocities: [BufferId; 2],
    /// Deepest penetration so far, m, as the bits of an `f32`.
    pub max_penetration: BufferId,
    /// With `SelfCollision`, the workgroups of its rebuild's passes, which the indirect
    /// dispatches read ([`crate::layout::REBUILD_PASSES`]).
    pub indirect: Option<BufferId>,
    /// With `SelfCollision`, its [`GpuSelfControl`].
    pub self_control: Option<BufferId>,
    /// With VBD, the velocities at the start of the last substep (its adaptive
    /// initialisation's), which a state written from the host resets to a substep of free fall.
    pub vbd_last_velocities: Option<BufferId>,
    /// With backward Euler, its conjugate gradients' [`GpuCgCounters`] (what the solver spent).
    pub cg_counters: Option<BufferId>,
}

/// Everything a backend creates for a simulation, and the schedule of its frames.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Plan {
    /// Buffers.
    pub buffers: Vec<BufferDesc>,
    /// Kernels.
    pub kernels: Vec<KernelDesc>,
    /// Pipelines.
    pub pipelines: Vec<PipelineDesc>,
    /// Bind groups.
    pub bind_groups: Vec<BindGroupDesc>,
    /// The dispatches of a frame.
    pub schedule: Schedule,
    /// The state's buffers.
    pub state: StateBuffers,
}

const READ: Binding = Binding::Storage { read_only: true };
const WRITE: Binding = Binding::Storage { read_only: false };
const PARAMS: Binding = Binding::Uniform { size: size_of::<GpuSimParams>() as u64, dynamic: false };
const COLOR_RANGE: Binding = Binding::Uniform { size: size_of::<GpuColorRange>() as u64, dynamic: true };
/// The colliders: a uniform block of [`MAX_COLLIDERS`] ([`GpuCollider::of_scene`]).
const COLLIDERS: Binding = Binding::Uniform { size: (size_of::<GpuCollider>() * MAX_COLLIDERS) as u64, dynamic: false };

/// The bindings 0-6 of both force kernels: the parameters, the colliders, positions and velocities
/// in, positions and velocities out, the deepest penetration.
const STATE_BINDINGS: [Binding; 7] = [PARAMS, COLLIDERS, READ, READ, WRITE, WRITE, WRITE];

/// `cloth_step`'s bindings 7-12: RK4's scratch, the packed `(x, v.x)` and `(v.y, v.z)` in, the
/// same out, the pin bits.
const STEP_EXTRA_BINDINGS: [Binding; 6] = [WRITE, READ, READ, WRITE, WRITE, READ];

/// The mesh colliders' distance fields: the last binding of the tiled and XPBD kernels, binding
/// 13 of `cloth_step`.
const DISTANCE_FIELDS: Binding = READ;

/// Self-collision's buffers as the force kernels bind them: the candidate lists and the hash
/// ([`SelfHashTable`]), read; the [`GpuSelfControl`], whose box of displacements the substeps
/// raise.
const SELF_COLLISION: [Binding; 3] = [READ, READ, WRITE];

/// `self_hash`'s bindings: the parameters, the positions it lists, the hash written (the insert
/// pass), the hash read (the candidates pass), the candidate lists, the control, the rebuild's
/// workgroups (the check's). Each pass binds placeholders where another pass's buffer goes: a
/// dispatch may not bind one buffer for writing and for reading, nor for writing and as its size.
const SELF_HASH_BINDINGS: [Binding; 7] = [PARAMS, READ, WRITE, READ, WRITE, WRITE, WRITE];

/// `xpbd`'s bindings: parameters, colliders, constraints, positions and velocities in, positions
/// and velocities out, the deepest penetration, the multipliers, the normal corrections, the
/// colour range (a block of the colour-range buffer, chosen by a dynamic offset), the distance
/// fields, self-collision's corrections, then its buffers ([`SELF_COLLISION`]).
const XPBD_BINDINGS: [Binding; 16] = [
    PARAMS,
    COLLIDERS,
    READ,
    READ,
    READ,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    COLOR_RANGE,
    DISTANCE_FIELDS,
    WRITE,
    SELF_COLLISION[0],
    SELF_COLLISION[1],
    SELF_COLLISION[2],
];

/// `vbd`'s bindings: parameters, colliders, positions and velocities in, positions and velocities
/// out, the deepest penetration, the inertial predictions, the last substep's velocities,
/// Chebyshev's history, the sweep (a block of the sweeps' buffer, chosen by a dynamic offset), the
/// distance fields, self-collision's buffers ([`SELF_COLLISION`]), then the multigrid
/// correction's levels ([`MultigridLevels`]; a placeholder without it).
const VBD_BINDINGS: [Binding; 16] = [
    PARAMS,
    COLLIDERS,
    READ,
    READ,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    Binding::Uniform { size: size_of::<GpuVbdSweep>() as u64, dynamic: true },
    DISTANCE_FIELDS,
    SELF_COLLISION[0],
    SELF_COLLISION[1],
    SELF_COLLISION[2],
    WRITE,
];

/// `implicit`'s bindings: parameters, colliders, positions and velocities in, the iterate (and
/// then the new state) out, the deepest penetration, CG's vectors, the vertices' blocks, the
/// partial sums, the counters, the iterations' steps, the iteration (a block of the iterations'
/// buffer, chosen by a dynamic offset), the distance fields, then self-collision's buffers
/// ([`SELF_COLLISION`]).
const IMPLICIT_BINDINGS: [Binding; 17] = [
    PARAMS,
    COLLIDERS,
    READ,
    READ,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    WRITE,
    Binding::Uniform { size: size_of::<GpuCgStep>() as u64, dynamic: true },
    DISTANCE_FIELDS,
    SELF_COLLISION[0],
    SELF_COLLISION[1],
    SELF_COLLISION[2],
];

const NAME: [&str; 2] = ["A", "B"];

/// Collects the plan's objects.
struct Builder<'a> {
    plan: Plan,
    scene: &'a Scene,
    tuning: &'a GpuTuning,
    limits: &'a DeviceLimits,
}

impl Builder<'_> {
    fn buffer(&mut self, label: &str, usage: BufferUsage, size: u64, contents: Option<Vec<u8>>) -> BufferId {
        self.plan.buffers.push(BufferDesc { label: format!("cloth {label}"), usage, size: size.max(4), contents });
        self.plan.buffers.len() - 1
    }

    fn filled(&mut self, label: &str, usage: BufferUsage, contents: &[u8]) -> BufferId {
        self.buffer(label, usage, contents.len() as u64, Some(contents.to_vec()))
    }

    fn kernel(&mut self, shader: Shader, bindings: &[Binding]) -> KernelId {
        self.plan.kernels.push(KernelDesc { shader, bindings: bindings.to_vec() });
        self.plan.kernels.len() - 1
    }

    /// A pipeline with the scene's effects, the workgroup size (but for the tiled kernel, whose
    /// workgroup is its tile) and the kernel's own constants; the hash's kernel takes its own
    /// constants only (no effect applies to it, and its workgroup is its scan's block).
    fn pipeline(&mut self, kernel: KernelId, label: &str, own: &[(Constant, u32)]) -> PipelineId {
        if self.plan.kernels[kernel].shader == Shader::SelfHash {
            let constants = own.to_vec();
            self.plan.pipelines.push(PipelineDesc {
                kernel,
                name: label.into(),
                label: format!("cloth {label} pipeline"),
                constants,
            });
            return self.plan.pipelines.len() - 1;
        }
        let mut constants: Vec<(Constant, u32)> =
            Effect::ALL.iter().map(|&e| (Constant::Effect(e), u32::from(self.scene.effects.contains(e)))).collect();
        constants.extend(
            ColliderKind::ALL.iter().map(|&k| (Constant::Collider(k), u32::from(has_collider_kind(self.scene, k)))),
        );
        if !matches!(self.plan.kernels[kernel].shader, Shader::Tiled(_)) {
            constants.push((Constant::WorkgroupSize, self.tuning.workgroup_size));
        }
        constants.extend_from_slice(own);
        self.plan.pipelines.push(PipelineDesc {
            kernel,
            name: label.into(),
            label: format!("cloth {label} pipeline"),
            constants,
        });
        self.plan.pipelines.len() - 1
    }

    fn group(&mut self, kernel: KernelId, label: String, buffers: Vec<BufferId>) -> BindGroupId {
        self.plan.bind_groups.push(BindGroupDesc { kernel, label: format!("cloth {label}"), buffers });
        self.plan.bind_groups.len() - 1
    }
}

impl Plan {
    /// The plan of `scene` on a device with `limits`, as `tuning` asks, for the backend named
    /// `backend`.
    ///
    /// # Errors
    /// [`SimError::InvalidOption`] for a tuning value that is wrong or that the device cannot
    /// run, [`SimError::TooLarge`] when a buffer exceeds the device's storage bindings,
    /// [`SimError::Unsupported`] when the device allows a kernel too few storage buffers.
    pub fn new(
        scene: &Scene,
        tuning: &GpuTuning,
        limits: &DeviceLimits,
        backend: &'static str,
    ) -> Result<Self, SimError> {
        tuning.check()?;
        if tuning.workgroup_size > limits.max_invocations {
            let allowed = format!("at most the {} invocations the device allows a workgroup", limits.max_invocations);
            return Err(invalid("GpuTuning::workgroup_size", tuning.workgroup_size, allowed));
        }
        crate::memory::check_fits(scene, limits.max_storage_binding, "storage buffer (the device's largest binding)")?;
        let model = ClothModel::new(scene);
        let v0 = scene.cloth.initial_velocity.map(|x| x as f32);
        let grid = &model.grid;
        // w: 1 free, minus the pin group pinned (the kernels' pin_group).
        let positions: Vec<[f32; 4]> = (grid.positions.iter().zip(&grid.pinned).zip(&grid.pin_group))
            .map(|((p, &pinned), &group)| {
                [p[0] as f32, p[1] as f32, p[2] as f32, if pinned { -f32::from(group) } else { 1.0 }]
            })
            .collect();
        let velocities: Vec<[f32; 4]> =
            grid.pinned.iter().map(|&pinned| if pinned { [0.0; 4] } else { [v0[0], v0[1], v0[2], 0.0] }).collect();
        let mut b = Builder { plan: Plan::default(), scene, tuning, limits };
        let (storage, drawable) = (BufferUsage::Storage, BufferUsage::StorageDrawable);
        let state = StateBuffers {
            params: b.filled("params", BufferUsage::Uniform, bytemuck::bytes_of(&GpuSimParams::of(scene))),
            colliders: b.filled("colliders", BufferUsage::Uniform, bytemuck::cast_slice(&GpuCollider::of_scene(scene))),
            distance_fields: b.filled(
                "distance fields",
                storage,
                bytemuck::cast_slice(&GpuCollider::distance_fields_of(scene)),
            ),
            positions: NAME.map(|n| b.filled(&format!("positions {n}"), drawable, bytemuck::cast_slice(&positions))),
            velocities: NAME.map(|n| b.filled(&format!("velocities {n}"), storage, bytemuck::cast_slice(&velocities))),
            max_penetration: b.buffer("max penetration", storage, 4, None),
            indirect: None,
            self_control: None,
            vbd_last_velocities: None,
            cg_counters: None,
        };
        b.plan.state = state;
        b.plan.schedule = match scene.integrator {
            Integrator::Xpbd => xpbd(&mut b, &model, limits),
            Integrator::Vbd => vbd(&mut b, &velocities, limits),
            Integrator::BackwardEuler => backward_euler(&mut b, limits),
            _ => force_based(&mut b, &positions, &velocities, limits)?,
        };
        let plan = b.plan;
        for kernel in &plan.kernels {
            let needed = kernel.bindings.iter().filter(|x| matches!(x, Binding::Storage { .. })).count() as u32;
            if needed > limits.storage_buffers_per_stage {
                return Err(SimError::Unsupported {
                    backend,
                    what: format!(
                        "devices that allow fewer than {needed} storage buffers per kernel (this one allows {})",
                        limits.storage_buffers_per_stage
                    ),
                    fix: "use another adapter, or the cpu backend".into(),
                });
            }
        }
        Ok(plan)
    }
}

/// Semi-implicit Euler, velocity Verlet and RK4 (`cloth_step`, and `cloth_step_tiled`).
fn force_based(
    b: &mut Builder,
    positions: &[[f32; 4]],
    velocities: &[[f32; 4]],
    limits: &DeviceLimits,
) -> Result<Schedule, SimError> {
    let (scene, tuning) = (b.scene, b.tuning);
    let [nx, ny] = scene.cloth.resolution;
    let n = positions.len() as u64;
    let storage = BufferUsage::Storage;
    let s = b.plan.state;
    let (p, v) = (s.positions, s.velocities);
    // Self-collision reads other vertices anywhere in the grid and the hash of the vec4 state: it
    // runs neither tiled nor on the packed state.
    let self_collision = scene.effects.contains(Effect::SelfCollision);
    let tile = if self_collision { None } else { TileConfig::choose(tuning, scene.integrator, nx * ny, limits)? };
    let self_buffers = self_collision_buffers(b);
    let rk4 = scene.integrator == Integrator::RungeKutta4;
    let rk4_scratch = b.buffer("RK4 scratch", storage, if rk4 { 64 * n } else { 64 }, None);
    // Placeholders for the packed bindings of the passes that do not use them: a read-only one,
    // and one for each written binding (a binding must not alias another of the same dispatch).
    let read = b.buffer("packed-state placeholder, read", storage, 64, None);
    let xv_out = b.buffer("packed-state placeholder, (x, v.x) out", storage, 64, None);
    let v_out = b.buffer("packed-state placeholder, (v.y, v.z) out", storage, 64, None);
    let unpacked = [read, read, xv_out, v_out, read];
    let kernel = b.kernel(
        Shader::Step,
        &[STATE_BINDINGS.as_slice(), &STEP_EXTRA_BINDINGS, &[DISTANCE_FIELDS], &SELF_COLLISION].concat(),
    );
    let blocks = BlockGrid::new(tuning, nx, ny, limits.max_workgroups_per_dimension);
    let w = blocks.width;
    let common = [s.params, s.colliders];
    let group = |b: &mut Builder, label: String, [x_in, v_in, x_out, v_out]: [BufferId; 4], packed: [BufferId; 5]| {
        let buffers = [
            &common[..],
            &[x_in, v_in, x_out, v_out, s.max_penetration, rk4_scratch],
            &packed[..],
            &[s.distance_fields],
            &self_buffers.bound(),
        ]
        .concat();
        b.group(kernel, label, buffers)
    };
    let pass = |pipeline, groups| Pass {
        pipeline,
        groups,
        workgroups: blocks.workgroups,
        dynamic_offset: None,
        indirect: None,
    };
    let step = |stage: u32| [(Constant::Stage, stage), (Constant::BlockWidth, w)];
    let mut schedule = Schedule::default();
    match scene.integrator {
        Integrator::SemiImplicitEuler => {
            let groups = [0, 1].map(|k| {
                group(b, format!("substep {} -> {}", NAME[k], NAME[1 - k]), [p[k], v[k], p[1 - k], v[1 - k]], unpacked)
            });
            let pipeline = b.pipeline(kernel, "Euler substep", &step(0));
            schedule.substep.push(pass(pipeline, groups));
            if let Some(tile) = tile {
                let tiled = b.kernel(Shader::Tiled(tile), &[STATE_BINDINGS.as_slice(), &[DISTANCE_FIELDS]].concat());
                let constants = [
                    (Constant::TileWidth, tile.width),
                    (Constant::TileHeight, tile.height),
                    (Constant::TileCells, tile.cells()),
                    (Constant::FusedSubsteps, tile.substeps),
                ];
                let pipeline = b.pipeline(tiled, "tiled Euler substeps", &constants);
                let groups = [0, 1].map(|k| {
                    let buffers = vec![
                        s.params,
                        s.colliders,
                        p[k],
                        v[k],
                        p[1 - k],
                        v[1 - k],
                        s.max_penetration,
                        s.distance_fields,
                    ];
                    b.group(tiled, format!("tiled substeps {} -> {}", NAME[k], NAME[1 - k]), buffers)
                });
                let workgroups = tile.workgroups(nx, ny);
                schedule.tiled = Some(TiledPass {
                    pass: Pass { pipeline, groups, workgroups, dynamic_offset: None, indirect: None },
                    substeps: tile.substeps,
                });
            } else if tuning.packed_state && !self_collision && scene.cloth.pin_groups.is_empty() {
                // (The packed state marks pins with one bit: it has no room for their groups.)
                schedule.packed = Some(packed(b, &group, kernel, w, blocks.workgroups, positions));
            }
        }
        Integrator::VelocityVerlet => {
            // The half-step velocities, and a sink for the positions the second kick does not
            // write.
            let v_half = b.filled("velocities (Verlet half step)", storage, bytemuck::cast_slice(velocities));
            let sink = b.buffer("positions sink (Verlet second kick)", storage, 16, None);
            let first = [0, 1].map(|k| {
                group(
                    b,
                    format!("Verlet kick and drift {} -> {}", NAME[k], NAME[1 - k]),
                    [p[k], v[k], p[1 - k], v_half],
                    unpacked,
                )
            });
            let second = [0, 1].map(|k| {
                group(b, format!("Verlet second kick -> {}", NAME[1 - k]), [p[1 - k], v_half, sink, v[1 - k]], unpacked)
            });
            let kick_drift = b.pipeline(kernel, "Verlet kick and drift", &step(1));
            let kick = b.pipeline(kernel, "Verlet second kick", &step(2));
            schedule.substep = vec![pass(kick_drift, first), pass(kick, second)];
        }
        _ => {
            // RK4's stage states alternate between a scratch state S and the output 1 - k:
            // k -> S -> 1-k -> S -> 1-k. S starts as the initial state, so its w (free or pinned)
            // is right from the first stage.
            let s_x = b.filled("RK4 stage positions", storage, bytemuck::cast_slice(positions));
            let s_v = b.filled("RK4 stage velocities", storage, bytemuck::cast_slice(velocities));
            for stage in 1..=4u32 {
                let groups = [0, 1].map(|k| {
                    let buffers = match stage {
                        1 => [p[k], v[k], s_x, s_v],
                        3 => [p[1 - k], v[1 - k], s_x, s_v],
                        _ => [s_x, s_v, p[1 - k], v[1 - k]],
                    };
                    group(b, format!("RK4 stage {stage} (state {})", NAME[k]), buffers, unpacked)
                });
                let pipeline = b.pipeline(kernel, &format!("RK4 stage {stage}"), &step(2 + stage));
                schedule.substep.push(pass(pipeline, groups));
            }
        }
    }
    if self_collision {
        schedule.self_collision = Some(self_collision_checks(b, &self_buffers));
    }
    Ok(schedule)
}

/// Self-collision's buffers the force kernels bind ([`SelfHashTable`], [`GpuSelfControl`]), sized
/// for the scene with `SelfCollision` and placeholders without.
struct SelfCollisionBuffers {
    /// The candidate lists.
    words: BufferId,
    /// The hash.
    links: BufferId,
    /// The control.
    control: BufferId,
}

impl SelfCollisionBuffers {
    /// The buffers of [`SELF_COLLISION`], in binding order.
    fn bound(&self) -> [BufferId; 3] {
        [self.words, self.links, self.control]
    }
}

fn self_collision_buffers(b: &mut Builder) -> SelfCollisionBuffers {
    let storage = BufferUsage::Storage;
    if !b.scene.effects.contains(Effect::SelfCollision) {
        let control = size_of::<GpuSelfControl>() as u64;
        return SelfCollisionBuffers {
            words: b.buffer("self-collision lists placeholder", storage, 16, None),
            links: b.buffer("self-collision hash placeholder", storage, 16, None),
            control: b.buffer("self-collision control placeholder", storage, control, None),
        };
    }
    let table = SelfHashTable::of(b.scene);
    let full = HashPass::rebuild(b.scene.vertex_count(), b.tuning.candidate_listing).map(|pass| {
        let [x, y] = self_hash_workgroups(b, pass);
        [x, y, 1, 0]
    });
    let control = GpuSelfControl { full, ..Default::default() };
    SelfCollisionBuffers {
        words: b.buffer("self-collision candidate lists", storage, 4 * table.list_words, None),
        links: b.filled("self-collision hash", storage, bytemuck::cast_slice(&table.initial_links())),
        control: b.filled("self-collision control", storage, bytemuck::bytes_of(&control)),
    }
}

/// The workgroups of a rebuild pass of `self_hash`: one invocation a vertex (the candidates pass
/// a [`LISTING_BLOCK`]² block of the grid a workgroup), or [`LISTING_VERTICES`] vertices a
/// workgroup when the candidates are listed in lanes.
fn self_hash_workgroups(b: &Builder, pass: HashPass) -> [u32; 2] {
    let n = b.scene.vertex_count() as u32;
    let max = b.limits.max_workgroups_per_dimension;
    match pass {
        HashPass::CandidatesInLanes => spilled_workgroups(n, LISTING_VERTICES, max),
        HashPass::Candidates => {
            // A workgroup a square block of the grid (LISTING_BLOCK).
            let [nx, ny] = b.scene.cloth.resolution;
            spilled_workgroups(nx.div_ceil(LISTING_BLOCK) * ny.div_ceil(LISTING_BLOCK), 1, max)
        }
        _ => spilled_workgroups(n, SELF_HASH_WORKGROUP, max),
    }
}

/// Self-collision's check (one workgroup) and the rebuild's indirect passes, reading state `k`'s
/// positions (`self_hash`), with the buffer of the rebuild's workgroups and the placeholders the
/// passes bind where another pass's buffer goes (no binding of a dispatch may alias another).
fn self_collision_checks(b: &mut Builder, buffers: &SelfCollisionBuffers) -> SelfCollisionChecks {
    let kernel = b.kernel(Shader::SelfHash, &SELF_HASH_BINDINGS);
    let s = b.plan.state;
    let bytes = (REBUILD_PASSES * size_of::<[u32; 4]>()) as u64;
    let workgroups = b.buffer("self-collision rebuild workgroups", BufferUsage::StorageIndirect, bytes, None);
    let [written, read, sizes] = ["hash written", "hash read", "workgroups"]
        .map(|what| b.buffer(&format!("self-collision placeholder ({what})"), BufferUsage::Storage, bytes, None));
    // Per pass: the hash written, the hash read, the rebuild's workgroups.
    let groups = |b: &mut Builder, which: HashPass, [written, read, dispatch]: [BufferId; 3]| {
        [0, 1].map(|k| {
            let (p, c) = (s.positions[k], buffers.control);
            let bound = vec![s.params, p, written, read, buffers.words, c, dispatch];
            b.group(kernel, format!("self-collision {} of {}", which.label(), NAME[k]), bound)
        })
    };
    let checks = groups(b, HashPass::Check, [written, read, workgroups]);
    let inserts = groups(b, HashPass::Insert, [buffers.links, read, sizes]);
    let rebuild_passes = HashPass::rebuild(b.scene.vertex_count(), b.tuning.candidate_listing);
    let candidates = groups(b, rebuild_passes[1], [written, buffers.links, sizes]);
    b.plan.state.indirect = Some(workgroups);
    b.plan.state.self_control = Some(buffers.control);
    let pass = |b: &mut Builder, which: HashPass, groups, indirect: Option<u64>| {
        let label = format!("self-collision {}", which.label());
        let pipeline = b.pipeline(kernel, &label, &[(Constant::HashPass, which as u32)]);
        // (An indirect pass's workgroups are the most the check writes: a rebuild's.)
        let workgroups = if indirect.is_some() { self_hash_workgroups(b, which) } else { [1, 1] };
        Pass { pipeline, groups, workgroups, dynamic_offset: None, indirect }
    };
    let check = pass(b, HashPass::Check, checks, None);
    let forced = pass(b, HashPass::ForcedCheck, checks, None);
    let rebuild = (rebuild_passes.iter().enumerate())
        .map(|(k, &which)| {
            let groups = if which == HashPass::Insert { inserts } else { candidates };
            pass(b, which, groups, Some((k * size_of::<[u32; 4]>()) as u64))
        })
        .collect();
    let interval = cloth_core::self_collision::SelfCollisionQuantities::of(b.scene).check_interval.max(1);
    SelfCollisionChecks { check, forced, rebuild, interval }
}

/// Semi-implicit Euler's packed passes (`geometry`'s packed state).
fn packed(
    b: &mut Builder,
    group: &impl Fn(&mut Builder, String, [BufferId; 4], [BufferId; 5]) -> BindGroupId,
    kernel: KernelId,
    width: u32,
    workgroups: [u32; 2],
    positions: &[[f32; 4]],
) -> PackedPasses {
    let storage = BufferUsage::Storage;
    let [xv_bytes, v_bytes] = geometry::packed_buffer_bytes(positions.len() as u64);
    let xv = NAME.map(|n| b.buffer(&format!("packed (x, v.x) {n}"), storage, xv_bytes, None));
    let pv = NAME.map(|n| b.buffer(&format!("packed (v.y, v.z) and time {n}"), storage, v_bytes, None));
    let pins = b.filled("pin bits", storage, bytemuck::cast_slice(&geometry::pin_bits(positions)));
    let alternate = width > 0 && geometry::alternates_order(b.tuning.block_order, positions.len() as u64);
    let pipeline = |b: &mut Builder, label: &str, packed_in: u32, packed_out: u32, reversed: bool| {
        let constants = [
            (Constant::Stage, 0),
            (Constant::BlockWidth, width),
            (Constant::PackedIn, packed_in),
            (Constant::PackedOut, packed_out),
            (Constant::ReversedOrder, u32::from(reversed)),
        ];
        let label = if reversed {
            format!("Euler substep, {label}, blocks backward")
        } else {
            format!("Euler substep, {label}")
        };
        b.pipeline(kernel, &label, &constants)
    };
    let first_pipeline = pipeline(b, "vec4 -> packed", 0, 1, false);
    let both = |b: &mut Builder, label: &str, packed_in: u32, packed_out: u32| {
        let forward = pipeline(b, label, packed_in, packed_out, false);
        [forward, if alternate { pipeline(b, label, packed_in, packed_out, true) } else { forward }]
    };
    let middle_pipelines = both(b, "packed -> packed", 1, 1);
    let last_pipelines = both(b, "packed -> vec4", 1, 0);
    let s = b.plan.state;
    let (p, v) = (s.positions, s.velocities);
    // Packed state m in, 1 - m out; the vec4 bindings a pass does not use hold state buffers it
    // does not touch either.
    let io = |m: usize| [xv[m], pv[m], xv[1 - m], pv[1 - m], pins];
    let vec4 = |k: usize| [p[k], v[k], p[1 - k], v[1 - k]];
    // `first` writes packed state A, reading nothing packed (B sits in the input bindings).
    let first = [0, 1].map(|k| group(b, format!("packed substep {} -> packed A", NAME[k]), vec4(k), io(1)));
    let middle = [0, 1]
        .map(|m| group(b, format!("packed substep packed {} -> packed {}", NAME[m], NAME[1 - m]), vec4(0), io(m)));
    let last = [0, 1].map(|k| {
        [0, 1].map(|m| group(b, format!("packed substep packed {} -> {}", NAME[m], NAME[1 - k]), vec4(k), io(m)))
    });
    PackedPasses { first_pipeline, middle_pipelines, last_pipelines, first, middle, last, workgroups }
}

/// XPBD (`xpbd`): predict; per iteration one dispatch per non-empty colour, one for the
/// self-contacts (with `SelfCollision`) and one for the colliders (with `Contact` or
/// `SelfCollision`, whose speed limit it applies); finish.
fn xpbd(b: &mut Builder, model: &ClothModel, limits: &DeviceLimits) -> Schedule {
    let (scene, storage) = (b.scene, BufferUsage::Storage);
    let colors = model.spring_colors();
    let mut constraints: Vec<GpuConstraint> = (colors.order.iter().map(|&i| &model.springs[i as usize]))
        .map(|s| GpuConstraint { a: s.a, b: s.b, kind: s.kind as u32, rest_length: s.rest_length as f32 })
        .collect();
    if constraints.is_empty() {
        constraints.push(GpuConstraint::default());
    }
    let range = |color: usize, iteration: u32| GpuColorRange {
        first: colors.first[color],
        count: colors.first[color + 1] - colors.first[color],
        first_iteration: u32::from(iteration == 0),
        pad: 0,
    };
    let mut ranges = vec![0u8; 2 * COLOR_COUNT * COLOR_RANGE_STRIDE as usize];
    for (iteration, color) in [0, 1].into_iter().flat_map(|i| (0..COLOR_COUNT).map(move |c| (i, c))) {
        let at = GpuColorRange::offset(color, iteration) as usize;
        ranges[at..at + size_of::<GpuColorRange>()].copy_from_slice(bytemuck::bytes_of(&range(color, iteration)));
    }
    let n = model.vertex_count() as u64;
    let constraint_buffer = b.filled("XPBD constraints", storage, bytemuck::cast_slice(&constraints));
    let lambdas = b.buffer("XPBD multipliers", storage, 4 * constraints.len() as u64, None);
    let corrections = b.buffer("XPBD normal corrections", storage, 4 * n, None);
    let range_buffer = b.filled("XPBD colour ranges", BufferUsage::Uniform, &ranges);
    let self_collision = scene.effects.contains(Effect::SelfCollision);
    let self_buffers = self_collision_buffers(b);
    let self_corrections =
        b.buffer("XPBD self-contact corrections", storage, if self_collision { 16 * n } else { 16 }, None);
    let kernel = b.kernel(Shader::Xpbd, &XPBD_BINDINGS);
    let s = b.plan.state;
    let groups = [0, 1].map(|k| {
        let (p, v) = (s.positions, s.velocities);
        let buffers = vec![s.params, s.colliders, constraint_buffer, p[k], v[k], p[1 - k], v[1 - k]];
        let buffers = [
            buffers,
            vec![s.max_penetration, lambdas, corrections, range_buffer, s.distance_fields, self_corrections],
            self_buffers.bound().to_vec(),
        ]
        .concat();
        b.group(kernel, format!("XPBD {} -> {}", NAME[k], NAME[1 - k]), buffers)
    });
    let pipelines = ["predict", "project one colour", "project the colliders", "finish", "self-contacts"]
        .iter()
        .enumerate()
        .map(|(pass, what)| b.pipeline(kernel, &format!("XPBD {what}"), &[(Constant::XpbdPass, pass as u32)]))
        .collect::<Vec<_>>();
    let (threads, max) = (b.tuning.workgroup_size, limits.max_workgroups_per_dimension);
    let vertices = spilled_workgroups(n as u32, threads, max);
    let pass = |pipeline: usize, workgroups, offset| Pass {
        pipeline: pipelines[pipeline],
        groups,
        workgroups,
        dynamic_offset: Some(offset),
        indirect: None,
    };
    let mut substep = vec![pass(0, vertices, 0)];
    let contact = scene.effects.contains(Effect::Contact) && !scene.colliders.is_empty();
    for iteration in 0..XPBD_ITERATIONS {
        for color in 0..COLOR_COUNT {
            let count = range(color, iteration).count;
            if count > 0 {
                substep.push(pass(1, spilled_workgroups(count, threads, max), GpuColorRange::offset(color, iteration)));
            }
        }
        if self_collision {
            substep.push(pass(4, vertices, 0));
        }
        if contact || self_collision {
            substep.push(pass(2, vertices, 0));
        }
    }
    substep.push(pass(3, vertices, 0));
    let checks = self_collision.then(|| self_collision_checks(b, &self_buffers));
    Schedule { substep, tiled: None, packed: None, self_collision: checks }
}

/// Vertex Block Descent (`vbd`): predict; per sweep one dispatch per vertex colour; finish. The
/// last substep's velocities start as a substep of free fall before the initial ones (the
/// reference's `assume_free_fall`).
fn vbd(b: &mut Builder, velocities: &[[f32; 4]], limits: &DeviceLimits) -> Schedule {
    let (scene, storage) = (b.scene, BufferUsage::Storage);
    let n = velocities.len() as u64;
    let solver = scene.solver;
    let q = cloth_core::SceneQuantities::of(scene);
    let hg = q.gravity.map(|g| (g * q.substep_dt) as f32);
    let last: Vec<[f32; 4]> = velocities.iter().map(|v| [v[0] - hg[0], v[1] - hg[1], v[2] - hg[2], 0.0]).collect();
    let predicted = b.buffer("VBD inertial predictions", storage, 16 * n, None);
    let last_velocities = b.filled("VBD last substep's velocities", storage, bytemuck::cast_slice(&last));
    let chebyshev = solver.chebyshev_rho > 0.0;
    let history = b.buffer("VBD Chebyshev history", storage, if chebyshev { 32 * n } else { 16 }, None);
    let [nx, ny] = scene.cloth.resolution;
    let multigrid = (solver.vbd_multigrid_every > 0).then(|| MultigridLevels::new(nx, ny, b.tuning.workgroup_size));
    let sweeps = b.filled("VBD sweeps", BufferUsage::Uniform, &GpuVbdSweep::blocks(&solver, multigrid.as_ref()));
    let levels_bytes = multigrid.as_ref().map_or(16, |m| 16 * m.vec4s);
    let levels = b.buffer("VBD multigrid levels", storage, levels_bytes, None);
    let self_collision = scene.effects.contains(Effect::SelfCollision);
    let self_buffers = self_collision_buffers(b);
    let kernel = b.kernel(Shader::Vbd, &VBD_BINDINGS);
    let s = b.plan.state;
    b.plan.state.vbd_last_velocities = Some(last_velocities);
    let groups = [0, 1].map(|k| {
        let (p, v) = (s.positions, s.velocities);
        let buffers = [
            vec![s.params, s.colliders, p[k], v[k], p[1 - k], v[1 - k], s.max_penetration],
            vec![predicted, last_velocities, history, sweeps, s.distance_fields],
            self_buffers.bound().to_vec(),
            vec![levels],
        ]
        .concat();
        b.group(kernel, format!("VBD {} -> {}", NAME[k], NAME[1 - k]), buffers)
    });
    let predict = b.pipeline(kernel, "VBD predict", &[(Constant::VbdPass, 0), (Constant::VbdColor, 0)]);
    let colors: Vec<PipelineId> = (0..VERTEX_COLOR_COUNT as u32)
        .map(|c| {
            let constants = [(Constant::VbdPass, 1), (Constant::VbdColor, c)];
            b.pipeline(kernel, &format!("VBD colour {c}"), &constants)
        })
        .collect();
    let finish = b.pipeline(kernel, "VBD finish", &[(Constant::VbdPass, 2), (Constant::VbdColor, 0)]);
    let (threads, max) = (b.tuning.workgroup_size, limits.max_workgroups_per_dimension);
    let vertices = spilled_workgroups(n as u32, threads, max);
    // A colour pass: one invocation for every fifth vertex of each row.
    let per_color = spilled_workgroups(nx.div_ceil(VERTEX_COLOR_COUNT as u32) * ny, threads, max);
    let pass = |pipeline, workgroups, offset| Pass {
        pipeline,
        groups,
        workgroups,
        dynamic_offset: Some(offset),
        indirect: None,
    };
    let correction = multigrid.map(|m| {
        let mut named = |name: &str, pass: u32, color: u32| {
            let constants = [(Constant::VbdPass, pass), (Constant::VbdColor, color)];
            b.pipeline(kernel, &format!("VBD multigrid {name}"), &constants)
        };
        let pipelines = MultigridPipelines {
            assemble: named("assemble", 3, 0),
            coarsen: named("coarsen", 4, 0),
            smooth: [0, 1, 2, 3].map(|c| named(&format!("smooth colour {c}"), 5, c)),
            restrict: named("restrict", 6, 0),
            model: named("model", 7, 0),
            prolong: named("prolong", 8, 0),
            apply: named("move", 9, 0),
        };
        multigrid_correction(&m, &pipelines, &solver, |pipeline, invocations, offset| {
            pass(pipeline, spilled_workgroups(invocations, threads, max), offset)
        })
    });
    let mut substep = vec![pass(predict, vertices, 0)];
    for sweep in 1..=solver.vbd_iterations {
        let every = solver.vbd_multigrid_every;
        if let Some(correction) = correction.as_ref().filter(|_| every > 0 && (sweep - 1) % every == 0) {
            substep.extend_from_slice(correction);
        }
        for &pipeline in &colors {
            substep.push(pass(pipeline, per_color, GpuVbdSweep::offset(sweep)));
        }
    }
    substep.push(pass(finish, vertices, 0));
    let checks = self_collision.then(|| self_collision_checks(b, &self_buffers));
    Schedule { substep, tiled: None, packed: None, self_collision: checks }
}

/// The pipelines of VBD's multigrid correction (`vbd.wgsl`'s passes 3 to 9).
struct MultigridPipelines {
    assemble: PipelineId,
    coarsen: PipelineId,
    smooth: [PipelineId; 4],
    restrict: PipelineId,
    model: PipelineId,
    prolong: PipelineId,
    apply: PipelineId,
}

/// One multigrid correction's passes, in the order `cloth_core::multigrid::v_cycle` and the
/// reference's coarse correction take them: assemble level 1, coarsen each level into the next,
/// then the V-cycle (on each level two smoothing sweeps, the next level's right-hand side, its
/// cycle, its step and prolongation, two sweeps; on the coarsest only the sweeps), the step of
/// level 1 and the vertices' move. `pass` makes a pass of a pipeline over that many invocations
/// with the level's dynamic offset.
fn multigrid_correction(
    m: &MultigridLevels,
    p: &MultigridPipelines,
    solver: &cloth_core::solver::SolverSpec,
    pass: impl Fn(PipelineId, u32, u32) -> Pass,
) -> Vec<Pass> {
    let offset = |l: usize| GpuVbdSweep::level_offset(solver, l);
    let levels = &m.levels;
    let coarsest = levels.len() - 1;
    let mut passes = vec![pass(p.assemble, levels[1].nodes(), offset(0))];
    for l in 1..coarsest {
        passes.push(pass(p.coarsen, levels[l + 1].nodes(), offset(l)));
    }
    let smooth = |passes: &mut Vec<Pass>, l: usize| {
        let level = levels[l];
        // A colour (i mod 2, j mod 2) pass over every other node of every other row.
        let per_colour = level.nx.div_ceil(2) * level.ny.div_ceil(2);
        for _ in 0..cloth_core::multigrid::SMOOTHING_SWEEPS {
            for (c, &pipeline) in p.smooth.iter().enumerate() {
                if (c % 2 == 0 || level.nx > 1) && (c / 2 == 0 || level.ny > 1) {
                    passes.push(pass(pipeline, per_colour, offset(l)));
                }
            }
        }
    };
    for l in 1..coarsest {
        smooth(&mut passes, l);
        passes.push(pass(p.restrict, levels[l + 1].nodes(), offset(l)));
    }
    smooth(&mut passes, coarsest);
    for l in (1..coarsest).rev() {
        passes.push(pass(p.model, levels[l + 1].nodes(), offset(l + 1)));
        passes.push(pass(p.prolong, levels[l].nodes(), offset(l)));
        smooth(&mut passes, l);
    }
    passes.push(pass(p.model, levels[1].nodes(), offset(1)));
    passes.push(pass(p.apply, levels[0].nodes(), offset(0)));
    passes
}

/// The CG vectors a vertex keeps (`vec4` each, `implicit.wgsl` lists them): Δ, r, q, z = P r and
/// the search direction twice, since a pass reads the last iteration's while it writes the next.
pub const CG_VECTORS: u64 = 6;
/// Sections of backward Euler's partial sums, one `vec2` a workgroup each: the linearisation's
/// and the line search's, p·q of odd iterations, r·z and r·r, p·q of even iterations.
pub const CG_PARTIAL_SECTIONS: u64 = 4;

/// Backward Euler (`implicit`): start; per Newton iteration a linearisation, per CG iteration its
/// two passes (the previous iteration's end, its new direction and the product with A; the
/// update), the last iteration's end, the Newton update and, with the line search, two passes
/// (the slopes, the step) for each slope it measures; finish.
/// Every iteration's dispatches are recorded (a solve that is done skips their work): the frame
/// stays one submission with no host round trip.
fn backward_euler(b: &mut Builder, limits: &DeviceLimits) -> Schedule {
    let (scene, storage) = (b.scene, BufferUsage::Storage);
    let n = scene.vertex_count() as u64;
    let solver = scene.solver;
    let (threads, max) = (b.tuning.workgroup_size, limits.max_workgroups_per_dimension);
    let vertices = spilled_workgroups(n as u32, threads, max);
    let partial_count = n.div_ceil(u64::from(threads));
    let cg = b.buffer("backward Euler CG vectors", storage, CG_VECTORS * 16 * n, None);
    let blocks = b.buffer("backward Euler blocks", storage, 80 * n, None);
    let partials = b.buffer("backward Euler partial sums", storage, CG_PARTIAL_SECTIONS * 8 * partial_count, None);
    let counters = GpuCgCounters { tolerance: solver.cg_tolerance as f32, ..Default::default() };
    let counters = b.filled("backward Euler CG counters", storage, bytemuck::bytes_of(&counters));
    // The CG iterations' entries, then three for each slope the line search measures.
    let steps_len = u64::from(solver.cg_max_iterations) + 2 + 3 * u64::from(LINE_SEARCH_SLOPES);
    let steps = b.buffer("backward Euler CG steps", storage, 8 * steps_len, None);
    let blocks_len = solver.cg_max_iterations.max(LINE_SEARCH_SLOPES);
    let iterations = b.filled("backward Euler CG iterations", BufferUsage::Uniform, &GpuCgStep::blocks(blocks_len));
    let self_collision = scene.effects.contains(Effect::SelfCollision);
    let self_buffers = self_collision_buffers(b);
    let kernel = b.kernel(Shader::Implicit, &IMPLICIT_BINDINGS);
    let s = b.plan.state;
    b.plan.state.cg_counters = Some(counters);
    let groups = [0, 1].map(|k| {
        let (p, v) = (s.positions, s.velocities);
        let buffers = [
            vec![s.params, s.colliders, p[k], v[k], p[1 - k], v[1 - k], s.max_penetration],
            vec![cg, blocks, partials, counters, steps, iterations, s.distance_fields],
            self_buffers.bound().to_vec(),
        ]
        .concat();
        b.group(kernel, format!("backward Euler {} -> {}", NAME[k], NAME[1 - k]), buffers)
    });
    let names = [
        "start",
        "linearise (first iteration)",
        "linearise",
        "CG product (first iteration)",
        "CG direction and product",
        "CG update",
        "CG end (last iteration)",
        "Newton update",
        "finish",
        "line search slopes",
        "line search step",
    ];
    let pipelines: Vec<PipelineId> = (names.iter().enumerate())
        .map(|(pass, what)| {
            b.pipeline(kernel, &format!("backward Euler {what}"), &[(Constant::ImplicitPass, pass as u32)])
        })
        .collect();
    let pass = |pipeline: usize, offset| Pass {
        pipeline: pipelines[pipeline],
        groups,
        workgroups: vertices,
        dynamic_offset: Some(offset),
        indirect: None,
    };
    let mut substep = vec![pass(0, 0)];
    for newton in 0..solver.newton_iterations {
        substep.push(pass(if newton == 0 { 1 } else { 2 }, 0));
        for k in 1..=solver.cg_max_iterations {
            let offset = GpuCgStep::offset(k);
            substep.push(pass(if k == 1 { 3 } else { 4 }, offset));
            substep.push(pass(5, offset));
        }
        substep.push(pass(6, GpuCgStep::offset(solver.cg_max_iterations)));
        substep.push(pass(7, 0));
        if solver.line_search {
            for r in 1..=LINE_SEARCH_SLOPES {
                substep.push(pass(9, GpuCgStep::offset(r)));
                substep.push(pass(10, GpuCgStep::offset(r)));
            }
        }
    }
    substep.push(pass(8, 0));
    let checks = self_collision.then(|| self_collision_checks(b, &self_buffers));
    Schedule { substep, tiled: None, packed: None, self_collision: checks }
}
