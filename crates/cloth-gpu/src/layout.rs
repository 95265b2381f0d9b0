//! The structs the host shares with the shaders, each defined once here.
//!
//! Every type is `#[repr(C)]` and `bytemuck::Pod`, laid out for WGSL and GLSL `std140`/`std430`
//! (16-byte vectors first, uniform blocks a multiple of 16 bytes). Each shading language
//! declares them once (`shaders/wgsl/layout.wgsl`, `shaders/glsl/layout.glsl`), and a test
//! reflects every shader module that uses them against [`struct_layouts`], which `gpu_struct!`
//! generates from the Rust definitions below: a field added here and not in a shader fails it.
//!
//! The buffers of a simulation are listed by `plan.rs`; velocities carry the time of their state
//! in `w` (s), so moving pins, moving colliders and gusts know the time of each stage without a
//! host round trip.

use bytemuck::{Pod, Zeroable};
pub use cloth_core::colliders::MAX_COLLIDERS;
use cloth_core::{Scene, SceneQuantities};

/// The byte layout of one shared struct: its name in the shaders, its size and its fields.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StructLayout {
    /// Name of the struct in the shaders.
    pub shader_name: &'static str,
    /// Size in bytes.
    pub size: usize,
    /// `(field name, byte offset)` in declaration order; the shaders use the same names.
    pub fields: Vec<(&'static str, usize)>,
}

