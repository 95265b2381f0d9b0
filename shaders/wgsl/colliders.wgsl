// The colliders' signed distances (crates/cloth-core/src/colliders.rs, function by function and
// operation by operation): each kind's surface seen from a point x, its signed distance φ (m,
// negative inside) and outward unit normal. Prepended, after layout.wgsl, to every module that
// meets colliders: the compute kernels and the inspector's render.wgsl. Each of those declares
// `distance_fields`, the mesh colliders' samples (`array<f32>`), at its own binding.
//
// A kind no collider of the scene has is compiled out: each COLLIDER_* is a pipeline-overridable
// constant (true when a collider of the scene has the kind), and the branch on a false one is
// removed when the pipeline is built.

override COLLIDER_SPHERE: bool = true;
override COLLIDER_PLANE: bool = true;
override COLLIDER_CAPSULE: bool = true;
override COLLIDER_BOX: bool = true;
override COLLIDER_MESH: bool = true;

struct Surface {
    distance: f32,
    normal: vec3<f32>,
}

// φ = |x − c| − r, n = (x − c)/|x − c| (+Y at the centre).
fn sphere_surface(x: vec3<f32>, center: vec3<f32>, radius: f32) -> Surface {
    let offset = x - center;
    let distance = sqrt(dot(offset, offset));
    var normal = vec3<f32>(0.0, 1.0, 0.0);
    if (distance > 0.0) {
        normal = offset * (1.0 / distance);
    }
    return Surface(distance - radius, normal);
}

// φ = n·(x − p), p a point of the plane.
fn plane_surface(x: vec3<f32>, point: vec3<f32>, normal: vec3<f32>) -> Surface {
    return Surface(dot(x - point, normal), normal);
}

// φ = |x − p| − r, p the nearest point of the axis c ± e a.
fn capsule_surface(x: vec3<f32>, center: vec3<f32>, axis: vec3<f32>, half_length: f32, radius: f32,
                   fallback: vec3<f32>) -> Surface {
    let along = min(max(dot(x - center, axis), -half_length), half_length);
    let offset = x - (center + axis * along);
    let distance = sqrt(dot(offset, offset));
    var normal = fallback;
    if (distance > 0.0) {
        normal = offset * (1.0 / distance);
    }
    return Surface(distance - radius, normal);
}

fn sign_of(v: f32) -> f32 {
    return select(1.0, -1.0, v < 0.0);
}

// A rounded box: p = Rᵀ(x − c), q = |p| − e, φ = |max(q, 0)| + min(max_k q_k, 0) − ρ.
fn box_surface(x: vec3<f32>, c: Collider, center: vec3<f32>) -> Surface {
    let d = x - center;
    let p = vec3<f32>(dot(d, c.axis_x), dot(d, c.axis_y), dot(d, c.axis_z));
    let q = vec3<f32>(abs(p.x) - c.extent.x, abs(p.y) - c.extent.y, abs(p.z) - c.extent.z);
    let outside = vec3<f32>(max(q.x, 0.0), max(q.y, 0.0), max(q.z, 0.0));
    let outside_length = sqrt(outside.x * outside.x + outside.y * outside.y + outside.z * outside.z);
    if (outside_length > 0.0) {
        let scale = 1.0 / outside_length;
        let local = vec3<f32>(sign_of(p.x) * outside.x * scale, sign_of(p.y) * outside.y * scale,
                              sign_of(p.z) * outside.z * scale);
        let normal = c.axis_x * local.x + c.axis_y * local.y + c.axis_z * local.z;
        return Surface(outside_length - c.radius, normal);
    }
    // Inside the core box: the nearest face is the axis of the largest q (ties to the first).
    if (q.x >= q.y && q.x >= q.z) {
        return Surface(q.x - c.radius, c.axis_x * sign_of(p.x));
    }
    if (q.y >= q.z) {
        return Surface(q.y - c.radius, c.axis_y * sign_of(p.y));
    }
    return Surface(q.z - c.radius, c.axis_z * sign_of(p.z));
}

// A mesh's distance field, sample (i, j, k) (cloth_core::mesh::DistanceField).
fn field_sample(c: Collider, i: u32, j: u32, k: u32) -> f32 {
    return distance_fields[c.field_first + i + c.field_dims.x * (j + c.field_dims.y * k)];
}

