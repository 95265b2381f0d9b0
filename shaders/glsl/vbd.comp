#version 450
#extension GL_GOOGLE_include_directive : require

// One Vertex Block Descent substep (cloth_core::Integrator::Vbd), as a sequence of passes: the
// GLSL twin of shaders/wgsl/vbd.wgsl. The local step mirrors crates/cloth-core/src/vbd.rs
// (LocalTerms) term by term, and the passes cloth_core::reference's vbd_substep. A substep is:
//   pass 0 (per vertex)     predict: the inertial prediction y = x + h v* (v* = v + h g, drag,
//                           wind, as XPBD predicts, plus h/m times self-collision's repulsion at
//                           the substep's start), and the initial guess (the adaptive
//                           initialisation: x + h v + h² s g, s the share of gravity the last
//                           substep showed);
//   then the solver's vbd_iterations sweeps of
//     pass 1 (per vertex of one colour, once per colour)  the vertex's Newton step on its local
//                           incremental potential (inertia, springs with damping, colliders with
//                           friction), optionally extrapolated by Chebyshev's weight of the sweep;
//   pass 2 (per vertex)     v = (x − x⁰)/h (with SelfCollision, the speed limit), deepest
//                           penetration, the velocity the next prediction compares with.
// With the solver's vbd_multigrid_every, a coarse correction (cloth_core::multigrid) comes
// before every that many sweeps, passes 3 to 9 as vbd.wgsl describes them.
// The vertices of colour c are those with (i + 2j) mod 5 = c (cloth_core::coloring::vertex_color).
// Units: m, kg, s, N/m.

#include "effects.glsl"

// Which pass this pipeline runs (see above).
layout(constant_id = 101) const uint VBD_PASS = 0u;
// The colour pass 1 moves.
layout(constant_id = 112) const uint VBD_COLOR = 0u;

// The binding of the mesh colliders' distance fields, which layout.glsl declares.
#define DISTANCE_FIELDS_BINDING 11
#include "layout.glsl"
#include "forces.glsl"

// Self-collision's candidate lists, its hash and its control (self_hash.comp; placeholders
// without SelfCollision).
layout(set = 0, binding = 12, std430) readonly buffer SelfWords { uint self_words[]; };
layout(set = 0, binding = 13, std430) readonly buffer SelfLinks { uvec4 self_links[]; };
layout(set = 0, binding = 14, std430) buffer SelfControlBuffer { SelfControl self_control; };

// The hash's words 4 at4 to 4 at4 + 3 (self_collision.glsl).
uvec4 link_words(uint at4) {
    return self_links[at4];
}

#include "self_collision.glsl"

// The state at the substep's start (w: 1 free, minus its pin group pinned; velocity w: the time).
layout(set = 0, binding = 2, std430) readonly buffer PositionsIn { vec4 positions_in[]; };
layout(set = 0, binding = 3, std430) readonly buffer VelocitiesIn { vec4 velocities_in[]; };
// The iterate, moved in place by the sweeps; then the new state.
layout(set = 0, binding = 4, std430) buffer PositionsOut { vec4 positions_out[]; };
layout(set = 0, binding = 5, std430) buffer VelocitiesOut { vec4 velocities_out[]; };
// Deepest penetration so far, m, as the bits of a non-negative float (see cloth_step.comp).
layout(set = 0, binding = 6, std430) buffer MaxPenetration { uint max_penetration_bits; };
// Each vertex's inertial prediction y, m.
layout(set = 0, binding = 7, std430) buffer Predicted { vec4 predicted[]; };
// Each vertex's velocity at the start of the previous substep, m/s (the adaptive initialisation).
layout(set = 0, binding = 8, std430) buffer LastVelocities { vec4 last_velocities[]; };
// Chebyshev's history (a placeholder without it): each vertex's iterate one sweep back at 2 i,
// two sweeps back at 2 i + 1, m.
layout(set = 0, binding = 9, std430) buffer History { vec4 history[]; };
// cloth_gpu::layout::GpuVbdSweep (48 bytes): the sweep pass 1 belongs to, or the level of a
// multigrid pass (offsets in vec4s of the multigrid buffer), selected by a dynamic offset.
layout(set = 0, binding = 10, std140) uniform VbdSweep {
    float omega;            // Chebyshev's weight of the sweep
    uint chebyshev;         // 1: Chebyshev acceleration on
    uint nx;                // this level's nodes along i (level 0: the grid's vertices)
    uint ny;                // and along j
    uint coarse_nx;         // the next coarser level's nodes along i
    uint coarse_ny;         // and along j
    uint stencil;           // this level's stencil, 27 vec4s a node
    uint vectors;           // this level's b, then its e
    uint partials;          // this level's partial sums
    uint coarse_stencil;    // the next level's stencil
    uint coarse_vectors;    // the next level's b, then its e
    uint coarse_partials;   // the next level's partial sums
} sweep;