/// Declares a shared struct (`#[repr(C)]`, `Pod`) and its [`StructLayout`] from one definition.
macro_rules! gpu_struct {
    ($(#[$meta:meta])* $name:ident as $shader:literal { $($(#[$field_meta:meta])* $field:ident: $ty:ty,)* }) => {
        $(#[$meta])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
        pub struct $name {
            $($(#[$field_meta])* pub $field: $ty,)*
        }

        /// Every field zero (arrays of any length, which `derive(Default)` does not reach).
        impl Default for $name {
            fn default() -> Self {
                Zeroable::zeroed()
            }
        }

        impl $name {
            /// The struct's layout, for the shader reflection tests.
            pub fn layout() -> StructLayout {
                StructLayout {
                    shader_name: $shader,
                    size: size_of::<Self>(),
                    fields: vec![$((stringify!($field), std::mem::offset_of!(Self, $field)),)*],
                }
            }
        }
    };
}

gpu_struct! {
    /// Simulation parameters, one uniform buffer (656 bytes). Every field can change between
    /// frames without rebuilding a pipeline.
    GpuSimParams as "SimParams" {
        /// Gravitational acceleration, m/s² (xyz; w unused).
        gravity: [f32; 4],
        /// Spring stiffness `k`, N/m, indexed by `SpringKind` (w unused).
        stiffness: [f32; 4],
        /// Spring damping `c_d`, N·s/m, indexed by `SpringKind` (w unused).
        damping: [f32; 4],
        /// Mass of each vertex, kg.
        vertex_mass: f32,
        /// Substep length `Δt`, s.
        substep_dt: f32,
        /// Air-drag rate `γ`, 1/s.
        air_drag: f32,
        /// Number of vertices.
        vertex_count: u32,
        /// Number of colliders in the collider buffer that the kernels test.
        collider_count: u32,
        /// Grid vertices along u.
        grid_nx: u32,
        /// Grid vertices along v.
        grid_ny: u32,
        /// Effect bit mask, for diagnostics (the kernels branch on pipeline constants instead).
        effects: u32,
        /// Wind: mean velocity, m/s (xyz), and `w` = coefficient × area per vertex, N·s/m.
        wind: [f32; 4],
        /// Gusts: `x` relative amplitude, `y` angular frequency `2π / period`, rad/s.
        gust: [f32; 4],
        /// The pin groups' motions ([`PIN_MOTION_WORDS`] `vec4`s each, group `g` from
        /// `PIN_MOTION_WORDS · g`): steady velocity, m/s (xyz), and `w` the angular frequency,
        /// rad/s; amplitude, m (xyz); angular velocity, rad/s (xyz; zero: the group only
        /// translates); pivot, m (xyz). A pinned vertex's position `w` is minus its group.
        pin_motion: [[f32; 4]; 16],
        /// Rest lengths, m: structural along u, along v, shear (bend: exactly twice the
        /// structural ones). The kernels compute the springs from the grid with these.
        rest_lengths: [f32; 4],
        /// Self-collision: thickness `r`, m; stiffness `k_s`, N/m; damping `c_s`, N·s/m;
        /// friction `μ` (`cloth_core::self_collision`).
        self_contact: [f32; 4],
        /// Self-collision: the candidate window `r + W`, the cell side of the hash, m; the speed
        /// limit `s_max`, m/s; the grid spacing along u and v, m (the rest-distance filter).
        self_hash: [f32; 4],
        /// The hash in its buffer ([`SelfHashTable`]): buckets `T`, the index of the first
        /// record; unused, unused.
        self_table: [u32; 4],
        /// Self-collision's motion bound: each of `cloth_core::self_collision::MOTION_DIRECTIONS`
        /// (xyz) and the factor that turns the displacements' extent along it into a bound on
        /// two vertices' relative displacement, `sec θ / |u|` (w)
        /// (`cloth_core::self_collision::relative_motion_bound`).
        motion_directions: [[f32; 4]; MOTION_DIRECTIONS],
        /// Self-collision's checks: the margin less its rounding share, `(1 − 2⁻¹⁰) W`, m; the
        /// lookahead `L`, m; the substeps between two checks `C` (`cloth_core::self_collision`);
        /// unused.
        self_lists: [f32; 4],
    }
}

/// `vec4`s a pin group's motion takes in [`GpuSimParams::pin_motion`].
pub const PIN_MOTION_WORDS: usize = 4;

/// Where self-collision's candidate lists and spatial hash live.
///
/// The candidate lists, a `u32` buffer (the "words"): one candidate count a vertex, then
/// [`LIST_CAPACITY`] candidate slots a vertex, slot-major (slot `k` of vertex `i` at
/// `n (k + 1) + i`, so the invocations of a workgroup read consecutive words).
///
/// The hash, a `u32` buffer (the "links"): two tables of `T` bucket heads (the rebuilds alternate
/// between them: rebuild `m` fills table `m mod 2` and clears the other for the next), then one
/// 16-byte record a vertex: its position at the rebuild (the bits of three `f32`, m) and its link
/// (the vertex listed after it in its bucket). A bucket lists its vertices from its head through
/// the links; `u32::MAX` ends a list. A search reads a listed vertex's position and its link
/// together, one 16-byte load from one memory sector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SelfHashTable {
    /// Buckets `T`.
    pub buckets: u32,
    /// Index of the first record (a multiple of 4: 16-byte aligned).
    pub records: u32,
    /// Words of the hash.
    pub link_words: u64,
    /// Words of the candidate lists.
    pub list_words: u64,
}

impl SelfHashTable {
    /// The hash and lists of `scene`'s vertices.
    pub fn of(scene: &Scene) -> Self {
        let buckets = cloth_core::self_collision::SelfCollisionQuantities::of(scene).buckets.max(4);
        let n = scene.vertex_count() as u64;
        let records = (2 * buckets).next_multiple_of(4);
        Self { buckets, records, link_words: records as u64 + 4 * n, list_words: (1 + LIST_CAPACITY as u64) * n }
    }

    /// The hash's initial words: every head empty (`u32::MAX`), the records zero.
    pub fn initial_links(&self) -> Vec<u32> {
        let mut words = vec![0; self.link_words as usize];
        words[..2 * self.buckets as usize].fill(u32::MAX);
        words
    }
}

/// The most candidates a vertex keeps (`cloth_core::self_collision::LIST_CAPACITY`).
pub const LIST_CAPACITY: u32 = cloth_core::self_collision::LIST_CAPACITY;

/// Invocations the candidates pass gives a vertex of a small grid (fewer than
/// [`LISTING_IN_LANES_BELOW`] vertices), each walking every `LISTING_LANES`-th of the 27 cells
/// the vertex searches. Walking the buckets' lists is a chain of dependent reads, record after
/// record: with one invocation a vertex, a small grid's few invocations leave most of the GPU
/// waiting on them, and lanes walk a vertex's cells at once (docs/performance.md, "What
/// self-collision costs").
pub const LISTING_LANES: u32 = 9;

/// Vertices the candidates pass lists a workgroup (of [`crate::plan::SELF_HASH_WORKGROUP`]
/// invocations) on a small grid, [`LISTING_LANES`] invocations each.
pub const LISTING_VERTICES: u32 = crate::plan::SELF_HASH_WORKGROUP / LISTING_LANES;

/// The side of the square block of vertices a workgroup of the candidates pass lists with one
/// invocation a vertex ([`crate::plan::SELF_HASH_WORKGROUP`] = `LISTING_BLOCK²`). The searches of
/// a block's vertices walk overlapping cells, whose records the workgroup then reads from its
/// multiprocessor's cache; a workgroup that took a quarter of a 1024-vertex row walked cells
/// strung along 86 cells of the cloth (docs/performance.md, "What self-collision costs").
pub const LISTING_BLOCK: u32 = 16;

/// Grids of fewer vertices than this list their candidates in lanes ([`LISTING_LANES`]); larger
/// ones one invocation a vertex: 2¹⁸, about the invocations the H200's 132 multiprocessors hold at
/// once (2048 each).
pub const LISTING_IN_LANES_BELOW: u32 = 1 << 18;

/// The passes that rebuild the hash and the candidate lists, in order, each an indirect
/// dispatch: insert, candidates. The check writes their workgroups `(x, y, z, unused)` into a
/// buffer of their own, [`REBUILD_PASSES`] `uvec4`s, which only the check binds (a dispatch may
/// not read its size from a buffer it binds for writing).
pub const REBUILD_PASSES: usize = 2;

/// The copies of the extents of the displacements in [`GpuSelfControl::motion`]: each workgroup of a
/// substep's kernel raises the keys of copy `workgroup mod MOTION_COPIES`, so that the atomics of
/// thousands of workgroups do not all meet on 26 words.
pub const MOTION_COPIES: usize = 64;

/// The directions along which the substeps measure the extent of their displacements
/// (`cloth_core::self_collision::MOTION_DIRECTIONS`); each copy in [`GpuSelfControl::motion`]
/// keeps a highest and a lowest projection on each.
pub const MOTION_DIRECTIONS: usize = cloth_core::self_collision::MOTION_DIRECTIONS.len();

gpu_struct! {
    /// What self-collision's check and the substeps share on the GPU (6704 bytes, one storage
    /// buffer): the extents of the displacements since the last check, the bound on the cloth's
    /// relative motion since the last rebuild, and the counters a test or a report reads.
    GpuSelfControl as "SelfControl" {
        /// The rebuild passes' workgroups `(x, y, z, unused)` for a rebuild, in
        /// [`REBUILD_PASSES`] order (the plan's): the check copies them to the dispatch buffer
        /// when a rebuild is due, and zeros otherwise.
        full: [[u32; 4]; REBUILD_PASSES],
        /// [`MOTION_COPIES`] copies of the extents of the displacements since the last check,
        /// as [`cloth_core::self_collision::order_key`]s of their projections on the
        /// [`MOTION_DIRECTIONS`]: the largest key along direction `k` at `k`, the largest
        /// inverted key (the smallest projection) at `MOTION_DIRECTIONS + k`; 0: none recorded.
        motion: [[u32; 2 * MOTION_DIRECTIONS]; MOTION_COPIES],
        /// The bound `B` on the relative motion since the last rebuild, m.
        bound: f32,
        /// Rebuilds so far (its parity says which table of heads the last one filled).
        rebuilds: u32,
        /// Checks so far.
        checks: u32,
        /// Lists that overflowed [`LIST_CAPACITY`], over all rebuilds so far (a vertex's at each
        /// rebuild).
        overflows: u32,
    }
}

gpu_struct! {
    /// One collider (144 bytes): a [`cloth_core::colliders::Placement`] in `f32`, with its
    /// contact parameters and motion. Every kind uses the same fields; `kind` says which
    /// signed distance the kernels evaluate.
    GpuCollider as "Collider" {
        /// Centre at time 0, m (a plane's point nearest the origin, a capsule's midpoint).
        center: [f32; 3],
        /// `ColliderKind::code`: 0 sphere, 1 plane, 2 capsule, 3 box, 4 mesh.
        kind: u32,
        /// First axis (a capsule's direction; a box's rotated x).
        axis_x: [f32; 3],
        /// Radius (sphere, capsule), rounding (box) or distance-field cell (mesh), m.
        radius: f32,
        /// Second axis (a plane's normal; a box's rotated y).
        axis_y: [f32; 3],
        /// Contact stiffness `k_c`, N/m.
        stiffness: f32,
        /// Third axis (a box's rotated z).
        axis_z: [f32; 3],
        /// Friction coefficient `c_f`.
        friction: f32,
        /// A capsule's half length (x); a box's half extents less the rounding; a mesh's
        /// distance-field origin in its own coordinates, m.
        extent: [f32; 3],
        /// Normal contact damping, N·s/m.
        damping: f32,
        /// Motion: steady velocity, m/s.
        velocity: [f32; 3],
        /// Motion: angular frequency of the oscillation, rad/s.
        omega: f32,
        /// Motion: amplitude of the oscillation, m.
        amplitude: [f32; 3],
        /// Thinnest width, m (a plane's is infinite): XPBD sweeps longer paths only.
        thickness: f32,
        /// A mesh's distance-field points along x, y, z.
        field_dims: [u32; 3],
        /// Distance within which a vertex counts as on the surface, m.
        tolerance: f32,
        /// Index of a mesh's first sample in the distance-field buffer.
        field_first: u32,
        /// Padding to 144 bytes.
        pad0: u32,
        /// Padding.
        pad1: u32,
        /// Padding.
        pad2: u32,
    }
}

gpu_struct! {
    /// One spring as an XPBD constraint between vertices `a < b` (16 bytes).
    GpuConstraint as "Constraint" {
        /// First vertex (the lower index).
        a: u32,
        /// Second vertex.
        b: u32,
        /// `SpringKind as u32`.
        kind: u32,
        /// Rest length, m.
        rest_length: f32,
    }
}

gpu_struct! {
    /// The constraints one XPBD projection dispatch handles: one colour (16 bytes, stored every
    /// [`COLOR_RANGE_STRIDE`] bytes of a uniform buffer and selected by a dynamic offset).
    GpuColorRange as "ColorRange" {
        /// Index of the colour's first constraint.
        first: u32,
        /// Number of constraints of the colour.
        count: u32,
        /// 1 in the first iteration of a substep, where the multipliers `λ` start from 0.
        first_iteration: u32,
        /// Padding to 16 bytes.
        pad: u32,
    }
}

gpu_struct! {
    /// What a Vertex Block Descent colour pass needs of its sweep, or a pass of the multigrid
    /// correction of its level (48 bytes, stored every [`COLOR_RANGE_STRIDE`] bytes of a uniform
    /// buffer and selected by a dynamic offset). Offsets count `vec4`s of the multigrid buffer
    /// ([`MultigridLevels`]).
    GpuVbdSweep as "VbdSweep" {
        /// Chebyshev's weight `ω_k` of the sweep (1 in the first).
        omega: f32,
        /// 1 when Chebyshev acceleration is on (the solver's `chebyshev_rho` > 0).
        chebyshev: u32,
        /// This level's nodes along i (level 0: the grid's vertices).
        nx: u32,
        /// This level's nodes along j.
        ny: u32,
        /// The next coarser level's nodes along i.
        coarse_nx: u32,
        /// The next coarser level's nodes along j.
        coarse_ny: u32,
        /// This level's stencil: 27 `vec4`s a node (9 blocks of 3 rows).
        stencil: u32,
        /// This level's right-hand sides `b`, then its corrections `e`, a `vec4` a node each.
        vectors: u32,
        /// This level's partial sums `(e·A e, b·e)`, one a workgroup.
        partials: u32,
        /// The next level's stencil.
        coarse_stencil: u32,
        /// The next level's right-hand sides, then its corrections.
        coarse_vectors: u32,
        /// The next level's partial sums.
        coarse_partials: u32,
    }
}

/// One level of VBD's multigrid correction in the multigrid buffer (`cloth_core::multigrid`):
/// its nodes and where its data starts, in `vec4`s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MultigridLevel {
    /// Nodes along i.
    pub nx: u32,
    /// Nodes along j.
    pub ny: u32,
    /// The stencil, 27 `vec4`s a node.
    pub stencil: u32,
    /// `b`, then `e`, a `vec4` a node each.
    pub vectors: u32,
    /// The partial sums, one a workgroup of a pass over the level's nodes.
    pub partials: u32,
}

impl MultigridLevel {
    /// The level's nodes.
    pub fn nodes(&self) -> u32 {
        self.nx * self.ny
    }
}

/// The levels of VBD's multigrid correction for an `nx × ny` grid: level 0 is the grid itself
/// (no data of its own), each next one its 2 × 2 aggregates, down to one node
/// (`cloth_core::multigrid::hierarchy`); the data of levels 1 and on follow one another in one
/// buffer of `vec4`s.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MultigridLevels {
    /// Level 0 (the grid) and the coarse levels.
    pub levels: Vec<MultigridLevel>,
    /// The buffer's length, `vec4`s.
    pub vec4s: u64,
}

impl MultigridLevels {
    /// The levels of an `nx × ny` grid with partial sums for workgroups of `workgroup_size`.
    pub fn new(nx: u32, ny: u32, workgroup_size: u32) -> Self {
        let mut levels = vec![MultigridLevel { nx, ny, ..Default::default() }];
        let mut at = 0u64;
        while levels.len() < 2 || levels.last().is_some_and(|l| l.nodes() > 1) {
            let last = levels[levels.len() - 1];
            let (nx, ny) = (last.nx.div_ceil(2), last.ny.div_ceil(2));
            let nodes = u64::from(nx * ny);
            let stencil = at;
            let vectors = stencil + 27 * nodes;
            let partials = vectors + 2 * nodes;
            at = partials + nodes.div_ceil(u64::from(workgroup_size));
            let offset = |v: u64| u32::try_from(v).expect("a multigrid buffer within 2^32 vec4s");
            levels.push(MultigridLevel {
                nx,
                ny,
                stencil: offset(stencil),
                vectors: offset(vectors),
                partials: offset(partials),
            });
        }
        Self { levels, vec4s: at.max(1) }
    }

    /// The uniform block of passes on level `l` (0: the grid), which also describes level `l + 1`.
    pub fn block(&self, l: usize) -> GpuVbdSweep {
        let this = self.levels[l];
        let next = self.levels.get(l + 1).copied().unwrap_or_default();
        GpuVbdSweep {
            omega: 1.0,
            chebyshev: 0,
            nx: this.nx,
            ny: this.ny,
            coarse_nx: next.nx,
            coarse_ny: next.ny,
            stencil: this.stencil,
            vectors: this.vectors,
            partials: this.partials,
            coarse_stencil: next.stencil,
            coarse_vectors: next.vectors,
            coarse_partials: next.partials,
        }
    }
}

impl GpuVbdSweep {
    /// The blocks of every sweep of a substep, `COLOR_RANGE_STRIDE` bytes apart: sweep `k`, from
    /// 1, at `(k − 1) COLOR_RANGE_STRIDE`, with its Chebyshev weight computed in `f32` as the
    /// reference computes it (`cloth_core::vbd::chebyshev_weight`); then, with the multigrid
    /// correction, one block a level ([`GpuVbdSweep::level_offset`]).
    pub fn blocks(solver: &cloth_core::solver::SolverSpec, multigrid: Option<&MultigridLevels>) -> Vec<u8> {
        let sweeps = solver.vbd_iterations.max(1) as usize;
        let levels = multigrid.map_or(0, |m| m.levels.len());
        let mut bytes = vec![0u8; (sweeps + levels) * COLOR_RANGE_STRIDE as usize];
        let chebyshev = solver.chebyshev_rho > 0.0;
        let mut put = |k: usize, block: GpuVbdSweep| {
            let at = k * COLOR_RANGE_STRIDE as usize;
            bytes[at..at + size_of::<Self>()].copy_from_slice(bytemuck::bytes_of(&block));
        };
        for k in 0..sweeps {
            let omega = cloth_core::vbd::chebyshev_weight(k as u32 + 1, solver.chebyshev_rho as f32);
            put(k, GpuVbdSweep { omega, chebyshev: u32::from(chebyshev), ..Default::default() });
        }
        for l in 0..levels {
            put(sweeps + l, multigrid.expect("levels").block(l));
        }
        bytes
    }

    /// The dynamic offset of sweep `k` (from 1).
    pub fn offset(k: u32) -> u32 {
        ((k.max(1) - 1) as u64 * COLOR_RANGE_STRIDE) as u32
    }

    /// The dynamic offset of multigrid level `l`'s block, after the solver's sweeps.
    pub fn level_offset(solver: &cloth_core::solver::SolverSpec, l: usize) -> u32 {
        ((u64::from(solver.vbd_iterations.max(1)) + l as u64) * COLOR_RANGE_STRIDE) as u32
    }
}

gpu_struct! {
    /// Backward Euler's conjugate gradients: what one solve keeps between its passes and what the
    /// solver has spent since creation (32 bytes, one storage buffer).
    GpuCgCounters as "CgCounters" {
        /// Newton iterations run (one solve each).
        newton: u32,
        /// Conjugate-gradient iterations run, over every solve.
        cg: u32,
        /// The most conjugate-gradient iterations one solve took.
        cg_most: u32,
        /// The current solve's iterations so far.
        solve_iterations: u32,
        /// The norm the current solve's residual is measured against, N·s: its `|b|`, or the
        /// largest of the substep's earlier Newton iterations where that is larger.
        b_norm: f32,
        /// The solver's relative tolerance (`solver.cg_tolerance`).
        tolerance: f32,
        /// The largest `|b|` of the substep's Newton iterations so far, N·s (zero at its start).
        largest_b_norm: f32,
        /// Padding to 32 bytes.
        pad1: u32,
    }
}

gpu_struct! {
    /// Which conjugate-gradient iteration a pass belongs to (16 bytes, stored every
    /// [`COLOR_RANGE_STRIDE`] bytes of a uniform buffer and selected by a dynamic offset).
    GpuCgStep as "CgStep" {
        /// The iteration, from 1.
        iteration: u32,
        /// Padding to 16 bytes.
        pad0: u32,
        /// Padding to 16 bytes.
        pad1: u32,
        /// Padding to 16 bytes.
        pad2: u32,
    }
}

impl GpuCgStep {
    /// The blocks of iterations 1 to `iterations`, `COLOR_RANGE_STRIDE` bytes apart.
    pub fn blocks(iterations: u32) -> Vec<u8> {
        let n = iterations.max(1) as usize;
        let mut bytes = vec![0u8; n * COLOR_RANGE_STRIDE as usize];
        for k in 0..n {
            let at = k * COLOR_RANGE_STRIDE as usize;
            let block = GpuCgStep { iteration: k as u32 + 1, ..Default::default() };
            bytes[at..at + size_of::<Self>()].copy_from_slice(bytemuck::bytes_of(&block));
        }
        bytes
    }

    /// The dynamic offset of iteration `k` (from 1).
    pub fn offset(k: u32) -> u32 {
        ((k.max(1) - 1) as u64 * COLOR_RANGE_STRIDE) as u32
    }
}

/// The layouts of every struct the shaders share with the host.
pub fn struct_layouts() -> Vec<StructLayout> {
    vec![
        GpuSimParams::layout(),
        GpuCollider::layout(),
        GpuConstraint::layout(),
        GpuColorRange::layout(),
        GpuSelfControl::layout(),
        GpuVbdSweep::layout(),
        GpuCgCounters::layout(),
        GpuCgStep::layout(),
    ]
}

/// Bytes between two [`GpuColorRange`]s in their uniform buffer: 256, the largest
/// `minUniformBufferOffsetAlignment` Vulkan allows, so the dynamic offsets suit every device.
pub const COLOR_RANGE_STRIDE: u64 = 256;

impl GpuColorRange {
    /// Byte offset of the range of colour `color` in iteration `iteration` (the dynamic offset):
    /// the first iteration's ranges, then the others'.
    pub fn offset(color: usize, iteration: u32) -> u32 {
        let slot = if iteration == 0 { color } else { cloth_core::coloring::COLOR_COUNT + color };
        (slot as u64 * COLOR_RANGE_STRIDE) as u32
    }
}

impl GpuSimParams {
    /// The parameters of a scene in `f32`, from [`SceneQuantities`].
    pub fn of(scene: &Scene) -> Self {
        let q = SceneQuantities::of(scene);
        let f = |v: f64| v as f32;
        let v4 = |v: [f64; 3], w: f64| [f(v[0]), f(v[1]), f(v[2]), f(w)];
        let [nx, ny] = q.resolution;
        let mut pin_motion = [[0.0; 4]; 16];
        for (g, m) in q.pin_motions.iter().enumerate().take(cloth_core::scene::MAX_PIN_GROUPS) {
            pin_motion[PIN_MOTION_WORDS * g..PIN_MOTION_WORDS * (g + 1)].copy_from_slice(&[
                v4(m.velocity, m.angular_frequency()),
                v4(m.amplitude, 0.0),
                v4(m.angular_velocity, 0.0),
                v4(m.pivot, 0.0),
            ]);
        }
        let s = cloth_core::self_collision::SelfCollisionQuantities::of(scene);
        let table = SelfHashTable::of(scene);
        Self {
            gravity: v4(q.gravity, 0.0),
            stiffness: v4(q.stiffness, 0.0),
            damping: v4(q.damping, 0.0),
            vertex_mass: f(q.vertex_mass),
            substep_dt: f(q.substep_dt),
            air_drag: f(q.air_drag),
            vertex_count: nx.saturating_mul(ny),
            collider_count: q.colliders.len() as u32,
            grid_nx: nx,
            grid_ny: ny,
            effects: scene.effects.bits(),
            wind: v4(q.wind_velocity, q.wind_coefficient_area),
            gust: [f(q.gust_amplitude), f(q.gust_omega), 0.0, 0.0],
            pin_motion,
            rest_lengths: v4(q.rest_lengths, 0.0),
            self_contact: [f(s.thickness), f(s.stiffness), f(s.damping), f(s.friction)],
            self_hash: [f(s.window), f(s.max_speed), f(s.spacing[0]), f(s.spacing[1])],
            self_table: [table.buckets, table.records, 0, 0],
            self_lists: [
                f(s.margin * (1.0 - cloth_core::self_collision::MARGIN_ROUNDING)),
                f(s.lookahead),
                s.check_interval as f32,
                0.0,
            ],
            motion_directions: {
                let factors = cloth_core::self_collision::motion_extent_factors();
                std::array::from_fn(|k| {
                    let [x, y, z] = cloth_core::self_collision::MOTION_DIRECTIONS[k].map(f32::from);
                    [x, y, z, factors[k] as f32]
                })
            },
        }
    }
}

impl GpuCollider {
    /// A scene collider in `f32`.
    pub fn from_spec(c: &cloth_core::colliders::ColliderSpec) -> Self {
        let p = cloth_core::colliders::Placement::of(&c.shape);
        let f = |v: [f64; 3]| v.map(|x| x as f32);
        Self {
            center: f(p.center),
            kind: p.kind.code(),
            axis_x: f(p.axes[0]),
            radius: p.radius as f32,
            axis_y: f(p.axes[1]),
            stiffness: c.stiffness as f32,
            axis_z: f(p.axes[2]),
            friction: c.friction as f32,
            extent: f(p.extent),
            damping: c.damping as f32,
            velocity: f(c.motion.velocity),
            omega: c.motion.angular_frequency() as f32,
            amplitude: f(c.motion.amplitude),
            thickness: p.thickness as f32,
            field_dims: p.field.as_ref().map_or([0; 3], |f| f.dims),
            tolerance: p.tolerance as f32,
            field_first: 0,
            pad0: 0,
            pad1: 0,
            pad2: 0,
        }
    }

    /// The kernels' uniform block of colliders for `scene`: the colliders they test (none
    /// without `Contact`), then zeroed ones up to [`MAX_COLLIDERS`] (`GpuSimParams::collider_count`
    /// says how many are real; validation refuses a scene with more).
    pub fn of_scene(scene: &Scene) -> Vec<Self> {
        let mut first = 0;
        let mut colliders: Vec<Self> = (SceneQuantities::of(scene).colliders.iter())
            .map(|spec| {
                let mut c = Self::from_spec(spec);
                c.field_first = first;
                first += c.field_dims.iter().product::<u32>();
                c
            })
            .collect();
        colliders.resize(MAX_COLLIDERS.max(colliders.len()), Self::default());
        colliders
    }

    /// The samples of every mesh collider's distance field of `scene`, one after the other in
    /// the order of its colliders (what `field_first` indexes), m; at least one value, so that
    /// the buffer is never empty.
    pub fn distance_fields_of(scene: &Scene) -> Vec<f32> {
        let mut samples: Vec<f32> = (SceneQuantities::of(scene).colliders.iter())
            .filter_map(|spec| cloth_core::colliders::Placement::of(&spec.shape).field)
            .flat_map(|field| field.samples.clone())
            .collect();
        if samples.is_empty() {
            samples.push(0.0);
        }
        samples
    }
}
