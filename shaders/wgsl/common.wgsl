// Shared by every WGSL compute kernel of the cloth (the backend prepends it, after layout.wgsl
// and colliders.wgsl, to each): the effect constants and the force model.
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
override EFFECT_WIND: bool = false;
override EFFECT_MOVING_PINS: bool = false;
override EFFECT_MOVING_COLLIDERS: bool = false;
override EFFECT_SELF_COLLISION: bool = false;
override WORKGROUP_SIZE: u32 = 256u;
// Any spring kind at all (one constant, so the branch on it is a constant too).
override ANY_SPRINGS: bool = EFFECT_STRUCTURAL || EFFECT_SHEAR || EFFECT_BEND;

// F_g = m g.
fn gravity_force(mass: f32, gravity: vec3<f32>) -> vec3<f32> {
    return gravity * mass;
}

// Hooke F_s = -k Δl and damping F_d = -c_d v_s, seen from vertex i, added to `force`
// (a zero-length spring adds nothing: branched around, measured faster on the H100 than adding 0).
fn add_spring_force(force: ptr<function, vec3<f32>>, x_i: vec3<f32>, x_j: vec3<f32>, v_i: vec3<f32>,
                    v_j: vec3<f32>, rest_length: f32, stiffness: f32, damping: f32) {
    let delta = x_j - x_i;
    let len_squared = dot(delta, delta);
    if (len_squared <= 0.0) {
        return;
    }
    // 1/L once (one instruction on a GPU; measured on the H100: docs/performance.md): u and L
    // from it.
    let inverse_len = inverseSqrt(len_squared);
    let u = delta * inverse_len;
    let len = len_squared * inverse_len;
    let extension_rate = dot(v_j - v_i, u);
    *force += u * (stiffness * (len - rest_length) + damping * extension_rate);
}

// Linear air drag F = -m γ v (an addition to the mass-spring model).
fn air_drag_force(mass: f32, rate: f32, v: vec3<f32>) -> vec3<f32> {
    return v * (-(mass * rate));
}

struct Contact {
    hit: bool,
    normal: vec3<f32>,
    force: vec3<f32>,
}

// F_c = k_c d with d = −φ 1_n, plus damping of the normal approach velocity (v relative to the
// collider), for every collider kind: the collider enters through its surface seen from x.
fn contact_force(v: vec3<f32>, surface: Surface, stiffness: f32, damping: f32) -> Contact {
    var c: Contact;
    let depth = -surface.distance;
    c.hit = depth > 0.0;
    if (!c.hit) {
        return c;
    }
    c.normal = surface.normal;
    let approach = min(dot(v, c.normal), 0.0);
    c.force = c.normal * (stiffness * depth - damping * approach);
    return c;
}

// R_on = (R_o·1_n)1_n, R_ot = R_o - R_on, F_f = -min(|R_ot|, c_f |R_on|) 1_t,
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

// Whether the model's friction holds the vertex still: |R_ot + m v_t / Δt| <= c_f |R_on|.
fn friction_holds(other_forces: vec3<f32>, v: vec3<f32>, normal: vec3<f32>,
                  mass: f32, dt: f32, coefficient: f32) -> bool {
    let r_on = normal * dot(other_forces, normal);
    let r_ot = other_forces - r_on;
    let v_t = v - normal * dot(v, normal);
    let tangential = r_ot + v_t * (mass / dt);
    return sqrt(dot(tangential, tangential)) <= coefficient * sqrt(dot(r_on, r_on));
}

// Linear wind pressure (an addition to the mass-spring model): F = c A ((w − v)·n) n, n the cloth's unit normal.
fn wind_force(normal: vec3<f32>, v: vec3<f32>, wind: vec3<f32>, coefficient_area: f32) -> vec3<f32> {
    return normal * (coefficient_area * dot(wind - v, normal));
}

// The wind at time t: w (1 + a sin(ω_g t)) (cloth_core::motion::wind_velocity).
fn wind_velocity(t: f32) -> vec3<f32> {
    return params.wind.xyz * (1.0 + params.gust.x * sin(params.gust.y * t));
}

// A prescribed motion (cloth_core::motion::MotionOf): d(t) = velocity t + amplitude sin(ω t).
fn motion_displacement(velocity: vec3<f32>, amplitude: vec3<f32>, omega: f32, t: f32) -> vec3<f32> {
    return velocity * t + amplitude * sin(omega * t);
}

// d'(t) = velocity + amplitude ω cos(ω t).
fn motion_velocity(velocity: vec3<f32>, amplitude: vec3<f32>, omega: f32, t: f32) -> vec3<f32> {
    return velocity + amplitude * (omega * cos(omega * t));
}

