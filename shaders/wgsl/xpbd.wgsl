// One XPBD substep (cloth_core::Integrator::Xpbd), as a sequence of passes. Prepended with
// common.wgsl (constants, structs, force model).
//
// The projections mirror crates/cloth-core/src/constraints.rs function by function and operation
// by operation. A substep is:
//   pass 0 (per vertex)     predict: v* = v + Δt g (+ drag), x* = x + Δt v*; clear the normal corrections;
//   then XPBD_ITERATIONS times:
//     pass 1 (per spring)   project the springs of one colour (springs of a colour share no
//                           vertex, so one invocation per spring needs no atomics), once per colour;
//     pass 4 (per vertex)   with SelfCollision: the vertex's self-contact corrections, averaged
//                           (Jacobi: every vertex reads the positions the springs left);
//     pass 2 (per vertex)   apply the self-contact correction; project the vertex out of the
//                           colliders (swept from its substep start, so a long step cannot
//                           tunnel), summing the corrections;
//   pass 3 (per vertex)     friction on the contacts' displacements, v = (x* − x)/Δt (with
//                           SelfCollision, the speed limit), deepest penetration.
// Units: m, kg, s, N/m.

// Which pass this pipeline runs (see above).
override XPBD_PASS: u32 = 0u;

@group(0) @binding(0) var<uniform> params: SimParams;
@group(0) @binding(1) var<uniform> colliders: array<Collider, MAX_COLLIDERS>;
@group(0) @binding(2) var<storage, read> constraints: array<Constraint>;
// The state at the substep's start (w: 1 free, minus its pin group pinned).
@group(0) @binding(3) var<storage, read> positions_in: array<vec4<f32>>;

// The position of vertex `index` in the state read, m (for common.wgsl's grid_normal).
fn position_in(index: u32) -> vec3<f32> {
    return positions_in[index].xyz;
}
@group(0) @binding(4) var<storage, read> velocities_in: array<vec4<f32>>;
// The predicted positions, projected in place; then the new state.
@group(0) @binding(5) var<storage, read_write> positions_out: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> velocities_out: array<vec4<f32>>;
// Deepest penetration so far, m, as the bits of a non-negative f32 (see cloth_step.wgsl).
@group(0) @binding(7) var<storage, read_write> max_penetration_bits: atomic<u32>;
// Each spring's Lagrange multiplier λ (in constraint order).
@group(0) @binding(8) var<storage, read_write> lambdas: array<f32>;
// Each vertex's summed collider correction in this substep, m.
@group(0) @binding(9) var<storage, read_write> normal_corrections: array<f32>;
// The colour pass 1 projects (selected by a dynamic offset).
@group(0) @binding(10) var<uniform> color: ColorRange;
// The mesh colliders' distance fields (colliders.wgsl), m.
@group(0) @binding(11) var<storage, read> distance_fields: array<f32>;
// Each vertex's averaged self-contact correction of the current iteration, m; self-collision's
// candidate lists, its hash and its control (self_hash.wgsl; placeholders without
// SelfCollision).
@group(0) @binding(12) var<storage, read_write> self_corrections: array<vec4<f32>>;
@group(0) @binding(13) var<storage, read> self_words: array<u32>;
@group(0) @binding(14) var<storage, read> self_links: array<vec4<u32>>;
@group(0) @binding(15) var<storage, read_write> self_control: SelfControl;

// The hash's words 4 at4 to 4 at4 + 3 (self_collision.wgsl).
fn link_words(at4: u32) -> vec4<u32> {
    return self_links[at4];
}

// XPBD's correction of free vertex i (inverse mass w_i) for its contact with vertex j (w_j, 0
// when pinned), m, and whether they touch (cloth_core::self_collision::self_contact_correction):
// i's share w_i / (w_i + w_j) of the depth r − d along u, and friction removing up to μ (r − d)
// of the pair's relative sliding since the substep's start.
fn self_contact_correction(x_i: vec3<f32>, x_j: vec3<f32>, x0_i: vec3<f32>, x0_j: vec3<f32>, w_i: f32,
                           w_j: f32) -> vec4<f32> {
    let r = params.self_contact.x;
    let delta = x_i - x_j;
    let d2 = dot(delta, delta);
    if ((d2 >= r * r) | (d2 <= 0.0)) {
        return vec4<f32>(0.0);
    }
    let d = sqrt(d2);
    let u = delta * (1.0 / d);
    let depth = r - d;
    let share = w_i / (w_i + w_j);
    var correction = u * (depth * share);
    let slide = (x_i - x0_i) - (x_j - x0_j);
    let tangential = slide - u * dot(slide, u);
    let length = sqrt(dot(tangential, tangential));
    if (length > 0.0) {
        correction -= tangential * (min(params.self_contact.w * depth, length) / length * share);
    }
    return vec4<f32>(correction, 1.0);
}

