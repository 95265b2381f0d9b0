//! How large a substep the semi-implicit Euler integrator tolerates.
//!
//! For one vertex of mass `m` tied by springs, the fastest mode's angular frequency obeys
//! (Gershgorin's bound on `M⁻¹K`) `ω_max² ≤ 2 Σk / m`, the sum running over the vertex's
//! springs (each neighbour can move against it). Damping adds `c = 2 Σc_d / m` (plus contact
//! damping and the air-drag rate). Semi-implicit Euler applied to `x'' = -ω² x - c x'` has the
//! amplification matrix with trace `2 - hc - h²ω²` and determinant `1 - hc`; it is stable when
//!
//! ```text
//! h < (-c + √(c² + 4ω²)) / ω²        (= 2/ω without damping)
//! ```
//!
//! Every collider adds its penalty stiffness `k_c` to `Σk` (once, not doubled: the collider
//! does not move with the vertex; a vertex can touch all of them at once). Self-collision adds
//! `2 k_s` for each of `CONTACTS_PER_VERTEX` contacts (the other vertex moves too). Masses are equal, so the most connected vertex (the grid's centre) sets
//! the bound.

use crate::effects::Effect;
use crate::scene::{Auto, Scene, Substeps};
use crate::springs::SpringKind;

/// Largest stable substep `h_max`, s, for the scene's springs, masses, damping and integrator
/// (`f64::INFINITY` when nothing in the scene limits the step).
///
/// Semi-implicit Euler and velocity Verlet share the bound below. For RK4 the undamped limit
/// `2√2/ω` replaces `2/ω`: the damped bound is scaled by `√2` (an estimate; RK4's stability
/// region is not the symplectic methods' shape).
pub fn stable_substep(scene: &Scene) -> f64 {
    let (omega_sq, damping_rate) = stiffness_and_damping_rates(scene);
    bound(omega_sq, damping_rate) * scene.integrator.stability_limit() / 2.0
}

/// `h_max` for the oscillator `x'' = -ω² x - c x'` under semi-implicit Euler.
pub fn bound(omega_sq: f64, damping_rate: f64) -> f64 {
    let (w2, c) = (omega_sq.max(0.0), damping_rate.max(0.0));
    if w2 > 0.0 {
        (-c + (c * c + 4.0 * w2).sqrt()) / w2
    } else if c > 0.0 {
        2.0 / c
    } else {
        f64::INFINITY
    }
}

/// `(ω_max², c)` bounds at the most connected vertex: 1/s² and 1/s.
pub fn stiffness_and_damping_rates(scene: &Scene) -> (f64, f64) {
    let m = scene.vertex_mass();
    if m.is_nan() || m <= 0.0 {
        return (f64::INFINITY, 0.0);
    }
    let [nx, ny] = scene.cloth.resolution;
    let (ci, cj) = ((nx / 2) as i64, (ny / 2) as i64);
    let inside = |di: i64, dj: i64| {
        let (i, j) = (ci + di, cj + dj);
        i >= 0 && j >= 0 && i < nx as i64 && j < ny as i64
    };
    let mut k_sum = 0.0;
    let mut c_sum = 0.0;
    for kind in SpringKind::ALL {
        if !scene.effects.contains(kind.effect()) {
            continue;
        }
        let spec = match kind {
            SpringKind::Structural => scene.springs.structural,
            SpringKind::Shear => scene.springs.shear,
            SpringKind::Bend => scene.springs.bend,
        };
        let offsets: &[(i64, i64)] = match kind {
            SpringKind::Structural => &[(1, 0), (-1, 0), (0, 1), (0, -1)],
            SpringKind::Shear => &[(1, 1), (-1, 1), (1, -1), (-1, -1)],
            SpringKind::Bend => &[(2, 0), (-2, 0), (0, 2), (0, -2)],
        };
        let n = offsets.iter().filter(|(di, dj)| inside(*di, *dj)).count() as f64;
        k_sum += 2.0 * n * spec.stiffness;
        if scene.effects.contains(Effect::SpringDamping) {
            c_sum += 2.0 * n * spec.damping;
        }
    }
    if scene.effects.contains(Effect::Contact) {
        for s in &scene.colliders {
            k_sum += s.stiffness;
            c_sum += s.damping;
        }
    }
    if scene.effects.contains(Effect::SelfCollision) {
        // Each self-contact is a spring both ends move against.
        let contacts = 2.0 * crate::self_collision::CONTACTS_PER_VERTEX;
        k_sum += contacts * scene.self_collision.stiffness;
        c_sum += contacts * scene.self_collision.damping;
    }
    let mut damping_rate = c_sum / m;
    if scene.effects.contains(Effect::AirDrag) {
        damping_rate += scene.air_drag;
    }
    (k_sum / m, damping_rate)
}