// The pin group of a pinned vertex, from its position's w (0, −1, −2, −3; free vertices have 1).
fn pin_group(w: f32) -> u32 {
    return u32(max(-w, 0.0));
}

// The rotation of v by the angle |θ| about θ/|θ| (cloth_core::motion::rotate, Rodrigues).
fn rotate(theta: vec3<f32>, v: vec3<f32>) -> vec3<f32> {
    let angle = sqrt(dot(theta, theta));
    if (angle == 0.0) {
        return v;
    }
    let k = theta * (1.0 / angle);
    let s = sin(angle);
    let c = cos(angle);
    return v * c + cross(k, v) * s + k * (dot(k, v) * (1.0 - c));
}

// Where a pin of `group` at x at time `from` is at `to` (MotionOf::carry): x + d(to) − d(from),
// or, turning, p(to) + R(ω (to − from))(x − p(from)) with p(t) = pivot + d(t). Without
// MovingPins it stays at x.
fn pin_carry(group: u32, x: vec3<f32>, from_t: f32, to_t: f32) -> vec3<f32> {
    if (EFFECT_MOVING_PINS) {
        let m = 4u * group;
        let v = params.pin_motion[m];
        let a = params.pin_motion[m + 1u].xyz;
        let w = params.pin_motion[m + 2u].xyz;
        let d_from = motion_displacement(v.xyz, a, v.w, from_t);
        let d_to = motion_displacement(v.xyz, a, v.w, to_t);
        if (all(w == vec3<f32>(0.0))) {
            return x + (d_to - d_from);
        }
        let pivot = params.pin_motion[m + 3u].xyz;
        let p_from = pivot + d_from;
        let p_to = pivot + d_to;
        return p_to + rotate(w * (to_t - from_t), x - p_from);
    }
    return x;
}

// The velocity of a pin of `group` at x at time t (MotionOf::point_velocity): d'(t), plus
// ω × (x − p(t)) turning; zero without MovingPins.
fn pin_velocity(group: u32, x: vec3<f32>, t: f32) -> vec3<f32> {
    if (EFFECT_MOVING_PINS) {
        let m = 4u * group;
        let v = params.pin_motion[m];
        let a = params.pin_motion[m + 1u].xyz;
        let w = params.pin_motion[m + 2u].xyz;
        let velocity = motion_velocity(v.xyz, a, v.w, t);
        if (all(w == vec3<f32>(0.0))) {
            return velocity;
        }
        let p = params.pin_motion[m + 3u].xyz + motion_displacement(v.xyz, a, v.w, t);
        return velocity + cross(w, x - p);
    }
    return vec3<f32>(0.0);
}

// Where collider `c`'s centre is at time t, and how fast it moves (still without
// MovingColliders).
fn collider_center(c: u32, t: f32) -> vec3<f32> {
    if (EFFECT_MOVING_COLLIDERS) {
        return colliders[c].center + motion_displacement(colliders[c].velocity, colliders[c].amplitude, colliders[c].omega, t);
    }
    return colliders[c].center;
}

fn collider_velocity(c: u32, t: f32) -> vec3<f32> {
    if (EFFECT_MOVING_COLLIDERS) {
        return motion_velocity(colliders[c].velocity, colliders[c].amplitude, colliders[c].omega, t);
    }
    return vec3<f32>(0.0);
}

// The cloth's unit normal at vertex i from its grid neighbours' positions, position_in(index)
// (defined by each kernel that calls this): (x[i+1,j] − x[i−1,j]) × (x[i,j+1] − x[i,j−1]), one-sided at the edges
// (cloth_core::forces::grid_normal).
fn grid_normal(index: u32) -> vec3<f32> {
    let nx = params.grid_nx;
    let i = index % nx;
    let j = index / nx;
    var left = i;
    if (i > 0u) { left = i - 1u; }
    var right = i;
    if (i + 1u < nx) { right = i + 1u; }
    var down = j;
    if (j > 0u) { down = j - 1u; }
    var up = j;
    if (j + 1u < params.grid_ny) { up = j + 1u; }
    let along_u = position_in(j * nx + right) - position_in(j * nx + left);
    let along_v = position_in(up * nx + i) - position_in(down * nx + i);
    let n = cross(along_u, along_v);
    let length = sqrt(dot(n, n));
    if (length > 0.0) {
        return n * (1.0 / length);
    }
    return vec3<f32>(0.0);
}

fn kind_enabled(kind: u32) -> bool {
    switch kind {
        case 0u: { return EFFECT_STRUCTURAL; }
        case 1u: { return EFFECT_SHEAR; }
        default: { return EFFECT_BEND; }
    }
}