// Free vertex i's correction for its contact with vertex j (self_contact_correction, from the
// positions the springs left and the substep's start), with w 1, or zero where they do not touch.
fn self_contact_with(j: u32, x: vec3<f32>, x0: vec3<f32>, w: f32) -> vec4<f32> {
    let q = positions_out[j];
    if (!in_contact(x, q.xyz)) {
        return vec4<f32>(0.0);
    }
    return self_contact_correction(x, q.xyz, x0, positions_in[j].xyz, w, max(q.w, 0.0) * w);
}

// The self-contact term of partner j (self_partners.wgsl): free vertex i's correction for it,
// from i's position c.x, its position at the substep's start c.a and its inverse mass c.s.
fn pair_term(j: u32, c: PairContext) -> vec4<f32> {
    return self_contact_with(j, c.x, c.a, c.s);
}

// Pass 4: free vertex i's self-contacts with its partners (sum_over_partners, in
// cloth_core::reference's project_self_contacts's order), averaged.
fn self_contacts(i: u32) {
    let p = positions_out[i];
    if (p.w <= 0.0) {
        self_corrections[i] = vec4<f32>(0.0);
        return;
    }
    let c = PairContext(p.xyz, positions_in[i].xyz, 1.0 / params.vertex_mass);
    let sum = sum_over_partners(i, i % params.grid_nx, i / params.grid_nx, c);
    var correction = vec3<f32>(0.0);
    if (sum.w > 0.0) {
        correction = sum.xyz * (1.0 / sum.w);
    }
    self_corrections[i] = vec4<f32>(correction, 0.0);
}

struct SpringProjection {
    x_a: vec3<f32>,
    x_b: vec3<f32>,
    lambda: f32,
}

// Δλ = (−C − α̃ λ) / (w_a + w_b + α̃), α̃ = 1/(k Δt²); the ends move by ±w Δλ n.
fn project_spring(x_a: vec3<f32>, x_b: vec3<f32>, inverse_mass_a: f32, inverse_mass_b: f32,
                  rest_length: f32, stiffness: f32, dt: f32, lambda: f32) -> SpringProjection {
    var r = SpringProjection(x_a, x_b, lambda);
    if (inverse_mass_a + inverse_mass_b <= 0.0 || stiffness <= 0.0) {
        return r;
    }
    let d = x_a - x_b;
    let length = sqrt(dot(d, d));
    if (length <= 0.0) {
        return r;
    }
    let n = d * (1.0 / length);
    let compliance = 1.0 / (stiffness * dt * dt);
    let delta_lambda = (-(length - rest_length) - compliance * lambda)
        / (inverse_mass_a + inverse_mass_b + compliance);
    r.lambda = lambda + delta_lambda;
    r.x_a = x_a + n * (inverse_mass_a * delta_lambda);
    r.x_b = x_b - n * (inverse_mass_b * delta_lambda);
    return r;
}

struct Projection {
    x: vec3<f32>,
    depth: f32,
}

// The non-penetration constraint φ(x) ≥ 0: move x by −φ 1_n, return the correction.
fn project_onto_surface(x: vec3<f32>, surface: Surface) -> Projection {
    let depth = -surface.distance;
    if (depth > 0.0) {
        return Projection(x + surface.normal * depth, depth);
    }
    return Projection(x, 0.0);
}

