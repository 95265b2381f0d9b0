// Self-collision (cloth_core::self_collision, operation by operation): vertex pairs closer than
// the thickness r repel, found through a spatial hash of cubic cells that the kernels of
// self_hash.wgsl rebuild every few substeps. Prepended, after common.wgsl, to the kernels that
// evaluate or build it. Parameters in params.self_contact, params.self_hash and
// params.self_table (cloth_gpu::layout::GpuSimParams).

// Self-collision's prefix sum scans this many buckets a workgroup (cloth_gpu::layout::HASH_SCAN_BLOCK).
const HASH_SCAN_BLOCK: u32 = 256u;

// The hash cell holding x: floor(x / h) per axis (cloth_core::self_collision::cell_of).
fn hash_cell(x: vec3<f32>) -> vec3<i32> {
    let inverse = 1.0 / params.self_hash.x;
    return vec3<i32>(floor(x * inverse));
}

// The bucket of cell c: the coordinates times large primes, combined by exclusive or, in
// wrapping u32 arithmetic, masked to the table's power-of-two size (bucket_of).
fn hash_bucket(c: vec3<i32>) -> u32 {
    let h = (u32(c.x) * 73856093u) ^ (u32(c.y) * 19349663u) ^ (u32(c.z) * 83492791u);
    return h & (params.self_table.x - 1u);
}

// The distances from x to the low and the high faces of its cell `base`, per axis, m: how far
// the neighbouring cells below and above are (hash_gaps in cloth_core::self_collision).
struct HashGaps {
    below: vec3<f32>,
    above: vec3<f32>,
}

fn hash_gaps(x: vec3<f32>, base: vec3<i32>) -> HashGaps {
    let h = params.self_hash.x;
    let below = x - vec3<f32>(base) * h;
    return HashGaps(below, vec3<f32>(h) - below);
}

// Whether the cell at offset (dx, dy, dz) from x's comes nearer x than the cell side h: a vertex
// listed farther than h from where x is now cannot be within the thickness of it
// (cell_in_reach).
fn hash_cell_in_reach(gaps: HashGaps, dx: i32, dy: i32, dz: i32) -> bool {
    let d = vec3<i32>(dx, dy, dz);
    let low = select(vec3<f32>(0.0), gaps.below, d < vec3<i32>(0));
    let high = select(vec3<f32>(0.0), gaps.above, d > vec3<i32>(0));
    let e = low + high;
    let h = params.self_hash.x;
    return dot(e, e) < h * h;
}

// Whether vertices a and b are at least the thickness apart at rest, from their grid
// coordinates (the rest-distance filter, apart_at_rest).
fn apart_at_rest(a: u32, b: u32) -> bool {
    let nx = params.grid_nx;
    let di = f32(a % nx) - f32(b % nx);
    let dj = f32(a / nx) - f32(b / nx);
    let du = di * params.self_hash.z;
    let dv = dj * params.self_hash.w;
    let r = params.self_contact.x;
    return du * du + dv * dv >= r * r;
}

// The force on vertex i from vertex j, N: repulsion k_s (r − d) and approach damping along
// u = (x_i − x_j)/d, and the layers' friction, capped by Coulomb and by a share of the force that
// stops the sliding (repulsion_force; 16 = 2 × CONTACTS_PER_VERTEX).
fn repulsion_force(x_i: vec3<f32>, x_j: vec3<f32>, v_i: vec3<f32>, v_j: vec3<f32>, mass: f32,
                   dt: f32) -> vec3<f32> {
    let r = params.self_contact.x;
    let delta = x_i - x_j;
    let d2 = dot(delta, delta);
    if ((d2 >= r * r) | (d2 <= 0.0)) {
        return vec3<f32>(0.0);
    }
    let d = sqrt(d2);
    let u = delta * (1.0 / d);
    let v_r = v_i - v_j;
    let approach = dot(v_r, u);
    let normal = params.self_contact.y * (r - d) - params.self_contact.z * min(approach, 0.0);
    var force = u * normal;
    let v_t = v_r - u * approach;
    let sliding = sqrt(dot(v_t, v_t));
    if (sliding > 0.0) {
        let stop = mass * sliding / (16.0 * dt);
        force += v_t * (-(min(stop, params.self_contact.w * abs(normal)) / sliding));
    }
    return force;
}

// The speed limit's part on a substep's displacement from x_start: at most s_max Δt
// (limit_speed).
fn limit_step(x_start: vec3<f32>, x: vec3<f32>) -> vec3<f32> {
    let step = x - x_start;
    let reach = params.self_hash.y * params.substep_dt;
    let length = sqrt(dot(step, step));
    if (length > reach) {
        return x_start + step * (reach / length);
    }
    return x;
}

// The speed limit's part on a velocity: at most s_max (limit_speed).
fn limit_velocity(v: vec3<f32>) -> vec3<f32> {
    let max_speed = params.self_hash.y;
    let speed = sqrt(dot(v, v));
    if (speed > max_speed) {
        return v * (max_speed / speed);
    }
    return v;
}
