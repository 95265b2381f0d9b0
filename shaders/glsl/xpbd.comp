#version 450
#extension GL_GOOGLE_include_directive : require

// One XPBD substep (cloth_core::Integrator::Xpbd), as a sequence of passes: the GLSL twin of
// shaders/wgsl/xpbd.wgsl. The projections mirror crates/cloth-core/src/constraints.rs function by
// function and operation by operation. A substep is:
//   pass 0 (per vertex)     predict: v* = v + Δt g (+ drag), x* = x + Δt v*; clear the normal corrections;
//   then XPBD_ITERATIONS times:
//     pass 1 (per spring)   project the springs of one colour (springs of a colour share no
//                           vertex, so one invocation per spring needs no atomics), once per colour;
//     pass 2 (per vertex)   project the vertex out of the colliders (swept from its substep start,
//                           so a long step cannot tunnel), summing the corrections;
//   pass 3 (per vertex)     friction on the contacts' displacements, v = (x* − x)/Δt, deepest
//                           penetration.
// Units: m, kg, s, N/m.

#include "effects.glsl"

// Which pass this pipeline runs (see above).
layout(constant_id = 101) const uint XPBD_PASS = 0u;

// The binding of the mesh colliders' distance fields, which layout.glsl declares.
#define DISTANCE_FIELDS_BINDING 11
#include "layout.glsl"
#include "forces.glsl"

// Self-collision's candidate lists, its hash and its control (self_hash.comp; placeholders
// without SelfCollision).
layout(set = 0, binding = 13, std430) readonly buffer SelfWords { uint self_words[]; };
layout(set = 0, binding = 14, std430) readonly buffer SelfLinks { uvec4 self_links[]; };
layout(set = 0, binding = 15, std430) buffer SelfControlBuffer { SelfControl self_control; };

// The hash's words 4 at4 to 4 at4 + 3 (self_collision.glsl).
uvec4 link_words(uint at4) {
    return self_links[at4];
}

#include "self_collision.glsl"

layout(set = 0, binding = 2, std430) readonly buffer Constraints { Constraint constraints[]; };
// The state at the substep's start (w: 1 free, minus its pin group pinned).
layout(set = 0, binding = 3, std430) readonly buffer PositionsIn { vec4 positions_in[]; };
layout(set = 0, binding = 4, std430) readonly buffer VelocitiesIn { vec4 velocities_in[]; };
// The predicted positions, projected in place; then the new state.
layout(set = 0, binding = 5, std430) buffer PositionsOut { vec4 positions_out[]; };
layout(set = 0, binding = 6, std430) buffer VelocitiesOut { vec4 velocities_out[]; };
// Deepest penetration so far, m, as the bits of a non-negative float (see cloth_step.comp).
layout(set = 0, binding = 7, std430) buffer MaxPenetration { uint max_penetration_bits; };
// Each spring's Lagrange multiplier λ (in constraint order).
layout(set = 0, binding = 8, std430) buffer Lambdas { float lambdas[]; };
// Each vertex's summed collider correction in this substep, m.
layout(set = 0, binding = 9, std430) buffer NormalCorrections { float normal_corrections[]; };
// cloth_gpu::layout::GpuColorRange (16 bytes): the colour pass 1 projects, selected by a
// dynamic offset.
layout(set = 0, binding = 10, std140) uniform ColorRange {
    uint first;
    uint count;
    uint first_iteration;   // 1: the multipliers start from 0
    uint pad;
} color;

// The position of vertex `index` in the state read, m (for grid.glsl's grid_normal).
vec3 position_in(uint index) {
    return positions_in[index].xyz;
}

#include "grid.glsl"

// Each vertex's averaged self-contact correction of the current iteration, m (a placeholder
// without SelfCollision).
layout(set = 0, binding = 12, std430) buffer SelfCorrections { vec4 self_corrections[]; };

