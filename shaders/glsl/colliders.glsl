// The colliders' signed distances: the GLSL twin of crates/cloth-core/src/colliders.rs and
// shaders/wgsl/colliders.wgsl (same names, same order of operations). Each kind's surface seen
// from a point x: its signed distance φ (m, negative inside) and outward unit normal. A kind no
// collider of the scene has is compiled out (the COLLIDER_* specialization constants of
// effects.glsl). Each kernel declares `distance_fields`, the mesh colliders' samples, at its own
// binding (layout.glsl declares `colliders`). A collider `c` is its index in `colliders`: each
// function reads the fields it needs from the buffer, so a kernel loads no more of a collider
// than its kind uses.

struct Surface {
    float distance;
    vec3 normal;
};

// φ = |x − c| − r, n = (x − c)/|x − c| (+Y at the centre).
Surface sphere_surface(vec3 x, vec3 center, float radius) {
    vec3 offset = x - center;
    float distance = sqrt(dot(offset, offset));
    vec3 normal = vec3(0.0, 1.0, 0.0);
    if (distance > 0.0) {
        normal = offset * (1.0 / distance);
    }
    return Surface(distance - radius, normal);
}

// φ = n·(x − p), p a point of the plane.
Surface plane_surface(vec3 x, vec3 point_, vec3 normal) {
    return Surface(dot(x - point_, normal), normal);
}

// φ = |x − p| − r, p the nearest point of the axis c ± e a.
Surface capsule_surface(vec3 x, vec3 center, vec3 axis, float half_length, float radius, vec3 fallback) {
    float along = min(max(dot(x - center, axis), -half_length), half_length);
    vec3 offset = x - (center + axis * along);
    float distance = sqrt(dot(offset, offset));
    vec3 normal = fallback;
    if (distance > 0.0) {
        normal = offset * (1.0 / distance);
    }
    return Surface(distance - radius, normal);
}

float sign_of(float v) {
    return v < 0.0 ? -1.0 : 1.0;
}

// A rounded box: p = Rᵀ(x − c), q = |p| − e, φ = |max(q, 0)| + min(max_k q_k, 0) − ρ.
Surface box_surface(vec3 x, uint c, vec3 center) {
    vec3 d = x - center;
    vec3 p = vec3(dot(d, colliders[c].axis_x), dot(d, colliders[c].axis_y), dot(d, colliders[c].axis_z));
    vec3 q = vec3(abs(p.x) - colliders[c].extent.x, abs(p.y) - colliders[c].extent.y, abs(p.z) - colliders[c].extent.z);
    vec3 outside = vec3(max(q.x, 0.0), max(q.y, 0.0), max(q.z, 0.0));
    float outside_length = sqrt(outside.x * outside.x + outside.y * outside.y + outside.z * outside.z);
    if (outside_length > 0.0) {
        float scale = 1.0 / outside_length;
        vec3 local_ = vec3(sign_of(p.x) * outside.x * scale, sign_of(p.y) * outside.y * scale,
                           sign_of(p.z) * outside.z * scale);
        vec3 normal = colliders[c].axis_x * local_.x + colliders[c].axis_y * local_.y + colliders[c].axis_z * local_.z;
        return Surface(outside_length - colliders[c].radius, normal);
    }
    // Inside the core box: the nearest face is the axis of the largest q (ties to the first).
    if (q.x >= q.y && q.x >= q.z) {
        return Surface(q.x - colliders[c].radius, colliders[c].axis_x * sign_of(p.x));
    }
    if (q.y >= q.z) {
        return Surface(q.y - colliders[c].radius, colliders[c].axis_y * sign_of(p.y));
    }
    return Surface(q.z - colliders[c].radius, colliders[c].axis_z * sign_of(p.z));
}

// A mesh's distance field, sample (i, j, k) (cloth_core::mesh::DistanceField).
float field_sample(uint c, uint i, uint j, uint k) {
    return distance_fields[colliders[c].field_first + i + colliders[c].field_dims.x * (j + colliders[c].field_dims.y * k)];
}

