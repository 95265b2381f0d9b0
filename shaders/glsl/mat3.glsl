// 3 × 3 blocks for the implicit integrators (vbd.comp, implicit.comp): cloth_core::real::Mat3 and
// the springs' blocks of cloth_core::forces, operation by operation. The GLSL twin of
// shaders/wgsl/mat3.wgsl.

// A 3 × 3 matrix by rows (cloth_core::real::Mat3).
struct Mat3 {
    vec3 r0;
    vec3 r1;
    vec3 r2;
};

Mat3 mat3_scaled(Mat3 m, float s) {
    return Mat3(m.r0 * s, m.r1 * s, m.r2 * s);
}

Mat3 mat3_add(Mat3 a, Mat3 b) {
    return Mat3(a.r0 + b.r0, a.r1 + b.r1, a.r2 + b.r2);
}

Mat3 mat3_zero() {
    return Mat3(vec3(0.0), vec3(0.0), vec3(0.0));
}

Mat3 mat3_identity() {
    return Mat3(vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0), vec3(0.0, 0.0, 1.0));
}

// a bᵀ.
Mat3 mat3_outer(vec3 a, vec3 b) {
    return Mat3(b * a.x, b * a.y, b * a.z);
}

// I − m.
Mat3 mat3_complement(Mat3 m) {
    return Mat3(vec3(1.0, 0.0, 0.0) - m.r0, vec3(0.0, 1.0, 0.0) - m.r1, vec3(0.0, 0.0, 1.0) - m.r2);
}

// M v.
vec3 mat3_mul(Mat3 m, vec3 v) {
    return vec3(dot(m.r0, v), dot(m.r1, v), dot(m.r2, v));
}

// The spring stiffness block K = k (u uᵀ + max(0, 1 − L0/L)(I − u uᵀ))
// (cloth_core::forces::spring_stiffness_block); zero for a zero-length spring.
Mat3 spring_stiffness_block(vec3 x_i, vec3 x_j, float rest_length, float stiffness) {
    vec3 delta = x_j - x_i;
    float len = sqrt(dot(delta, delta));
    if (len <= 0.0) {
        return mat3_zero();
    }
    vec3 u = delta * (1.0 / len);
    Mat3 axial = mat3_outer(u, u);
    float transverse = max(1.0 - rest_length / len, 0.0);
    return mat3_scaled(mat3_add(axial, mat3_scaled(mat3_complement(axial), transverse)), stiffness);
}

// The spring damping block C = c_d u uᵀ (cloth_core::forces::spring_damping_block); zero for a
// zero-length spring.
Mat3 spring_damping_block(vec3 x_i, vec3 x_j, float damping) {
    vec3 delta = x_j - x_i;
    float len = sqrt(dot(delta, delta));
    if (len <= 0.0) {
        return mat3_zero();
    }
    vec3 u = delta * (1.0 / len);
    return mat3_scaled(mat3_outer(u, u), damping);
}
