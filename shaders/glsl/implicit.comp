#version 450
#extension GL_GOOGLE_include_directive : require

// One backward-Euler substep (cloth_core::Integrator::BackwardEuler), as a sequence of passes: the
// GLSL twin of shaders/wgsl/implicit.wgsl, which describes the passes and the two-level sums. The
// passes mirror cloth_core::reference's backward_euler_substep and cloth_core::implicit's
// conjugate_gradients; the Newton iterate (x̄, v̄) lives in the output state. Units: m, kg, s, N/m.

#include "effects.glsl"

// Which pass this pipeline runs (implicit.wgsl lists them).
layout(constant_id = 101) const uint IMPLICIT_PASS = 0u;

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

// The state at the substep's start (w: 1 free, minus its pin group pinned; velocity w: the time).
layout(set = 0, binding = 2, std430) readonly buffer PositionsIn { vec4 positions_in[]; };
layout(set = 0, binding = 3, std430) readonly buffer VelocitiesIn { vec4 velocities_in[]; };
// The Newton iterate (x̄, v̄); then the new state.
layout(set = 0, binding = 4, std430) buffer PositionsOut { vec4 positions_out[]; };
layout(set = 0, binding = 5, std430) buffer VelocitiesOut { vec4 velocities_out[]; };
// Deepest penetration so far, m, as the bits of a non-negative float (see cloth_step.comp).
layout(set = 0, binding = 6, std430) buffer MaxPenetration { uint max_penetration_bits; };
// Conjugate gradients' vectors, CG_SLOTS a vertex: Δ (m/s) at slot 0, r (N·s) at 1, q = A p (N·s)
// at 3, z = P r (m/s) at 4, and the direction p (m/s) of odd iterations at 2, of even ones at 5.
layout(set = 0, binding = 7, std430) buffer Cg { vec4 cg[]; };
const uint CG_SLOTS = 6u;

// The slot of iteration k's search direction p.
uint direction_slot(uint k) {
    return (k & 1u) == 1u ? 2u : 5u;
}

// The partials' section of iteration k's p·q.
uint product_section(uint k) {
    return (k & 1u) == 1u ? 1u : 3u;
}
// Five a vertex: the rows of the inverse of its diagonal block of A (1/kg), with the right-hand
// side b (N·s) in their w; its contacts' block
// h C_c + h² K_c (kg) as (xx, yy, zz, xy) and (xz, yz).
layout(set = 0, binding = 8, std430) buffer Blocks { vec4 blocks[]; };
// The workgroups' partial sums: four sections of partial_count() each (implicit.wgsl).
layout(set = 0, binding = 9, std430) buffer Partials { vec2 partials[]; };
layout(set = 0, binding = 10, std430) buffer Counters { CgCounters counters; };
// Per CG iteration k: r·z at its start (the bits of a float) and 1 once the solve is done.
layout(set = 0, binding = 11, std430) buffer Steps { uvec2 steps[]; };
// cloth_gpu::layout::GpuCgStep (16 bytes): the CG iteration passes 3 to 6 belong to, selected by
// a dynamic offset.
layout(set = 0, binding = 12, std140) uniform CgStep {
    uint iteration;         // from 1
    uint pad0;
    uint pad1;
    uint pad2;
} step;

// The position of vertex `index` in the Newton iterate, m (grid.glsl's grid_normal: the wind sees
// the iterate's normal).
vec3 position_in(uint index) {
    return positions_out[index].xyz;
}

#include "grid.glsl"
#include "self_partners.glsl"

// The self-collision term of partner j (self_partners.glsl): its repulsion on free vertex i at
// c.x moving at c.a in the iterate, with the friction's step c.s.
vec4 pair_term(uint j, PairContext c) {
    vec3 x_j = positions_out[j].xyz;
    if (!in_contact(c.x, x_j)) {
        return vec4(0.0);
    }
    return vec4(repulsion_force(c.x, x_j, c.a, velocities_out[j].xyz, params.vertex_mass, c.s), 0.0);
}

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

Mat3 mat3_zero() {
    return Mat3(vec3(0.0), vec3(0.0), vec3(0.0));
}