// XPBD's correction of free vertex i (inverse mass w_i) for its contact with vertex j (w_j, 0
// when pinned), m, in xyz, and w = 1 where they touch (cloth_core::self_collision::
// self_contact_correction): i's share w_i / (w_i + w_j) of the depth r − d along u, and friction
// removing up to μ (r − d) of the pair's relative sliding since the substep's start.
vec4 self_contact_correction(vec3 x_i, vec3 x_j, vec3 x0_i, vec3 x0_j, float w_i, float w_j) {
    float r = params.self_contact.x;
    vec3 delta = x_i - x_j;
    float d2 = dot(delta, delta);
    if (d2 >= r * r || d2 <= 0.0) {
        return vec4(0.0);
    }
    float d = sqrt(d2);
    vec3 u = delta * (1.0 / d);
    float depth = r - d;
    float share = w_i / (w_i + w_j);
    vec3 correction = u * (depth * share);
    vec3 slide = (x_i - x0_i) - (x_j - x0_j);
    vec3 tangential = slide - u * dot(slide, u);
    float len = sqrt(dot(tangential, tangential));
    if (len > 0.0) {
        correction -= tangential * (min(params.self_contact.w * depth, len) / len * share);
    }
    return vec4(correction, 1.0);
}

// Free vertex i's correction for its contact with vertex j (self_contact_correction, from the
// positions the springs left and the substep's start), with w 1, or zero where they do not touch.
vec4 self_contact_with(uint j, vec3 x, vec3 x0, float w) {
    vec4 q = positions_out[j];
    if (!in_contact(x, q.xyz)) {
        return vec4(0.0);
    }
    return self_contact_correction(x, q.xyz, x0, positions_in[j].xyz, w, max(q.w, 0.0) * w);
}

#include "self_partners.glsl"

// The self-contact term of partner j (self_partners.glsl): free vertex i's correction for it,
// from i's position c.x, its position at the substep's start c.a and its inverse mass c.s.
vec4 pair_term(uint j, PairContext c) {
    return self_contact_with(j, c.x, c.a, c.s);
}

// Pass 4: free vertex i's self-contacts with its partners (sum_over_partners, in
// cloth_core::reference's project_self_contacts's order), averaged.
void self_contacts(uint i) {
    vec4 p = positions_out[i];
    if (p.w <= 0.0) {
        self_corrections[i] = vec4(0.0);
        return;
    }
    PairContext c = PairContext(p.xyz, positions_in[i].xyz, 1.0 / params.vertex_mass);
    vec4 sum = sum_over_partners(i, i % params.grid_nx, i / params.grid_nx, c);
    vec3 correction = sum.w > 0.0 ? sum.xyz * (1.0 / sum.w) : vec3(0.0);
    self_corrections[i] = vec4(correction, 0.0);
}

// Δλ = (−C − α̃ λ) / (w_a + w_b + α̃), α̃ = 1/(k Δt²); the ends move by ±w Δλ n.
void project_spring(inout vec3 x_a, inout vec3 x_b, float inverse_mass_a, float inverse_mass_b,
                    float rest_length, float stiffness, float dt, inout float lambda) {
    if (inverse_mass_a + inverse_mass_b <= 0.0 || stiffness <= 0.0) {
        return;
    }
    vec3 d = x_a - x_b;
    float len = sqrt(dot(d, d));
    if (len <= 0.0) {
        return;
    }
    vec3 n = d * (1.0 / len);
    float compliance = 1.0 / (stiffness * dt * dt);
    float delta_lambda = (-(len - rest_length) - compliance * lambda) / (inverse_mass_a + inverse_mass_b + compliance);
    lambda = lambda + delta_lambda;
    x_a = x_a + n * (inverse_mass_a * delta_lambda);
    x_b = x_b - n * (inverse_mass_b * delta_lambda);
}

// The non-penetration constraint φ(x) ≥ 0: move x by −φ 1_n, return the correction.
float project_onto_surface(inout vec3 x, Surface surface) {
    float depth = -surface.distance;
    if (depth > 0.0) {
        x = x + surface.normal * depth;
        return depth;
    }
    return 0.0;
}

