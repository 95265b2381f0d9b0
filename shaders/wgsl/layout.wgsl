// The structs the host shares with the shaders: the WGSL view of crates/cloth-gpu/src/layout.rs,
// declared once here and prepended to every WGSL module that uses them (the compute kernels and
// the inspector's render.wgsl). A test reflects every such module against the Rust types.

// cloth_gpu::layout::GpuSimParams (656 bytes).
struct SimParams {
    gravity: vec4<f32>,      // m/s² (xyz)
    stiffness: vec4<f32>,    // N/m by spring kind: structural, shear, bend
    damping: vec4<f32>,      // N·s/m by spring kind
    vertex_mass: f32,        // kg
    substep_dt: f32,         // s
    air_drag: f32,           // 1/s
    vertex_count: u32,
    collider_count: u32,
    grid_nx: u32,
    grid_ny: u32,
    effects: u32,
    wind: vec4<f32>,         // mean wind velocity, m/s (xyz); w: coefficient × area per vertex, N·s/m
    gust: vec4<f32>,         // x: relative amplitude, y: angular frequency, rad/s
    // Four vec4s a pin group (cloth_gpu::layout::PIN_MOTION_WORDS): steady velocity, m/s (xyz),
    // w the angular frequency, rad/s; amplitude, m; angular velocity, rad/s; pivot, m.
    pin_motion: array<vec4<f32>, 16>,
    rest_lengths: vec4<f32>, // m: structural along u, along v, shear (bend: twice the structural)
    self_contact: vec4<f32>, // self-collision: thickness r, m; k_s, N/m; c_s, N·s/m; friction μ
    self_hash: vec4<f32>,    // the candidate window r + W (the hash's cell side), m; speed limit, m/s; grid spacing along u, v, m
    self_table: vec4<u32>,   // buckets T; first record (position at the rebuild, link); unused; unused (cloth_gpu::layout::SelfHashTable)
    // The directions of the motion bound (xyz) and the factor sec θ / |u| that turns the extent
    // along each into a bound on two vertices' relative displacement (w).
    motion_directions: array<vec4<f32>, 13>,
    self_lists: vec4<f32>,   // the margin less its rounding share, m; lookahead, m; substeps between checks
}

// The colliders' uniform block holds this many (cloth_core::colliders::MAX_COLLIDERS; params
// says how many are real). Every invocation reads the same collider at once, which a uniform block
// serves from the constant cache.
const MAX_COLLIDERS: u32 = 64u;

// cloth_gpu::layout::GpuCollider (144 bytes): one collider of any kind.
struct Collider {
    center: vec3<f32>,       // m, at time 0 (a plane's point nearest the origin, a capsule's midpoint)
    kind: u32,               // 0 sphere, 1 plane, 2 capsule, 3 box, 4 mesh
    axis_x: vec3<f32>,       // a capsule's direction; a box's rotated x
    radius: f32,             // m: sphere, capsule; a box's rounding; a mesh's distance-field cell
    axis_y: vec3<f32>,       // a plane's normal; a box's rotated y
    stiffness: f32,          // k_c, N/m
    axis_z: vec3<f32>,       // a box's rotated z
    friction: f32,           // c_f
    extent: vec3<f32>,       // m: a capsule's half length (x); a box's half extents less the rounding; a mesh's field origin
    damping: f32,            // N·s/m
    velocity: vec3<f32>,     // steady velocity, m/s (MovingColliders)
    omega: f32,              // angular frequency of the oscillation, rad/s
    amplitude: vec3<f32>,    // amplitude of the oscillation, m
    thickness: f32,          // m: thinnest width (XPBD sweeps longer paths only)
    field_dims: vec3<u32>,   // a mesh's distance-field points along x, y, z
    tolerance: f32,          // m: within this of the surface a vertex is on it
    field_first: u32,        // a mesh's first sample in distance_fields
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// cloth_gpu::layout::GpuConstraint (16 bytes): one spring as an XPBD constraint, a < b.
struct Constraint {
    a: u32,
    b: u32,
    kind: u32,
    rest_length: f32,        // m
}

// cloth_gpu::layout::GpuColorRange (16 bytes): the constraints of one XPBD colour.
struct ColorRange {
    first: u32,
    count: u32,
    first_iteration: u32,    // 1: the multipliers start from 0
    pad: u32,
}

// cloth_gpu::layout::GpuVbdSweep (48 bytes): what a VBD colour pass needs of its sweep, or a
// multigrid pass of its level (offsets in vec4s of the multigrid buffer).
struct VbdSweep {
    omega: f32,              // Chebyshev's weight of the sweep
    chebyshev: u32,          // 1: Chebyshev acceleration on
    nx: u32,                 // this level's nodes along i (level 0: the grid's vertices)
    ny: u32,                 // and along j
    coarse_nx: u32,          // the next coarser level's nodes along i
    coarse_ny: u32,          // and along j
    stencil: u32,            // this level's stencil, 27 vec4s a node
    vectors: u32,            // this level's b, then its e
    partials: u32,           // this level's partial sums
    coarse_stencil: u32,     // the next level's stencil
    coarse_vectors: u32,     // the next level's b, then its e
    coarse_partials: u32,    // the next level's partial sums
}

// cloth_gpu::layout::GpuCgCounters (32 bytes): backward Euler's conjugate gradients' counters.
struct CgCounters {
    newton: u32,             // Newton iterations run
    cg: u32,                 // CG iterations run
    cg_most: u32,            // the most CG iterations of one solve
    solve_iterations: u32,   // the current solve's iterations so far
    b_norm: f32,             // what the solve's residual is measured against, N·s
    tolerance: f32,          // the relative tolerance
    largest_b_norm: f32,     // the largest |b| of the substep's Newton iterations so far, N·s
    pad1: u32,
}

// cloth_gpu::layout::GpuCgStep (16 bytes): the CG iteration a pass belongs to.
struct CgStep {
    iteration: u32,          // from 1
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// cloth_gpu::layout::GpuSelfControl (6704 bytes): self-collision's check and the substeps share
// it.
struct SelfControl {
    full: array<vec4<u32>, 2>,              // workgroups of the insert and candidates passes for a rebuild
    // MOTION_COPIES copies of the extents of the displacements since the check, as order keys of
    // their projections on the 13 motion directions: the highest along direction k at k, the
    // highest inverted one (the lowest projection) at 13 + k.
    motion: array<array<atomic<u32>, 26>, 64>,
    bound: f32,                             // the relative motion since the rebuild, at most, m
    rebuilds: u32,
    checks: u32,
    overflows: atomic<u32>,                 // lists that overflowed, over all rebuilds so far
}