Mat3 mat3_identity() {
    return Mat3(vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0));
}

// a bᵀ.
Mat3 mat3_outer(vec3 a, vec3 b) {
    return Mat3(b * a.x, b * a.y, b * a.z);
}

vec3 mat3_mul(Mat3 m, vec3 v) {
    return vec3(dot(m.r0, v), dot(m.r1, v), dot(m.r2, v));
}

// The inverse (Mat3::inverse), or the identity where the determinant is zero or not finite.
Mat3 mat3_inverse_or_identity(Mat3 m) {
    vec3 a = m.r0;
    vec3 b = m.r1;
    vec3 c = m.r2;
    float det = dot(a, cross(b, c));
    if (det == 0.0 || isinf(det) || isnan(det)) {
        return mat3_identity();
    }
    float inv = 1.0 / det;
    vec3 c0 = cross(b, c);
    vec3 c1 = cross(c, a);
    vec3 c2 = cross(a, b);
    return Mat3(vec3(c0.x, c1.x, c2.x) * inv, vec3(c0.y, c1.y, c2.y) * inv, vec3(c0.z, c1.z, c2.z) * inv);
}

// The least transverse stiffness of a spring in the linearisation, a fraction of k
// (cloth_core::implicit::TRANSVERSE_STIFFNESS_FLOOR, which says why).
const float TRANSVERSE_STIFFNESS_FLOOR = 0.05;

// The spring stiffness block K = k (u uᵀ + max(floor, 1 − L0/L)(I − u uᵀ))
// (cloth_core::forces::spring_stiffness_block_floored).
Mat3 spring_stiffness_block(vec3 x_i, vec3 x_j, float rest_length, float stiffness) {
    vec3 delta = x_j - x_i;
    float len = sqrt(dot(delta, delta));
    if (len <= 0.0) {
        return mat3_zero();
    }
    vec3 u = delta * (1.0 / len);
    Mat3 axial = mat3_outer(u, u);
    float transverse = max(1.0 - rest_length / len, TRANSVERSE_STIFFNESS_FLOOR);
    Mat3 across = Mat3(vec3(1.0, 0.0, 0.0) - axial.r0, vec3(0.0, 1.0, 0.0) - axial.r1, vec3(0.0, 0.0, 1.0) - axial.r2);
    return mat3_scaled(mat3_add(axial, mat3_scaled(across, transverse)), stiffness);
}

// K_s and C_s of the spring from x_i to x_j, and its block of A, h C_s + h² K_s.
struct SpringBlocks {
    Mat3 stiffness;
    Mat3 damping;
    Mat3 system;
};

SpringBlocks spring_blocks(vec3 x_i, vec3 x_j, uint kind, float rest_length) {
    float h = params.substep_dt;
    Mat3 k = spring_stiffness_block(x_i, x_j, rest_length, params.stiffness[kind]);
    Mat3 c = mat3_zero();
    if (EFFECT_SPRING_DAMPING) {
        // C_s = c_d u uᵀ (cloth_core::forces::spring_damping_block).
        vec3 delta = x_j - x_i;
        float len = sqrt(dot(delta, delta));
        if (len > 0.0) {
            vec3 u = delta * (1.0 / len);
            c = mat3_scaled(mat3_outer(u, u), params.damping[kind]);
        }
    }
    return SpringBlocks(k, c, mat3_add(mat3_scaled(c, h), mat3_scaled(k, h * h)));
}

// The stencil neighbour (i + di, j + dj) of vertex (i, j), or NO_VERTEX off the grid.
uint neighbour(uint i, uint j, int di, int dj) {
    uint ni = uint(int(i) + di);
    uint nj = uint(int(j) + dj);
    if (ni >= params.grid_nx || nj >= params.grid_ny) {
        return NO_VERTEX;
    }
    return nj * params.grid_nx + ni;
}

// The stencil's twelve springs in the reference's order (cloth_step.comp's add_stencil_springs):
// offset, kind, rest length.
struct StencilSpring {
    int di;
    int dj;
    uint kind;
    float rest_length;
};

