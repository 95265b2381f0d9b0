// The mass-spring force model, one function per force: the GLSL twin of
// crates/cloth-core/src/forces.rs and shaders/wgsl/common.wgsl (same names, same order of
// operations). Units: m, kg, s, N/m, N·s/m.

// F_g = m g.
vec3 gravity_force(float mass, vec3 gravity) {
    return gravity * mass;
}

// Hooke F_s = -k Δl and damping F_d = -c_d v_s, seen from vertex i, added to `force`
// (a zero-length spring adds nothing: branched around, measured faster on the H100 than adding 0).
void add_spring_force(inout vec3 force, vec3 x_i, vec3 x_j, vec3 v_i, vec3 v_j, float rest_length, float stiffness,
                      float damping) {
    vec3 delta = x_j - x_i;
    float len_squared = dot(delta, delta);
    if (len_squared <= 0.0) {
        return;
    }
    // 1/L once (one instruction on a GPU; measured on the H100: docs/performance.md): u and L
    // from it.
    float inverse_len = inversesqrt(len_squared);
    vec3 u = delta * inverse_len;
    float len = len_squared * inverse_len;
    float extension_rate = dot(v_j - v_i, u);
    force += u * (stiffness * (len - rest_length) + damping * extension_rate);
}

// Linear air drag F = -m γ v (an addition to the mass-spring model).
vec3 air_drag_force(float mass, float rate, vec3 v) {
    return v * (-(mass * rate));
}

// F_c = k_c d with d = −φ 1_n, plus damping of the normal approach velocity (v relative to the
// collider), for every collider kind: the collider enters through its surface seen from x.
// Returns false outside.
bool contact_force(vec3 v, Surface surface, float stiffness, float damping, out vec3 normal, out vec3 force) {
    float depth = -surface.distance;
    normal = vec3(0.0);
    force = vec3(0.0);
    if (depth <= 0.0) {
        return false;
    }
    normal = surface.normal;
    float approach = min(dot(v, normal), 0.0);
    force = normal * (stiffness * depth - damping * approach);
    return true;
}

// R_on = (R_o·1_n)1_n, R_ot = R_o - R_on, F_f = -min(|R_ot|, c_f |R_on|) 1_t,
// with m v_t / Δt added to R_ot (see docs/model.md).
vec3 friction_force(vec3 other_forces, vec3 v, vec3 normal, float mass, float dt, float coefficient) {
    vec3 r_on = normal * dot(other_forces, normal);
    vec3 r_ot = other_forces - r_on;
    vec3 v_t = v - normal * dot(v, normal);
    vec3 tangential = r_ot + v_t * (mass / dt);
    float magnitude = sqrt(dot(tangential, tangential));
    if (magnitude <= 0.0) {
        return vec3(0.0);
    }
    float limit = coefficient * sqrt(dot(r_on, r_on));
    return tangential * (-(min(magnitude, limit) / magnitude));
}

// Whether the model's friction holds the vertex still: |R_ot + m v_t / Δt| <= c_f |R_on|.
bool friction_holds(vec3 other_forces, vec3 v, vec3 normal, float mass, float dt, float coefficient) {
    vec3 r_on = normal * dot(other_forces, normal);
    vec3 r_ot = other_forces - r_on;
    vec3 v_t = v - normal * dot(v, normal);
    vec3 tangential = r_ot + v_t * (mass / dt);
    return sqrt(dot(tangential, tangential)) <= coefficient * sqrt(dot(r_on, r_on));
}

// Linear wind pressure (an addition to the mass-spring model): F = c A ((w − v)·n) n, n the cloth's unit normal.
vec3 wind_force(vec3 normal, vec3 v, vec3 wind, float coefficient_area) {
    return normal * (coefficient_area * dot(wind - v, normal));
}

// The wind at time t: w (1 + a sin(ω_g t)) (cloth_core::motion::wind_velocity).
vec3 wind_velocity(float t) {
    return params.wind.xyz * (1.0 + params.gust.x * sin(params.gust.y * t));
}

