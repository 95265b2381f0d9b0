#version 450
#extension GL_GOOGLE_include_directive : require

// One substep of the mass-spring cloth under a force-based integrator (semi-implicit Euler,
// velocity Verlet): one invocation per vertex. Effects the scene leaves out are compiled out
// (effects.glsl).

#include "effects.glsl"

// Which integration stage this pipeline runs: 0 semi-implicit Euler (the model's); 1 and 2 the
// two halves of velocity Verlet: 1 = kick and drift (v½ = v + ½Δt F(x, v)/m, x' = x + Δt v½),
// 2 = the second kick (v' = v½ + ½Δt F(x', v½)/m, positions untouched); 3 to 6 the four stages
// of classical Runge–Kutta, each evaluating a_k = F(x_k, v_k)/m at the state it reads:
//   3: x_2 = x + ½Δt v,   v_2 = v + ½Δt a_1    (stores x, v, Σx = v, Σv = a_1 in rk4_scratch)
//   4: x_3 = x + ½Δt v_2, v_3 = v + ½Δt a_2    (Σx += 2 v_2, Σv += 2 a_2)
//   5: x_4 = x + Δt v_3,  v_4 = v + Δt a_3     (Σx += 2 v_3, Σv += 2 a_3)
//   6: x' = x + Δt/6 (Σx + v_4), v' = v + Δt/6 (Σv + a_4); a vertex that friction holds at
//      this last stage's state sticks (its tangential motion over the substep is undone)
layout(constant_id = 101) const uint STAGE = 0u;

// The binding of the mesh colliders' distance fields, which layout.glsl declares.
#define DISTANCE_FIELDS_BINDING 13
#include "layout.glsl"
#include "forces.glsl"

// Self-collision's candidate lists, its hash and its control (self_hash.comp; placeholders
// without SelfCollision).
layout(set = 0, binding = 14, std430) readonly buffer SelfWords { uint self_words[]; };
layout(set = 0, binding = 15, std430) readonly buffer SelfLinks { uvec4 self_links[]; };
layout(set = 0, binding = 16, std430) buffer SelfControlBuffer { SelfControl self_control; };

// The hash's words 4 at4 to 4 at4 + 3 (self_collision.glsl).
uvec4 link_words(uint at4) {
    return self_links[at4];
}

#include "self_collision.glsl"

// No spring list: the springs are computed from the grid (add_stencil_springs).
layout(set = 0, binding = 2, std430) readonly buffer PositionsIn { vec4 positions_in[]; };    // w: 1 free, minus its pin group pinned
layout(set = 0, binding = 3, std430) readonly buffer VelocitiesIn { vec4 velocities_in[]; };
layout(set = 0, binding = 4, std430) buffer PositionsOut { vec4 positions_out[]; };
layout(set = 0, binding = 5, std430) buffer VelocitiesOut { vec4 velocities_out[]; };
// Deepest penetration so far, m, as the bits of a non-negative float (their order as uints is
// their order as floats, so atomicMax on uint is max on float).
layout(set = 0, binding = 6, std430) buffer MaxPenetration { uint max_penetration_bits; };
// RK4 only (a 64-byte placeholder otherwise): per vertex, the substep's start x and v and the
// running sums Σx and Σv, four vec4s. Each invocation touches only its own vertex's.
layout(set = 0, binding = 7, std430) buffer Rk4Scratch { vec4 rk4_scratch[]; };

// Semi-implicit Euler's packed state (cloth_gpu::geometry; 64-byte placeholders for
// the other integrators): 24 bytes a vertex instead of 32, for the substeps inside a submission.
// The first substep of a submission reads the vec4 state above and writes the packed one, the
// ones between read and write the packed state, the last reads it and writes the vec4 state
// (PACKED_IN, PACKED_OUT): what the renderer and the read-backs see is the vec4 state.
//   packed_xv: (x, v.x) a vertex; packed_v: (v.y, v.z) a vertex, then one more element whose x
//   is the state's time, s (written by vertex 0's invocation); pin_bits: bit i % 32 of word
//   i / 32 set where vertex i is pinned (the vec4 state keeps that in positions.w).
layout(set = 0, binding = 8, std430) readonly buffer PackedXvIn { vec4 packed_xv_in[]; };
layout(set = 0, binding = 9, std430) readonly buffer PackedVIn { vec2 packed_v_in[]; };
layout(set = 0, binding = 10, std430) buffer PackedXvOut { vec4 packed_xv_out[]; };
layout(set = 0, binding = 11, std430) buffer PackedVOut { vec2 packed_v_out[]; };
layout(set = 0, binding = 12, std430) readonly buffer PinBits { uint pin_bits[]; };
// 1: this pipeline reads (PACKED_IN) or writes (PACKED_OUT) the packed state; STAGE 0 only.
layout(constant_id = 108) const uint PACKED_IN = 0u;
layout(constant_id = 109) const uint PACKED_OUT = 0u;