// project_onto_surface made continuous for a sphere: a path from x_start (outside) that went
// through the sphere and out the far side is put back where it entered; a path ending inside is
// projected as usual.
float project_sphere_swept(inout vec3 x, vec3 x_start, vec3 center, float radius) {
    vec3 o = x_start - center;
    float outside_at_start = dot(o, o) - radius * radius;
    vec3 end_ = x - center;
    float outside_at_end = dot(end_, end_) - radius * radius;
    if (outside_at_start >= 0.0 && outside_at_end > 0.0) {
        vec3 d = x - x_start;
        float a = dot(d, d);
        float b = dot(o, d);
        float discriminant = b * b - a * outside_at_start;
        if (a > 0.0 && b < 0.0 && discriminant >= 0.0) {
            float s = (-b - sqrt(discriminant)) / a;
            if (s <= 1.0) {
                vec3 entry = x_start + d * s;
                vec3 moved = x - entry;
                x = entry;
                return sqrt(dot(moved, moved));
            }
        }
        return 0.0;
    }
    return project_onto_surface(x, sphere_surface(x, center, radius));
}

// Steps and stopping distance (of the thickness) of the sweep (cloth_core::constraints).
const uint SWEEP_STEPS = 32u;
const float SWEEP_TOLERANCE = 0.01;

// Any collider, continuously (cloth_core::constraints::project_swept): the sphere exactly; a
// plane by its end point; a capsule or box path longer than the collider is thick that ends
// outside is sphere-traced from its start and stopped where it enters.
float project_swept(inout vec3 x, vec3 x_start, uint c, vec3 center) {
    if (COLLIDER_SPHERE) {
        if (colliders[c].kind == 0u) {
            return project_sphere_swept(x, x_start, center, colliders[c].radius);
        }
    }
    float end_ = collider_distance(c, center, x);
    if (end_ > 0.0 && colliders[c].kind != 1u) {
        vec3 d = x - x_start;
        float len = sqrt(dot(d, d));
        if (len > colliders[c].thickness && collider_distance(c, center, x_start) >= 0.0) {
            float inverse_length = 1.0 / len;
            float stop = colliders[c].thickness * SWEEP_TOLERANCE;
            float s = 0.0;
            for (uint k = 0u; k < SWEEP_STEPS; k++) {
                vec3 p = x_start + d * s;
                float phi = collider_distance(c, center, p);
                if (phi <= stop) {
                    vec3 moved = x - p;
                    x = p;
                    return sqrt(dot(moved, moved));
                }
                s = s + phi * inverse_length;
                if (s >= 1.0) {
                    break;
                }
            }
        }
        return 0.0;
    }
    // The normal only for a vertex inside: outside the projection does nothing.
    if (end_ < 0.0) {
        return project_onto_surface(x, collider_surface(c, center, x));
    }
    return 0.0;
}

// Coulomb friction in position form: the tangential part of the substep's displacement is undone
// up to c_f times the normal correction (static: the vertex sticks), shortened by that beyond;
// only on the collider (φ within its tolerance).
vec3 contact_friction(vec3 x, vec3 x_start, Surface surface, float tolerance, float coefficient,
                      float normal_correction) {
    if (surface.distance > tolerance) {
        return x;
    }
    vec3 n = surface.normal;
    vec3 dx = x - x_start;
    vec3 dx_t = dx - n * dot(dx, n);
    float slide = sqrt(dot(dx_t, dx_t));
    float budget = coefficient * normal_correction;
    if (slide > 0.0) {
        return x - dx_t * (min(slide, budget) / slide);
    }
    return x;
}

void predict(uint i) {
    vec4 p = positions_in[i];
    vec4 state = velocities_in[i];
    float t = state.w;
    float h = params.substep_dt;
    vec3 x = p.xyz;
    if (p.w > 0.0) {
        float m = params.vertex_mass;
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
        x = x + v * h;
    } else {
        x = pin_carry(pin_group(p.w), x, t, t + h);
    }
    positions_out[i] = vec4(x, p.w);
    normal_corrections[i] = 0.0;
}

void project_color(uint t) {
    if (!ANY_SPRINGS) {
        return;
    }
    if (t >= color.count) {
        return;
    }
    uint c = color.first + t;
    Constraint s = constraints[c];
    if (!kind_enabled(s.kind)) {
        return;
    }
    vec4 pa = positions_out[s.a];
    vec4 pb = positions_out[s.b];
    float w = 1.0 / params.vertex_mass;
    float lambda = color.first_iteration != 0u ? 0.0 : lambdas[c];
    vec3 x_a = pa.xyz;
    vec3 x_b = pb.xyz;
    project_spring(x_a, x_b, max(pa.w, 0.0) * w, max(pb.w, 0.0) * w, s.rest_length, params.stiffness[s.kind], params.substep_dt, lambda);
    lambdas[c] = lambda;
    positions_out[s.a] = vec4(x_a, pa.w);
    positions_out[s.b] = vec4(x_b, pb.w);
}

