// One substep of the mass-spring cloth: one invocation per vertex.
//
// The force model mirrors crates/cloth-core/src/forces.rs function by function and operation by
// operation (same names, same order of the sums), so that f32 results agree with the CPU
// reference up to rounding. Units: m, kg, s, N/m, N·s/m.
//
// Effects the scene leaves out are compiled out: each EFFECT_* is a pipeline-overridable
// constant set from cloth_core::EffectSet::shader_constants, and a branch on a false constant
// is removed when the pipeline is built.

override EFFECT_GRAVITY: bool = true;
override EFFECT_STRUCTURAL: bool = true;
override EFFECT_SHEAR: bool = true;
override EFFECT_BEND: bool = true;
override EFFECT_SPRING_DAMPING: bool = true;
override EFFECT_CONTACT: bool = true;
override EFFECT_FRICTION: bool = true;
override EFFECT_AIR_DRAG: bool = false;
override WORKGROUP_SIZE: u32 = 64u;
// Which integration stage this pipeline runs: 0 semi-implicit Euler (the brief's); 1 and 2 the
// two halves of velocity Verlet: 1 = kick and drift (v½ = v + ½Δt F(x, v)/m, x' = x + Δt v½),
// 2 = the second kick (v' = v½ + ½Δt F(x', v½)/m, positions untouched).
override STAGE: u32 = 0u;

// cloth_core::layout::GpuSimParams (80 bytes).
struct SimParams {
    gravity: vec4<f32>,      // m/s² (xyz)
    stiffness: vec4<f32>,    // N/m by spring kind: structural, shear, bend
    damping: vec4<f32>,      // N·s/m by spring kind
    vertex_mass: f32,        // kg
    substep_dt: f32,         // s
    air_drag: f32,           // 1/s
    vertex_count: u32,
    sphere_count: u32,
    grid_nx: u32,
    grid_ny: u32,
    effects: u32,
}

// cloth_core::layout::GpuSphere (32 bytes).
struct Sphere {
    center: vec3<f32>,       // m
    radius: f32,             // m
    stiffness: f32,          // k_c, N/m
    friction: f32,           // c_f
    damping: f32,            // N·s/m
    pad: f32,
}

// cloth_core::layout::GpuSpringRange (8 bytes).
struct SpringRange {
    first: u32,
    count: u32,
}