// The cell of a mesh's distance field around p = Rᵀ(x − c) (cloth_core::mesh::FieldCell): its
// eight samples (c000, c100, c010, c110 in `low`, the same at k + 1 in `high`), the fractions of
// the way across it, and `outside`, the way (m) from the nearest grid point when x is outside the
// grid (zero inside).
struct FieldCell {
    vec4 low;
    vec4 high;
    vec3 fraction;
    vec3 outside;
};

FieldCell field_cell(vec3 x, uint c, vec3 center) {
    vec3 d = x - center;
    vec3 p = vec3(dot(d, colliders[c].axis_x), dot(d, colliders[c].axis_y), dot(d, colliders[c].axis_z));
    float cell = colliders[c].radius;
    vec3 g = (p - colliders[c].extent) * (1.0 / cell);
    vec3 high = vec3(float(colliders[c].field_dims.x - 1u), float(colliders[c].field_dims.y - 1u), float(colliders[c].field_dims.z - 1u));
    vec3 q = vec3(min(max(g.x, 0.0), high.x), min(max(g.y, 0.0), high.y), min(max(g.z, 0.0), high.z));
    // The cell's lowest corner: at most the last but one point, so the cell exists.
    uint i = min(uint(floor(q.x)), colliders[c].field_dims.x - 2u);
    uint j = min(uint(floor(q.y)), colliders[c].field_dims.y - 2u);
    uint k = min(uint(floor(q.z)), colliders[c].field_dims.z - 2u);
    vec4 low_corners = vec4(field_sample(c, i, j, k), field_sample(c, i + 1u, j, k),
                            field_sample(c, i, j + 1u, k), field_sample(c, i + 1u, j + 1u, k));
    vec4 high_corners = vec4(field_sample(c, i, j, k + 1u), field_sample(c, i + 1u, j, k + 1u),
                             field_sample(c, i, j + 1u, k + 1u), field_sample(c, i + 1u, j + 1u, k + 1u));
    vec3 fraction = vec3(q.x - float(i), q.y - float(j), q.z - float(k));
    vec3 outside = vec3(g.x - q.x, g.y - q.y, g.z - q.z) * cell;
    return FieldCell(low_corners, high_corners, fraction, outside);
}

// Trilinear in the cell: along x (c00, c10, c01, c11 for the four edges along x), then y, then z.
vec4 field_edges(FieldCell f) {
    float gx = 1.0 - f.fraction.x;
    float fx = f.fraction.x;
    return vec4(f.low.x * gx + f.low.y * fx, f.low.z * gx + f.low.w * fx,
                f.high.x * gx + f.high.y * fx, f.high.z * gx + f.high.w * fx);
}

float field_value(FieldCell f, vec4 edges) {
    float gy = 1.0 - f.fraction.y;
    float fy = f.fraction.y;
    float c0 = edges.x * gy + edges.y * fy;
    float c1 = edges.z * gy + edges.w * fy;
    return c0 * (1.0 - f.fraction.z) + c1 * f.fraction.z;
}

// A mesh: trilinear in its distance field, the normal the trilinear gradient (outside the field's
// grid: the nearest grid point's φ plus the way there, the normal along that way), rotated back.
Surface mesh_surface(vec3 x, uint c, vec3 center) {
    FieldCell f = field_cell(x, c, center);
    vec4 edges = field_edges(f);
    float value = field_value(f, edges);
    float outside_length = sqrt(dot(f.outside, f.outside));
    vec3 n = vec3(0.0, 1.0, 0.0);
    float distance = value;
    if (outside_length > 0.0) {
        n = f.outside * (1.0 / outside_length);
        distance = value + outside_length;
    } else {
        float gx = 1.0 - f.fraction.x;
        float gy = 1.0 - f.fraction.y;
        float gz = 1.0 - f.fraction.z;
        float fx = f.fraction.x;
        float fy = f.fraction.y;
        float fz = f.fraction.z;
        // The trilinear function's gradient in the cell (per grid unit: the direction is all the
        // normal needs).
        float dx = ((f.low.y - f.low.x) * gy + (f.low.w - f.low.z) * fy) * gz
            + ((f.high.y - f.high.x) * gy + (f.high.w - f.high.z) * fy) * fz;
        float dy = ((f.low.z - f.low.x) * gx + (f.low.w - f.low.y) * fx) * gz
            + ((f.high.z - f.high.x) * gx + (f.high.w - f.high.y) * fx) * fz;
        float dz = (edges.z - edges.x) * gy + (edges.w - edges.y) * fy;
        vec3 gradient = vec3(dx, dy, dz);
        float len = sqrt(dot(gradient, gradient));
        if (len > 0.0) {
            n = gradient * (1.0 / len);
        }
    }
    return Surface(distance, colliders[c].axis_x * n.x + colliders[c].axis_y * n.y + colliders[c].axis_z * n.z);
}