// The multigrid correction's levels: each node's 3 × 3 stencil of 3 × 3 blocks (27 rows), the
// right-hand sides b, the corrections e, the partial sums (a placeholder without it).
layout(set = 0, binding = 15, std430) buffer Multigrid { vec4 multigrid[]; };

// The position of vertex `index` in the state read, m (for grid.glsl's grid_normal).
vec3 position_in(uint index) {
    return positions_in[index].xyz;
}

#include "grid.glsl"
#include "self_partners.glsl"

// The self-collision term of partner j (self_partners.glsl): its repulsion at the substep's
// start on free vertex i at c.x moving at c.a, with the friction's step c.s.
vec4 pair_term(uint j, PairContext c) {
    vec3 x_j = positions_in[j].xyz;
    if (!in_contact(c.x, x_j)) {
        return vec4(0.0);
    }
    return vec4(repulsion_force(c.x, x_j, c.a, velocities_in[j].xyz, params.vertex_mass, c.s), 0.0);
}

// The slip speed below which friction holds a vertex like a stiff tangential spring, m/s
// (cloth_core::vbd::FRICTION_SLIP_SPEED).
const float FRICTION_SLIP_SPEED = 1e-4;

// The band outside a collider's surface within which a vertex's local potential holds the
// contact's curvature, and from beyond which a step into the collider stops at its surface, m
// (cloth_core::vbd::CONTACT_BAND).
const float CONTACT_BAND = 1e-4;

// A 3 × 3 matrix by rows (cloth_core::real::Mat3).
struct Mat3 {
    vec3 r0;
    vec3 r1;
    vec3 r2;
};

Mat3 mat3_scaled(Mat3 m, float s) {
    return Mat3(m.r0 * s, m.r1 * s, m.r2 * s);
}

Mat3 mat3_add(Mat3 a, Mat3 b) {
    return Mat3(a.r0 + b.r0, a.r1 + b.r1, a.r2 + b.r2);
}

Mat3 mat3_identity() {
    return Mat3(vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0));
}

// a bᵀ.
Mat3 mat3_outer(vec3 a, vec3 b) {
    return Mat3(b * a.x, b * a.y, b * a.z);
}

// I − m.
Mat3 mat3_complement(Mat3 m) {
    return Mat3(vec3(1.0, 0.0, 0.0) - m.r0, vec3(0.0, 1.0, 0.0) - m.r1, vec3(0.0, 0.0, 1.0) - m.r2);
}

// The vertex's local gradient g, N, and Hessian H, N/m (cloth_core::vbd::LocalTerms).
struct LocalTerms {
    vec3 g;
    Mat3 h;
};

// The spring stiffness block K = k (u uᵀ + max(0, 1 − L0/L)(I − u uᵀ))
// (cloth_core::forces::spring_stiffness_block).
Mat3 spring_stiffness_block(vec3 x_i, vec3 x_j, float rest_length, float stiffness) {
    vec3 delta = x_j - x_i;
    float len = sqrt(dot(delta, delta));
    if (len <= 0.0) {
        return mat3_scaled(mat3_identity(), 0.0);
    }
    vec3 u = delta * (1.0 / len);
    Mat3 axial = mat3_outer(u, u);
    float transverse = max(1.0 - rest_length / len, 0.0);
    return mat3_scaled(mat3_add(axial, mat3_scaled(mat3_complement(axial), transverse)), stiffness);
}

// The spring damping block C = c_d u uᵀ (cloth_core::forces::spring_damping_block).
Mat3 spring_damping_block(vec3 x_i, vec3 x_j, float damping) {
    vec3 delta = x_j - x_i;
    float len = sqrt(dot(delta, delta));
    if (len <= 0.0) {
        return mat3_scaled(mat3_identity(), 0.0);
    }
    vec3 u = delta * (1.0 / len);
    return mat3_scaled(mat3_outer(u, u), damping);
}

