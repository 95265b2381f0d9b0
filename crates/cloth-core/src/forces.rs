//! The mass-spring force model, one function per force.
//!
//! Every function is generic over the precision `R` so the CPU reference runs in `f32` and
//! `f64`. The GPU shaders (`shaders/wgsl/`, `shaders/glsl/`) implement the same functions
//! with the same names and the same operation order.

use crate::colliders::Surface;
use crate::real::{Mat3, Real, Vec3};

/// Gravity, `F_g = m g` (N), with `m` in kg and `g` in m/s².
pub fn gravity_force<R: Real>(mass: R, gravity: Vec3<R>) -> Vec3<R> {
    gravity * mass
}

/// Adds to `force` the force on vertex `i` from one spring to vertex `j`: Hooke's law plus
/// damping, N.
///
/// With `L = |x_j − x_i|` and `u = (x_j − x_i) / L`:
/// * Hooke (`F_s = −k Δl` seen from vertex `i`): `k (L − L0) u`,
///   pulling `i` towards `j` when the spring is stretched;
/// * damping (`F_d = −c_d v_s`): `c_d ((v_j − v_i) · u) u`, resisting the extension rate
///   `v_s = dL/dt = (v_j − v_i) · u`.
///
/// `k` in N/m, `c_d` in N·s/m, `L0` in m. A zero-length spring adds nothing (its direction is
/// undefined).
///
/// Computed as the GPU kernels compute it, operation by operation: `1/L` once, as `1 / √(L²)` (the
/// kernels' inverse square root, one instruction on a GPU), then `u = (x_j − x_i) · 1/L` and
/// `L = L² · 1/L`; and a zero-length spring is skipped rather than added as zero (the kernels
/// branch around it: measured faster on the H100). lavapipe (Mesa 22.3's llvmpipe) evaluates the
/// inverse square root as a correctly rounded square root and division, as here, which is what
/// keeps it bit-exact with this reference; the Vulkan spec allows 2 ulp, so another Mesa (or a
/// GPU) may differ in the last bits, which the conformance suite would report.
#[allow(clippy::too_many_arguments)]
pub fn add_spring_force<R: Real>(
    force: &mut Vec3<R>,
    x_i: Vec3<R>,
    x_j: Vec3<R>,
    v_i: Vec3<R>,
    v_j: Vec3<R>,
    rest_length: R,
    stiffness: R,
    damping: R,
) {
    let delta = x_j - x_i;
    let length_squared = delta.dot(delta);
    if length_squared <= R::zero() {
        return;
    }
    let inverse_length = R::one() / length_squared.sqrt();
    let u = delta * inverse_length;
    let length = length_squared * inverse_length;
    let extension_rate = (v_j - v_i).dot(u);
    *force += u * (stiffness * (length - rest_length) + damping * extension_rate);
}

/// The stiffness block of a spring between vertices `i` and `j`, N/m: `K` with
/// `∂F_i/∂x_i = −K` and `∂F_i/∂x_j = K` for the Hooke force of [`add_spring_force`], made
/// positive semi-definite for implicit integrators.
///
/// With `L = |x_j − x_i|`, `u = (x_j − x_i)/L` and `P = I − u uᵀ` (the projection across the
/// spring), Hooke's force `k (L − L0) u` has the Jacobian
///
/// ```text
/// K = k (u uᵀ + (1 − L0/L) P)
/// ```
///
/// along the spring its stiffness `k`, across it the tension per length `k (L − L0)/L`. A
/// compressed spring (`L < L0`) has a negative transverse term: it would buckle, and the implicit
/// system `M − h² ∂F/∂x` could lose its positive definiteness, which conjugate gradients and Vertex
/// Block Descent's Newton steps need. The transverse term is clamped at zero (`max(0, 1 − L0/L)`,
/// as Choi and Ko's cloth solver does), so a compressed spring keeps only its axial stiffness.
/// `k` in N/m, `L0` in m. A zero-length spring has no direction and gives the zero block.
pub fn spring_stiffness_block<R: Real>(x_i: Vec3<R>, x_j: Vec3<R>, rest_length: R, stiffness: R) -> Mat3<R> {
    spring_stiffness_block_floored(x_i, x_j, rest_length, stiffness, R::zero())
}

