// Buffer layouts shared by every kernel: the GLSL view of crates/cloth-gpu/src/layout.rs
// (checked by tests/tests/shader_layouts.rs), with the two bindings all kernels share
// (0: parameters, 1: colliders) and the colliders' signed distances (colliders.glsl). Each kernel declares its other bindings.

// cloth_gpu::layout::GpuSimParams (656 bytes, std140).
layout(set = 0, binding = 0, std140) uniform SimParams {
    vec4 gravity;       // m/s² (xyz)
    vec4 stiffness;     // N/m by spring kind: structural, shear, bend
    vec4 damping;       // N·s/m by spring kind
    float vertex_mass;  // kg
    float substep_dt;   // s
    float air_drag;     // 1/s
    uint vertex_count;
    uint collider_count;
    uint grid_nx;
    uint grid_ny;
    uint effects;
    vec4 wind;          // mean wind velocity, m/s (xyz); w: coefficient × area per vertex, N·s/m
    vec4 gust;          // x: relative amplitude, y: angular frequency, rad/s
    // Four vec4s a pin group (cloth_gpu::layout::PIN_MOTION_WORDS): steady velocity, m/s (xyz),
    // w the angular frequency, rad/s; amplitude, m; angular velocity, rad/s; pivot, m.
    vec4 pin_motion[16];
    vec4 rest_lengths;  // m: structural along u, along v, shear (bend: twice the structural)
    vec4 self_contact;  // self-collision: thickness r, m; k_s, N/m; c_s, N·s/m; friction μ
    vec4 self_hash;     // the candidate window r + W (the hash's cell side), m; speed limit, m/s; grid spacing along u, v, m
    uvec4 self_table;   // buckets T; first record (position at the rebuild, link); unused; unused (cloth_gpu::layout::SelfHashTable)
    // The directions of the motion bound (xyz) and the factor sec θ / |u| that turns the extent
    // along each into a bound on two vertices' relative displacement (w).
    vec4 motion_directions[13];
    vec4 self_lists;    // the margin less its rounding share, m; lookahead, m; substeps between checks
} params;

// cloth_gpu::layout::GpuCgCounters (32 bytes): backward Euler's conjugate gradients' counters.
struct CgCounters {
    uint newton;            // Newton iterations run
    uint cg;                // CG iterations run
    uint cg_most;           // the most CG iterations of one solve
    uint solve_iterations;  // the current solve's iterations so far
    float b_norm;           // what the solve's residual is measured against, N·s
    float tolerance;        // the relative tolerance
    float largest_b_norm;   // the largest |b| of the substep's Newton iterations so far, N·s
    uint pad1;
};

// cloth_gpu::layout::GpuSelfControl (6704 bytes, std430): self-collision's check and the
// substeps share it.
struct SelfControl {
    uvec4 full[2];          // workgroups of the insert and candidates passes for a rebuild
    // MOTION_COPIES copies of the extents of the displacements since the check, as order keys of
    // their projections on the 13 motion directions (atomic): the highest along direction k at
    // k, the highest inverted one (the lowest projection) at 13 + k.
    uint motion[64][26];
    float bound;            // the relative motion since the rebuild, at most, m
    uint rebuilds;
    uint checks;
    uint overflows;         // lists that overflowed, over all rebuilds so far (atomic)
};

#ifndef PARAMS_ONLY
// (A kernel that needs the parameters only defines PARAMS_ONLY first: self_hash.comp.)

// cloth_gpu::layout::GpuCollider (144 bytes): one collider of any kind.
struct Collider {
    vec3 center;        // m, at time 0 (a plane's point nearest the origin, a capsule's midpoint)
    uint kind;          // 0 sphere, 1 plane, 2 capsule, 3 box, 4 mesh
    vec3 axis_x;        // a capsule's direction; a box's rotated x
    float radius;       // m: sphere, capsule; a box's rounding; a mesh's distance-field cell
    vec3 axis_y;        // a plane's normal; a box's rotated y
    float stiffness;    // k_c, N/m
    vec3 axis_z;        // a box's rotated z
    float friction;     // c_f
    vec3 extent;        // m: a capsule's half length (x); a box's half extents less the rounding; a mesh's field origin
    float damping;      // N·s/m
    vec3 velocity;      // steady velocity, m/s (MovingColliders)
    float omega;        // angular frequency of the oscillation, rad/s
    vec3 amplitude;     // amplitude of the oscillation, m
    float thickness;    // m: thinnest width (XPBD sweeps longer paths only)
    uvec3 field_dims;   // a mesh's distance-field points along x, y, z
    float tolerance;    // m: within this of the surface a vertex is on it
    uint field_first;   // a mesh's first sample in distance_fields
    uint pad0;
    uint pad1;
    uint pad2;
};

// cloth_gpu::layout::GpuConstraint (16 bytes): one spring as an XPBD constraint, a < b.
struct Constraint {
    uint a;
    uint b;
    uint kind;
    float rest_length;  // m
};

// The bindings every kernel shares: the parameters and the colliders, and the mesh colliders'
// distance fields (m) at the binding the kernel names before including this file.
// The colliders: a uniform block of MAX_COLLIDERS (cloth_core::colliders::MAX_COLLIDERS; params
// says how many are real). Every invocation reads the same collider at once, which a uniform block
// serves from the constant cache.
#define MAX_COLLIDERS 64
layout(set = 0, binding = 1, std140) uniform Colliders { Collider colliders[MAX_COLLIDERS]; };
layout(set = 0, binding = DISTANCE_FIELDS_BINDING, std430) readonly buffer DistanceFields { float distance_fields[]; };

#include "colliders.glsl"
#endif
