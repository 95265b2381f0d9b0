// Self-collision (cloth_core::self_collision, operation by operation): vertex pairs closer than
// the thickness r repel, found through a spatial hash of cubic cells that self_hash.comp rebuilds
// every few substeps. Included, after layout.glsl, by the kernels that evaluate or build it.
// Parameters in params.self_contact, params.self_hash and params.self_table
// (cloth_gpu::layout::GpuSimParams).

// Self-collision's prefix sum scans this many buckets a workgroup (cloth_gpu::layout::HASH_SCAN_BLOCK).
#define HASH_SCAN_BLOCK 256u

// The hash cell holding x: floor(x / h) per axis (cloth_core::self_collision::cell_of).
ivec3 hash_cell(vec3 x) {
    float inverse = 1.0 / params.self_hash.x;
    return ivec3(floor(x * inverse));
}

// The bucket of cell c: the coordinates times large primes, combined by exclusive or, in
// wrapping uint arithmetic, masked to the table's power-of-two size (bucket_of).
uint hash_bucket(ivec3 c) {
    uint h = (uint(c.x) * 73856093u) ^ (uint(c.y) * 19349663u) ^ (uint(c.z) * 83492791u);
    return h & (params.self_table.x - 1u);
}

// The distances from x to the low faces of its cell `base`, per axis, m (the high faces are h
// minus these): how far the neighbouring cells below and above are (hash_gaps in
// cloth_core::self_collision).
vec3 hash_gaps(vec3 x, ivec3 base) {
    return x - vec3(base) * params.self_hash.x;
}

// Whether the cell at offset d from x's comes nearer x than the cell side h: a vertex listed
// farther than h from where x is now cannot be within the thickness of it (cell_in_reach).
bool hash_cell_in_reach(vec3 below, ivec3 d) {
    float h = params.self_hash.x;
    vec3 above = vec3(h) - below;
    vec3 e = mix(vec3(0.0), below, lessThan(d, ivec3(0))) + mix(vec3(0.0), above, greaterThan(d, ivec3(0)));
    return dot(e, e) < h * h;
}

// Whether vertices a and b are at least the thickness apart at rest, from their grid
// coordinates (the rest-distance filter, apart_at_rest).
bool apart_at_rest(uint a, uint b) {
    uint nx = params.grid_nx;
    float di = float(a % nx) - float(b % nx);
    float dj = float(a / nx) - float(b / nx);
    float du = di * params.self_hash.z;
    float dv = dj * params.self_hash.w;
    float r = params.self_contact.x;
    return du * du + dv * dv >= r * r;
}

// The force on vertex i from vertex j, N: repulsion k_s (r − d) and approach damping along
// u = (x_i − x_j)/d, and the layers' friction, capped by Coulomb and by a share of the force that
// stops the sliding (repulsion_force; 16 = 2 × CONTACTS_PER_VERTEX).
vec3 repulsion_force(vec3 x_i, vec3 x_j, vec3 v_i, vec3 v_j, float mass, float dt) {
    float r = params.self_contact.x;
    vec3 delta = x_i - x_j;
    float d2 = dot(delta, delta);
    if (d2 >= r * r || d2 <= 0.0) {
        return vec3(0.0);
    }
    float d = sqrt(d2);
    vec3 u = delta * (1.0 / d);
    vec3 v_r = v_i - v_j;
    float approach = dot(v_r, u);
    float normal = params.self_contact.y * (r - d) - params.self_contact.z * min(approach, 0.0);
    vec3 force = u * normal;
    vec3 v_t = v_r - u * approach;
    float sliding = sqrt(dot(v_t, v_t));
    if (sliding > 0.0) {
        float stop = mass * sliding / (16.0 * dt);
        force += v_t * (-(min(stop, params.self_contact.w * abs(normal)) / sliding));
    }
    return force;
}

// The speed limit's part on a substep's displacement from x_start: at most s_max Δt
// (limit_speed).
vec3 limit_step(vec3 x_start, vec3 x) {
    vec3 step_ = x - x_start;
    float reach = params.self_hash.y * params.substep_dt;
    float len = sqrt(dot(step_, step_));
    if (len > reach) {
        return x_start + step_ * (reach / len);
    }
    return x;
}

// The speed limit's part on a velocity: at most s_max (limit_speed).
vec3 limit_velocity(vec3 v) {
    float max_speed = params.self_hash.y;
    float speed = sqrt(dot(v, v));
    if (speed > max_speed) {
        return v * (max_speed / speed);
    }
    return v;
}