// cloth_core::layout::GpuSpringEnd (16 bytes).
struct SpringEnd {
    other: u32,
    kind: u32,
    rest_length: f32,        // m
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: SimParams;
@group(0) @binding(1) var<storage, read> spheres: array<Sphere>;
@group(0) @binding(2) var<storage, read> spring_ranges: array<SpringRange>;
@group(0) @binding(3) var<storage, read> spring_ends: array<SpringEnd>;
@group(0) @binding(4) var<storage, read> positions_in: array<vec4<f32>>;   // w: 1 free, 0 pinned
@group(0) @binding(5) var<storage, read> velocities_in: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> positions_out: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read_write> velocities_out: array<vec4<f32>>;
// Deepest penetration so far, m, as the bits of a non-negative f32 (whose bit patterns order
// like the numbers, so atomicMax on u32 is max on f32).
@group(0) @binding(8) var<storage, read_write> max_penetration_bits: atomic<u32>;

// Brief: F_g = m g.
fn gravity_force(mass: f32, gravity: vec3<f32>) -> vec3<f32> {
    return gravity * mass;
}

// Brief: Hooke F_s = -k Δl and damping F_d = -c_d v_s, seen from vertex i.
fn spring_force(x_i: vec3<f32>, x_j: vec3<f32>, v_i: vec3<f32>, v_j: vec3<f32>,
                rest_length: f32, stiffness: f32, damping: f32) -> vec3<f32> {
    let delta = x_j - x_i;
    let len = sqrt(dot(delta, delta));
    if (len <= 0.0) {
        return vec3<f32>(0.0);
    }
    let u = delta * (1.0 / len);
    let extension_rate = dot(v_j - v_i, u);
    return u * (stiffness * (len - rest_length) + damping * extension_rate);
}

// Linear air drag F = -m γ v (not in the brief).
fn air_drag_force(mass: f32, rate: f32, v: vec3<f32>) -> vec3<f32> {
    return v * (-(mass * rate));
}

struct Contact {
    hit: bool,
    normal: vec3<f32>,
    force: vec3<f32>,
}

// Brief: F_c = k_c d, plus damping of the normal approach velocity.
fn contact_force(x: vec3<f32>, v: vec3<f32>, s: Sphere) -> Contact {
    var c: Contact;
    let offset = x - s.center;
    let distance = sqrt(dot(offset, offset));
    let depth = s.radius - distance;
    c.hit = depth > 0.0;
    if (!c.hit) {
        return c;
    }
    if (distance > 0.0) {
        c.normal = offset * (1.0 / distance);
    } else {
        c.normal = vec3<f32>(0.0, 1.0, 0.0);
    }
    let approach = min(dot(v, c.normal), 0.0);
    c.force = c.normal * (s.stiffness * depth - s.damping * approach);
    return c;
}

// Brief: R_on = (R_o·1_n)1_n, R_ot = R_o - R_on, F_f = -min(|R_ot|, c_f |R_on|) 1_t,
// with m v_t / Δt added to R_ot (see docs/model.md).
fn friction_force(other_forces: vec3<f32>, v: vec3<f32>, normal: vec3<f32>,
                  mass: f32, dt: f32, coefficient: f32) -> vec3<f32> {
    let r_on = normal * dot(other_forces, normal);
    let r_ot = other_forces - r_on;
    let v_t = v - normal * dot(v, normal);
    let tangential = r_ot + v_t * (mass / dt);
    let magnitude = sqrt(dot(tangential, tangential));
    if (magnitude <= 0.0) {
        return vec3<f32>(0.0);
    }
    let limit = coefficient * sqrt(dot(r_on, r_on));
    return tangential * (-(min(magnitude, limit) / magnitude));
}

fn kind_enabled(kind: u32) -> bool {
    switch kind {
        case 0u: { return EFFECT_STRUCTURAL; }
        case 1u: { return EFFECT_SHEAR; }
        default: { return EFFECT_BEND; }
    }
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn substep(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    // 2D dispatch: more than 65535 workgroups spill into y.
    let i = id.y * groups.x * WORKGROUP_SIZE + id.x;
    if (i >= params.vertex_count) {
        return;
    }
    let p = positions_in[i];
    let x = p.xyz;
    let v = velocities_in[i].xyz;
    var x_new = x;
    var v_new = vec3<f32>(0.0);
    if (p.w != 0.0) {
        let mass = params.vertex_mass;
        let dt = params.substep_dt;
        let half = dt * 0.5;
        // The step the friction's stopping term refers to: what this stage's velocity update spans.
        var friction_dt = dt;
        if (STAGE != 0u) {
            friction_dt = half;
        }
        var force = vec3<f32>(0.0);
        if (EFFECT_GRAVITY) {
            force += gravity_force(mass, params.gravity.xyz);
        }
        if (EFFECT_STRUCTURAL || EFFECT_SHEAR || EFFECT_BEND) {
            let range = spring_ranges[i];
            for (var e = range.first; e < range.first + range.count; e++) {
                let end = spring_ends[e];
                if (!kind_enabled(end.kind)) {
                    continue;
                }
                var damping = 0.0;
                if (EFFECT_SPRING_DAMPING) {
                    damping = params.damping[end.kind];
                }
                force += spring_force(x, positions_in[end.other].xyz, v, velocities_in[end.other].xyz,
                                      end.rest_length, params.stiffness[end.kind], damping);
            }
        }
        if (EFFECT_AIR_DRAG) {
            force += air_drag_force(mass, params.air_drag, v);
        }
        let other_forces = force;
        if (EFFECT_CONTACT) {
            for (var s = 0u; s < params.sphere_count; s++) {
                let c = contact_force(x, v, spheres[s]);
                if (c.hit) {
                    force += c.force;
                    if (EFFECT_FRICTION) {
                        force += friction_force(other_forces, v, c.normal, mass, friction_dt, spheres[s].friction);
                    }
                }
            }
        }
        if (STAGE == 0u) {
            // Brief: v_c = v_p + Δt R/m, x_c = x_p + Δt v_c (semi-implicit Euler).
            v_new = v + force * (dt / mass);
            x_new = x + v_new * dt;
        } else {
            // Verlet: a half kick, then (stage 1) a full drift.
            v_new = v + force * (half / mass);
            if (STAGE == 1u) {
                x_new = x + v_new * dt;
            }
        }
    }
    velocities_out[i] = vec4<f32>(v_new, 0.0);
    if (STAGE == 2u) {
        return; // the second kick leaves the positions of the first stage as they are
    }
    positions_out[i] = vec4<f32>(x_new, p.w);
    if (EFFECT_CONTACT) {
        var deepest = 0.0;
        for (var s = 0u; s < params.sphere_count; s++) {
            let offset = x_new - spheres[s].center;
            deepest = max(deepest, spheres[s].radius - sqrt(dot(offset, offset)));
        }
        if (deepest > 0.0) {
            atomicMax(&max_penetration_bits, bitcast<u32>(deepest));
        }
    }
}