// The position of vertex `index` in the state read, m (grid.glsl's grid_normal reads it too).
vec3 position_in(uint index) {
    if (PACKED_IN != 0u) {
        return packed_xv_in[index].xyz;
    }
    return positions_in[index].xyz;
}

// The position (m) and velocity (m/s) of vertex `index` in the state read.
void state_in(uint index, out vec3 x, out vec3 v) {
    if (PACKED_IN != 0u) {
        vec4 xv = packed_xv_in[index];
        x = xv.xyz;
        v = vec3(xv.w, packed_v_in[index]);
    } else {
        x = positions_in[index].xyz;
        v = velocities_in[index].xyz;
    }
}

#include "grid.glsl"

// The repulsion of vertex j on free vertex i at x moving at v, N (its velocity read only for a
// pair in contact).
vec3 self_repulsion(uint j, vec3 x, vec3 v, float friction_dt) {
    vec3 x_j = position_in(j);
    if (!in_contact(x, x_j)) {
        return vec3(0.0);
    }
    vec3 v_j;
    state_in(j, x_j, v_j);
    return repulsion_force(x, x_j, v, v_j, params.vertex_mass, friction_dt);
}

#include "self_partners.glsl"

// The self-collision term of partner j (self_partners.glsl): its repulsion on free vertex i at
// c.x moving at c.a, with the friction's step c.s.
vec4 pair_term(uint j, PairContext c) {
    return vec4(self_repulsion(j, c.x, c.a, c.s), 0.0);
}

// The self-collision force on free vertex i at (vi, vj), at x moving at v, N: the repulsion of
// every partner (sum_over_partners, in cloth_core::reference's self_collision_force's order).
vec3 self_collision_force(uint i, uint vi, uint vj, vec3 x, vec3 v, float friction_dt) {
    return sum_over_partners(i, vi, vj, PairContext(x, v, friction_dt)).xyz;
}

// Adds to `force` the spring from vertex (i, j) (buffer index `index`) to its grid neighbour
// (i + di, j + dj), if that neighbour exists: Hooke plus damping, with the kind's k and c_d and
// the given rest length. `interior`: (i, j) is two or more vertices from every edge, so every
// neighbour exists and its index is an offset from `index` (no edge checks; measured on the
// H100: docs/performance.md).
void add_spring(inout vec3 force, int i, int j, uint index, bool interior, int di, int dj, uint kind,
                float rest_length, vec3 x, vec3 v) {
    uint other = uint(int(index) + dj * int(params.grid_nx) + di);
    if (!interior) {
        // The neighbour's column and row as uint: one off the grid on the low side wraps to a
        // huge value, so one comparison a coordinate tests both sides (nx, ny < 2^31).
        uint ni = uint(i + di);
        uint nj = uint(j + dj);
        // (An early return, not a flag around the load below: with a flag every neighbour's
        // load sits under a condition, and the WGSL twin's kernel was 6-8% slower on the H100,
        // docs/performance.md.)
        if (ni >= params.grid_nx || nj >= params.grid_ny) {
            return;
        }
        other = nj * params.grid_nx + ni;
    }
    float damping = 0.0;
    if (EFFECT_SPRING_DAMPING) {
        damping = params.damping[kind];
    }
    vec3 x_other;
    vec3 v_other;
    state_in(other, x_other, v_other);
    add_spring_force(force, x, x_other, v, v_other, rest_length, params.stiffness[kind], damping);
}