/// [`spring_stiffness_block`] with the transverse term held at `floor` or more,
/// `K = k (u uᵀ + max(floor, 1 − L0/L) P)` (`floor` dimensionless, a fraction of `k`): a modified
/// Jacobian for a Newton method (see [`crate::implicit::TRANSVERSE_STIFFNESS_FLOOR`]).
pub fn spring_stiffness_block_floored<R: Real>(
    x_i: Vec3<R>,
    x_j: Vec3<R>,
    rest_length: R,
    stiffness: R,
    floor: R,
) -> Mat3<R> {
    let delta = x_j - x_i;
    let length = delta.length();
    if length <= R::zero() {
        return Mat3::zero();
    }
    let u = delta * (R::one() / length);
    let axial = Mat3::outer(u, u);
    let transverse = (R::one() - rest_length / length).max(floor);
    (axial + (Mat3::identity() - axial) * transverse) * stiffness
}

/// The damping block of a spring between vertices `i` and `j`, N·s/m: `C = c_d u uᵀ`, with
/// `∂F_i/∂v_i = −C` and `∂F_i/∂v_j = C` for the damping of [`add_spring_force`]
/// (`c_d ((v_j − v_i) · u) u`, linear in the velocities; the change of `u` with the positions is
/// left to the stiffness block, as Baraff and Witkin do). A zero-length spring gives the zero block.
pub fn spring_damping_block<R: Real>(x_i: Vec3<R>, x_j: Vec3<R>, damping: R) -> Mat3<R> {
    let delta = x_j - x_i;
    let length = delta.length();
    if length <= R::zero() {
        return Mat3::zero();
    }
    let u = delta * (R::one() / length);
    Mat3::outer(u, u) * damping
}

/// The stiffness block of a contact, N/m: `K_c = k_c n nᵀ` where the vertex is inside the
/// collider (`φ < 0`), zero outside, so that `∂F/∂x ≈ −K_c` for [`contact_force`]'s penalty
/// `k_c d n` (`d = −φ(x)`, `∇φ = n`). Exact for a plane; on a curved collider the change of the
/// normal adds `k_c d ∂n/∂x`, a term across the normal that would make `K_c` indefinite, and is
/// left out, as for a compressed spring.
pub fn contact_stiffness_block<R: Real>(surface: Surface<R>, stiffness: R) -> Mat3<R> {
    if surface.distance >= R::zero() {
        return Mat3::zero();
    }
    Mat3::outer(surface.normal, surface.normal) * stiffness
}

/// The damping block of a contact, N·s/m: `C_c = c n nᵀ` while the vertex, inside, approaches the
/// surface at `v` (`v · n < 0`), zero otherwise: the velocity Jacobian of [`contact_force`]'s
/// damping `−c min(v · n, 0) n` at `v` (m/s, relative to the collider).
pub fn contact_damping_block<R: Real>(v: Vec3<R>, surface: Surface<R>, damping: R) -> Mat3<R> {
    if surface.distance >= R::zero() || v.dot(surface.normal) >= R::zero() {
        return Mat3::zero();
    }
    Mat3::outer(surface.normal, surface.normal) * damping
}

/// Linear air drag, `F = −m γ v` (N), with `γ` in 1/s. An addition to the mass-spring model: the `AirDrag` effect.
pub fn air_drag_force<R: Real>(mass: R, rate: R, v: Vec3<R>) -> Vec3<R> {
    v * (-(mass * rate))
}