// A mesh: trilinear in its distance field at p = Rᵀ(x − c), the normal the trilinear gradient
// (outside the field's grid: the nearest grid point's φ plus the way there), rotated back.
fn mesh_surface(x: vec3<f32>, c: Collider, center: vec3<f32>) -> Surface {
    let d = x - center;
    let p = vec3<f32>(dot(d, c.axis_x), dot(d, c.axis_y), dot(d, c.axis_z));
    let cell = c.radius;
    let g = (p - c.extent) * (1.0 / cell);
    let high = vec3<f32>(f32(c.field_dims.x - 1u), f32(c.field_dims.y - 1u), f32(c.field_dims.z - 1u));
    let q = vec3<f32>(min(max(g.x, 0.0), high.x), min(max(g.y, 0.0), high.y), min(max(g.z, 0.0), high.z));
    let i = min(u32(floor(q.x)), c.field_dims.x - 2u);
    let j = min(u32(floor(q.y)), c.field_dims.y - 2u);
    let k = min(u32(floor(q.z)), c.field_dims.z - 2u);
    let fx = q.x - f32(i);
    let fy = q.y - f32(j);
    let fz = q.z - f32(k);
    let c000 = field_sample(c, i, j, k);
    let c100 = field_sample(c, i + 1u, j, k);
    let c010 = field_sample(c, i, j + 1u, k);
    let c110 = field_sample(c, i + 1u, j + 1u, k);
    let c001 = field_sample(c, i, j, k + 1u);
    let c101 = field_sample(c, i + 1u, j, k + 1u);
    let c011 = field_sample(c, i, j + 1u, k + 1u);
    let c111 = field_sample(c, i + 1u, j + 1u, k + 1u);
    let gx = 1.0 - fx;
    let gy = 1.0 - fy;
    let gz = 1.0 - fz;
    let c00 = c000 * gx + c100 * fx;
    let c10 = c010 * gx + c110 * fx;
    let c01 = c001 * gx + c101 * fx;
    let c11 = c011 * gx + c111 * fx;
    let c0 = c00 * gy + c10 * fy;
    let c1 = c01 * gy + c11 * fy;
    let value = c0 * gz + c1 * fz;
    let outside = vec3<f32>(g.x - q.x, g.y - q.y, g.z - q.z) * cell;
    let outside_length = sqrt(dot(outside, outside));
    var n = vec3<f32>(0.0, 1.0, 0.0);
    var distance = value;
    if (outside_length > 0.0) {
        n = outside * (1.0 / outside_length);
        distance = value + outside_length;
    } else {
        let dx = ((c100 - c000) * gy + (c110 - c010) * fy) * gz + ((c101 - c001) * gy + (c111 - c011) * fy) * fz;
        let dy = ((c010 - c000) * gx + (c110 - c100) * fx) * gz + ((c011 - c001) * gx + (c111 - c101) * fx) * fz;
        let dz = (c01 - c00) * gy + (c11 - c10) * fy;
        let gradient = vec3<f32>(dx, dy, dz);
        let len = sqrt(dot(gradient, gradient));
        if (len > 0.0) {
            n = gradient * (1.0 / len);
        }
    }
    return Surface(distance, c.axis_x * n.x + c.axis_y * n.y + c.axis_z * n.z);
}

// The surface of collider c, its centre at `center`, seen from x.
fn collider_surface(c: Collider, center: vec3<f32>, x: vec3<f32>) -> Surface {
    if (COLLIDER_SPHERE) {
        if (c.kind == 0u) {
            return sphere_surface(x, center, c.radius);
        }
    }
    if (COLLIDER_PLANE) {
        if (c.kind == 1u) {
            return plane_surface(x, center, c.axis_y);
        }
    }
    if (COLLIDER_CAPSULE) {
        if (c.kind == 2u) {
            return capsule_surface(x, center, c.axis_x, c.extent.x, c.radius, c.axis_y);
        }
    }
    if (COLLIDER_BOX) {
        if (c.kind == 3u) {
            return box_surface(x, c, center);
        }
    }
    if (COLLIDER_MESH) {
        if (c.kind == 4u) {
            return mesh_surface(x, c, center);
        }
    }
    // A kind compiled out is never in the buffer (the pipeline is built for the scene's kinds).
    return Surface(3.0e38, vec3<f32>(0.0, 1.0, 0.0));
}

