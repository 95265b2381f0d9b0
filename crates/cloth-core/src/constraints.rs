//! The constraint projections of XPBD ([`crate::Integrator::Xpbd`]), one function per
//! constraint, as the force model is one function per force in [`crate::forces`].
//!
//! XPBD (Macklin, Müller & Chentanez 2016) moves positions instead of summing forces. A spring of
//! stiffness `k` becomes the constraint `C = |x_a − x_b| − L0` with compliance `α = 1/k`; with the
//! time-scaled compliance `α̃ = α/Δt²`, one projection computes the change of the spring's
//! Lagrange multiplier
//!
//! ```text
//! Δλ = (−C − α̃ λ) / (w_a + w_b + α̃)
//! ```
//!
//! (`w = 1/m`, 0 for a pinned vertex) and moves the ends along `n = (x_a − x_b)/|x_a − x_b|` by
//! `+w_a Δλ n` and `−w_b Δλ n`. The accumulated `λ` makes the result independent of the number
//! of iterations in the limit: the spring then acts as Hooke's law with stiffness `k`, while a
//! stiff spring (`α̃ → 0`) becomes a hard length constraint instead of an unstable step.
//!
//! The GPU shaders (`shaders/wgsl/xpbd.wgsl`, `shaders/glsl/xpbd.comp`) implement the same
//! functions with the same names and the same order of operations.

use crate::colliders::{Collider, ColliderKind, Surface, sphere_surface};
use crate::real::{Real, Vec3};

/// Projects one spring constraint. `x_a`, `x_b` are moved in place; `lambda` is the spring's
/// accumulated multiplier (N·s², starts at 0 in each substep). `inverse_mass_a/b` in 1/kg (0 for
/// a pinned end), `stiffness` in N/m, `dt` in s. Does nothing for a zero-length spring, two
/// pinned ends or a zero stiffness.
#[allow(clippy::too_many_arguments)]
pub fn project_spring<R: Real>(
    x_a: &mut Vec3<R>,
    x_b: &mut Vec3<R>,
    inverse_mass_a: R,
    inverse_mass_b: R,
    rest_length: R,
    stiffness: R,
    dt: R,
    lambda: &mut R,
) {
    if inverse_mass_a + inverse_mass_b <= R::zero() || stiffness <= R::zero() {
        return;
    }
    let d = *x_a - *x_b;
    let length = d.length();
    if length <= R::zero() {
        return;
    }
    let n = d * (R::one() / length);
    let compliance = R::one() / (stiffness * dt * dt);
    let delta_lambda =
        (-(length - rest_length) - compliance * *lambda) / (inverse_mass_a + inverse_mass_b + compliance);
    *lambda = *lambda + delta_lambda;
    *x_a += n * (inverse_mass_a * delta_lambda);
    *x_b -= n * (inverse_mass_b * delta_lambda);
}

/// Projects a vertex out of a collider (the non-penetration constraint `φ(x) ≥ 0`, with zero
/// compliance) given the collider's surface seen from it: moves `x` by `−φ 1_n`, to the surface
/// (exactly for a sphere, plane, capsule or box, whose `φ` is a true distance), and returns the
/// correction's length, m (0 when outside). XPBD's counterpart of the penalty force `F_c = k_c d`.
pub fn project_onto_surface<R: Real>(x: &mut Vec3<R>, surface: Surface<R>) -> R {
    let depth = -surface.distance;
    if depth > R::zero() {
        *x += surface.normal * depth;
        depth
    } else {
        R::zero()
    }
}

/// Projects a vertex out of a sphere (see [`project_onto_surface`]).
pub fn project_sphere<R: Real>(x: &mut Vec3<R>, center: Vec3<R>, radius: R) -> R {
    project_onto_surface(x, sphere_surface(*x, center, radius))
}