// A spring to neighbour j (LocalTerms::add_spring).
void add_local_spring(inout LocalTerms t, vec3 x, vec3 x0, uint j, uint kind, float rest_length) {
    vec3 x_j = positions_out[j].xyz;
    vec3 x0_j = positions_in[j].xyz;
    float inv_h = 1.0 / params.substep_dt;
    float damping = EFFECT_SPRING_DAMPING ? params.damping[kind] : 0.0;
    vec3 force = vec3(0.0);
    add_spring_force(force, x, x_j, (x - x0) * inv_h, (x_j - x0_j) * inv_h, rest_length, params.stiffness[kind], damping);
    t.g = t.g - force;
    t.h = mat3_add(t.h, spring_stiffness_block(x, x_j, rest_length, params.stiffness[kind]));
    if (damping > 0.0) {
        t.h = mat3_add(t.h, mat3_scaled(spring_damping_block(x, x_j, damping), inv_h));
    }
}

// The spring from vertex (i, j) to its grid neighbour (i + di, j + dj), if it exists.
void add_neighbour(inout LocalTerms t, vec3 x, vec3 x0, int i, int j, int di, int dj, uint kind, float rest_length) {
    uint ni = uint(i + di);
    uint nj = uint(j + dj);
    if (ni >= params.grid_nx || nj >= params.grid_ny) {
        return;
    }
    add_local_spring(t, x, x0, nj * params.grid_nx + ni, kind, rest_length);
}

// Collider c whose surface seen from x is `surface`, moving at `velocity` (LocalTerms::add_contact).
void add_local_contact(inout LocalTerms t, vec3 x, vec3 x0, Surface surface, vec3 velocity, uint c) {
    float h = params.substep_dt;
    float inv_h = 1.0 / h;
    vec3 v_rel = (x - x0) * inv_h - velocity;
    vec3 contact_normal;
    vec3 force;
    bool hit = contact_force(v_rel, surface, colliders[c].stiffness, colliders[c].damping, contact_normal, force);
    vec3 n = surface.normal;
    if (hit) {
        t.g = t.g - force;
    }
    // (Inside, φ < 0, and in the band outside the surface, without a force there
    // (CONTACT_BAND): the stiffness block k_c n nᵀ; the damping block c n nᵀ while approaching.)
    Mat3 blocks = mat3_scaled(mat3_outer(n, n), colliders[c].stiffness);
    if (dot(v_rel, n) < 0.0) {
        blocks = mat3_add(blocks, mat3_scaled(mat3_scaled(mat3_outer(n, n), colliders[c].damping), inv_h));
    }
    t.h = mat3_add(t.h, blocks);
    if (!hit) {
        return;
    }
    float friction = EFFECT_FRICTION ? colliders[c].friction : 0.0;
    float normal_force = dot(force, n);
    if (friction <= 0.0 || normal_force <= 0.0) {
        return;
    }
    vec3 slip = v_rel * h;
    vec3 u = slip - n * dot(slip, n);
    float reach = max(sqrt(dot(u, u)), FRICTION_SLIP_SPEED * h);
    float scale = friction * normal_force / reach;
    t.g = t.g + u * scale;
    t.h = mat3_add(t.h, mat3_scaled(mat3_complement(mat3_outer(n, n)), scale));
}

// x − H⁻¹ g (LocalTerms::step): the inverse's columns are the cross products of the rows over
// the determinant; the vertex stays where H is singular.
vec3 newton_step(vec3 x, LocalTerms t) {
    vec3 a = t.h.r0;
    vec3 b = t.h.r1;
    vec3 c = t.h.r2;
    float det = dot(a, cross(b, c));
    if (det == 0.0 || isinf(det) || isnan(det)) {
        return x;
    }
    float inv = 1.0 / det;
    vec3 c0 = cross(b, c) * inv;
    vec3 c1 = cross(c, a) * inv;
    vec3 c2 = cross(a, b) * inv;
    vec3 g = t.g;
    return x - vec3(dot(vec3(c0.x, c1.x, c2.x), g), dot(vec3(c0.y, c1.y, c2.y), g), dot(vec3(c0.z, c1.z, c2.z), g));
}

// The share of gravity the adaptive initialisation adds (cloth_core::vbd::gravity_share).
float gravity_share(vec3 acceleration, vec3 gravity) {
    float g2 = dot(gravity, gravity);
    if (g2 <= 0.0) {
        return 0.0;
    }
    return min(max(dot(acceleration, gravity) / g2, 0.0), 1.0);
}