// The signed distance alone (cloth_core::colliders::Collider::distance): each kind's surface
// distance by the same operations, without the normal, which a vertex outside does not need.
fn sphere_distance(x: vec3<f32>, center: vec3<f32>, radius: f32) -> f32 {
    let offset = x - center;
    return sqrt(dot(offset, offset)) - radius;
}

fn capsule_distance(x: vec3<f32>, center: vec3<f32>, axis: vec3<f32>, half_length: f32, radius: f32) -> f32 {
    let along = min(max(dot(x - center, axis), -half_length), half_length);
    let offset = x - (center + axis * along);
    return sqrt(dot(offset, offset)) - radius;
}

fn box_distance(x: vec3<f32>, c: Collider, center: vec3<f32>) -> f32 {
    let d = x - center;
    let q = vec3<f32>(abs(dot(d, c.axis_x)) - c.extent.x, abs(dot(d, c.axis_y)) - c.extent.y,
                      abs(dot(d, c.axis_z)) - c.extent.z);
    let outside = vec3<f32>(max(q.x, 0.0), max(q.y, 0.0), max(q.z, 0.0));
    let outside_length = sqrt(outside.x * outside.x + outside.y * outside.y + outside.z * outside.z);
    if (outside_length > 0.0) {
        return outside_length - c.radius;
    }
    if (q.x >= q.y && q.x >= q.z) {
        return q.x - c.radius;
    }
    if (q.y >= q.z) {
        return q.y - c.radius;
    }
    return q.z - c.radius;
}

fn mesh_distance(x: vec3<f32>, c: Collider, center: vec3<f32>) -> f32 {
    let d = x - center;
    let p = vec3<f32>(dot(d, c.axis_x), dot(d, c.axis_y), dot(d, c.axis_z));
    let cell = c.radius;
    let g = (p - c.extent) * (1.0 / cell);
    let high = vec3<f32>(f32(c.field_dims.x - 1u), f32(c.field_dims.y - 1u), f32(c.field_dims.z - 1u));
    let q = vec3<f32>(min(max(g.x, 0.0), high.x), min(max(g.y, 0.0), high.y), min(max(g.z, 0.0), high.z));
    let i = min(u32(floor(q.x)), c.field_dims.x - 2u);
    let j = min(u32(floor(q.y)), c.field_dims.y - 2u);
    let k = min(u32(floor(q.z)), c.field_dims.z - 2u);
    let fx = q.x - f32(i);
    let fy = q.y - f32(j);
    let fz = q.z - f32(k);
    let gx = 1.0 - fx;
    let gy = 1.0 - fy;
    let gz = 1.0 - fz;
    let c00 = field_sample(c, i, j, k) * gx + field_sample(c, i + 1u, j, k) * fx;
    let c10 = field_sample(c, i, j + 1u, k) * gx + field_sample(c, i + 1u, j + 1u, k) * fx;
    let c01 = field_sample(c, i, j, k + 1u) * gx + field_sample(c, i + 1u, j, k + 1u) * fx;
    let c11 = field_sample(c, i, j + 1u, k + 1u) * gx + field_sample(c, i + 1u, j + 1u, k + 1u) * fx;
    let c0 = c00 * gy + c10 * fy;
    let c1 = c01 * gy + c11 * fy;
    let value = c0 * gz + c1 * fz;
    let outside = vec3<f32>(g.x - q.x, g.y - q.y, g.z - q.z) * cell;
    let outside_length = sqrt(dot(outside, outside));
    if (outside_length > 0.0) {
        return value + outside_length;
    }
    return value;
}

// The signed distance of collider c, its centre at `center`, at x.
fn collider_distance(c: Collider, center: vec3<f32>, x: vec3<f32>) -> f32 {
    if (COLLIDER_SPHERE) {
        if (c.kind == 0u) {
            return sphere_distance(x, center, c.radius);
        }
    }
    if (COLLIDER_PLANE) {
        if (c.kind == 1u) {
            return dot(x - center, c.axis_y);
        }
    }
    if (COLLIDER_CAPSULE) {
        if (c.kind == 2u) {
            return capsule_distance(x, center, c.axis_x, c.extent.x, c.radius);
        }
    }
    if (COLLIDER_BOX) {
        if (c.kind == 3u) {
            return box_distance(x, c, center);
        }
    }
    if (COLLIDER_MESH) {
        if (c.kind == 4u) {
            return mesh_distance(x, c, center);
        }
    }
    return 3.0e38;
}
