// Buffer layouts shared by every kernel: the GLSL view of crates/cloth-gpu/src/layout.rs
// (checked by tests/tests/shader_layouts.rs), with the two bindings all kernels share
// (0: parameters, 1: spheres). Each kernel declares its other bindings.

// cloth_gpu::layout::GpuSimParams (160 bytes, std140).
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
    vec4 wind;          // mean wind velocity, m/s (xyz); w: coefficient × area per vertex, N·s/m
    vec4 gust;          // x: relative amplitude, y: angular frequency, rad/s
    vec4 pin_velocity;  // pins' steady velocity, m/s (xyz); w: angular frequency, rad/s
    vec4 pin_amplitude; // pins' oscillation amplitude, m (xyz)
    vec4 rest_lengths;  // m: structural along u, along v, shear (bend: twice the structural)
} params;

// cloth_gpu::layout::GpuSphere (64 bytes).
struct Sphere {
    vec3 center;        // m, at time 0
    float radius;       // m
    float stiffness;    // k_c, N/m
    float friction;     // c_f
    float damping;      // N·s/m
    float pad;
    vec3 velocity;      // steady velocity, m/s (MovingSpheres)
    float omega;        // angular frequency of the oscillation, rad/s
    vec3 amplitude;     // amplitude of the oscillation, m
    float pad2;
};

// cloth_gpu::layout::GpuConstraint (16 bytes): one spring as an XPBD constraint, a < b.
struct Constraint {
    uint a;
    uint b;
    uint kind;
    float rest_length;  // m
};

// The bindings every kernel shares: the parameters and the spheres.
layout(set = 0, binding = 1, std430) readonly buffer Spheres { Sphere spheres[]; };
