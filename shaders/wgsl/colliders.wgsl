// The colliders' signed distances (crates/cloth-core/src/colliders.rs, function by function and
// operation by operation): each kind's surface seen from a point x, its signed distance φ (m,
// negative inside) and outward unit normal. Prepended, after layout.wgsl, to every module that
// meets colliders: the compute kernels and the inspector's render.wgsl. Each of those declares
// `colliders` (an array of `Collider`: the kernels' uniform block, the view's storage buffer) and
// `distance_fields`, the mesh colliders' samples (`array<f32>`), at its own bindings. A collider
// `c` is its index in `colliders`: each function reads the fields it needs, so a kernel loads no
// more of a collider than its kind uses.
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
fn box_surface(x: vec3<f32>, c: u32, center: vec3<f32>) -> Surface {
    let d = x - center;
    let p = vec3<f32>(dot(d, colliders[c].axis_x), dot(d, colliders[c].axis_y), dot(d, colliders[c].axis_z));
    let q = vec3<f32>(abs(p.x) - colliders[c].extent.x, abs(p.y) - colliders[c].extent.y, abs(p.z) - colliders[c].extent.z);
    let outside = vec3<f32>(max(q.x, 0.0), max(q.y, 0.0), max(q.z, 0.0));
    let outside_length = sqrt(outside.x * outside.x + outside.y * outside.y + outside.z * outside.z);
    if (outside_length > 0.0) {
        let scale = 1.0 / outside_length;
        let local = vec3<f32>(sign_of(p.x) * outside.x * scale, sign_of(p.y) * outside.y * scale,
                              sign_of(p.z) * outside.z * scale);
        let normal = colliders[c].axis_x * local.x + colliders[c].axis_y * local.y + colliders[c].axis_z * local.z;
        return Surface(outside_length - colliders[c].radius, normal);
    }
    // Inside the core box: the nearest face is the axis of the largest q (ties to the first).
    if ((q.x >= q.y) & (q.x >= q.z)) {
        return Surface(q.x - colliders[c].radius, colliders[c].axis_x * sign_of(p.x));
    }
    if (q.y >= q.z) {
        return Surface(q.y - colliders[c].radius, colliders[c].axis_y * sign_of(p.y));
    }
    return Surface(q.z - colliders[c].radius, colliders[c].axis_z * sign_of(p.z));
}

// A mesh's distance field, sample (i, j, k) (cloth_core::mesh::DistanceField).
fn field_sample(c: u32, i: u32, j: u32, k: u32) -> f32 {
    return distance_fields[colliders[c].field_first + i + colliders[c].field_dims.x * (j + colliders[c].field_dims.y * k)];
}

// The cell of a mesh's distance field around p = Rᵀ(x − c) (cloth_core::mesh::FieldCell): its
// eight samples (c000, c100, c010, c110 in `low`, the same at k + 1 in `high`), the fractions of
// the way across it, and `outside`, the way (m) from the nearest grid point when x is outside the
// grid (zero inside).
struct FieldCell {
    low: vec4<f32>,
    high: vec4<f32>,
    fraction: vec3<f32>,
    outside: vec3<f32>,
}

fn field_cell(x: vec3<f32>, c: u32, center: vec3<f32>) -> FieldCell {
    let d = x - center;
    let p = vec3<f32>(dot(d, colliders[c].axis_x), dot(d, colliders[c].axis_y), dot(d, colliders[c].axis_z));
    let cell = colliders[c].radius;
    let g = (p - colliders[c].extent) * (1.0 / cell);
    let high = vec3<f32>(f32(colliders[c].field_dims.x - 1u), f32(colliders[c].field_dims.y - 1u), f32(colliders[c].field_dims.z - 1u));
    let q = vec3<f32>(min(max(g.x, 0.0), high.x), min(max(g.y, 0.0), high.y), min(max(g.z, 0.0), high.z));
    // The cell's lowest corner: at most the last but one point, so the cell exists.
    let i = min(u32(floor(q.x)), colliders[c].field_dims.x - 2u);
    let j = min(u32(floor(q.y)), colliders[c].field_dims.y - 2u);
    let k = min(u32(floor(q.z)), colliders[c].field_dims.z - 2u);
    let low_corners = vec4<f32>(field_sample(c, i, j, k), field_sample(c, i + 1u, j, k),
                                field_sample(c, i, j + 1u, k), field_sample(c, i + 1u, j + 1u, k));
    let high_corners = vec4<f32>(field_sample(c, i, j, k + 1u), field_sample(c, i + 1u, j, k + 1u),
                                 field_sample(c, i, j + 1u, k + 1u), field_sample(c, i + 1u, j + 1u, k + 1u));
    let fraction = vec3<f32>(q.x - f32(i), q.y - f32(j), q.z - f32(k));
    let outside = vec3<f32>(g.x - q.x, g.y - q.y, g.z - q.z) * cell;
    return FieldCell(low_corners, high_corners, fraction, outside);
}