void predict(uint i) {
    vec4 p = positions_in[i];
    vec4 state = velocities_in[i];
    float t = state.w;
    float h = params.substep_dt;
    float m = params.vertex_mass;
    vec3 y = p.xyz;
    vec3 guess = p.xyz;
    if (p.w > 0.0) {
        vec3 v = state.xyz;
        if (EFFECT_GRAVITY) {
            v += params.gravity.xyz * h;
        }
        if (EFFECT_AIR_DRAG) {
            v += air_drag_force(m, params.air_drag, v) * (h / m);
        }
        if (EFFECT_WIND) {
            v += wind_force(grid_normal(i), v, wind_velocity(t), params.wind.w) * (h / m);
        }
        y = p.xyz + v * h;
        if (EFFECT_SELF_COLLISION) {
            uint nx = params.grid_nx;
            vec3 push = sum_over_partners(i, i % nx, i / nx, PairContext(p.xyz, state.xyz, h)).xyz;
            y += push * (h * h / m);
        }
        vec3 acceleration = (state.xyz - last_velocities[i].xyz) * (1.0 / h);
        vec3 gravity = params.gravity.xyz;
        guess = p.xyz + state.xyz * h + gravity * (gravity_share(acceleration, gravity) * h * h);
    } else {
        y = pin_carry(pin_group(p.w), p.xyz, t, t + h);
        guess = y;
    }
    predicted[i] = vec4(y, p.w);
    positions_out[i] = vec4(guess, p.w);
    if (sweep.chebyshev != 0u) {
        history[2u * i] = vec4(guess, 0.0);
        history[2u * i + 1u] = vec4(guess, 0.0);
    }
}

// The local terms of free vertex `index` at (i, j), where the sweeps have it (positions_out):
// inertia, its springs and its colliders (cloth_core::reference's vbd_substep, local_terms).
LocalTerms vertex_terms(uint index, uint i, uint j) {
    float h = params.substep_dt;
    float m = params.vertex_mass;
    vec3 x = positions_out[index].xyz;
    vec3 x0 = positions_in[index].xyz;
    float w = m / (h * h);
    LocalTerms t = LocalTerms((x - predicted[index].xyz) * w, mat3_scaled(mat3_identity(), w));
    // The stencil in the reference's spring order (cloth_step.comp's add_stencil_springs).
    int ii = int(i);
    int jj = int(j);
    vec4 rest = params.rest_lengths;
    if (EFFECT_STRUCTURAL) {
        add_neighbour(t, x, x0, ii, jj, 0, -1, 0u, rest.y);
        add_neighbour(t, x, x0, ii, jj, -1, 0, 0u, rest.x);
        add_neighbour(t, x, x0, ii, jj, 1, 0, 0u, rest.x);
        add_neighbour(t, x, x0, ii, jj, 0, 1, 0u, rest.y);
    }
    if (EFFECT_SHEAR) {
        add_neighbour(t, x, x0, ii, jj, -1, -1, 1u, rest.z);
        add_neighbour(t, x, x0, ii, jj, 1, -1, 1u, rest.z);
        add_neighbour(t, x, x0, ii, jj, 1, 1, 1u, rest.z);
        add_neighbour(t, x, x0, ii, jj, -1, 1, 1u, rest.z);
    }
    if (EFFECT_BEND) {
        add_neighbour(t, x, x0, ii, jj, 0, -2, 2u, 2.0 * rest.y);
        add_neighbour(t, x, x0, ii, jj, -2, 0, 2u, 2.0 * rest.x);
        add_neighbour(t, x, x0, ii, jj, 2, 0, 2u, 2.0 * rest.x);
        add_neighbour(t, x, x0, ii, jj, 0, 2, 2u, 2.0 * rest.y);
    }
    if (EFFECT_CONTACT) {
        float t_end = velocities_in[index].w + h;
        for (uint c = 0u; c < params.collider_count; c++) {
            vec3 center = collider_center(c, t_end);
            if (collider_distance(c, center, x) < CONTACT_BAND) {
                add_local_contact(t, x, x0, collider_surface(c, center, x), collider_velocity(c, t_end), c);
            }
        }
    }
    return t;
}