/// [`project_sphere`] made continuous: a vertex that started the substep outside the sphere, at
/// `x_start`, and whose path to `x` went through it (entered and came out on the far side: a step
/// longer than the sphere is wide tunnels) is put back where its path entered the sphere. A path
/// that ends inside is projected as usual. Returns the correction's length, m.
///
/// With `d = x − x_start` and `o = x_start − c`, the path enters at the smaller root of
/// `|o + s d|² = r²`: `s = (−o·d − √((o·d)² − |d|²(|o|² − r²))) / |d|²`.
pub fn project_sphere_swept<R: Real>(x: &mut Vec3<R>, x_start: Vec3<R>, center: Vec3<R>, radius: R) -> R {
    let o = x_start - center;
    let outside_at_start = o.dot(o) - radius * radius;
    let end = *x - center;
    let outside_at_end = end.dot(end) - radius * radius;
    if outside_at_start >= R::zero() && outside_at_end > R::zero() {
        let d = *x - x_start;
        let a = d.dot(d);
        let b = o.dot(d);
        let discriminant = b * b - a * outside_at_start;
        if a > R::zero() && b < R::zero() && discriminant >= R::zero() {
            let s = (-b - discriminant.sqrt()) / a;
            if s <= R::one() {
                let entry = x_start + d * s;
                let moved = (*x - entry).length();
                *x = entry;
                return moved;
            }
        }
        return R::zero();
    }
    project_sphere(x, center, radius)
}

/// Steps of the sweep of [`project_swept`] along a path.
pub const SWEEP_STEPS: u32 = 32;
/// The sweep stops where `φ` falls below this fraction of the collider's thickness.
pub const SWEEP_TOLERANCE: f64 = 0.01;

/// Projects a vertex out of any collider, continuously: the sphere as
/// [`project_sphere_swept`]; a plane (a half-space cannot be crossed and left) as
/// [`project_onto_surface`]; a capsule or box whose path from `x_start` (outside) to `x` is
/// longer than the collider is thick, and ends outside, is swept by sphere tracing: from the
/// start, step along the path by `φ` (a true distance: a step never enters the collider) until
/// `φ` falls below [`SWEEP_TOLERANCE`] of the thickness (the path enters there: the vertex is put
/// back there) or the path ends, at most [`SWEEP_STEPS`] steps. A shorter path cannot cross the
/// collider and ends where the usual projection puts it. `center` is where the collider ends the
/// substep; `x_start` the vertex's start carried along with the collider. Returns the
/// correction's length, m.
pub fn project_swept<R: Real>(x: &mut Vec3<R>, x_start: Vec3<R>, collider: &Collider<R>, center: Vec3<R>) -> R {
    if collider.kind == ColliderKind::Sphere {
        return project_sphere_swept(x, x_start, center, collider.radius);
    }
    let end = collider.distance(center, *x);
    if end > R::zero() && collider.kind != ColliderKind::Plane {
        let d = *x - x_start;
        let length = d.dot(d).sqrt();
        // A vertex that starts inside leaves: nothing to stop.
        if length > collider.thickness && collider.distance(center, x_start) >= R::zero() {
            let (inverse_length, stop) = (R::one() / length, collider.thickness * R::of(SWEEP_TOLERANCE));
            let mut s = R::zero();
            for _ in 0..SWEEP_STEPS {
                let p = x_start + d * s;
                // (φ may fall just below 0 by rounding after a step onto a face: the path enters there.)
                let phi = collider.distance(center, p);
                if phi <= stop {
                    let moved = (*x - p).length();
                    *x = p;
                    return moved;
                }
                s = s + phi * inverse_length;
                if s >= R::one() {
                    break;
                }
            }
        }
        return R::zero();
    }
    // The normal only for a vertex inside (φ < 0): outside the projection does nothing.
    if end < R::zero() { project_onto_surface(x, collider.surface(center, *x)) } else { R::zero() }
}