// Trilinear in the cell: along x (c00, c10, c01, c11 for the four edges along x), then y, then z.
fn field_edges(f: FieldCell) -> vec4<f32> {
    let gx = 1.0 - f.fraction.x;
    let fx = f.fraction.x;
    return vec4<f32>(f.low.x * gx + f.low.y * fx, f.low.z * gx + f.low.w * fx,
                     f.high.x * gx + f.high.y * fx, f.high.z * gx + f.high.w * fx);
}

fn field_value(f: FieldCell, edges: vec4<f32>) -> f32 {
    let gy = 1.0 - f.fraction.y;
    let fy = f.fraction.y;
    let c0 = edges.x * gy + edges.y * fy;
    let c1 = edges.z * gy + edges.w * fy;
    return c0 * (1.0 - f.fraction.z) + c1 * f.fraction.z;
}

// A mesh: trilinear in its distance field, the normal the trilinear gradient (outside the field's
// grid: the nearest grid point's φ plus the way there, the normal along that way), rotated back.
fn mesh_surface(x: vec3<f32>, c: u32, center: vec3<f32>) -> Surface {
    let f = field_cell(x, c, center);
    let edges = field_edges(f);
    let value = field_value(f, edges);
    let outside_length = sqrt(dot(f.outside, f.outside));
    var n = vec3<f32>(0.0, 1.0, 0.0);
    var distance = value;
    if (outside_length > 0.0) {
        n = f.outside * (1.0 / outside_length);
        distance = value + outside_length;
    } else {
        let gx = 1.0 - f.fraction.x;
        let gy = 1.0 - f.fraction.y;
        let gz = 1.0 - f.fraction.z;
        let fx = f.fraction.x;
        let fy = f.fraction.y;
        let fz = f.fraction.z;
        // The trilinear function's gradient in the cell (per grid unit: the direction is all the
        // normal needs).
        let dx = ((f.low.y - f.low.x) * gy + (f.low.w - f.low.z) * fy) * gz
            + ((f.high.y - f.high.x) * gy + (f.high.w - f.high.z) * fy) * fz;
        let dy = ((f.low.z - f.low.x) * gx + (f.low.w - f.low.y) * fx) * gz
            + ((f.high.z - f.high.x) * gx + (f.high.w - f.high.y) * fx) * fz;
        let dz = (edges.z - edges.x) * gy + (edges.w - edges.y) * fy;
        let gradient = vec3<f32>(dx, dy, dz);
        let len = sqrt(dot(gradient, gradient));
        if (len > 0.0) {
            n = gradient * (1.0 / len);
        }
    }
    return Surface(distance, colliders[c].axis_x * n.x + colliders[c].axis_y * n.y + colliders[c].axis_z * n.z);
}

// Whether the scene has colliders of one kind only: then no collider's kind needs a test (a
// constant expression of the COLLIDER_* constants, folded when the pipeline is built).
fn one_collider_kind() -> bool {
    return u32(COLLIDER_SPHERE) + u32(COLLIDER_PLANE) + u32(COLLIDER_CAPSULE) + u32(COLLIDER_BOX)
        + u32(COLLIDER_MESH) == 1u;
}

// Whether collider c has `kind`, of the kinds compiled in. (`|` and `&` rather than `||` and `&&`
// in this file: naga turns each short-circuit operator into a branch, see add_stencil_springs in
// cloth_step.wgsl. No operand has side effects.)
fn collider_is(c: u32, kind: u32) -> bool {
    return one_collider_kind() | (colliders[c].kind == kind);
}