// Where a move of a vertex from `x` to `moved`, at the substep's end time `t_end`, stops: at the
// surface of a collider it would enter from beyond its band (cloth_core::vbd::surface_fraction).
vec3 stop_at_surfaces(vec3 x, vec3 moved, float t_end) {
    float fraction = 1.0;
    for (uint c = 0u; c < params.collider_count; c++) {
        vec3 center = collider_center(c, t_end);
        float start = collider_distance(c, center, x);
        float end = collider_distance(c, center, moved);
        if (start > CONTACT_BAND && end < 0.0) {
            fraction = min(fraction, start / (start - end));
        }
    }
    if (fraction < 1.0) {
        return x + (moved - x) * fraction;
    }
    return moved;
}

// Pass 1: the vertex of colour VBD_COLOR that invocation `k` moves (row j, every fifth column
// from the row's first of the colour).
void step_color(uint k) {
    uint nx = params.grid_nx;
    uint per_row = (nx + 4u) / 5u;
    uint j = k / per_row;
    if (j >= params.grid_ny) {
        return;
    }
    uint i = (VBD_COLOR + 5u - (2u * j) % 5u) % 5u + 5u * (k % per_row);
    if (i >= nx) {
        return;
    }
    uint index = j * nx + i;
    vec4 p = positions_out[index];
    if (p.w <= 0.0) {
        return;
    }
    vec3 x = p.xyz;
    LocalTerms t = vertex_terms(index, i, j);
    vec3 moved = newton_step(x, t);
    if (EFFECT_CONTACT) {
        // A step from outside a collider into it stops at its surface.
        moved = stop_at_surfaces(x, moved, velocities_in[index].w + params.substep_dt);
    }
    if (sweep.chebyshev != 0u) {
        vec3 before = history[2u * index + 1u].xyz;
        moved = before + (moved - before) * sweep.omega;
        history[2u * index + 1u] = history[2u * index];
        history[2u * index] = vec4(moved, 0.0);
    }
    positions_out[index] = vec4(moved, p.w);
}

// Pass 2; returns the vertex's displacement over the substep (w 1).
vec4 finish(uint i) {
    vec4 p = positions_out[i];
    vec4 start = velocities_in[i];
    float t_end = start.w + params.substep_dt;
    vec3 x = p.xyz;
    vec3 v = pin_velocity(pin_group(p.w), x, t_end);
    if (p.w > 0.0) {
        vec3 x0 = positions_in[i].xyz;
        v = (x - x0) * (1.0 / params.substep_dt);
        if (EFFECT_SELF_COLLISION) {
            // The speed limit (self_collision.glsl).
            x = limit_step(x0, x);
            v = limit_velocity(v);
            positions_out[i] = vec4(x, p.w);
        }
    }
    last_velocities[i] = vec4(start.xyz, 0.0);
    velocities_out[i] = vec4(v, t_end);
    if (EFFECT_CONTACT) {
        float deepest = 0.0;
        for (uint s = 0u; s < params.collider_count; s++) {
            deepest = max(deepest, -collider_distance(s, collider_center(s, t_end), x));
        }
        if (deepest > 0.0) {
            atomicMax(max_penetration_bits, floatBitsToUint(deepest));
        }
    }
    return vec4(x - positions_in[i].xyz, 1.0);
}

// Runs the pipeline's pass for the invocation; returns the vertex's displacement over the
// substep in the finishing pass (w 1), zero otherwise.
vec4 run_pass() {
    // 2D dispatch: more than maxComputeWorkGroupCount[0] workgroups spill into y.
    uint k = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (VBD_PASS == 1u) {
        step_color(k);
        return vec4(0.0);
    }
    if (k >= params.vertex_count) {
        return vec4(0.0);
    }
    if (VBD_PASS == 0u) {
        predict(k);
        return vec4(0.0);
    }
    return finish(k);
}

// The multigrid correction (passes 3 to 9; cloth_core::multigrid).

vec3 mat3_mul(Mat3 m, vec3 v) {
    return vec3(dot(m.r0, v), dot(m.r1, v), dot(m.r2, v));
}

// The stencil entry of the node at (di, dj) from a node (cloth_core::multigrid::slot).
uint mg_slot(int di, int dj) {
    return uint((di + 1) + 3 * (dj + 1));
}

// Block `s` of node `node` of the stencil at `base`.
Mat3 mg_block(uint base, uint node, uint s) {
    uint at = base + 27u * node + 3u * s;
    return Mat3(multigrid[at].xyz, multigrid[at + 1u].xyz, multigrid[at + 2u].xyz);
}