StencilSpring stencil_spring(uint s) {
    vec4 rest = params.rest_lengths;
    switch (s) {
        case 0u: return StencilSpring(0, -1, 0u, rest.y);
        case 1u: return StencilSpring(-1, 0, 0u, rest.x);
        case 2u: return StencilSpring(1, 0, 0u, rest.x);
        case 3u: return StencilSpring(0, 1, 0u, rest.y);
        case 4u: return StencilSpring(-1, -1, 1u, rest.z);
        case 5u: return StencilSpring(1, -1, 1u, rest.z);
        case 6u: return StencilSpring(1, 1, 1u, rest.z);
        case 7u: return StencilSpring(-1, 1, 1u, rest.z);
        case 8u: return StencilSpring(0, -2, 2u, 2.0 * rest.y);
        case 9u: return StencilSpring(-2, 0, 2u, 2.0 * rest.x);
        case 10u: return StencilSpring(2, 0, 2u, 2.0 * rest.x);
        default: return StencilSpring(0, 2, 2u, 2.0 * rest.y);
    }
}

// The model's force on free vertex i at (vi, vj) in the iterate state (x, v) at time t, N
// (cloth_core::reference's variant_force_and_stick, as cloth_step.comp evaluates it), with the
// friction's step h; `stuck` and `stick_normal`: a contact whose friction holds the vertex.
vec3 iterate_force(uint i, uint vi, uint vj, vec3 x, vec3 v, float t, out bool stuck, out vec3 stick_normal) {
    float mass = params.vertex_mass;
    float h = params.substep_dt;
    vec3 force = vec3(0.0);
    if (EFFECT_GRAVITY) {
        force += gravity_force(mass, params.gravity.xyz);
    }
    if (ANY_SPRINGS) {
        for (uint s = 0u; s < 12u; s++) {
            StencilSpring spring = stencil_spring(s);
            if (!kind_enabled(spring.kind)) {
                continue;
            }
            uint j = neighbour(vi, vj, spring.di, spring.dj);
            if (j == NO_VERTEX) {
                continue;
            }
            float damping = EFFECT_SPRING_DAMPING ? params.damping[spring.kind] : 0.0;
            add_spring_force(force, x, positions_out[j].xyz, v, velocities_out[j].xyz, spring.rest_length,
                             params.stiffness[spring.kind], damping);
        }
    }
    if (EFFECT_AIR_DRAG) {
        force += air_drag_force(mass, params.air_drag, v);
    }
    if (EFFECT_WIND) {
        force += wind_force(grid_normal(i), v, wind_velocity(t), params.wind.w);
    }
    if (EFFECT_SELF_COLLISION) {
        force += sum_over_partners(i, vi, vj, PairContext(x, v, h)).xyz;
    }
    vec3 other_forces = force;
    stuck = false;
    stick_normal = vec3(0.0);
    if (EFFECT_CONTACT) {
        for (uint c = 0u; c < params.collider_count; c++) {
            vec3 center = collider_center(c, t);
            Surface surface = collider_contact(c, center, x);
            if (surface.distance >= 0.0) {
                continue;
            }
            vec3 v_rel = v - collider_velocity(c, t);
            vec3 normal;
            vec3 contact;
            if (contact_force(v_rel, surface, colliders[c].stiffness, colliders[c].damping, normal, contact)) {
                force += contact;
                if (EFFECT_FRICTION) {
                    float mu = colliders[c].friction;
                    force += friction_force(other_forces, v_rel, normal, mass, h, mu);
                    if (!stuck && friction_holds(other_forces, v_rel, normal, mass, h, mu)) {
                        stuck = true;
                        stick_normal = normal;
                    }
                }
            }
        }
    }
    return force;
}

// Where pinned vertex j's motion puts it at the substep's end, and its velocity there.
void pin_end(uint j, out vec3 x, out vec3 v) {
    vec4 p = positions_in[j];
    float t = velocities_in[j].w;
    float t_end = t + params.substep_dt;
    x = pin_carry(pin_group(p.w), p.xyz, t, t_end);
    v = pin_velocity(pin_group(p.w), x, t_end);
}