/// Coulomb friction on a contact, in position form (the model's
/// `F_f = −min(|R_ot|, c_f |R_on|) 1_t` with displacements for forces, as XPBD does it): the
/// tangential part of the substep's displacement `x − x_start` is undone when it is within `c_f`
/// times the normal correction the colliders made (static friction: the vertex sticks), and
/// shortened by that much otherwise (kinetic friction). `x` is the projected position, m, and
/// `surface` the collider's surface seen from it; a vertex not on the collider (`φ` beyond its
/// `tolerance`, m) is left alone. Returns the new position.
///
/// Applied to velocities instead (cutting the tangential velocity after the substep), friction
/// cannot hold anything: the position has already slid by `g sin θ Δt²` in every substep, a creep
/// of `g sin θ Δt` (3 cm/s at Δt = 4 ms on a 45° slope), and a drape slid off a sphere of friction
/// coefficient 1.5 that way (`scenes/hard/creep.ron`).
pub fn contact_friction<R: Real>(
    x: Vec3<R>,
    x_start: Vec3<R>,
    surface: Surface<R>,
    tolerance: R,
    coefficient: R,
    normal_correction: R,
) -> Vec3<R> {
    if surface.distance > tolerance {
        return x;
    }
    let n = surface.normal;
    let dx = x - x_start;
    let dx_t = dx - n * dx.dot(n);
    let slide = dx_t.length();
    let budget = coefficient * normal_correction;
    if slide > R::zero() { x - dx_t * (slide.min(budget) / slide) } else { x }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vec3<f64> {
        Vec3::new(x, y, z)
    }

    #[test]
    fn a_stiff_spring_is_restored_to_its_rest_length_in_one_projection() {
        let (mut a, mut b, mut lambda) = (v(0., 0., 0.), v(2., 0., 0.), 0.0);
        project_spring(&mut a, &mut b, 1.0, 1.0, 1.0, 1e12, 0.01, &mut lambda);
        assert!(((b - a).length() - 1.0).abs() < 1e-6, "{a:?} {b:?}");
        assert!((a.x - 0.5).abs() < 1e-6 && (b.x - 1.5).abs() < 1e-6, "equal masses move equally");
    }

    #[test]
    fn a_pinned_end_does_not_move() {
        let (mut a, mut b, mut lambda) = (v(0., 0., 0.), v(2., 0., 0.), 0.0);
        project_spring(&mut a, &mut b, 0.0, 1.0, 1.0, 1e12, 0.01, &mut lambda);
        assert_eq!(a, v(0., 0., 0.));
        assert!((b.x - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_compliant_spring_moves_as_hookes_law_over_one_step() {
        // One free unit mass on a spring of k = 10 N/m stretched by 0.1 m, Δt = 0.01 s: the
        // position change over the step is F Δt²/m = k·0.1·Δt² to first order in k Δt²/m.
        let (mut a, mut b, mut lambda) = (v(0., 0., 0.), v(1.1, 0., 0.), 0.0);
        project_spring(&mut a, &mut b, 0.0, 1.0, 1.0, 10.0, 0.01, &mut lambda);
        let expected = 10.0 * 0.1 * 0.01 * 0.01;
        assert!(((1.1 - b.x) - expected).abs() < expected * 1e-2, "{}", 1.1 - b.x);
    }

    #[test]
    fn spheres_push_out_to_the_surface() {
        let mut x = v(0., 0.9, 0.);
        let depth = project_sphere(&mut x, v(0., 0., 0.), 1.0);
        assert!((depth - 0.1).abs() < 1e-12 && (x.y - 1.0).abs() < 1e-12);
        assert_eq!(project_sphere(&mut x, v(0., 0., 0.), 0.5), 0.0);
    }

    #[test]
    fn a_path_through_the_sphere_is_stopped_where_it_entered() {
        let c = v(0., 0., 0.);
        // From 2 m above to 2 m below a unit sphere: tunnelled; put back at the top.
        let mut x = v(0., -2., 0.);
        let moved = project_sphere_swept(&mut x, v(0., 2., 0.), c, 1.0);
        assert!((x.y - 1.0).abs() < 1e-12 && (moved - 3.0).abs() < 1e-12, "{x:?} {moved}");
        // A path that misses the sphere, or ends inside it, is left to the usual projection.
        let mut x = v(2., -2., 0.);
        assert_eq!(project_sphere_swept(&mut x, v(2., 2., 0.), c, 1.0), 0.0);
        assert_eq!(x, v(2., -2., 0.));
        let mut x = v(0., 0.9, 0.);
        assert!((project_sphere_swept(&mut x, v(0., 2., 0.), c, 1.0) - 0.1).abs() < 1e-12);
        assert!((x.y - 1.0).abs() < 1e-12);
        // Moving away from the sphere never triggers it.
        let mut x = v(0., 3., 0.);
        assert_eq!(project_sphere_swept(&mut x, v(0., 2., 0.), c, 1.0), 0.0);
    }

    #[test]
    fn friction_holds_a_short_slide_and_shortens_a_long_one() {
        let c = v(0., 0., 0.);
        // On top of a unit sphere after a normal correction of 0.01 m: with c_f = 0.5 the budget
        // is 5 mm of tangential displacement.
        // Both end points are on the sphere, 3 mm and 20 mm from the start along it.
        let on_sphere = |s: f64| v(s, (1.0 - s * s).sqrt(), 0.);
        let start = v(0., 1.0, 0.);
        let friction = |x| contact_friction(x, start, sphere_surface(x, c, 1.0), 1e-6, 0.5, 0.01);
        let held = friction(on_sphere(0.003));
        assert!(held.x.abs() < 1e-5, "static: back where it started, {held:?}");
        let slid = friction(on_sphere(0.02));
        assert!((slid.x - 0.015).abs() < 1e-4, "kinetic: 5 mm shorter, {slid:?}");
        // Off the sphere, no friction.
        assert_eq!(friction(v(0.02, 1.1, 0.)), v(0.02, 1.1, 0.));
    }

    #[test]
    fn a_path_through_a_box_or_capsule_is_stopped_where_it_entered() {
        use crate::colliders::{ColliderSpec, Shape};
        let slab = Collider::<f64>::of(&ColliderSpec::of(Shape::Box {
            center: [0., 0., 0.],
            half_extents: [1., 0.05, 1.],
            axis: [0., 1., 0.],
            angle: 0.0,
            rounding: 0.0,
        }));
        // Straight down through a 10 cm slab, and slanted at 30° from the face.
        let mut x = v(0., -0.5, 0.);
        let moved = project_swept(&mut x, v(0., 0.5, 0.), &slab, slab.center);
        assert!((x.y - 0.05).abs() <= 0.01 * 0.1 + 1e-12 && x.y >= 0.05 - 1e-12, "{x:?}");
        assert!((moved - (x.y + 0.5)).abs() < 1e-12);
        let start = v(-0.5, 0.3, 0.);
        let mut x = start + v(3f64.sqrt(), -1.0, 0.) * 0.8;
        project_swept(&mut x, start, &slab, slab.center);
        assert!(x.y >= 0.05 - 1e-12 && x.y < 0.05 + 0.002, "slanted {x:?}");
        // A short path ending outside (a slide along the face) is left alone.
        let mut x = v(0.05, 0.0501, 0.);
        assert_eq!(project_swept(&mut x, v(0., 0.0501, 0.), &slab, slab.center), 0.0);
        let capsule =
            Collider::<f64>::of(&ColliderSpec::of(Shape::Capsule { a: [0., 0., -1.], b: [0., 0., 1.], radius: 0.1 }));
        let mut x = v(0.5, 0.0, 0.2);
        project_swept(&mut x, v(-0.5, 0.0, 0.2), &capsule, capsule.center);
        assert!(x.x <= -0.1 + 1e-12 && x.x > -0.102, "{x:?}");
    }
}