/// `ω_max Δt` that `Substeps::Auto` gives XPBD, which has no stability limit: its
/// [`crate::integrator::XPBD_ITERATIONS`] Gauss–Seidel sweeps bring the springs to their
/// compliance only while `ω Δt` stays below about this. Beyond, a landing leaves the stiff springs
/// stretched far from where their force would hold them, and that elastic energy appears from
/// nowhere (measured on `scenes/hard/stiff_springs.ron`, 10 × 10 with springs 1000 times the
/// default: at `ω Δt` = 156, 39, 20 and 10 the elastic energy right after the landing reached
/// 10, 0.7, 0.13 and 0.04 J, for 1.4 J of energy in the scene).
pub const XPBD_AUTO_OMEGA_DT: f64 = 10.0;

/// `ω_max Δt` that `Substeps::Auto` gives VBD: its sweeps, a fixed number a substep, spread a
/// disturbance only so far through stiff springs, so its cloth acts softer and springier the
/// larger the step (measured on `scenes/mesh.ron` at 16 × 16 with 10 sweeps: at `ω Δt` ≈ 10, 4
/// substeps a frame, the cloth still bounced 12 cm above the ring after 1.25 s; at 8 substeps, or
/// with 40 sweeps, it rested on it).
pub const VBD_AUTO_OMEGA_DT: f64 = 5.0;

/// XPBD's `Auto` also keeps a moving collider's travel in one substep below this fraction of the
/// smaller grid cell side. Its swept projection never misses the cloth, but the 10 sweeps of a
/// substep spread the sphere's push only so far through the springs: a ball moving across a
/// large part of a cell per substep leaves them stretched, elastic energy from nowhere (measured
/// on `scenes/hard/fast_sphere.ron`, a ball at 8 m/s through a 12 × 12 cloth of 7 cm cells:
/// at 5 substeps per frame, 0.37 cells per substep, the f64 run's energy reached 19.7 J for
/// 1.0 J at the start; at 10, 0.18 cells, the f32 run's reached 14.8 J; at 19, 0.1 cells, both
/// stayed below 5.8 J, what the ball can give).
pub const XPBD_AUTO_COLLIDER_CELLS: f64 = 0.1;

/// The substep `Substeps::Auto` aims below, s: `Auto::SAFETY × h_max` for the explicit
/// integrators; for those without a stability limit (XPBD, backward Euler, VBD), which `Auto`
/// steps for accuracy instead, `XPBD_AUTO_OMEGA_DT / ω_max` (VBD: [`VBD_AUTO_OMEGA_DT`]; `ω_max`
/// of the springs alone: XPBD's
/// colliders are constraints, and the implicit integrators solve their penalty springs with the
/// rest) and, with moving colliders, the step in which the fastest moves
/// [`XPBD_AUTO_COLLIDER_CELLS`] of a cell.
pub fn auto_target_substep(scene: &Scene) -> f64 {
    if scene.integrator.unconditionally_stable() {
        // Only the springs: the colliders are constraints or solved implicitly.
        let mut springs_only = scene.clone();
        springs_only.effects.set(Effect::Contact, false);
        let (omega_sq, _) = stiffness_and_damping_rates(&springs_only);
        let target =
            if scene.integrator == crate::integrator::Integrator::Vbd { VBD_AUTO_OMEGA_DT } else { XPBD_AUTO_OMEGA_DT };
        let springs = if omega_sq > 0.0 { target / omega_sq.sqrt() } else { f64::INFINITY };
        let moving = scene.effects.contains(Effect::MovingColliders) && scene.effects.contains(Effect::Contact);
        let speed = if moving { scene.colliders.iter().map(|s| s.motion.max_speed()).fold(0.0, f64::max) } else { 0.0 };
        if speed <= 0.0 {
            return springs;
        }
        let [du, dv] = scene.cloth.spacing();
        let cell = du.min(dv);
        return springs.min(XPBD_AUTO_COLLIDER_CELLS * cell / speed);
    }
    stable_substep(scene) * Auto::SAFETY
}

/// Substeps per frame `Substeps::Auto` needs: the fewest that keep each substep below
/// [`auto_target_substep`], as a real number (it may exceed any integer type; validation
/// refuses more than [`crate::budget::MAX_SUBSTEPS_PER_FRAME`]).
pub fn auto_substeps_needed(scene: &Scene) -> f64 {
    let h = auto_target_substep(scene);
    if h.is_nan() || h <= 0.0 || !scene.time.frame_dt.is_finite() {
        return 1.0;
    }
    (scene.time.frame_dt / h).ceil().max(1.0)
}

/// Substeps per frame chosen by `Substeps::Auto` ([`auto_substeps_needed`], which validation
/// keeps within [`crate::budget::MAX_SUBSTEPS_PER_FRAME`]).
pub fn auto_substeps(scene: &Scene) -> u32 {
    let n = auto_substeps_needed(scene);
    if n.is_finite() { n.clamp(1.0, u32::MAX as f64) as u32 } else { 1 }
}