/// The cloth's unit normal at vertex `index` of an `nx × ny` grid, from its grid neighbours:
/// `n = (x[i+1,j] − x[i−1,j]) × (x[i,j+1] − x[i,j−1])`, normalised (one-sided differences at the
/// edges); zero where the cloth is folded flat on itself.
pub fn grid_normal<R: Real>(x: &[Vec3<R>], index: usize, nx: usize, ny: usize) -> Vec3<R> {
    let (i, j) = (index % nx, index / nx);
    let (left, right) = (if i > 0 { i - 1 } else { i }, if i + 1 < nx { i + 1 } else { i });
    let (down, up) = (if j > 0 { j - 1 } else { j }, if j + 1 < ny { j + 1 } else { j });
    let along_u = x[j * nx + right] - x[j * nx + left];
    let along_v = x[up * nx + i] - x[down * nx + i];
    let n = along_u.cross(along_v);
    let length = n.length();
    if length > R::zero() { n * (R::one() / length) } else { Vec3::zero() }
}

/// Wind on a vertex, N: `F = c A ((w − v) · n) n`, the air's velocity relative to the vertex
/// projected on the cloth's unit normal `n`, times `c A` (N·s/m: the wind coefficient, N·s/m³,
/// times the cloth's area per vertex). An addition to the mass-spring model: the `Wind` effect. A cloth edge-on to
/// the wind feels none; one facing it is pushed at the relative normal speed.
pub fn wind_force<R: Real>(normal: Vec3<R>, v: Vec3<R>, wind: Vec3<R>, coefficient_area: R) -> Vec3<R> {
    normal * (coefficient_area * (wind - v).dot(normal))
}

/// A vertex in contact with a collider.
#[derive(Clone, Copy, Debug)]
pub struct Contact<R> {
    /// Outward unit normal of the collider at the vertex, `1_n`.
    pub normal: Vec3<R>,
    /// Penetration depth `d = −φ`, m (> 0).
    pub depth: R,
    /// Penalty force plus normal damping, N.
    pub force: Vec3<R>,
}

/// Penalty contact with a collider whose surface seen from the vertex is `surface` (signed
/// distance `φ`, normal `1_n`; see [`crate::colliders`]): `F_c = k_c d` (N) with the penetration
/// vector `d = −φ 1_n` and the contact stiffness `k_c` (N/m), plus a normal damping
/// `−c_n min(v·1_n, 0) 1_n` (N·s/m) that resists only the approach, so the contact never pulls.
/// `v` is the vertex's velocity relative to the collider. Returns `None` when the vertex is
/// outside (`φ ≥ 0`). The same function for every collider kind.
pub fn contact_force<R: Real>(v: Vec3<R>, surface: Surface<R>, stiffness: R, damping: R) -> Option<Contact<R>> {
    let depth = -surface.distance;
    if depth <= R::zero() {
        return None;
    }
    let normal = surface.normal;
    let approach = v.dot(normal).min(R::zero());
    let force = normal * (stiffness * depth - damping * approach);
    Some(Contact { normal, depth, force })
}

/// Friction from the resultant of the other forces, N (the model's four equations):
///
/// ```text
/// R_on = (R_o · 1_n) 1_n          normal part of the other forces
/// R_ot = R_o − R_on               tangential part
/// 1_t  = R_ot / |R_ot|
/// F_f  = −min(|R_ot|, c_f |R_on|) 1_t
/// ```
///
/// `R_o` is the resultant of gravity, springs and drag, without the contact force (at rest
/// the contact force cancels the normal load, so including it would cancel the friction).
///
/// One extension, documented in `docs/model.md`: a vertex that already slides also has the
/// tangential force that would stop it within this substep, `m v_t / Δt`, added to `R_ot`.
/// At rest (`v_t = 0`) this is exactly the model's formula; while sliding, friction opposes
/// the sliding with at most `c_f |R_on|` (Coulomb), and a vertex whose friction budget
/// suffices is stopped exactly (static friction), instead of gliding on forever.
pub fn friction_force<R: Real>(
    other_forces: Vec3<R>,
    v: Vec3<R>,
    normal: Vec3<R>,
    mass: R,
    dt: R,
    coefficient: R,
) -> Vec3<R> {
    let r_on = normal * other_forces.dot(normal);
    let r_ot = other_forces - r_on;
    let v_t = v - normal * v.dot(normal);
    let tangential = r_ot + v_t * (mass / dt);
    let magnitude = tangential.length();
    if magnitude <= R::zero() {
        return Vec3::zero();
    }
    let limit = coefficient * r_on.length();
    tangential * (-(magnitude.min(limit) / magnitude))
}

