#version 450
#extension GL_GOOGLE_include_directive : require

// Several semi-implicit Euler substeps in one dispatch, each workgroup on a tile of the grid in
// workgroup (shared) memory, one invocation per cell: temporal blocking (cloth_gpu::geometry says
// how and why). The tile's constants come from cloth_gpu::geometry::TileConfig as specialization
// constants. Each vertex's
// arithmetic is cloth_step.comp's with STAGE = 0, operation by operation (springs, normal and
// state read from shared memory instead of the state buffers), so the result is the same to the
// bit. Mirrors shaders/wgsl/cloth_step_tiled.wgsl.

#define TILED_WORKGROUP
#include "effects.glsl"

// The workgroup is the tile: local_size_x = TILE_WIDTH (id 102), local_size_y = TILE_HEIGHT
// (id 103), one invocation per cell.
layout(local_size_x = 32, local_size_y = 16, local_size_x_id = 102, local_size_y_id = 103) in;
#define TILE_WIDTH gl_WorkGroupSize.x   // cells along i, halo included
#define TILE_HEIGHT gl_WorkGroupSize.y  // cells along j
layout(constant_id = 104) const uint TILE_CELLS = 512u;      // TILE_WIDTH × TILE_HEIGHT
layout(constant_id = 106) const uint FUSED_SUBSTEPS = 2u;    // substeps per dispatch

// The binding of the mesh colliders' distance fields, which layout.glsl declares.
#define DISTANCE_FIELDS_BINDING 7
#include "layout.glsl"
#include "forces.glsl"

layout(set = 0, binding = 2, std430) readonly buffer PositionsIn { vec4 positions_in[]; };    // w: 1 free, minus its pin group pinned
layout(set = 0, binding = 3, std430) readonly buffer VelocitiesIn { vec4 velocities_in[]; };  // w: the state's time, s
layout(set = 0, binding = 4, std430) buffer PositionsOut { vec4 positions_out[]; };
layout(set = 0, binding = 5, std430) buffer VelocitiesOut { vec4 velocities_out[]; };
layout(set = 0, binding = 6, std430) buffer MaxPenetration { uint max_penetration_bits; };

// The tile's state, one array per component (24 bytes a cell): cell c = a + b · TILE_WIDTH holds
// the grid vertex (a, b) cells from the tile's corner (the output block's corner less the halo).
shared float tile_px[TILE_CELLS];
shared float tile_py[TILE_CELLS];
shared float tile_pz[TILE_CELLS];
shared float tile_vx[TILE_CELLS];
shared float tile_vy[TILE_CELLS];
shared float tile_vz[TILE_CELLS];

vec3 tile_position(uint c) {
    return vec3(tile_px[c], tile_py[c], tile_pz[c]);
}

vec3 tile_velocity(uint c) {
    return vec3(tile_vx[c], tile_vy[c], tile_vz[c]);
}

void set_tile_state(uint c, vec3 x, vec3 v) {
    tile_px[c] = x.x;
    tile_py[c] = x.y;
    tile_pz[c] = x.z;
    tile_vx[c] = v.x;
    tile_vy[c] = v.y;
    tile_vz[c] = v.z;
}

// cloth_step.comp's add_spring, the neighbour read from the tile: (i, j) is cell c's vertex.
void add_tile_spring(inout vec3 force, uint c, int i, int j, int di, int dj, uint kind, float rest_length, vec3 x, vec3 v) {
    int ni = i + di;
    int nj = j + dj;
    if (ni < 0 || nj < 0 || ni >= int(params.grid_nx) || nj >= int(params.grid_ny)) {
        return;
    }
    uint other = uint(int(c) + di + dj * int(TILE_WIDTH));
    float damping = 0.0;
    if (EFFECT_SPRING_DAMPING) {
        damping = params.damping[kind];
    }
    add_spring_force(force, x, tile_position(other), v, tile_velocity(other),
                     rest_length, params.stiffness[kind], damping);
}

// cloth_step.comp's add_stencil_springs (same springs, same order), from the tile.
void add_tile_springs(inout vec3 force, uint c, int i, int j, vec3 x, vec3 v) {
    vec4 rest = params.rest_lengths;
    if (EFFECT_STRUCTURAL) {
        add_tile_spring(force, c, i, j, 0, -1, 0u, rest.y, x, v);
        add_tile_spring(force, c, i, j, -1, 0, 0u, rest.x, x, v);
        add_tile_spring(force, c, i, j, 1, 0, 0u, rest.x, x, v);
        add_tile_spring(force, c, i, j, 0, 1, 0u, rest.y, x, v);
    }
    if (EFFECT_SHEAR) {
        add_tile_spring(force, c, i, j, -1, -1, 1u, rest.z, x, v);
        add_tile_spring(force, c, i, j, 1, -1, 1u, rest.z, x, v);
        add_tile_spring(force, c, i, j, 1, 1, 1u, rest.z, x, v);
        add_tile_spring(force, c, i, j, -1, 1, 1u, rest.z, x, v);
    }
    if (EFFECT_BEND) {
        add_tile_spring(force, c, i, j, 0, -2, 2u, 2.0 * rest.y, x, v);
        add_tile_spring(force, c, i, j, -2, 0, 2u, 2.0 * rest.x, x, v);
        add_tile_spring(force, c, i, j, 2, 0, 2u, 2.0 * rest.x, x, v);
        add_tile_spring(force, c, i, j, 0, 2, 2u, 2.0 * rest.y, x, v);
    }
}