// The surface of collider c, its centre at `center`, seen from x.
fn collider_surface(c: u32, center: vec3<f32>, x: vec3<f32>) -> Surface {
    if (COLLIDER_SPHERE) {
        if (collider_is(c, 0u)) {
            return sphere_surface(x, center, colliders[c].radius);
        }
    }
    if (COLLIDER_PLANE) {
        if (collider_is(c, 1u)) {
            return plane_surface(x, center, colliders[c].axis_y);
        }
    }
    if (COLLIDER_CAPSULE) {
        if (collider_is(c, 2u)) {
            return capsule_surface(x, center, colliders[c].axis_x, colliders[c].extent.x, colliders[c].radius, colliders[c].axis_y);
        }
    }
    if (COLLIDER_BOX) {
        if (collider_is(c, 3u)) {
            return box_surface(x, c, center);
        }
    }
    if (COLLIDER_MESH) {
        if (collider_is(c, 4u)) {
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

fn box_distance(x: vec3<f32>, c: u32, center: vec3<f32>) -> f32 {
    let d = x - center;
    let q = vec3<f32>(abs(dot(d, colliders[c].axis_x)) - colliders[c].extent.x, abs(dot(d, colliders[c].axis_y)) - colliders[c].extent.y,
                      abs(dot(d, colliders[c].axis_z)) - colliders[c].extent.z);
    let outside = vec3<f32>(max(q.x, 0.0), max(q.y, 0.0), max(q.z, 0.0));
    let outside_length = sqrt(outside.x * outside.x + outside.y * outside.y + outside.z * outside.z);
    if (outside_length > 0.0) {
        return outside_length - colliders[c].radius;
    }
    if ((q.x >= q.y) & (q.x >= q.z)) {
        return q.x - colliders[c].radius;
    }
    if (q.y >= q.z) {
        return q.y - colliders[c].radius;
    }
    return q.z - colliders[c].radius;
}

fn mesh_distance(x: vec3<f32>, c: u32, center: vec3<f32>) -> f32 {
    let f = field_cell(x, c, center);
    let value = field_value(f, field_edges(f));
    let outside_length = sqrt(dot(f.outside, f.outside));
    if (outside_length > 0.0) {
        return value + outside_length;
    }
    return value;
}

// The signed distance of collider c, its centre at `center`, at x.
fn collider_distance(c: u32, center: vec3<f32>, x: vec3<f32>) -> f32 {
    if (COLLIDER_SPHERE) {
        if (collider_is(c, 0u)) {
            return sphere_distance(x, center, colliders[c].radius);
        }
    }
    if (COLLIDER_PLANE) {
        if (collider_is(c, 1u)) {
            return dot(x - center, colliders[c].axis_y);
        }
    }
    if (COLLIDER_CAPSULE) {
        if (collider_is(c, 2u)) {
            return capsule_distance(x, center, colliders[c].axis_x, colliders[c].extent.x, colliders[c].radius);
        }
    }
    if (COLLIDER_BOX) {
        if (collider_is(c, 3u)) {
            return box_distance(x, c, center);
        }
    }
    if (COLLIDER_MESH) {
        if (collider_is(c, 4u)) {
            return mesh_distance(x, c, center);
        }
    }
    return 3.0e38;
}

// The surface for the contact forces: the signed distance, and the normal only where x is inside
// (φ < 0; elsewhere +Y, which no force uses). A sphere's one square root gives both; the other
// kinds test the distance alone first.
fn collider_contact(c: u32, center: vec3<f32>, x: vec3<f32>) -> Surface {
    if (COLLIDER_SPHERE) {
        if (collider_is(c, 0u)) {
            let offset = x - center;
            let distance = sqrt(dot(offset, offset));
            var normal = vec3<f32>(0.0, 1.0, 0.0);
            if ((distance < colliders[c].radius) & (distance > 0.0)) {
                normal = offset * (1.0 / distance);
            }
            return Surface(distance - colliders[c].radius, normal);
        }
    }
    let distance = collider_distance(c, center, x);
    if (distance >= 0.0) {
        return Surface(distance, vec3<f32>(0.0, 1.0, 0.0));
    }
    return collider_surface(c, center, x);
}
