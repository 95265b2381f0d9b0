// Buffer layouts and bindings of the substep kernel: the GLSL view of
// crates/cloth-core/src/layout.rs (checked by crates/cloth-vulkano/tests/layout.rs).

// cloth_core::layout::GpuSimParams (80 bytes, std140).
layout(set = 0, binding = 0, std140) uniform SimParams {
    vec4 gravity;       // m/s² (xyz)
    vec4 stiffness;     // N/m by spring kind: structural, shear, bend
    vec4 damping;       // N·s/m by spring kind
    float vertex_mass;  // kg
    float substep_dt;   // s
    float air_drag;     // 1/s
    uint vertex_count;
    uint sphere_count;
    uint grid_nx;
    uint grid_ny;
    uint effects;
} params;

// cloth_core::layout::GpuSphere (32 bytes).
struct Sphere {
    vec3 center;        // m
    float radius;       // m
    float stiffness;    // k_c, N/m
    float friction;     // c_f
    float damping;      // N·s/m
    float pad;
};

// cloth_core::layout::GpuSpringRange (8 bytes).
struct SpringRange {
    uint first;
    uint count;
};

// cloth_core::layout::GpuSpringEnd (16 bytes).
struct SpringEnd {
    uint other;
    uint kind;
    float rest_length;  // m
    uint pad;
};

layout(set = 0, binding = 1, std430) readonly buffer Spheres { Sphere spheres[]; };
layout(set = 0, binding = 2, std430) readonly buffer SpringRanges { SpringRange spring_ranges[]; };
layout(set = 0, binding = 3, std430) readonly buffer SpringEnds { SpringEnd spring_ends[]; };
layout(set = 0, binding = 4, std430) readonly buffer PositionsIn { vec4 positions_in[]; };    // w: 1 free, 0 pinned
layout(set = 0, binding = 5, std430) readonly buffer VelocitiesIn { vec4 velocities_in[]; };
layout(set = 0, binding = 6, std430) buffer PositionsOut { vec4 positions_out[]; };
layout(set = 0, binding = 7, std430) buffer VelocitiesOut { vec4 velocities_out[]; };
// Deepest penetration so far, m, as the bits of a non-negative float (their order as uints is
// their order as floats, so atomicMax on uint is max on float).
layout(set = 0, binding = 8, std430) buffer MaxPenetration { uint max_penetration_bits; };