// The change d_x (m) and d_v (m/s) the right-hand side linearises over, of vertex j: for a free
// vertex x + h v̄ − x̄ and 0, for a pinned one its prescribed end state less the iterate.
void change_of(uint j, out vec3 dx, out vec3 dv) {
    vec4 x_bar = positions_out[j];
    vec3 v_bar = velocities_out[j].xyz;
    if (x_bar.w > 0.0) {
        dx = positions_in[j].xyz + v_bar * params.substep_dt - x_bar.xyz;
        dv = vec3(0.0);
        return;
    }
    vec3 x_end;
    vec3 v_end;
    pin_end(j, x_end, v_end);
    dx = x_end - x_bar.xyz;
    dv = v_end - v_bar;
}

// Passes 1 and 2: returns (r·z, b·b) of the vertex.
vec2 linearise(uint i, bool first) {
    vec4 p_bar = positions_out[i];
    if (p_bar.w <= 0.0) {
        cg[CG_SLOTS * i] = vec4(0.0);
        cg[CG_SLOTS * i + 1u] = vec4(0.0);
        cg[CG_SLOTS * i + direction_slot(1u)] = vec4(0.0);
        blocks[5u * i] = vec4(1.0, 0.0, 0.0, 0.0);
        blocks[5u * i + 1u] = vec4(0.0, 1.0, 0.0, 0.0);
        blocks[5u * i + 2u] = vec4(0.0, 0.0, 1.0, 0.0);
        blocks[5u * i + 3u] = vec4(0.0);
        blocks[5u * i + 4u] = vec4(0.0);
        return vec2(0.0);
    }
    float h = params.substep_dt;
    float m = params.vertex_mass;
    uint nx = params.grid_nx;
    uint vi = i % nx;
    uint vj = i / nx;
    vec3 x = p_bar.xyz;
    vec3 v = velocities_out[i].xyz;
    vec3 x0 = positions_in[i].xyz;
    vec3 v0 = velocities_in[i].xyz;
    float t = velocities_in[i].w;
    if (!first) {
        t = t + h;
    }
    bool stuck;
    vec3 stick_normal;
    vec3 f = iterate_force(i, vi, vj, x, v, t, stuck, stick_normal);
    vec3 own_dx;
    vec3 own_dv;
    change_of(i, own_dx, own_dv);
    vec3 drop = vec3(0.0);
    Mat3 diagonal = mat3_scaled(mat3_identity(), m);
    if (ANY_SPRINGS) {
        for (uint s = 0u; s < 12u; s++) {
            StencilSpring spring = stencil_spring(s);
            if (!kind_enabled(spring.kind)) {
                continue;
            }
            uint j = neighbour(vi, vj, spring.di, spring.dj);
            if (j == NO_VERTEX) {
                continue;
            }
            vec3 other_dx;
            vec3 other_dv;
            change_of(j, other_dx, other_dv);
            SpringBlocks b = spring_blocks(x, positions_out[j].xyz, spring.kind, spring.rest_length);
            drop += mat3_mul(b.stiffness, own_dx - other_dx) + mat3_mul(b.damping, own_dv - other_dv);
            diagonal = mat3_add(diagonal, b.system);
        }
    }
    Mat3 contact = mat3_zero();
    vec3 pull = vec3(0.0);
    if (EFFECT_CONTACT) {
        // The end position the iterate's velocity gives (x̄ itself after the first iteration).
        vec3 y = x0 + v * h;
        for (uint c = 0u; c < params.collider_count; c++) {
            vec3 center = collider_center(c, t);
            float stiffness = colliders[c].stiffness;
            // In the linearisation where the vertex is inside at x̄ or at y; linearised about y
            // where y is inside (implicit.wgsl's linearise).
            Surface at_iterate = collider_surface(c, center, x);
            Surface at_end = collider_surface(c, center, y);
            bool ends_inside = at_end.distance < 0.0;
            if (ends_inside || at_iterate.distance < 0.0) {
                vec3 at = ends_inside ? y : x;
                Surface surface = ends_inside ? at_end : at_iterate;
                vec3 n = surface.normal;
                Mat3 k_c = mat3_scaled(mat3_outer(n, n), stiffness);
                Mat3 c_c = mat3_zero();
                if (dot(v - collider_velocity(c, t), n) < 0.0) {
                    c_c = mat3_scaled(mat3_outer(n, n), colliders[c].damping);
                }
                drop += mat3_mul(k_c, own_dx) + mat3_mul(c_c, own_dv);
                pull += n * (-stiffness * min(surface.distance, 0.0))
                    - at_iterate.normal * (-stiffness * min(at_iterate.distance, 0.0)) + mat3_mul(k_c, at - x);
                contact = mat3_add(contact, mat3_add(mat3_scaled(c_c, h), mat3_scaled(k_c, h * h)));
            }
        }
    }
    diagonal = mat3_add(diagonal, contact);
    vec3 b = (f + pull - drop) * h - (v - v0) * m;
    Mat3 pre = mat3_inverse_or_identity(diagonal);
    vec3 z = mat3_mul(pre, b);
    cg[CG_SLOTS * i] = vec4(0.0);
    cg[CG_SLOTS * i + 1u] = vec4(b, 0.0);
    cg[CG_SLOTS * i + direction_slot(1u)] = vec4(z, 0.0);
    blocks[5u * i] = vec4(pre.r0, b.x);
    blocks[5u * i + 1u] = vec4(pre.r1, b.y);
    blocks[5u * i + 2u] = vec4(pre.r2, b.z);
    blocks[5u * i + 3u] = vec4(contact.r0.x, contact.r1.y, contact.r2.z, contact.r0.y);
    blocks[5u * i + 4u] = vec4(contact.r0.z, contact.r1.z, 0.0, 0.0);
    return vec2(dot(b, z), dot(b, b));
}