// Whether the scene has colliders of one kind only: then no collider's kind needs a test (an
// expression of the COLLIDER_* constants, folded when the pipeline is specialised).
bool one_collider_kind() {
    return int(COLLIDER_SPHERE) + int(COLLIDER_PLANE) + int(COLLIDER_CAPSULE) + int(COLLIDER_BOX)
        + int(COLLIDER_MESH) == 1;
}

// Whether collider c has `kind`, of the kinds compiled in.
bool collider_is(uint c, uint kind) {
    return one_collider_kind() || colliders[c].kind == kind;
}

// The surface of collider c, its centre at `center`, seen from x.
Surface collider_surface(uint c, vec3 center, vec3 x) {
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
    return Surface(3.0e38, vec3(0.0, 1.0, 0.0));
}

// The signed distance alone (cloth_core::colliders::Collider::distance): each kind's surface
// distance by the same operations, without the normal, which a vertex outside does not need.
float sphere_distance(vec3 x, vec3 center, float radius) {
    vec3 offset = x - center;
    return sqrt(dot(offset, offset)) - radius;
}

float capsule_distance(vec3 x, vec3 center, vec3 axis, float half_length, float radius) {
    float along = min(max(dot(x - center, axis), -half_length), half_length);
    vec3 offset = x - (center + axis * along);
    return sqrt(dot(offset, offset)) - radius;
}

float box_distance(vec3 x, uint c, vec3 center) {
    vec3 d = x - center;
    vec3 q = vec3(abs(dot(d, colliders[c].axis_x)) - colliders[c].extent.x, abs(dot(d, colliders[c].axis_y)) - colliders[c].extent.y,
                      abs(dot(d, colliders[c].axis_z)) - colliders[c].extent.z);
    vec3 outside = vec3(max(q.x, 0.0), max(q.y, 0.0), max(q.z, 0.0));
    float outside_length = sqrt(outside.x * outside.x + outside.y * outside.y + outside.z * outside.z);
    if (outside_length > 0.0) {
        return outside_length - colliders[c].radius;
    }
    if (q.x >= q.y && q.x >= q.z) {
        return q.x - colliders[c].radius;
    }
    if (q.y >= q.z) {
        return q.y - colliders[c].radius;
    }
    return q.z - colliders[c].radius;
}

float mesh_distance(vec3 x, uint c, vec3 center) {
    FieldCell f = field_cell(x, c, center);
    float value = field_value(f, field_edges(f));
    float outside_length = sqrt(dot(f.outside, f.outside));
    if (outside_length > 0.0) {
        return value + outside_length;
    }
    return value;
}

// The signed distance of collider c, its centre at `center`, at x.
float collider_distance(uint c, vec3 center, vec3 x) {
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
Surface collider_contact(uint c, vec3 center, vec3 x) {
    if (COLLIDER_SPHERE) {
        if (collider_is(c, 0u)) {
            vec3 offset = x - center;
            float distance = sqrt(dot(offset, offset));
            vec3 normal = vec3(0.0, 1.0, 0.0);
            if (distance < colliders[c].radius && distance > 0.0) {
                normal = offset * (1.0 / distance);
            }
            return Surface(distance - colliders[c].radius, normal);
        }
    }
    float distance = collider_distance(c, center, x);
    if (distance >= 0.0) {
        return Surface(distance, vec3(0.0, 1.0, 0.0));
    }
    return collider_surface(c, center, x);
}