/// Largest stable substep from the actual fastest mode of the cloth, s: `ω_max² = λ_max(M⁻¹K)`
/// found by power iteration on the springs' stiffness matrix at the rest shape (pinned vertices
/// held), plus the contact stiffness, with the damping rate bounded as in [`stable_substep`].
///
/// Tighter than [`stable_substep`], which bounds `λ_max` by Gershgorin's theorem and so counts
/// every spring of a vertex as if all of them could stretch at once; this one is an estimate
/// (power iteration approaches `λ_max` from below), so validation and `Auto` keep the safe bound.
pub fn spectral_stable_substep(model: &crate::model::ClothModel) -> f64 {
    let scene = &model.scene;
    let m = scene.vertex_mass();
    let n = model.vertex_count();
    if n == 0 || m.is_nan() || m <= 0.0 {
        return f64::INFINITY;
    }
    let stiffness = |kind: SpringKind| match kind {
        SpringKind::Structural => scene.springs.structural.stiffness,
        SpringKind::Shear => scene.springs.shear.stiffness,
        SpringKind::Bend => scene.springs.bend.stiffness,
    };
    // Unit directions of the springs at rest.
    let springs: Vec<(usize, usize, f64, [f64; 3])> = model
        .springs
        .iter()
        .filter_map(|s| {
            let (a, b) = (model.grid.positions[s.a as usize], model.grid.positions[s.b as usize]);
            let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            (l > 0.0).then(|| (s.a as usize, s.b as usize, stiffness(s.kind), [d[0] / l, d[1] / l, d[2] / l]))
        })
        .collect();
    let pinned = &model.grid.pinned;
    let apply = |x: &[[f64; 3]], y: &mut [[f64; 3]]| {
        y.iter_mut().for_each(|v| *v = [0.0; 3]);
        for &(a, b, k, u) in &springs {
            let d = [x[a][0] - x[b][0], x[a][1] - x[b][1], x[a][2] - x[b][2]];
            let f = k * (u[0] * d[0] + u[1] * d[1] + u[2] * d[2]);
            for c in 0..3 {
                y[a][c] += f * u[c];
                y[b][c] -= f * u[c];
            }
        }
        for (i, v) in y.iter_mut().enumerate() {
            if pinned[i] {
                *v = [0.0; 3];
            }
        }
    };
    // A start vector with every mode in it (deterministic, no zero entries on free vertices).
    let mut x: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            if pinned[i] {
                return [0.0; 3];
            }
            let h = |k: usize| {
                (((i * 3 + k) as f64 * 0.618_033_988_75).fract() - 0.5)
                    + if (i + k).is_multiple_of(2) { 1.0 } else { -1.0 }
            };
            [h(0), h(1), h(2)]
        })
        .collect();
    let mut y = vec![[0.0; 3]; n];
    let norm = |v: &[[f64; 3]]| v.iter().flat_map(|p| p.iter()).map(|c| c * c).sum::<f64>().sqrt();
    let mut lambda = 0.0;
    for _ in 0..300 {
        let nx = norm(&x);
        if nx == 0.0 {
            break;
        }
        x.iter_mut().for_each(|p| p.iter_mut().for_each(|c| *c /= nx));
        apply(&x, &mut y);
        lambda = x.iter().zip(&y).map(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).sum::<f64>();
        std::mem::swap(&mut x, &mut y);
    }
    let mut omega_sq = lambda / m;
    let (_, damping_rate) = stiffness_and_damping_rates(scene);
    if scene.effects.contains(Effect::Contact) {
        omega_sq += scene.colliders.iter().map(|s| s.stiffness).sum::<f64>() / m;
    }
    bound(omega_sq, damping_rate) * scene.integrator.stability_limit() / 2.0
}

/// `Δt / h_max`: below 1 is stable, above 1 diverges.
pub fn stability_margin(scene: &Scene) -> f64 {
    scene.substep_dt() / stable_substep(scene)
}

impl Scene {
    /// Length of one substep, s (for `Auto`, the one [`auto_substeps`] picks).
    pub fn substep_dt(&self) -> f64 {
        self.time.frame_dt / self.substeps_per_frame() as f64
    }

    /// Substeps per frame, resolving `Auto` against the stability bound.
    pub fn substeps_per_frame(&self) -> u32 {
        match self.time.substeps {
            Substeps::Fixed(n) => n.max(1),
            Substeps::Auto => auto_substeps(self),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undamped_bound_is_two_over_omega() {
        assert!((bound(100.0, 0.0) - 0.2).abs() < 1e-12);
        assert!(bound(100.0, 5.0) < 0.2, "damping shrinks the step");
        assert_eq!(bound(0.0, 0.0), f64::INFINITY);
    }

    #[test]
    fn auto_picks_enough_substeps() {
        let scene = Scene {
            time: crate::scene::TimeSpec { substeps: crate::scene::Substeps::Auto, ..Default::default() },
            ..Default::default()
        };
        let n = auto_substeps(&scene);
        assert!(scene.time.frame_dt / n as f64 <= Auto::SAFETY * stable_substep(&scene) * (1.0 + 1e-12));
        assert!(scene.time.frame_dt / (n - 1) as f64 > Auto::SAFETY * stable_substep(&scene));
    }
}