// The preconditioner's z = P r of vertex i.
vec3 preconditioned(uint i, vec3 r) {
    Mat3 p = Mat3(blocks[5u * i].xyz, blocks[5u * i + 1u].xyz, blocks[5u * i + 2u].xyz);
    return mat3_mul(p, r);
}

// Iteration k's direction p at vertex j: for k = 1 the linearisation's; for k > 1 formed from
// iteration k − 1's as z + β p (pass 6 of the reference's conjugate_gradients).
vec3 direction(uint j, uint k, float beta) {
    if (k == 1u) {
        return cg[CG_SLOTS * j + direction_slot(1u)].xyz;
    }
    return cg[CG_SLOTS * j + 4u].xyz + cg[CG_SLOTS * j + direction_slot(k - 1u)].xyz * beta;
}

// Passes 3 and 4: q = A p at vertex i (zero at a pinned one, whose p is read as zero) for
// iteration k's direction, which pass 4 forms at the vertex (and writes to its slot) and at each
// neighbour (`direction`); returns p·q.
float apply_system(uint i, uint k, float beta) {
    vec4 p_bar = positions_out[i];
    vec3 p_i = direction(i, k, beta);
    if (k > 1u) {
        cg[CG_SLOTS * i + direction_slot(k)] = vec4(p_i, 0.0);
    }
    if (p_bar.w <= 0.0) {
        cg[CG_SLOTS * i + 3u] = vec4(0.0);
        return 0.0;
    }
    vec3 q = p_i * params.vertex_mass;
    uint nx = params.grid_nx;
    uint vi = i % nx;
    uint vj = i / nx;
    if (ANY_SPRINGS) {
        for (uint s = 0u; s < 12u; s++) {
            StencilSpring spring = stencil_spring(s);
            if (!kind_enabled(spring.kind)) {
                continue;
            }
            uint j = neighbour(vi, vj, spring.di, spring.dj);
            if (j == NO_VERTEX) {
                continue;
            }
            vec4 x_j = positions_out[j];
            vec3 p_j = x_j.w > 0.0 ? direction(j, k, beta) : vec3(0.0);
            SpringBlocks b = spring_blocks(p_bar.xyz, x_j.xyz, spring.kind, spring.rest_length);
            q += mat3_mul(b.system, p_i - p_j);
        }
    }
    if (EFFECT_CONTACT) {
        vec4 d = blocks[5u * i + 3u];
        vec4 e = blocks[5u * i + 4u];
        q += vec3(d.x * p_i.x + d.w * p_i.y + e.x * p_i.z, d.w * p_i.x + d.y * p_i.y + e.y * p_i.z,
                  e.x * p_i.x + e.y * p_i.y + d.z * p_i.z);
    }
    cg[CG_SLOTS * i + 3u] = vec4(q, 0.0);
    return dot(p_i, q);
}