// project_onto_surface made continuous for a sphere: a path from x_start (outside) that went
// through the sphere and out the far side is put back where it entered; a path ending inside is
// projected as usual.
fn project_sphere_swept(x: vec3<f32>, x_start: vec3<f32>, center: vec3<f32>, radius: f32) -> Projection {
    let o = x_start - center;
    let outside_at_start = dot(o, o) - radius * radius;
    let end = x - center;
    let outside_at_end = dot(end, end) - radius * radius;
    if (outside_at_start >= 0.0 && outside_at_end > 0.0) {
        let d = x - x_start;
        let a = dot(d, d);
        let b = dot(o, d);
        let discriminant = b * b - a * outside_at_start;
        if (a > 0.0 && b < 0.0 && discriminant >= 0.0) {
            let s = (-b - sqrt(discriminant)) / a;
            if (s <= 1.0) {
                let entry = x_start + d * s;
                let moved = x - entry;
                return Projection(entry, sqrt(dot(moved, moved)));
            }
        }
        return Projection(x, 0.0);
    }
    return project_onto_surface(x, sphere_surface(x, center, radius));
}

// Steps and stopping distance (of the thickness) of the sweep (cloth_core::constraints).
const SWEEP_STEPS: u32 = 32u;
const SWEEP_TOLERANCE: f32 = 0.01;

// Any collider, continuously (cloth_core::constraints::project_swept): the sphere exactly; a
// plane by its end point; a capsule or box path longer than the collider is thick that ends
// outside is sphere-traced from its start and stopped where it enters.
fn project_swept(x: vec3<f32>, x_start: vec3<f32>, c: u32, center: vec3<f32>) -> Projection {
    if (COLLIDER_SPHERE) {
        if (colliders[c].kind == 0u) {
            return project_sphere_swept(x, x_start, center, colliders[c].radius);
        }
    }
    let end = collider_distance(c, center, x);
    if (end > 0.0 && colliders[c].kind != 1u) {
        let d = x - x_start;
        let length = sqrt(dot(d, d));
        if (length > colliders[c].thickness && collider_distance(c, center, x_start) >= 0.0) {
            let inverse_length = 1.0 / length;
            let stop = colliders[c].thickness * SWEEP_TOLERANCE;
            var s = 0.0;
            for (var k = 0u; k < SWEEP_STEPS; k++) {
                let p = x_start + d * s;
                let phi = collider_distance(c, center, p);
                if (phi <= stop) {
                    let moved = x - p;
                    return Projection(p, sqrt(dot(moved, moved)));
                }
                s = s + phi * inverse_length;
                if (s >= 1.0) {
                    break;
                }
            }
        }
        return Projection(x, 0.0);
    }
    // The normal only for a vertex inside: outside the projection does nothing.
    if (end < 0.0) {
        return project_onto_surface(x, collider_surface(c, center, x));
    }
    return Projection(x, 0.0);
}

// Coulomb friction in position form: the tangential part of the substep's displacement is undone
// up to c_f times the normal correction (static: the vertex sticks), shortened by that beyond;
// only on the collider (φ within its tolerance).
fn contact_friction(x: vec3<f32>, x_start: vec3<f32>, surface: Surface, tolerance: f32,
                    coefficient: f32, normal_correction: f32) -> vec3<f32> {
    if (surface.distance > tolerance) {
        return x;
    }
    let n = surface.normal;
    let dx = x - x_start;
    let dx_t = dx - n * dot(dx, n);
    let slide = sqrt(dot(dx_t, dx_t));
    let budget = coefficient * normal_correction;
    if (slide > 0.0) {
        return x - dx_t * (min(slide, budget) / slide);
    }
    return x;
}

