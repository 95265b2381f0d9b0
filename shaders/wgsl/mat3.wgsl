// 3 × 3 blocks for the implicit integrators (vbd.wgsl, implicit.wgsl): cloth_core::real::Mat3 and
// the springs' blocks of cloth_core::forces, operation by operation. Prepended to their modules.

// A 3 × 3 matrix by rows (cloth_core::real::Mat3).
struct Mat3 {
    r0: vec3<f32>,
    r1: vec3<f32>,
    r2: vec3<f32>,
}

fn mat3_scaled(m: Mat3, s: f32) -> Mat3 {
    return Mat3(m.r0 * s, m.r1 * s, m.r2 * s);
}

fn mat3_add(a: Mat3, b: Mat3) -> Mat3 {
    return Mat3(a.r0 + b.r0, a.r1 + b.r1, a.r2 + b.r2);
}

fn mat3_zero() -> Mat3 {
    return Mat3(vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
}

fn mat3_identity() -> Mat3 {
    return Mat3(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
}

// a bᵀ.
fn mat3_outer(a: vec3<f32>, b: vec3<f32>) -> Mat3 {
    return Mat3(b * a.x, b * a.y, b * a.z);
}

// I − m.
fn mat3_complement(m: Mat3) -> Mat3 {
    return Mat3(vec3<f32>(1.0, 0.0, 0.0) - m.r0, vec3<f32>(0.0, 1.0, 0.0) - m.r1, vec3<f32>(0.0, 0.0, 1.0) - m.r2);
}

// M v.
fn mat3_mul(m: Mat3, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(m.r0, v), dot(m.r1, v), dot(m.r2, v));
}

// The spring stiffness block K = k (u uᵀ + max(0, 1 − L0/L)(I − u uᵀ))
// (cloth_core::forces::spring_stiffness_block); zero for a zero-length spring.
fn spring_stiffness_block(x_i: vec3<f32>, x_j: vec3<f32>, rest_length: f32, stiffness: f32) -> Mat3 {
    let delta = x_j - x_i;
    let length = sqrt(dot(delta, delta));
    if (length <= 0.0) {
        return mat3_zero();
    }
    let u = delta * (1.0 / length);
    let axial = mat3_outer(u, u);
    let transverse = max(1.0 - rest_length / length, 0.0);
    return mat3_scaled(mat3_add(axial, mat3_scaled(mat3_complement(axial), transverse)), stiffness);
}

// The spring damping block C = c_d u uᵀ (cloth_core::forces::spring_damping_block); zero for a
// zero-length spring.
fn spring_damping_block(x_i: vec3<f32>, x_j: vec3<f32>, damping: f32) -> Mat3 {
    let delta = x_j - x_i;
    let length = sqrt(dot(delta, delta));
    if (length <= 0.0) {
        return mat3_zero();
    }
    let u = delta * (1.0 / length);
    return mat3_scaled(mat3_outer(u, u), damping);
}