// The two-level sums (implicit.wgsl) start with workgroup_sum.
#include "workgroup_sum.glsl"

// Workgroups of a per-vertex pass that hold vertices: one partial sum each.
uint partial_count() {
    return (params.vertex_count + gl_WorkGroupSize.x - 1u) / gl_WorkGroupSize.x;
}

// Writes the workgroup's sum of `value` as its partial of `section` (uniform control flow).
void write_partial(vec2 value, uint section, uint local, uint group) {
    vec2 total = workgroup_sum(value, local);
    uint count = partial_count();
    if (local == 0u && group < count) {
        partials[section * count + group] = total;
    }
}

// The total of `section`'s partials, in every invocation (uniform control flow).
vec2 total_of(uint section, uint local) {
    uint count = partial_count();
    vec2 sum = vec2(0.0);
    for (uint k = local; k < count; k += gl_WorkGroupSize.x) {
        sum += partials[section * count + k];
    }
    return workgroup_sum(sum, local);
}

// How CG iteration k ended: whether the solve is done, else the β of the next direction.
struct IterationEnd {
    bool done;
    float beta;
};

// Ends CG iteration k from its totals, p·q and pass 5's r·z and r·r (uniform control flow): done
// when it stopped (done before, or p·q ≤ 0) or converged (|r| ≤ tol |b|); else β = r·z' / r·z.
// The first workgroup counts the iteration and records at k + 1 of `steps` the next r·z and
// whether the solve is done.
IterationEnd end_iteration(uint k, uint local, uint group) {
    float pq = total_of(product_section(k), local).x;
    vec2 next = total_of(2u, local);
    float rz = uintBitsToFloat(steps[k].x);
    bool stopped = steps[k].y != 0u || pq <= 0.0;
    bool converged = !stopped && sqrt(next.y) <= counters.tolerance * counters.b_norm;
    if (group == 0u && local == 0u) {
        if (!stopped) {
            counters.solve_iterations += 1u;
            counters.cg += 1u;
        }
        if (stopped || converged) {
            steps[k + 1u] = uvec2(steps[k].x, 1u);
        } else {
            steps[k + 1u] = uvec2(floatBitsToUint(next.x), 0u);
        }
    }
    return IterationEnd(stopped || converged, next.x / rz);
}

// Pass 7: the Newton update of vertex i.
void newton_update(uint i) {
    vec4 p = positions_in[i];
    float t = velocities_in[i].w;
    if (p.w > 0.0) {
        vec3 v = velocities_out[i].xyz + cg[CG_SLOTS * i].xyz;
        positions_out[i] = vec4(p.xyz + v * params.substep_dt, p.w);
        velocities_out[i] = vec4(v, t);
    } else {
        vec3 x_end;
        vec3 v_end;
        pin_end(i, x_end, v_end);
        positions_out[i] = vec4(x_end, p.w);
        velocities_out[i] = vec4(v_end, t);
    }
}

// Pass 9: the slopes of the incremental potential along the Newton iteration's change of vertex i,
// at the iterate before the change and where the iterate is now (implicit.wgsl's
// line_search_slopes).
vec2 line_search_slopes(uint i) {
    vec4 p_bar = positions_out[i];
    if (p_bar.w <= 0.0) {
        return vec2(0.0);
    }
    float h = params.substep_dt;
    uint nx = params.grid_nx;
    vec3 v = velocities_out[i].xyz;
    vec3 change = cg[CG_SLOTS * i].xyz;
    vec3 b = vec3(blocks[5u * i].w, blocks[5u * i + 1u].w, blocks[5u * i + 2u].w);
    bool stuck;
    vec3 n;
    vec3 f = iterate_force(i, i % nx, i / nx, p_bar.xyz, v, velocities_in[i].w + h, stuck, n);
    return vec2(-dot(change, b), dot(change, (v - velocities_in[i].xyz) * params.vertex_mass - f * h));
}