/// Whether the model's friction holds the vertex still (static friction): the tangential force it
/// has to cancel, `R_ot + m v_t / Δt` (see [`friction_force`]), is within `c_f |R_on|`.
///
/// RK4 uses it: friction switches between sticking and sliding, which a smooth four-stage method
/// cannot follow (no combination of its stages stops a velocity in one step), so RK4 makes a
/// vertex that friction holds at the end of a substep stick exactly (see
/// `reference::ReferenceSimulator`, and `STAGE` 6 of the shaders).
pub fn friction_holds<R: Real>(
    other_forces: Vec3<R>,
    v: Vec3<R>,
    normal: Vec3<R>,
    mass: R,
    dt: R,
    coefficient: R,
) -> bool {
    let r_on = normal * other_forces.dot(normal);
    let r_ot = other_forces - r_on;
    let v_t = v - normal * v.dot(normal);
    let tangential = r_ot + v_t * (mass / dt);
    tangential.length() <= coefficient * r_on.length()
}

/// Makes a vertex stick to a contact: removes the tangential part (to `normal`) of its
/// displacement over the substep, `x − x_start`, and of its velocity. Returns `(x, v)`.
pub fn stick<R: Real>(x: Vec3<R>, v: Vec3<R>, x_start: Vec3<R>, normal: Vec3<R>) -> (Vec3<R>, Vec3<R>) {
    let d = x - x_start;
    let d_t = d - normal * d.dot(normal);
    (x - d_t, normal * v.dot(normal))
}