// grid.glsl's grid_normal, from the tile: one-sided at the grid's edges.
vec3 tile_normal(uint c, int i, int j) {
    int w = int(TILE_WIDTH);
    int left = i > 0 ? -1 : 0;
    int right = i + 1 < int(params.grid_nx) ? 1 : 0;
    int down = j > 0 ? -w : 0;
    int up = j + 1 < int(params.grid_ny) ? w : 0;
    vec3 along_u = tile_position(uint(int(c) + right)) - tile_position(uint(int(c) + left));
    vec3 along_v = tile_position(uint(int(c) + up)) - tile_position(uint(int(c) + down));
    vec3 n = cross(along_u, along_v);
    float len = sqrt(dot(n, n));
    if (len > 0.0) {
        return n * (1.0 / len);
    }
    return vec3(0.0);
}

void main() {
    uint halo = 2u * FUSED_SUBSTEPS;
    int nx = int(params.grid_nx);
    int ny = int(params.grid_ny);
    // This invocation's cell (a, b) of the tile, c in the tile's arrays, and its grid vertex
    // (i, j): the output block's corner less the halo (outside the grid at the grid's low edges;
    // such cells are never read, since the grid-edge checks come first).
    uint a = gl_LocalInvocationID.x;
    uint b = gl_LocalInvocationID.y;
    uint c = a + b * TILE_WIDTH;
    int i = int(gl_WorkGroupID.x * (TILE_WIDTH - 2u * halo) + a) - int(halo);
    int j = int(gl_WorkGroupID.y * (TILE_HEIGHT - 2u * halo) + b) - int(halo);
    bool in_grid = i >= 0 && j >= 0 && i < nx && j < ny;
    uint index = 0u;
    float free_w = 0.0;   // 1 free, minus the pin group pinned
    float t = 0.0;        // the state's time, s
    if (in_grid) {
        index = uint(j) * params.grid_nx + uint(i);
        vec4 p = positions_in[index];
        vec4 state = velocities_in[index];
        set_tile_state(c, p.xyz, state.xyz);
        free_w = p.w;
        t = state.w;
    }
    barrier();
    float dt = params.substep_dt;
    float mass = params.vertex_mass;
    // The output block: the cells at least `halo` from the tile's edge (each vertex is in exactly
    // one output block).
    bool is_output = in_grid && a >= halo && b >= halo && a < TILE_WIDTH - halo && b < TILE_HEIGHT - halo;
    float deepest = 0.0;
    for (uint s = 1u; s <= FUSED_SUBSTEPS; s++) {
        // Exact after this substep: the cells at least 2s from the tile's edge.
        uint lo = 2u * s;
        bool is_active = in_grid && a >= lo && b >= lo && a < TILE_WIDTH - lo && b < TILE_HEIGHT - lo;
        vec3 x_new = vec3(0.0);
        vec3 v_new = vec3(0.0);
        if (is_active) {
            vec3 x = tile_position(c);
            vec3 v = tile_velocity(c);
            float t_out = t + dt;
            if (free_w > 0.0) {
                vec3 force = vec3(0.0);
                if (EFFECT_GRAVITY) {
                    force += gravity_force(mass, params.gravity.xyz);
                }
                if (ANY_SPRINGS) {
                    add_tile_springs(force, c, i, j, x, v);
                }
                if (EFFECT_AIR_DRAG) {
                    force += air_drag_force(mass, params.air_drag, v);
                }
                if (EFFECT_WIND) {
                    force += wind_force(tile_normal(c, i, j), v, wind_velocity(t), params.wind.w);
                }
                vec3 other_forces = force;
                if (EFFECT_CONTACT) {
                    for (uint n = 0u; n < params.collider_count; n++) {
                        vec3 center = collider_center(n, t);
                        // The normal only for a vertex inside: outside, the distance alone.
                        Surface surface = collider_contact(n, center, x);
                        if (surface.distance >= 0.0) {
                            continue;
                        }
                        vec3 v_rel = v - collider_velocity(n, t);
                        vec3 normal;
                        vec3 contact;
                        if (contact_force(v_rel, surface, colliders[n].stiffness,
                                  colliders[n].damping, normal, contact)) {
                            force += contact;
                            if (EFFECT_FRICTION) {
                                force += friction_force(other_forces, v_rel, normal, mass, dt, colliders[n].friction);
                            }
                        }
                    }
                }
                // v_c = v_p + Δt R/m, x_c = x_p + Δt v_c (semi-implicit Euler).
                v_new = v + force * (dt / mass);
                x_new = x + v_new * dt;
            } else {
                // A pin stays put, or follows its group's motion (MovingPins) from t to t_out.
                uint group = pin_group(free_w);
                x_new = pin_carry(group, x, t, t_out);
                v_new = pin_velocity(group, x_new, t_out);
            }
            t = t_out;
            // The deepest penetration at the end of each substep, over the output block.
            if (EFFECT_CONTACT) {
                if (is_output) {
                    for (uint n = 0u; n < params.collider_count; n++) {
                        deepest = max(deepest, -collider_distance(n, collider_center(n, t_out), x_new));
                    }
                }
            }
        }
        barrier();
        if (is_active) {
            set_tile_state(c, x_new, v_new);
        }
        barrier();
    }
    if (is_output) {
        positions_out[index] = vec4(tile_position(c), free_w);
        velocities_out[index] = vec4(tile_velocity(c), t);
    }
    if (EFFECT_CONTACT) {
        if (deepest > 0.0) {
            atomicMax(max_penetration_bits, floatBitsToUint(deepest));
        }
    }
}