// Backward Euler's line search by regula falsi with the Illinois rule (implicit.wgsl's Bracket):
// step lengths lo < hi with slopes g(lo) < 0 <= g(hi), whether the search is on, and which end
// the last cut replaced (0 none, 1 lo, 2 hi).
struct Bracket {
    vec2 lo;
    vec2 hi;
    bool open;
    uint last;
};

// The bracket after slope measurement r (from 1): `steps`' last entries, three a measurement
// counted from the end (implicit.wgsl's bracket_at).
uint bracket_at(uint r) {
    return uint(steps.length()) - 3u * r;
}

Bracket read_bracket(uint r) {
    uint at = bracket_at(r);
    return Bracket(uintBitsToFloat(steps[at]), uintBitsToFloat(steps[at + 1u]), steps[at + 2u].x != 0u,
                   steps[at + 2u].y);
}

void write_bracket(uint r, Bracket b) {
    uint at = bracket_at(r);
    steps[at] = floatBitsToUint(b.lo);
    steps[at + 1u] = floatBitsToUint(b.hi);
    steps[at + 2u] = uvec2(b.open ? 1u : 0u, b.last);
}

float secant(Bracket b) {
    return b.lo.x + (b.hi.x - b.lo.x) * b.lo.y / (b.lo.y - b.hi.y);
}

// Pass 10 of slope measurement r (implicit.wgsl's line_search_step).
void line_search_step(uint i, uint r, vec2 slopes, bool records) {
    float trial = 1.0;
    Bracket b;
    if (r == 1u) {
        b = Bracket(vec2(0.0, slopes.x), vec2(1.0, slopes.y), slopes.x < 0.0 && slopes.y > 0.0, 0u);
    } else {
        b = read_bracket(r - 1u);
        if (b.open) {
            trial = secant(b);
            if (slopes.y < 0.0) {
                b.lo = vec2(trial, slopes.y);
                if (b.last == 1u) {
                    b.hi.y *= 0.5;
                }
                b.last = 1u;
            } else {
                b.hi = vec2(trial, slopes.y);
                if (b.last == 2u) {
                    b.lo.y *= 0.5;
                }
                b.last = 2u;
            }
        }
    }
    if (records) {
        write_bracket(r, b);
    }
    if (i >= params.vertex_count) {
        return;
    }
    vec4 p = positions_in[i];
    if (p.w <= 0.0 || !b.open) {
        return;
    }
    vec3 v = velocities_out[i].xyz + cg[CG_SLOTS * i].xyz * (secant(b) - trial);
    positions_out[i] = vec4(p.xyz + v * params.substep_dt, p.w);
    velocities_out[i] = vec4(v, velocities_out[i].w);
}