fn predict(i: u32) {
    let p = positions_in[i];
    let state = velocities_in[i];
    let t = state.w;
    let h = params.substep_dt;
    var x = p.xyz;
    if (p.w > 0.0) {
        let m = params.vertex_mass;
        var v = state.xyz;
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
    positions_out[i] = vec4<f32>(x, p.w);
    normal_corrections[i] = 0.0;
}

fn project_color(t: u32) {
    if (!ANY_SPRINGS) {
        return;
    }
    if (t >= color.count) {
        return;
    }
    let c = color.first + t;
    let s = constraints[c];
    if (!kind_enabled(s.kind)) {
        return;
    }
    let pa = positions_out[s.a];
    let pb = positions_out[s.b];
    let w = 1.0 / params.vertex_mass;
    var lambda = lambdas[c];
    if (color.first_iteration != 0u) {
        lambda = 0.0;
    }
    let r = project_spring(pa.xyz, pb.xyz, max(pa.w, 0.0) * w, max(pb.w, 0.0) * w, s.rest_length, params.stiffness[s.kind],
                           params.substep_dt, lambda);
    lambdas[c] = r.lambda;
    positions_out[s.a] = vec4<f32>(r.x_a, pa.w);
    positions_out[s.b] = vec4<f32>(r.x_b, pb.w);
}

fn project_colliders(i: u32) {
    let p = positions_out[i];
    if (p.w <= 0.0) {
        return;
    }
    let t = velocities_in[i].w;
    let t_end = t + params.substep_dt;
    var x = p.xyz;
    if (EFFECT_SELF_COLLISION) {
        // Pass 4's self-contact correction, applied to every vertex at once.
        x = x + self_corrections[i].xyz;
    }
    var correction = normal_corrections[i];
    for (var s = 0u; s < params.collider_count; s++) {
        // Where the collider ends the substep, and the vertex's start carried along with it.
        let center = collider_center(s, t_end);
        let x_start = positions_in[i].xyz + (center - collider_center(s, t));
        let r = project_swept(x, x_start, s, center);
        x = r.x;
        correction = correction + r.depth;
    }
    positions_out[i] = vec4<f32>(x, p.w);
    normal_corrections[i] = correction;
}

// Pass 3; returns the vertex's displacement over the substep (w 1).
fn finish(i: u32) -> vec4<f32> {
    let p = positions_out[i];
    let t = velocities_in[i].w;
    let t_end = t + params.substep_dt;
    var x = p.xyz;
    var v = pin_velocity(pin_group(p.w), x, t_end);
    if (p.w > 0.0) {
        let x0 = positions_in[i].xyz;
        let correction = normal_corrections[i];
        if (EFFECT_FRICTION) {
            if (correction > 0.0) {
                for (var s = 0u; s < params.collider_count; s++) {
                    let center = collider_center(s, t_end);
                    let x_start = x0 + (center - collider_center(s, t));
                    // Off the collider friction does nothing: the normal only on it.
                    if (collider_distance(s, center, x) <= colliders[s].tolerance) {
                        let surface = collider_surface(s, center, x);
                        x = contact_friction(x, x_start, surface, colliders[s].tolerance, colliders[s].friction, correction);
                    }
                }
                positions_out[i] = vec4<f32>(x, p.w);
            }
        }
        v = (x - x0) * (1.0 / params.substep_dt);
        if (EFFECT_SELF_COLLISION) {
            // The speed limit (self_collision.wgsl).
            x = limit_step(x0, x);
            v = limit_velocity(v);
            positions_out[i] = vec4<f32>(x, p.w);
        }
    }
    velocities_out[i] = vec4<f32>(v, t_end);
    if (EFFECT_CONTACT) {
        var deepest = 0.0;
        for (var s = 0u; s < params.collider_count; s++) {
            deepest = max(deepest, -collider_distance(s, collider_center(s, t_end), x));
        }
        if (deepest > 0.0) {
            atomicMax(&max_penetration_bits, bitcast<u32>(deepest));
        }
    }
    return vec4<f32>(x - positions_in[i].xyz, 1.0);
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn xpbd(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>,
        @builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) local: u32) {
    // (The conditions written out, not kept in a variable: a constant condition compiles the
    // branch out.)
    if (EFFECT_SELF_COLLISION & (XPBD_PASS == 3u)) {
        clear_motion(local);
    }
    let moved = run_pass(id, groups);
    if (EFFECT_SELF_COLLISION & (XPBD_PASS == 3u)) {
        // The box of the substep's displacements, which the next check adds to its bound.
        record_motion(moved, local, group.y * groups.x + group.x);
    }
}

// Runs the pipeline's pass for the invocation; returns the vertex's displacement over the
// substep in the finishing pass (w 1), zero otherwise.
fn run_pass(id: vec3<u32>, groups: vec3<u32>) -> vec4<f32> {
    // 2D dispatch: more than 65535 workgroups spill into y.
    let t = id.y * groups.x * WORKGROUP_SIZE + id.x;
    if (XPBD_PASS == 1u) {
        project_color(t);
        return vec4<f32>(0.0);
    }
    if (t >= params.vertex_count) {
        return vec4<f32>(0.0);
    }
    switch XPBD_PASS {
        case 0u: { predict(t); }
        case 2u: {
            if (EFFECT_CONTACT | EFFECT_SELF_COLLISION) {
                project_colliders(t);
            }
        }
        case 4u: {
            if (EFFECT_SELF_COLLISION) {
                self_contacts(t);
            }
        }
        default: { return finish(t); }
    }
    return vec4<f32>(0.0);
}