void mg_store_block(uint base, uint node, uint s, Mat3 m) {
    uint at = base + 27u * node + 3u * s;
    multigrid[at] = vec4(m.r0, 0.0);
    multigrid[at + 1u] = vec4(m.r1, 0.0);
    multigrid[at + 2u] = vec4(m.r2, 0.0);
}

Mat3 mat3_zero() {
    return Mat3(vec3(0.0), vec3(0.0), vec3(0.0));
}

// This level's correction at node `node`.
vec3 mg_e(uint node) {
    return multigrid[sweep.vectors + sweep.nx * sweep.ny + node].xyz;
}

// (A e) at node (i, j) of this level, leaving out the node's own block when `skip_self`.
vec3 mg_apply(uint i, uint j, bool skip_self) {
    uint node = j * sweep.nx + i;
    vec3 sum = vec3(0.0);
    for (int dj = -1; dj <= 1; dj++) {
        for (int di = -1; di <= 1; di++) {
            if (skip_self && di == 0 && dj == 0) {
                continue;
            }
            int ni = int(i) + di;
            int nj = int(j) + dj;
            if (ni < 0 || nj < 0 || ni >= int(sweep.nx) || nj >= int(sweep.ny)) {
                continue;
            }
            sum += mat3_mul(mg_block(sweep.stencil, node, mg_slot(di, dj)), mg_e(uint(nj) * sweep.nx + uint(ni)));
        }
    }
    return sum;
}

// The coupling block −(K_s + C_s/h) of vertex (i, j)'s spring to its neighbour (i + di, j + dj), if
// both are free, added to the level-1 stencil entry of the neighbour's aggregate.
void mg_add_coupling(inout Mat3 blocks[9], vec3 x, int i, int j, int di, int dj, uint kind, float rest_length) {
    int ni = i + di;
    int nj = j + dj;
    if (ni < 0 || nj < 0 || ni >= int(params.grid_nx) || nj >= int(params.grid_ny)) {
        return;
    }
    vec4 other = positions_out[uint(nj) * params.grid_nx + uint(ni)];
    if (other.w <= 0.0) {
        return;
    }
    Mat3 k = spring_stiffness_block(x, other.xyz, rest_length, params.stiffness[kind]);
    if (EFFECT_SPRING_DAMPING) {
        float c = params.damping[kind];
        k = mat3_add(k, mat3_scaled(spring_damping_block(x, other.xyz, c), 1.0 / params.substep_dt));
    }
    uint s = mg_slot(ni / 2 - i / 2, nj / 2 - j / 2);
    blocks[s] = mat3_add(blocks[s], mat3_scaled(k, -1.0));
}

// Pass 3: level-1 node k from its 2 × 2 vertices (cloth_core::multigrid::first_level).
void mg_assemble(uint k) {
    uint cnx = sweep.coarse_nx;
    if (k >= cnx * sweep.coarse_ny) {
        return;
    }
    uint ci = k % cnx;
    uint cj = k / cnx;
    Mat3 blocks[9];
    for (uint s = 0u; s < 9u; s++) {
        blocks[s] = mat3_zero();
    }
    vec3 b = vec3(0.0);
    vec4 rest = params.rest_lengths;
    for (uint dj = 0u; dj < 2u; dj++) {
        for (uint di = 0u; di < 2u; di++) {
            uint i = 2u * ci + di;
            uint j = 2u * cj + dj;
            if (i >= params.grid_nx || j >= params.grid_ny) {
                continue;
            }
            uint index = j * params.grid_nx + i;
            vec4 p = positions_out[index];
            if (p.w <= 0.0) {
                continue;
            }
            LocalTerms t = vertex_terms(index, i, j);
            b -= t.g;
            blocks[4] = mat3_add(blocks[4], t.h);
            int ii = int(i);
            int jj = int(j);
            if (EFFECT_STRUCTURAL) {
                mg_add_coupling(blocks, p.xyz, ii, jj, 0, -1, 0u, rest.y);
                mg_add_coupling(blocks, p.xyz, ii, jj, -1, 0, 0u, rest.x);
                mg_add_coupling(blocks, p.xyz, ii, jj, 1, 0, 0u, rest.x);
                mg_add_coupling(blocks, p.xyz, ii, jj, 0, 1, 0u, rest.y);
            }
            if (EFFECT_SHEAR) {
                mg_add_coupling(blocks, p.xyz, ii, jj, -1, -1, 1u, rest.z);
                mg_add_coupling(blocks, p.xyz, ii, jj, 1, -1, 1u, rest.z);
                mg_add_coupling(blocks, p.xyz, ii, jj, 1, 1, 1u, rest.z);
                mg_add_coupling(blocks, p.xyz, ii, jj, -1, 1, 1u, rest.z);
            }
            if (EFFECT_BEND) {
                mg_add_coupling(blocks, p.xyz, ii, jj, 0, -2, 2u, 2.0 * rest.y);
                mg_add_coupling(blocks, p.xyz, ii, jj, -2, 0, 2u, 2.0 * rest.x);
                mg_add_coupling(blocks, p.xyz, ii, jj, 2, 0, 2u, 2.0 * rest.x);
                mg_add_coupling(blocks, p.xyz, ii, jj, 0, 2, 2u, 2.0 * rest.y);
            }
        }
    }
    for (uint s = 0u; s < 9u; s++) {
        mg_store_block(sweep.coarse_stencil, k, s, blocks[s]);
    }
    uint nodes = cnx * sweep.coarse_ny;
    multigrid[sweep.coarse_vectors + k] = vec4(b, 0.0);
    multigrid[sweep.coarse_vectors + nodes + k] = vec4(0.0);
}