// Pass 8; returns the vertex's displacement over the substep (w 1).
vec4 finish(uint i) {
    vec4 p = positions_out[i];
    float t_end = velocities_in[i].w + params.substep_dt;
    vec3 x = p.xyz;
    vec3 v = velocities_out[i].xyz;
    if (EFFECT_FRICTION && p.w > 0.0) {
        // Static friction at the substep's end: a vertex friction holds keeps its solved
        // position and loses its tangential velocity (implicit.wgsl's finish).
        uint nx = params.grid_nx;
        bool stuck;
        vec3 n;
        iterate_force(i, i % nx, i / nx, x, v, t_end, stuck, n);
        if (stuck) {
            v = n * dot(v, n);
        }
    }
    if (EFFECT_SELF_COLLISION && p.w > 0.0) {
        // The speed limit (self_collision.glsl).
        vec3 x0 = positions_in[i].xyz;
        x = limit_step(x0, x);
        v = limit_velocity(v);
        positions_out[i] = vec4(x, p.w);
    }
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

void main() {
    // 2D dispatch: more than maxComputeWorkGroupCount[0] workgroups spill into y.
    uint i = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uint local = gl_LocalInvocationIndex;
    bool vertex = i < params.vertex_count;
    uint k = step.iteration;
    if (IMPLICIT_PASS == 0u) {
        if (vertex) {
            positions_out[i] = positions_in[i];
            velocities_out[i] = velocities_in[i];
        }
        if (i == 0u) {
            counters.largest_b_norm = 0.0;
        }
    } else if (IMPLICIT_PASS == 1u || IMPLICIT_PASS == 2u) {
        vec2 terms = vec2(0.0);
        if (vertex) {
            terms = linearise(i, IMPLICIT_PASS == 1u);
        }
        write_partial(terms, 0u, local, group);
    } else if (IMPLICIT_PASS == 3u || IMPLICIT_PASS == 4u) {
        bool done;
        float beta = 0.0;
        if (IMPLICIT_PASS == 3u) {
            // The solve's start: r·z and |b| of the linearisation. The residual is measured
            // against |b| or the substep's largest earlier |b| (implicit.rs's
            // `conjugate_gradients`): done at once when b is within the tolerance of it.
            // Workgroup 0 raises `largest_b_norm` while others may read it; either value gives
            // the same maximum with this |b|.
            vec2 initial = total_of(0u, local);
            float b_norm = sqrt(initial.y);
            float reference = max(b_norm, counters.largest_b_norm);
            done = b_norm <= counters.tolerance * reference;
            if (group == 0u && local == 0u) {
                counters.newton += 1u;
                counters.solve_iterations = 0u;
                counters.b_norm = reference;
                counters.largest_b_norm = reference;
                steps[1] = uvec2(floatBitsToUint(initial.x), done ? 1u : 0u);
            }
        } else {
            IterationEnd end = end_iteration(k - 1u, local, group);
            done = end.done;
            beta = end.beta;
        }
        float pq = 0.0;
        if (vertex && !done) {
            pq = apply_system(i, k, beta);
        }
        write_partial(vec2(pq, 0.0), product_section(k), local, group);
    } else if (IMPLICIT_PASS == 5u) {
        float pq = total_of(product_section(k), local).x;
        bool stop = steps[k].y != 0u || pq <= 0.0;
        vec2 terms = vec2(0.0);
        if (vertex && !stop) {
            float alpha = uintBitsToFloat(steps[k].x) / pq;
            if (positions_out[i].w > 0.0) {
                vec3 p = cg[CG_SLOTS * i + direction_slot(k)].xyz;
                cg[CG_SLOTS * i] = vec4(cg[CG_SLOTS * i].xyz + p * alpha, 0.0);
            }
            vec3 r = cg[CG_SLOTS * i + 1u].xyz - cg[CG_SLOTS * i + 3u].xyz * alpha;
            cg[CG_SLOTS * i + 1u] = vec4(r, 0.0);
            vec3 z = preconditioned(i, r);
            cg[CG_SLOTS * i + 4u] = vec4(z, 0.0);
            terms = vec2(dot(r, z), dot(r, r));
        }
        write_partial(terms, 2u, local, group);
    } else if (IMPLICIT_PASS == 6u) {
        end_iteration(k, local, group);
    } else if (IMPLICIT_PASS == 7u) {
        if (group == 0u && local == 0u) {
            counters.cg_most = max(counters.cg_most, counters.solve_iterations);
        }
        if (vertex) {
            newton_update(i);
        }
    } else if (IMPLICIT_PASS == 9u) {
        vec2 terms = vec2(0.0);
        if (vertex) {
            terms = line_search_slopes(i);
        }
        write_partial(terms, 0u, local, group);
    } else if (IMPLICIT_PASS == 10u) {
        vec2 slopes = total_of(0u, local);
        line_search_step(i, k, slopes, group == 0u && local == 0u);
    } else {
        if (EFFECT_SELF_COLLISION) {
            clear_motion(local);
        }
        vec4 moved = vertex ? finish(i) : vec4(0.0);
        if (EFFECT_SELF_COLLISION) {
            // The extents of the substep's displacements along the motion directions, which the
            // next check turns into its bound.
            record_motion(moved, local, group);
        }
    }
}
