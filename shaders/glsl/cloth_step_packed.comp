#version 450
#extension GL_GOOGLE_include_directive : require
// EXPERIMENT (timing only, not kept): cloth_step.comp's Euler substep on a packed state of 24
// bytes a vertex, vec4 (x, y, z, v.x) + vec2 (v.y, v.z); every vertex free, time 0.
#include "effects.glsl"
layout(constant_id = 101) const uint STAGE = 0u;
#include "layout.glsl"
#include "forces.glsl"
layout(set = 0, binding = 2, std430) readonly buffer AIn { vec4 a_in[]; };
layout(set = 0, binding = 3, std430) readonly buffer BIn { vec2 b_in[]; };
layout(set = 0, binding = 4, std430) buffer AOut { vec4 a_out[]; };
layout(set = 0, binding = 5, std430) buffer BOut { vec2 b_out[]; };
layout(set = 0, binding = 6, std430) buffer MaxPenetration { uint max_penetration_bits; };
layout(constant_id = 107) const uint BLOCK_WIDTH = 0u;

void add_spring(inout vec3 force, int i, int j, uint index, bool interior, int di, int dj, uint kind,
                float rest_length, vec3 x, vec3 v) {
    uint other = uint(int(index) + dj * int(params.grid_nx) + di);
    if (!interior) {
        int ni = i + di;
        int nj = j + dj;
        if (ni < 0 || nj < 0 || ni >= int(params.grid_nx) || nj >= int(params.grid_ny)) {
            return;
        }
        other = uint(nj) * params.grid_nx + uint(ni);
    }
    float damping = 0.0;
    if (EFFECT_SPRING_DAMPING) {
        damping = params.damping[kind];
    }
    vec4 a = a_in[other];
    vec2 b = b_in[other];
    add_spring_force(force, x, a.xyz, v, vec3(a.w, b), rest_length, params.stiffness[kind], damping);
}

void main() {
    uint width = max(BLOCK_WIDTH, 1u);
    uint block = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uint blocks_along_i = (params.grid_nx + width - 1u) / width;
    uint local_index = gl_LocalInvocationIndex;
    uint vi = (block % blocks_along_i) * width + local_index % width;
    uint vj = (block / blocks_along_i) * (gl_WorkGroupSize.x / width) + local_index / width;
    if (vi >= params.grid_nx || vj >= params.grid_ny) {
        return;
    }
    uint i = vj * params.grid_nx + vi;
    vec4 a = a_in[i];
    vec2 b = b_in[i];
    vec3 x = a.xyz;
    vec3 v = vec3(a.w, b);
    float dt = params.substep_dt;
    float mass = params.vertex_mass;
    vec3 force = vec3(0.0);
    if (EFFECT_GRAVITY) {
        force += gravity_force(mass, params.gravity.xyz);
    }
    int ii = int(vi);
    int jj = int(vj);
    bool interior = ii >= 2 && jj >= 2 && ii + 2 < int(params.grid_nx) && jj + 2 < int(params.grid_ny);
    vec4 rest = params.rest_lengths;
    if (EFFECT_STRUCTURAL) {
        add_spring(force, ii, jj, i, interior, 0, -1, 0u, rest.y, x, v);
        add_spring(force, ii, jj, i, interior, -1, 0, 0u, rest.x, x, v);
        add_spring(force, ii, jj, i, interior, 1, 0, 0u, rest.x, x, v);
        add_spring(force, ii, jj, i, interior, 0, 1, 0u, rest.y, x, v);
    }
    if (EFFECT_SHEAR) {
        add_spring(force, ii, jj, i, interior, -1, -1, 1u, rest.z, x, v);
        add_spring(force, ii, jj, i, interior, 1, -1, 1u, rest.z, x, v);
        add_spring(force, ii, jj, i, interior, 1, 1, 1u, rest.z, x, v);
        add_spring(force, ii, jj, i, interior, -1, 1, 1u, rest.z, x, v);
    }
    if (EFFECT_BEND) {
        add_spring(force, ii, jj, i, interior, 0, -2, 2u, 2.0 * rest.y, x, v);
        add_spring(force, ii, jj, i, interior, -2, 0, 2u, 2.0 * rest.x, x, v);
        add_spring(force, ii, jj, i, interior, 2, 0, 2u, 2.0 * rest.x, x, v);
        add_spring(force, ii, jj, i, interior, 0, 2, 2u, 2.0 * rest.y, x, v);
    }
    vec3 other_forces = force;
    if (EFFECT_CONTACT) {
        for (uint s = 0u; s < params.sphere_count; s++) {
            vec3 normal;
            vec3 contact;
            if (contact_force(x, v, spheres[s].center, spheres[s], normal, contact)) {
                force += contact;
                if (EFFECT_FRICTION) {
                    force += friction_force(other_forces, v, normal, mass, dt, spheres[s].friction);
                }
            }
        }
    }
    vec3 v_new = v + force * (dt / mass);
    vec3 x_new = x + v_new * dt;
    a_out[i] = vec4(x_new, v_new.x);
    b_out[i] = v_new.yz;
    if (EFFECT_CONTACT) {
        float deepest = 0.0;
        for (uint s = 0u; s < params.sphere_count; s++) {
            vec3 offset = x_new - spheres[s].center;
            deepest = max(deepest, spheres[s].radius - sqrt(dot(offset, offset)));
        }
        if (deepest > 0.0) {
            atomicMax(max_penetration_bits, floatBitsToUint(deepest));
        }
    }
}