// The spring forces on vertex `index`, from its grid neighbours: the springs are a stencil of the
// grid (no spring list is read; rest lengths from params.rest_lengths). They are added in the
// order of the CPU reference's per-vertex spring list (cloth_core::model::Adjacency), so the sums
// round alike: kind by kind, and within a kind the springs from lower-indexed vertices first:
// structural (0,-1) (-1,0) (+1,0) (0,+1); shear (-1,-1) (+1,-1) (+1,+1) (-1,+1); bend (0,-2)
// (-2,0) (+2,0) (0,+2).
void add_stencil_springs(inout vec3 force, int i, int j, uint index, vec3 x, vec3 v) {
    bool interior = i >= 2 && j >= 2 && i + 2 < int(params.grid_nx) && j + 2 < int(params.grid_ny);
    vec4 rest = params.rest_lengths;
    if (EFFECT_STRUCTURAL) {
        add_spring(force, i, j, index, interior, 0, -1, 0u, rest.y, x, v);
        add_spring(force, i, j, index, interior, -1, 0, 0u, rest.x, x, v);
        add_spring(force, i, j, index, interior, 1, 0, 0u, rest.x, x, v);
        add_spring(force, i, j, index, interior, 0, 1, 0u, rest.y, x, v);
    }
    if (EFFECT_SHEAR) {
        add_spring(force, i, j, index, interior, -1, -1, 1u, rest.z, x, v);
        add_spring(force, i, j, index, interior, 1, -1, 1u, rest.z, x, v);
        add_spring(force, i, j, index, interior, 1, 1, 1u, rest.z, x, v);
        add_spring(force, i, j, index, interior, -1, 1, 1u, rest.z, x, v);
    }
    if (EFFECT_BEND) {
        add_spring(force, i, j, index, interior, 0, -2, 2u, 2.0 * rest.y, x, v);
        add_spring(force, i, j, index, interior, -2, 0, 2u, 2.0 * rest.x, x, v);
        add_spring(force, i, j, index, interior, 2, 0, 2u, 2.0 * rest.x, x, v);
        add_spring(force, i, j, index, interior, 0, 2, 2u, 2.0 * rest.y, x, v);
    }
}

// Vertices along i of the block of the grid one workgroup updates (GpuTuning::
// block_width): a workgroup updates BLOCK_WIDTH × (workgroup size / BLOCK_WIDTH) vertices, so
// the rows its springs reach are mostly its own (L1 hits). 0: a workgroup's worth of a row.
layout(constant_id = 107) const uint BLOCK_WIDTH = 0u;
// 1: the workgroups take the grid's blocks last first (BLOCK_WIDTH != 0 only). Semi-implicit
// Euler's packed passes alternate the order from substep to substep
// (cloth_gpu::geometry::alternates_order), so each substep starts on the blocks the one before
// wrote last, which the L2 cache still holds.
layout(constant_id = 110) const uint REVERSED_ORDER = 0u;