// Pass 4: node k of the next level, this level's stencil summed 2 × 2 (Level::coarsen).
void mg_coarsen(uint k) {
    uint cnx = sweep.coarse_nx;
    if (k >= cnx * sweep.coarse_ny) {
        return;
    }
    int ci = int(k % cnx);
    int cj = int(k / cnx);
    Mat3 blocks[9];
    for (uint s = 0u; s < 9u; s++) {
        blocks[s] = mat3_zero();
    }
    for (int b = 0; b < 2; b++) {
        for (int a = 0; a < 2; a++) {
            int i = 2 * ci + a;
            int j = 2 * cj + b;
            if (i >= int(sweep.nx) || j >= int(sweep.ny)) {
                continue;
            }
            uint node = uint(j) * sweep.nx + uint(i);
            for (int dj = -1; dj <= 1; dj++) {
                for (int di = -1; di <= 1; di++) {
                    int ni = i + di;
                    int nj = j + dj;
                    if (ni < 0 || nj < 0 || ni >= int(sweep.nx) || nj >= int(sweep.ny)) {
                        continue;
                    }
                    uint s = mg_slot(ni / 2 - ci, nj / 2 - cj);
                    blocks[s] = mat3_add(blocks[s], mg_block(sweep.stencil, node, mg_slot(di, dj)));
                }
            }
        }
    }
    for (uint s = 0u; s < 9u; s++) {
        mg_store_block(sweep.coarse_stencil, k, s, blocks[s]);
    }
}

// Pass 5: block Gauss–Seidel at node k of colour VBD_COLOR (Level::smooth).
void mg_smooth(uint k) {
    uint half_nx = (sweep.nx + 1u) / 2u;
    uint i = 2u * (k % half_nx) + VBD_COLOR % 2u;
    uint j = 2u * (k / half_nx) + VBD_COLOR / 2u;
    if (i >= sweep.nx || j >= sweep.ny) {
        return;
    }
    uint node = j * sweep.nx + i;
    vec3 rhs = multigrid[sweep.vectors + node].xyz - mg_apply(i, j, true);
    // A⁻¹ rhs as newton_step's x − H⁻¹ g at x = 0, g = −rhs (0 where the block is singular).
    vec3 e = newton_step(vec3(0.0), LocalTerms(-rhs, mg_block(sweep.stencil, node, 4u)));
    multigrid[sweep.vectors + sweep.nx * sweep.ny + node] = vec4(e, 0.0);
}

// Pass 6: node k of the next level: the sum of its children's residuals b − A e, and e' = 0.
void mg_restrict(uint k) {
    uint cnx = sweep.coarse_nx;
    uint nodes = cnx * sweep.coarse_ny;
    if (k >= nodes) {
        return;
    }
    uint ci = k % cnx;
    uint cj = k / cnx;
    vec3 b = vec3(0.0);
    for (uint dj = 0u; dj < 2u; dj++) {
        for (uint di = 0u; di < 2u; di++) {
            uint i = 2u * ci + di;
            uint j = 2u * cj + dj;
            if (i < sweep.nx && j < sweep.ny) {
                b += multigrid[sweep.vectors + j * sweep.nx + i].xyz - mg_apply(i, j, false);
            }
        }
    }
    multigrid[sweep.coarse_vectors + k] = vec4(b, 0.0);
    multigrid[sweep.coarse_vectors + nodes + k] = vec4(0.0);
}