// A prescribed motion (cloth_core::motion::MotionOf): d(t) = velocity t + amplitude sin(ω t).
vec3 motion_displacement(vec3 velocity, vec3 amplitude, float omega, float t) {
    return velocity * t + amplitude * sin(omega * t);
}

// d'(t) = velocity + amplitude ω cos(ω t).
vec3 motion_velocity(vec3 velocity, vec3 amplitude, float omega, float t) {
    return velocity + amplitude * (omega * cos(omega * t));
}

// The pin group of a pinned vertex, from its position's w (0, −1, −2, −3; free vertices have 1).
uint pin_group(float w) {
    return uint(max(-w, 0.0));
}

// The rotation of v by the angle |θ| about θ/|θ| (cloth_core::motion::rotate, Rodrigues).
vec3 rotate(vec3 theta, vec3 v) {
    float angle = sqrt(dot(theta, theta));
    if (angle == 0.0) {
        return v;
    }
    vec3 k = theta * (1.0 / angle);
    float s = sin(angle);
    float c = cos(angle);
    return v * c + cross(k, v) * s + k * (dot(k, v) * (1.0 - c));
}

// Where a pin of `group` at x at time `from` is at `to` (MotionOf::carry): x + d(to) − d(from),
// or, turning, p(to) + R(ω (to − from))(x − p(from)) with p(t) = pivot + d(t). Without
// MovingPins it stays at x.
vec3 pin_carry(uint group, vec3 x, float from_t, float to_t) {
    if (EFFECT_MOVING_PINS) {
        uint m = 4u * group;
        vec4 v = params.pin_motion[m];
        vec3 a = params.pin_motion[m + 1u].xyz;
        vec3 w = params.pin_motion[m + 2u].xyz;
        vec3 d_from = motion_displacement(v.xyz, a, v.w, from_t);
        vec3 d_to = motion_displacement(v.xyz, a, v.w, to_t);
        if (all(equal(w, vec3(0.0)))) {
            return x + (d_to - d_from);
        }
        vec3 pivot = params.pin_motion[m + 3u].xyz;
        vec3 p_from = pivot + d_from;
        vec3 p_to = pivot + d_to;
        return p_to + rotate(w * (to_t - from_t), x - p_from);
    }
    return x;
}

// The velocity of a pin of `group` at x at time t (MotionOf::point_velocity): d'(t), plus
// ω × (x − p(t)) turning; zero without MovingPins.
vec3 pin_velocity(uint group, vec3 x, float t) {
    if (EFFECT_MOVING_PINS) {
        uint m = 4u * group;
        vec4 v = params.pin_motion[m];
        vec3 a = params.pin_motion[m + 1u].xyz;
        vec3 w = params.pin_motion[m + 2u].xyz;
        vec3 velocity = motion_velocity(v.xyz, a, v.w, t);
        if (all(equal(w, vec3(0.0)))) {
            return velocity;
        }
        vec3 p = params.pin_motion[m + 3u].xyz + motion_displacement(v.xyz, a, v.w, t);
        return velocity + cross(w, x - p);
    }
    return vec3(0.0);
}

// Where collider `c`'s centre is at time t, and how fast it moves (still without
// MovingColliders).
vec3 collider_center(uint c, float t) {
    if (EFFECT_MOVING_COLLIDERS) {
        return colliders[c].center + motion_displacement(colliders[c].velocity, colliders[c].amplitude, colliders[c].omega, t);
    }
    return colliders[c].center;
}

vec3 collider_velocity(uint c, float t) {
    if (EFFECT_MOVING_COLLIDERS) {
        return motion_velocity(colliders[c].velocity, colliders[c].amplitude, colliders[c].omega, t);
    }
    return vec3(0.0);
}

// Whether springs of this kind are simulated (a specialization constant per kind).
bool kind_enabled(uint kind) {
    if (kind == 0u) return EFFECT_STRUCTURAL;
    if (kind == 1u) return EFFECT_SHEAR;
    return EFFECT_BEND;
}