// Advances the invocation's vertex; returns its displacement over the substep where this stage
// ends one (w 1), zero otherwise (w 0: another stage, or no vertex).
vec4 advance_vertex() {
    // The vertex's index and grid coordinates.
    uint i;
    uint vi;
    uint vj;
    if (BLOCK_WIDTH != 0u) {
        // One workgroup per block, the workgroup grid the grid's blocks (cloth_gpu::
        // geometry::BlockGrid): the workgroup id is the block's column and row, no division needed.
        // (max: not a specialization-constant operation, so vulkano does not fold a quotient by
        // zero when it specializes a pipeline with BLOCK_WIDTH = 0.)
        uint width = max(BLOCK_WIDTH, 1u);
        uvec2 block = gl_WorkGroupID.xy;
        if (REVERSED_ORDER != 0u) {
            block = gl_NumWorkGroups.xy - 1u - block;
        }
        uint local_index = gl_LocalInvocationIndex;
        vi = block.x * width + local_index % width;
        vj = block.y * (gl_WorkGroupSize.x / width) + local_index / width;
        if (vi >= params.grid_nx || vj >= params.grid_ny) {
            return vec4(0.0);
        }
        i = vj * params.grid_nx + vi;
    } else {
        // 2D dispatch: more than maxComputeWorkGroupCount[0] workgroups spill into y.
        i = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
        if (i >= params.vertex_count) {
            return vec4(0.0);
        }
        vi = i % params.grid_nx;
        vj = i / params.grid_nx;
    }
    vec3 x;
    vec3 v;
    state_in(i, x, v);
    // Whether the vertex moves freely (positions.w, or its pin bit), and the time of the state
    // read (velocities.w, or the packed state's clock) and of the state written.
    // The packed state has no pin groups (cloth_gpu::plan keeps a scene with several on the vec4
    // state), so its pins are group 0.
    bool free_vertex;
    float w_in;
    float t;
    if (PACKED_IN != 0u) {
        free_vertex = (pin_bits[i >> 5u] & (1u << (i & 31u))) == 0u;
        w_in = free_vertex ? 1.0 : 0.0;
        t = packed_v_in[params.vertex_count].x;
    } else {
        w_in = positions_in[i].w;
        free_vertex = w_in > 0.0;
        t = velocities_in[i].w;
    }
    float dt = params.substep_dt;
    float half_dt = dt * 0.5;
    float t_out = t + dt;     // Euler, Verlet's kick and drift
    if (STAGE == 2u || STAGE == 4u || STAGE == 6u) {
        t_out = t;            // Verlet's second kick; RK4's second and fourth stages (same time)
    }
    if (STAGE == 3u) {
        t_out = t + half_dt;  // RK4's first stage
        // It keeps the substep's start time for the third (every vertex).
        rk4_scratch[4u * i] = vec4(x, t);
    }
    if (STAGE == 5u) {
        t_out = rk4_scratch[4u * i].w + dt; // RK4's third stage: the substep's end
    }
    vec3 x_new = x;
    vec3 v_new = vec3(0.0);
    if (free_vertex) {
        float mass = params.vertex_mass;
        // The step the friction's stopping term refers to: what this stage's velocity update spans.
        float friction_dt = (STAGE == 1u || STAGE == 2u) ? half_dt : dt;
        vec3 force = vec3(0.0);
        if (EFFECT_GRAVITY) {
            force += gravity_force(mass, params.gravity.xyz);
        }
        if (ANY_SPRINGS) {
            add_stencil_springs(force, int(vi), int(vj), i, x, v);
        }
        if (EFFECT_AIR_DRAG) {
            force += air_drag_force(mass, params.air_drag, v);
        }
        if (EFFECT_WIND) {
            force += wind_force(grid_normal(i), v, wind_velocity(t), params.wind.w);
        }
        if (EFFECT_SELF_COLLISION) {
            force += self_collision_force(i, vi, vj, x, v, friction_dt);
        }
        // Against a moving collider, contact and friction act on the velocity relative to it.
        vec3 other_forces = force;
        // RK4's last stage: the normal of a contact whose friction holds the vertex (it sticks).
        bool stuck = false;
        vec3 stick_normal = vec3(0.0);
        if (EFFECT_CONTACT) {
            for (uint s = 0u; s < params.collider_count; s++) {
                vec3 center = collider_center(s, t);
                // The normal only for a vertex inside: outside, the distance alone.
                Surface surface = collider_contact(s, center, x);
                if (surface.distance >= 0.0) {
                    continue;
                }
                vec3 v_rel = v - collider_velocity(s, t);
                vec3 normal;
                vec3 contact;
                if (contact_force(v_rel, surface, colliders[s].stiffness,
                                  colliders[s].damping, normal, contact)) {
                    force += contact;
                    if (EFFECT_FRICTION) {
                        force += friction_force(other_forces, v_rel, normal, mass, friction_dt, colliders[s].friction);
                        if (STAGE == 6u && !stuck
                            && friction_holds(other_forces, v_rel, normal, mass, friction_dt, colliders[s].friction)) {
                            stuck = true;
                            stick_normal = normal;
                        }
                    }
                }
            }
        }
        if (STAGE == 0u) {
            // v_c = v_p + Δt R/m, x_c = x_p + Δt v_c (semi-implicit Euler).
            v_new = v + force * (dt / mass);
            x_new = x + v_new * dt;
            if (EFFECT_SELF_COLLISION) {
                // The speed limit (self_collision.glsl), on the substep's end.
                x_new = limit_step(x, x_new);
                v_new = limit_velocity(v_new);
            }
        } else if (STAGE <= 2u) {
            // Verlet: a half kick, then (stage 1) a full drift.
            v_new = v + force * (half_dt / mass);
            if (STAGE == 1u) {
                x_new = x + v_new * dt;
                if (EFFECT_SELF_COLLISION) {
                    x_new = limit_step(x, x_new);
                }
            } else if (EFFECT_SELF_COLLISION) {
                v_new = limit_velocity(v_new);
            }
        } else {
            // RK4 (see STAGE above): x, v here are the stage's state x_k, v_k.
            vec3 a = force * (1.0 / mass);
            uint slot = 4u * i;
            if (STAGE == 3u) {
                rk4_scratch[slot] = vec4(x, t);
                rk4_scratch[slot + 1u] = vec4(v, 0.0);
                rk4_scratch[slot + 2u] = vec4(v, 0.0);
                rk4_scratch[slot + 3u] = vec4(a, 0.0);
                x_new = x + v * half_dt;
                v_new = v + a * half_dt;
            } else {
                vec3 x_start = rk4_scratch[slot].xyz;
                vec3 v_start = rk4_scratch[slot + 1u].xyz;
                vec3 sum_x = rk4_scratch[slot + 2u].xyz;
                vec3 sum_v = rk4_scratch[slot + 3u].xyz;
                if (STAGE == 6u) {
                    float sixth = dt / 6.0;
                    x_new = x_start + (sum_x + v) * sixth;
                    v_new = v_start + (sum_v + a) * sixth;
                    if (stuck) {
                        // Static friction: no tangential motion over the substep.
                        vec3 d = x_new - x_start;
                        x_new = x_new - (d - stick_normal * dot(d, stick_normal));
                        v_new = stick_normal * dot(v_new, stick_normal);
                    }
                    if (EFFECT_SELF_COLLISION) {
                        x_new = limit_step(x_start, x_new);
                        v_new = limit_velocity(v_new);
                    }
                } else {
                    rk4_scratch[slot + 2u] = vec4(sum_x + v * 2.0, 0.0);
                    rk4_scratch[slot + 3u] = vec4(sum_v + a * 2.0, 0.0);
                    float step_dt = STAGE == 5u ? dt : half_dt;
                    x_new = x_start + v * step_dt;
                    v_new = v_start + a * step_dt;
                }
            }
        }
    } else {
        // A pin stays put, or follows its group's motion (MovingPins) from t to t_out.
        uint group = pin_group(w_in);
        x_new = pin_carry(group, x, t, t_out);
        v_new = pin_velocity(group, x_new, t_out);
    }
    if (PACKED_OUT != 0u) {
        packed_xv_out[i] = vec4(x_new, v_new.x);
        packed_v_out[i] = v_new.yz;
        if (i == 0u) {
            packed_v_out[params.vertex_count] = vec2(t_out, 0.0);
        }
    } else {
        velocities_out[i] = vec4(v_new, t_out);
        if (STAGE == 2u) {
            return vec4(0.0); // the second kick leaves the positions of the first stage as they are
        }
        positions_out[i] = vec4(x_new, w_in);
    }
    // The deepest penetration is checked on the state that ends a substep, as on the CPU.
    // (Nested ifs: a constant condition stays one branch, which a compiler removes whole.)
    if (EFFECT_CONTACT) {
        if (STAGE == 0u || STAGE == 1u || STAGE == 6u) {
            float deepest = 0.0;
            for (uint s = 0u; s < params.collider_count; s++) {
                deepest = max(deepest, -collider_distance(s, collider_center(s, t_out), x_new));
            }
            if (deepest > 0.0) {
                atomicMax(max_penetration_bits, floatBitsToUint(deepest));
            }
        }
    }
    if (STAGE == 0u || STAGE == 1u) {
        return vec4(x_new - x, 1.0);
    }
    if (STAGE == 6u) {
        return vec4(x_new - rk4_scratch[4u * i].xyz, 1.0);
    }
    return vec4(0.0);
}

void main() {
    if (EFFECT_SELF_COLLISION) {
        clear_motion(gl_LocalInvocationIndex);
    }
    vec4 moved = advance_vertex();
    if (EFFECT_SELF_COLLISION) {
        // The extents of the substep's displacements along the motion directions, which the next
        // check turns into its bound.
        record_motion(moved, gl_LocalInvocationIndex, gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x);
    }
}
