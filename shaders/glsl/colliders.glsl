// The colliders' signed distances: the GLSL twin of crates/cloth-core/src/colliders.rs and
// shaders/wgsl/colliders.wgsl (same names, same order of operations). Each kind's surface seen
// from a point x: its signed distance φ (m, negative inside) and outward unit normal. A kind no
// collider of the scene has is compiled out (the COLLIDER_* specialization constants of
// effects.glsl). Each kernel declares `distance_fields`, the mesh colliders' samples, at its own
// binding.

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
Surface box_surface(vec3 x, Collider c, vec3 center) {
    vec3 d = x - center;
    vec3 p = vec3(dot(d, c.axis_x), dot(d, c.axis_y), dot(d, c.axis_z));
    vec3 q = vec3(abs(p.x) - c.extent.x, abs(p.y) - c.extent.y, abs(p.z) - c.extent.z);
    vec3 outside = vec3(max(q.x, 0.0), max(q.y, 0.0), max(q.z, 0.0));
    float outside_length = sqrt(outside.x * outside.x + outside.y * outside.y + outside.z * outside.z);
    if (outside_length > 0.0) {
        float scale = 1.0 / outside_length;
        vec3 local_ = vec3(sign_of(p.x) * outside.x * scale, sign_of(p.y) * outside.y * scale,
                           sign_of(p.z) * outside.z * scale);
        vec3 normal = c.axis_x * local_.x + c.axis_y * local_.y + c.axis_z * local_.z;
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
float field_sample(Collider c, uint i, uint j, uint k) {
    return distance_fields[c.field_first + i + c.field_dims.x * (j + c.field_dims.y * k)];
}

// A mesh: trilinear in its distance field at p = Rᵀ(x − c), the normal the trilinear gradient
// (outside the field's grid: the nearest grid point's φ plus the way there), rotated back.
Surface mesh_surface(vec3 x, Collider c, vec3 center) {
    vec3 d = x - center;
    vec3 p = vec3(dot(d, c.axis_x), dot(d, c.axis_y), dot(d, c.axis_z));
    float cell = c.radius;
    vec3 g = (p - c.extent) * (1.0 / cell);
    vec3 high = vec3(float(c.field_dims.x - 1u), float(c.field_dims.y - 1u), float(c.field_dims.z - 1u));
    vec3 q = vec3(min(max(g.x, 0.0), high.x), min(max(g.y, 0.0), high.y), min(max(g.z, 0.0), high.z));
    uint i = min(uint(floor(q.x)), c.field_dims.x - 2u);
    uint j = min(uint(floor(q.y)), c.field_dims.y - 2u);
    uint k = min(uint(floor(q.z)), c.field_dims.z - 2u);
    float fx = q.x - float(i);
    float fy = q.y - float(j);
    float fz = q.z - float(k);
    float c000 = field_sample(c, i, j, k);
    float c100 = field_sample(c, i + 1u, j, k);
    float c010 = field_sample(c, i, j + 1u, k);
    float c110 = field_sample(c, i + 1u, j + 1u, k);
    float c001 = field_sample(c, i, j, k + 1u);
    float c101 = field_sample(c, i + 1u, j, k + 1u);
    float c011 = field_sample(c, i, j + 1u, k + 1u);
    float c111 = field_sample(c, i + 1u, j + 1u, k + 1u);
    float gx = 1.0 - fx;
    float gy = 1.0 - fy;
    float gz = 1.0 - fz;
    float c00 = c000 * gx + c100 * fx;
    float c10 = c010 * gx + c110 * fx;
    float c01 = c001 * gx + c101 * fx;
    float c11 = c011 * gx + c111 * fx;
    float c0 = c00 * gy + c10 * fy;
    float c1 = c01 * gy + c11 * fy;
    float value = c0 * gz + c1 * fz;
    vec3 outside = vec3(g.x - q.x, g.y - q.y, g.z - q.z) * cell;
    float outside_length = sqrt(dot(outside, outside));
    vec3 n = vec3(0.0, 1.0, 0.0);
    float distance = value;
    if (outside_length > 0.0) {
        n = outside * (1.0 / outside_length);
        distance = value + outside_length;
    } else {
        float dx = ((c100 - c000) * gy + (c110 - c010) * fy) * gz + ((c101 - c001) * gy + (c111 - c011) * fy) * fz;
        float dy = ((c010 - c000) * gx + (c110 - c100) * fx) * gz + ((c011 - c001) * gx + (c111 - c101) * fx) * fz;
        float dz = (c01 - c00) * gy + (c11 - c10) * fy;
        vec3 gradient = vec3(dx, dy, dz);
        float len = sqrt(dot(gradient, gradient));
        if (len > 0.0) {
            n = gradient * (1.0 / len);
        }
    }
    return Surface(distance, c.axis_x * n.x + c.axis_y * n.y + c.axis_z * n.z);
}

// The surface of collider c, its centre at `center`, seen from x.
Surface collider_surface(Collider c, vec3 center, vec3 x) {
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

float box_distance(vec3 x, Collider c, vec3 center) {
    vec3 d = x - center;
    vec3 q = vec3(abs(dot(d, c.axis_x)) - c.extent.x, abs(dot(d, c.axis_y)) - c.extent.y,
                      abs(dot(d, c.axis_z)) - c.extent.z);
    vec3 outside = vec3(max(q.x, 0.0), max(q.y, 0.0), max(q.z, 0.0));
    float outside_length = sqrt(outside.x * outside.x + outside.y * outside.y + outside.z * outside.z);
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

float mesh_distance(vec3 x, Collider c, vec3 center) {
    vec3 d = x - center;
    vec3 p = vec3(dot(d, c.axis_x), dot(d, c.axis_y), dot(d, c.axis_z));
    float cell = c.radius;
    vec3 g = (p - c.extent) * (1.0 / cell);
    vec3 high = vec3(float(c.field_dims.x - 1u), float(c.field_dims.y - 1u), float(c.field_dims.z - 1u));
    vec3 q = vec3(min(max(g.x, 0.0), high.x), min(max(g.y, 0.0), high.y), min(max(g.z, 0.0), high.z));
    uint i = min(uint(floor(q.x)), c.field_dims.x - 2u);
    uint j = min(uint(floor(q.y)), c.field_dims.y - 2u);
    uint k = min(uint(floor(q.z)), c.field_dims.z - 2u);
    float fx = q.x - float(i);
    float fy = q.y - float(j);
    float fz = q.z - float(k);
    float gx = 1.0 - fx;
    float gy = 1.0 - fy;
    float gz = 1.0 - fz;
    float c00 = field_sample(c, i, j, k) * gx + field_sample(c, i + 1u, j, k) * fx;
    float c10 = field_sample(c, i, j + 1u, k) * gx + field_sample(c, i + 1u, j + 1u, k) * fx;
    float c01 = field_sample(c, i, j, k + 1u) * gx + field_sample(c, i + 1u, j, k + 1u) * fx;
    float c11 = field_sample(c, i, j + 1u, k + 1u) * gx + field_sample(c, i + 1u, j + 1u, k + 1u) * fx;
    float c0 = c00 * gy + c10 * fy;
    float c1 = c01 * gy + c11 * fy;
    float value = c0 * gz + c1 * fz;
    vec3 outside = vec3(g.x - q.x, g.y - q.y, g.z - q.z) * cell;
    float outside_length = sqrt(dot(outside, outside));
    if (outside_length > 0.0) {
        return value + outside_length;
    }
    return value;
}

// The signed distance of collider c, its centre at `center`, at x.
float collider_distance(Collider c, vec3 center, vec3 x) {
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