void project_colliders(uint i) {
    vec4 p = positions_out[i];
    if (p.w <= 0.0) {
        return;
    }
    float t = velocities_in[i].w;
    float t_end = t + params.substep_dt;
    vec3 x = p.xyz;
    if (EFFECT_SELF_COLLISION) {
        // Pass 4's self-contact correction, applied to every vertex at once.
        x = x + self_corrections[i].xyz;
    }
    float correction = normal_corrections[i];
    for (uint s = 0u; s < params.collider_count; s++) {
        // Where the collider ends the substep, and the vertex's start carried along with it.
        vec3 center = collider_center(s, t_end);
        vec3 x_start = positions_in[i].xyz + (center - collider_center(s, t));
        correction = correction + project_swept(x, x_start, s, center);
    }
    positions_out[i] = vec4(x, p.w);
    normal_corrections[i] = correction;
}

// Pass 3; returns the vertex's displacement over the substep (w 1).
vec4 finish(uint i) {
    vec4 p = positions_out[i];
    float t = velocities_in[i].w;
    float t_end = t + params.substep_dt;
    vec3 x = p.xyz;
    vec3 v = pin_velocity(pin_group(p.w), x, t_end);
    if (p.w > 0.0) {
        vec3 x0 = positions_in[i].xyz;
        float correction = normal_corrections[i];
        if (EFFECT_FRICTION) {
            if (correction > 0.0) {
                for (uint s = 0u; s < params.collider_count; s++) {
                    vec3 center = collider_center(s, t_end);
                    vec3 x_start = x0 + (center - collider_center(s, t));
                    // Off the collider friction does nothing: the normal only on it.
                    if (collider_distance(s, center, x) <= colliders[s].tolerance) {
                        Surface surface = collider_surface(s, center, x);
                        x = contact_friction(x, x_start, surface, colliders[s].tolerance, colliders[s].friction, correction);
                    }
                }
                positions_out[i] = vec4(x, p.w);
            }
        }
        v = (x - x0) * (1.0 / params.substep_dt);
        if (EFFECT_SELF_COLLISION) {
            // The speed limit (self_collision.glsl).
            x = limit_step(x0, x);
            v = limit_velocity(v);
            positions_out[i] = vec4(x, p.w);
        }
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

// Runs the pipeline's pass for the invocation; returns the vertex's displacement over the
// substep in the finishing pass (w 1), zero otherwise.
vec4 run_pass() {
    // 2D dispatch: more than maxComputeWorkGroupCount[0] workgroups spill into y.
    uint t = gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x + gl_GlobalInvocationID.x;
    if (XPBD_PASS == 1u) {
        project_color(t);
        return vec4(0.0);
    }
    if (t >= params.vertex_count) {
        return vec4(0.0);
    }
    if (XPBD_PASS == 0u) {
        predict(t);
    } else if (XPBD_PASS == 2u) {
        if (EFFECT_CONTACT || EFFECT_SELF_COLLISION) {
            project_colliders(t);
        }
    } else if (XPBD_PASS == 4u) {
        if (EFFECT_SELF_COLLISION) {
            self_contacts(t);
        }
    } else {
        return finish(t);
    }
    return vec4(0.0);
}

void main() {
    // (The conditions written out, not kept in a variable: a constant condition compiles the
    // branch out.)
    if (EFFECT_SELF_COLLISION && XPBD_PASS == 3u) {
        clear_motion(gl_LocalInvocationIndex);
    }
    vec4 moved = run_pass();
    if (EFFECT_SELF_COLLISION && XPBD_PASS == 3u) {
        // The extents of the substep's displacements along the motion directions, which the next
        // check turns into its bound.
        record_motion(moved, gl_LocalInvocationIndex, gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x);
    }
}