#include "workgroup_sum.glsl"

// Pass 7: this level's partial sums of e·A e and b·e, one a workgroup (uniform control flow).
void mg_model(uint k, uint local, uint group) {
    vec2 value = vec2(0.0);
    if (k < sweep.nx * sweep.ny) {
        uint i = k % sweep.nx;
        uint j = k / sweep.nx;
        vec3 e = mg_e(k);
        value = vec2(dot(e, mg_apply(i, j, false)), dot(multigrid[sweep.vectors + k].xyz, e));
    }
    vec2 total = workgroup_sum(value, local);
    if (local == 0u) {
        multigrid[sweep.partials + group] = vec4(total, 0.0, 0.0);
    }
}

// The step α = (b'·e') / (e'·A'e') along the next level's correction, from its partials
// (multigrid::step_length; 0 where the curvature is not positive), in every invocation.
float mg_step_length(uint local) {
    uint count = (sweep.coarse_nx * sweep.coarse_ny + gl_WorkGroupSize.x - 1u) / gl_WorkGroupSize.x;
    vec2 sum = vec2(0.0);
    for (uint k = local; k < count; k += gl_WorkGroupSize.x) {
        sum += multigrid[sweep.coarse_partials + k].xy;
    }
    vec2 total = workgroup_sum(sum, local);
    // (slope − slope is NaN for an infinite or NaN slope.)
    if (total.x > 0.0 && total.y - total.y == 0.0) {
        return total.y / total.x;
    }
    return 0.0;
}

// Pass 8: this level's node k moves by α times its parent's correction (uniform control flow).
void mg_prolong(uint k, uint local) {
    float alpha = mg_step_length(local);
    if (k >= sweep.nx * sweep.ny) {
        return;
    }
    uint parent = (k / sweep.nx / 2u) * sweep.coarse_nx + (k % sweep.nx) / 2u;
    uint cnodes = sweep.coarse_nx * sweep.coarse_ny;
    uint at = sweep.vectors + sweep.nx * sweep.ny + k;
    multigrid[at] = vec4(multigrid[at].xyz + multigrid[sweep.coarse_vectors + cnodes + parent].xyz * alpha, 0.0);
}

// Pass 9: free vertex k moves by α times its aggregate's level-1 correction, stopping at the
// surface of a collider it would enter (uniform control flow).
void mg_move(uint k, uint local) {
    float alpha = mg_step_length(local);
    if (k >= params.vertex_count) {
        return;
    }
    vec4 p = positions_out[k];
    if (p.w <= 0.0) {
        return;
    }
    uint nx = params.grid_nx;
    uint parent = (k / nx / 2u) * sweep.coarse_nx + (k % nx) / 2u;
    uint cnodes = sweep.coarse_nx * sweep.coarse_ny;
    vec3 moved = p.xyz + multigrid[sweep.coarse_vectors + cnodes + parent].xyz * alpha;
    if (EFFECT_CONTACT) {
        moved = stop_at_surfaces(p.xyz, moved, velocities_in[k].w + params.substep_dt);
    }
    positions_out[k] = vec4(moved, p.w);
}

void main() {
    if (VBD_PASS >= 3u) {
        uint k = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
        uint g = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
        uint local = gl_LocalInvocationIndex;
        if (VBD_PASS == 3u) {
            mg_assemble(k);
        } else if (VBD_PASS == 4u) {
            mg_coarsen(k);
        } else if (VBD_PASS == 5u) {
            mg_smooth(k);
        } else if (VBD_PASS == 6u) {
            mg_restrict(k);
        } else if (VBD_PASS == 7u) {
            mg_model(k, local, g);
        } else if (VBD_PASS == 8u) {
            mg_prolong(k, local);
        } else {
            mg_move(k, local);
        }
        return;
    }
    if (EFFECT_SELF_COLLISION && VBD_PASS == 2u) {
        clear_motion(gl_LocalInvocationIndex);
    }
    vec4 moved = run_pass();
    if (EFFECT_SELF_COLLISION && VBD_PASS == 2u) {
        // The extents of the substep's displacements along the motion directions, which the next
        // check turns into its bound.
        record_motion(moved, gl_LocalInvocationIndex, gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x);
    }
}