/// Semi-implicit (symplectic) Euler, the model's integrator:
/// `v_c = v_p + Δt R / m`, then `x_c = x_p + Δt v_c`. Returns `(x_c, v_c)`.
pub fn integrate<R: Real>(x: Vec3<R>, v: Vec3<R>, resultant: Vec3<R>, mass: R, dt: R) -> (Vec3<R>, Vec3<R>) {
    let v_new = v + resultant * (dt / mass);
    let x_new = x + v_new * dt;
    (x_new, v_new)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_contacts_blocks_are_its_force_jacobians_on_a_plane() {
        // A tilted plane through p with normal n; the vertex 4 mm inside, approaching.
        let n = Vec3::new(0.0, 0.8, 0.6);
        let p = Vec3::new(0.1, 0.2, -0.3);
        let (k, c) = (1000.0, 0.2);
        let surface = |x: Vec3<f64>| Surface { distance: (x - p).dot(n), normal: n };
        let force = |x: Vec3<f64>, v: Vec3<f64>| contact_force(v, surface(x), k, c).map_or(Vec3::zero(), |c| c.force);
        let x = p - n * 0.004 + Vec3::new(0.3, 0.0, 0.0);
        let v = n * -0.5;
        let (stiffness, damping) = (contact_stiffness_block(surface(x), k), contact_damping_block(v, surface(x), c));
        let h = 1e-7;
        for e in Mat3::<f64>::identity().rows {
            let dx = (force(x + e * h, v) - force(x - e * h, v)) * (0.5 / h);
            assert!((dx + stiffness.mul_vec(e)).length() < 1e-6 * k, "∂F/∂x {dx:?}");
            let dv = (force(x, v + e * h) - force(x, v - e * h)) * (0.5 / h);
            assert!((dv + damping.mul_vec(e)).length() < 1e-6, "∂F/∂v {dv:?}");
        }
        // Separating: no damping; outside: nothing.
        assert_eq!(contact_damping_block(-v, surface(x), c), Mat3::zero());
        let outside = x + n * 0.01;
        assert_eq!(contact_stiffness_block(surface(outside), k), Mat3::zero());
        assert_eq!(force(outside, v), Vec3::zero());
    }

    /// The Hooke force on `i` from a spring to `j` (no damping), N.
    fn hooke(x_i: Vec3<f64>, x_j: Vec3<f64>, rest: f64, k: f64) -> Vec3<f64> {
        let mut f = Vec3::zero();
        add_spring_force(&mut f, x_i, x_j, Vec3::zero(), Vec3::zero(), rest, k, 0.0);
        f
    }

    /// `∂F_i/∂x_i` by central differences, by columns.
    fn hooke_jacobian(x_i: Vec3<f64>, x_j: Vec3<f64>, rest: f64, k: f64) -> [Vec3<f64>; 3] {
        let h = 1e-6;
        let axes = Mat3::<f64>::identity().rows;
        axes.map(|e| (hooke(x_i + e * h, x_j, rest, k) - hooke(x_i - e * h, x_j, rest, k)) * (0.5 / h))
    }

    #[test]
    fn a_stretched_springs_stiffness_block_is_its_force_jacobian() {
        let (x_i, x_j, rest, k) = (Vec3::new(0.1, -0.2, 0.3), Vec3::new(0.4, 0.2, 0.1), 0.3, 250.0);
        assert!((x_j - x_i).length() > rest, "stretched");
        let block = spring_stiffness_block(x_i, x_j, rest, k);
        for (c, column) in hooke_jacobian(x_i, x_j, rest, k).into_iter().enumerate() {
            let e = Mat3::<f64>::identity().rows[c];
            // ∂F_i/∂x_i = −K.
            let d = column + block.mul_vec(e);
            assert!(d.length() < 1e-6 * k, "column {c}: {column:?} against {:?}", block.mul_vec(e));
        }
        // And F_i depends on x_j − x_i only: ∂F_i/∂x_j = K.
        let h = 1e-6;
        let e = Vec3::new(0.0, 1.0, 0.0);
        let column = (hooke(x_i, x_j + e * h, rest, k) - hooke(x_i, x_j - e * h, rest, k)) * (0.5 / h);
        assert!((column - block.mul_vec(e)).length() < 1e-6 * k);
    }

    #[test]
    fn a_compressed_springs_stiffness_block_keeps_its_axial_part_only() {
        let (x_i, x_j, rest, k) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.2, 0.0, 0.0), 0.3, 100.0);
        let block = spring_stiffness_block(x_i, x_j, rest, k);
        let (along, across) = (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
        // The exact Jacobian's transverse curvature is negative (the spring would buckle) ...
        let exact = hooke_jacobian(x_i, x_j, rest, k);
        let transverse = -exact[2].dot(across);
        assert!(transverse < -1.0, "k (1 − L0/L) = −50 N/m: {transverse}");
        // ... the block's is zero, and along the spring it is k.
        assert!(block.mul_vec(across).length() < 1e-12);
        assert!((along.dot(block.mul_vec(along)) - k).abs() < 1e-9);
        // Positive semi-definite: vᵀ K v ≥ 0 for every v.
        for v in [Vec3::new(1.0, 2.0, -3.0), Vec3::new(-0.5, 0.1, 0.7), across] {
            assert!(v.dot(block.mul_vec(v)) >= 0.0);
        }
    }

    #[test]
    fn the_damping_block_is_the_damping_forces_velocity_jacobian() {
        let (x_i, x_j, c) = (Vec3::new(0.0, 0.1, 0.0), Vec3::new(0.3, 0.5, -0.2), 0.7);
        let block = spring_damping_block(x_i, x_j, c);
        let damping = |v_i: Vec3<f64>| {
            let mut f = Vec3::zero();
            add_spring_force(&mut f, x_i, x_j, v_i, Vec3::zero(), (x_j - x_i).length(), 0.0, c);
            f
        };
        for e in Mat3::<f64>::identity().rows {
            // Linear in v_i: ∂F_i/∂v_i = −C exactly.
            let column = damping(e) - damping(Vec3::zero());
            assert!((column + block.mul_vec(e)).length() < 1e-12, "{column:?}");
        }
        assert_eq!(spring_damping_block(x_i, x_i, c), Mat3::zero(), "a zero-length spring");
    }

    fn v(x: f64, y: f64, z: f64) -> Vec3<f64> {
        Vec3::new(x, y, z)
    }

    /// The force of one spring alone.
    fn spring(x_j: Vec3<f64>, v_j: Vec3<f64>, rest_length: f64, stiffness: f64, damping: f64) -> Vec3<f64> {
        let mut f = Vec3::zero();
        add_spring_force(&mut f, v(0., 0., 0.), x_j, v(0., 0., 0.), v_j, rest_length, stiffness, damping);
        f
    }

    #[test]
    fn stretched_spring_pulls_towards_the_other_end() {
        assert_eq!(spring(v(2., 0., 0.), v(0., 0., 0.), 1.0, 10.0, 0.0), v(10., 0., 0.));
        assert_eq!(spring(v(0.5, 0., 0.), v(0., 0., 0.), 1.0, 10.0, 0.0), v(-5., 0., 0.));
    }

    #[test]
    fn damping_resists_the_extension_rate_only() {
        assert_eq!(spring(v(1., 0., 0.), v(2., 3., 0.), 1.0, 0.0, 0.5), v(1., 0., 0.));
    }

    #[test]
    fn a_zero_length_spring_adds_nothing() {
        let mut f = v(-0.0, 1.0, 2.0);
        add_spring_force(&mut f, v(1., 1., 1.), v(1., 1., 1.), v(0., 0., 0.), v(3., 0., 0.), 1.0, 10.0, 0.5);
        assert_eq!(f, v(-0.0, 1.0, 2.0));
        assert!(f.x.is_sign_negative(), "skipped, not added as +0");
    }

    #[test]
    fn contact_pushes_out_along_the_normal() {
        let sphere = |x| crate::colliders::sphere_surface(x, v(0., 0., 0.), 1.0);
        let c = contact_force(v(0., 0., 0.), sphere(v(0., 0.9, 0.)), 100.0, 0.0).unwrap();
        assert!((c.depth - 0.1).abs() < 1e-12);
        assert!((c.force.y - 10.0).abs() < 1e-9);
        assert!(contact_force(v(0., 0., 0.), sphere(v(0., 1.1, 0.)), 100.0, 0.0).is_none());
        // Approaching at 2 m/s with c_n = 0.5 adds 1 N; leaving adds nothing.
        let c = contact_force(v(0., -2., 0.), sphere(v(0., 0.9, 0.)), 100.0, 0.5).unwrap();
        assert!((c.force.y - 11.0).abs() < 1e-9);
        let c = contact_force(v(0., 2., 0.), sphere(v(0., 0.9, 0.)), 100.0, 0.5).unwrap();
        assert!((c.force.y - 10.0).abs() < 1e-9);
    }

    #[test]
    fn friction_cancels_small_tangential_forces_and_caps_large_ones() {
        let n = v(0., 1., 0.);
        // Normal load 10 N, tangential 3 N, c_f 0.5: limit 5 N > 3 N, cancelled exactly.
        let f = friction_force(v(3., -10., 0.), v(0., 0., 0.), n, 1.0, 0.01, 0.5);
        assert_eq!(f, v(-3., 0., 0.));
        // Tangential 8 N > limit: friction is 5 N against it.
        let f = friction_force(v(8., -10., 0.), v(0., 0., 0.), n, 1.0, 0.01, 0.5);
        assert!((f.x + 5.0).abs() < 1e-12 && f.y == 0.0);
    }

    #[test]
    fn symplectic_euler_updates_velocity_first() {
        let (x, vel) = integrate(v(0., 0., 0.), v(1., 0., 0.), v(0., -2., 0.), 2.0, 0.5);
        assert_eq!(vel, v(1., -0.5, 0.));
        assert_eq!(x, v(0.5, -0.25, 0.));
    }
}
