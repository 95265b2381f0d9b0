//! Vertex Block Descent's local step: one vertex's Newton step on the substep's incremental
//! potential, the others held (Chen, Macklin et al., SIGGRAPH 2024).
//!
//! Backward Euler's substep of length `h` minimises the incremental potential
//!
//! ```text
//! G(x) = Σ_i m_i/(2h²) |x_i − y_i|² + E(x),   y_i = x_i⁰ + h v_i⁰ + h² F_ext,i / m_i
//! ```
//!
//! (`y` the inertial prediction, `E` the springs' elastic energy `Σ_s k_s (|x_b − x_a| − L0)²/2`).
//! Vertex Block Descent minimises it one vertex at a time: holding the other vertices, vertex
//! `i`'s part of `G` has the gradient and Hessian
//!
//! ```text
//! g_i = m_i/h² (x_i − y_i) − F_i,    H_i = m_i/h² I + Σ_s K_s
//! ```
//!
//! with `F_i` the springs' force on `i` and `K_s` their stiffness blocks
//! ([`crate::forces::spring_stiffness_block`], positive semi-definite), and the vertex moves by the
//! Newton step `−H_i⁻¹ g_i` ([`local_step`]). Vertices that share no spring can move at once: a
//! sweep takes the colours of [`crate::coloring::vertex_color`] in turn (Gauss–Seidel across
//! colours, every vertex of a colour together: [`sweep`]). After the sweeps, `v = (x − x⁰)/h`.
//!
//! **Chebyshev acceleration** (optional) extrapolates each vertex's new position from its own
//! position two sweeps back, `x_k ← ω_k (x̂_k − x_{k−2}) + x_{k−2}`, right after its Newton step
//! (so the next colours already see the extrapolated position, as in the paper), with `ω_1 = 1`, `ω_2 = 2/(2 − ρ²)` and
//! `ω_k = 4/(4 − ρ² ω_{k−1})` for an estimate `ρ < 1` of the sweeps' convergence rate
//! ([`chebyshev_weight`]).

use crate::colliders::Surface;
use crate::coloring::{VERTEX_COLOR_COUNT, vertex_color};
use crate::forces::{
    add_spring_force, contact_damping_block, contact_force, contact_stiffness_block, spring_damping_block,
    spring_stiffness_block,
};
use crate::model::Adjacency;
use crate::real::{Mat3, Real, Vec3};

/// The gradient (N) and Hessian (N/m) of vertex `i`'s part of the incremental potential at
/// `x` (m), with the other vertices where `positions` has them: `mass` (kg), the step `h` (s), its
/// inertial prediction `y` (m), and its springs as `(other vertex, rest length m, stiffness N/m)`.
pub fn local_gradient_and_hessian<R: Real>(
    x: Vec3<R>,
    y: Vec3<R>,
    mass: R,
    h: R,
    springs: impl Iterator<Item = (Vec3<R>, R, R)>,
) -> (Vec3<R>, Mat3<R>) {
    let inertia = mass / (h * h);
    let mut force = Vec3::zero();
    let mut hessian = Mat3::identity() * inertia;
    for (x_j, rest_length, stiffness) in springs {
        add_spring_force(&mut force, x, x_j, Vec3::zero(), Vec3::zero(), rest_length, stiffness, R::zero());
        hessian = hessian + spring_stiffness_block(x, x_j, rest_length, stiffness);
    }
    ((x - y) * inertia - force, hessian)
}

/// Vertex `i`'s new position after its Newton step `x − H⁻¹ g` (see
/// [`local_gradient_and_hessian`] for the arguments). `H` is the inertia plus positive
/// semi-definite blocks, so it is invertible; if rounding made it singular, the vertex stays.
pub fn local_step<R: Real>(
    x: Vec3<R>,
    y: Vec3<R>,
    mass: R,
    h: R,
    springs: impl Iterator<Item = (Vec3<R>, R, R)>,
) -> Vec3<R> {
    let (gradient, hessian) = local_gradient_and_hessian(x, y, mass, h, springs);
    match hessian.inverse() {
        Some(inverse) => x - inverse.mul_vec(gradient),
        None => x,
    }
}

/// The slip speed below which VBD's friction holds a vertex like a stiff tangential spring, m/s
/// (IPC's mollifier `ε_v`): a contact whose friction could hold the vertex lets it creep at most
/// this fast (the stability suite's creep case allows 2e-4 m/s; at 1e-3 the drape crept at 2e-4).
pub const FRICTION_SLIP_SPEED: f64 = 1e-4;

/// The band outside a collider's surface, m, within which a vertex's local potential already
/// holds the contact's curvature (`k_c n nᵀ`, and `c/h n nᵀ` while approaching; no force yet), and
/// from beyond which a step into the collider stops at its surface ([`surface_fraction`]). A
/// sweep or a coarse correction leaves a stopped vertex on the surface (`φ = 0` up to rounding);
/// with the contact in its potential it steps from there to where the contact and friction hold
/// it. Without the band it would step outside the contact, stop at once, and stay where it is
/// in every direction: on `scenes/mesh.ron` at 16 × 16 two corner vertices resting on the ground
/// glided at constant velocity for six frames, compressing the spring between them by 21%.
pub const CONTACT_BAND: f64 = 1e-4;

/// Vertex `i`'s part of the incremental potential with everything a substep of the model puts in
/// it, summed term by term: its gradient `g` (N) and Hessian `H` (N/m) at the vertex's current
/// position `x`, with `v = (x − x⁰)/h` the velocity the substep gives it.
///
/// ```text
/// inertia      g += m/h² (x − y)                      H += m/h² I
/// spring s     g −= F_s(x, v)  (Hooke + damping)       H += K_s + C_s/h
/// contact      g −= k_c d n − c min(v·n, 0) n          H += k_c n nᵀ + c/h n nᵀ (approaching)
/// friction     g += μ F_n u / max(|u|, ε_u)           H += μ F_n / max(|u|, ε_u) (I − n nᵀ)
/// ```
///
/// `u` is the contact's tangential displacement over the substep relative to the collider,
/// `ε_u = ε_v h` with `ε_v` = [`FRICTION_SLIP_SPEED`], and `F_n` the contact's normal force at the
/// current iterate (lagged, as IPC's friction): below `ε_u` the friction is a tangential spring of
/// stiffness `μ F_n / ε_u`, beyond it a Coulomb force of magnitude `μ F_n` whose direction the
/// Hessian's lagged `μ F_n / |u|` keeps positive semi-definite.
#[derive(Clone, Copy, Debug)]
pub struct LocalTerms<R> {
    /// `g`, N.
    pub gradient: Vec3<R>,
    /// `H`, N/m.
    pub hessian: Mat3<R>,
}

impl<R: Real> LocalTerms<R> {
    /// The inertia of a vertex of mass `m` (kg) at `x` with inertial prediction `y` (m), step `h`.
    pub fn inertia(x: Vec3<R>, y: Vec3<R>, m: R, h: R) -> Self {
        let w = m / (h * h);
        Self { gradient: (x - y) * w, hessian: Mat3::identity() * w }
    }

    /// A spring to vertex `j`: the vertex at `x` having started the substep at `x0`, `j` at `x_j`
    /// from `x0_j` (m); rest length (m), stiffness (N/m), damping (N·s/m), step `h` (s).
    #[allow(clippy::too_many_arguments)]
    pub fn add_spring(
        &mut self,
        (x, x0): (Vec3<R>, Vec3<R>),
        (x_j, x0_j): (Vec3<R>, Vec3<R>),
        rest_length: R,
        stiffness: R,
        damping: R,
        h: R,
    ) {
        let inv_h = R::one() / h;
        let mut force = Vec3::zero();
        add_spring_force(&mut force, x, x_j, (x - x0) * inv_h, (x_j - x0_j) * inv_h, rest_length, stiffness, damping);
        self.gradient -= force;
        self.hessian = self.hessian + spring_stiffness_block(x, x_j, rest_length, stiffness);
        if damping > R::zero() {
            self.hessian = self.hessian + spring_damping_block(x, x_j, damping) * inv_h;
        }
    }

    /// A collider whose surface seen from `x` is `surface`, moving at `collider_velocity` (m/s):
    /// penalty stiffness (N/m), damping (N·s/m) and friction coefficient `μ` (0 without the
    /// `Friction` effect). `x0` is where the vertex started the substep, `h` the step (s).
    #[allow(clippy::too_many_arguments)]
    pub fn add_contact(
        &mut self,
        (x, x0): (Vec3<R>, Vec3<R>),
        surface: Surface<R>,
        collider_velocity: Vec3<R>,
        stiffness: R,
        damping: R,
        friction: R,
        h: R,
    ) {
        let inv_h = R::one() / h;
        let v_rel = (x - x0) * inv_h - collider_velocity;
        let Some(contact) = contact_force(v_rel, surface, stiffness, damping) else {
            // In the band outside the surface: the curvature the contact has once the vertex
            // enters, without a force (CONTACT_BAND).
            let inside = Surface { distance: -R::one(), normal: surface.normal };
            self.hessian = self.hessian
                + contact_stiffness_block(inside, stiffness)
                + contact_damping_block(v_rel, inside, damping) * inv_h;
            return;
        };
        let n = contact.normal;
        self.gradient -= contact.force;
        self.hessian = self.hessian
            + contact_stiffness_block(surface, stiffness)
            + contact_damping_block(v_rel, surface, damping) * inv_h;
        let normal_force = contact.force.dot(n);
        if friction <= R::zero() || normal_force <= R::zero() {
            return;
        }
        let slip = v_rel * h;
        let u = slip - n * slip.dot(n);
        let reach = u.length().max(R::of(FRICTION_SLIP_SPEED) * h);
        let scale = friction * normal_force / reach;
        self.gradient += u * scale;
        self.hessian = self.hessian + (Mat3::identity() - Mat3::outer(n, n)) * scale;
    }

    /// The Newton step's result `x − H⁻¹ g` (the vertex stays where it is if rounding made `H`
    /// singular).
    pub fn step(&self, x: Vec3<R>) -> Vec3<R> {
        match self.hessian.inverse() {
            Some(inverse) => x - inverse.mul_vec(self.gradient),
            None => x,
        }
    }
}

/// The share of gravity `g` (m/s²) that VBD's adaptive initialisation adds to a vertex's inertial
/// step (Chen et al. 2024): its last substep's acceleration `a` (m/s²) along `g`, as a fraction of
/// `|g|` clamped to `[0, 1]`. A vertex in free fall starts from the full inertial prediction; one
/// at rest on a support or hanging from its springs starts where it is, close to the solution, so
/// that few sweeps do not have to carry the support's force across the whole cloth.
pub fn gravity_share<R: Real>(acceleration: Vec3<R>, gravity: Vec3<R>) -> R {
    let g2 = gravity.dot(gravity);
    if g2 <= R::zero() {
        return R::zero();
    }
    (acceleration.dot(gravity) / g2).max(R::zero()).min(R::one())
}

/// Where along a local step a vertex outside a collider's [`CONTACT_BAND`] (`φ` = `start` at its
/// position) that the step would take inside (`φ` = `end` < 0) meets the surface: the fraction
/// `start/(start − end)` of the step (`φ` interpolated linearly along it), or `None` for a step
/// that does not enter or that starts within the band, whose potential held the contact.
///
/// The penalty contact is a quadratic only inside: a Newton step taken outside, where the contact
/// is not in the local potential, can go as deep as the inertial prediction, and the next sweep's
/// step, with the contact, back out beyond the surface; the sweeps then alternate and never
/// settle (measured on `scenes/floor.ron` at 12 × 12, 3 substeps a frame: 1.1 cm of penetration
/// with 10 sweeps and with 100, against 0.4 mm for backward Euler). Stopping at the surface, the
/// vertex meets the contact from there on.
pub fn surface_fraction<R: Real>(start: R, end: R) -> Option<R> {
    (start > R::of(CONTACT_BAND) && end < R::zero()).then(|| start / (start - end))
}

/// What a sweep needs besides the positions: the grid's width, each vertex's mass (kg), whether
/// it moves freely, its inertial prediction `y` (m), its springs and their stiffness by kind
/// (N/m, structural, shear, bend), and the step `h` (s).
pub struct SweepInputs<'a, R> {
    /// Vertices along `i`.
    pub nx: usize,
    /// Each vertex's mass, kg.
    pub masses: &'a [R],
    /// Whether each vertex moves (a pinned vertex is held where it is).
    pub free: &'a [bool],
    /// The inertial prediction `y`, m.
    pub predicted: &'a [Vec3<R>],
    /// Each vertex's springs.
    pub adjacency: &'a Adjacency,
    /// Stiffness `k` by spring kind, N/m.
    pub stiffness: [R; 3],
    /// The substep `h`, s.
    pub step: R,
}

/// Vertex `i`'s springs as [`local_step`] takes them, `(x_j, L0, k)`: the other end's position in
/// `positions` (m), the rest length (m) and the stiffness of the spring's kind (N/m).
pub fn springs_of<'a, R: Real>(
    positions: &'a [Vec3<R>],
    adjacency: &'a Adjacency,
    i: usize,
    stiffness: [R; 3],
) -> impl Iterator<Item = (Vec3<R>, R, R)> + 'a {
    adjacency
        .of(i)
        .iter()
        .map(move |end| (positions[end.other as usize], R::of(end.rest_length), stiffness[end.kind as usize]))
}

/// One Vertex Block Descent iteration over `positions` (m): each colour in turn, and within a
/// colour the free vertices in `order` (vertex indices, every vertex once), each moved by its
/// [`local_step`]. A colour's vertices share no spring, so the order within a colour does not
/// change the result (a GPU moves them at once).
pub fn sweep<R: Real>(positions: &mut [Vec3<R>], inputs: &SweepInputs<'_, R>, order: &[usize]) {
    for color in 0..VERTEX_COLOR_COUNT {
        for &i in order {
            if !inputs.free[i] || vertex_color((i % inputs.nx) as u32, (i / inputs.nx) as u32) != color {
                continue;
            }
            let springs = springs_of(positions, inputs.adjacency, i, inputs.stiffness);
            positions[i] = local_step(positions[i], inputs.predicted[i], inputs.masses[i], inputs.step, springs);
        }
    }
}

/// The Chebyshev weight `ω_k` of sweep `k` (from 1) for the convergence-rate estimate `rho`
/// (`0 ≤ ρ < 1`): 1 for the first sweep, then `2/(2 − ρ²)`, then `4/(4 − ρ² ω_{k−1})`.
pub fn chebyshev_weight<R: Real>(k: u32, rho: R) -> R {
    let (one, two, four) = (R::one(), R::of(2.0), R::of(4.0));
    let rho2 = rho * rho;
    let mut omega = one;
    for step in 2..=k {
        omega = if step == 2 { two / (two - rho2) } else { four / (four - rho2 * omega) };
    }
    omega
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::EffectSet;
    use crate::grid::Grid;
    use crate::scene::ClothSpec;

    fn v(x: f64, y: f64, z: f64) -> Vec3<f64> {
        Vec3::new(x, y, z)
    }

    #[test]
    fn a_stretched_spring_along_its_axis_is_solved_in_one_step() {
        // Vertex 1 held by a spring to the origin: along x the potential is quadratic,
        // m/(2h²)(x − y)² + k (x − L0)²/2, whose minimum is (m y/h² + k L0)/(m/h² + k).
        let (m, h, k, rest, y) = (0.05, 4e-3, 300.0, 0.1, 0.14);
        let spring = || std::iter::once((v(0.0, 0.0, 0.0), rest, k));
        let x = local_step(v(0.12, 0.0, 0.0), v(y, 0.0, 0.0), m, h, spring());
        let expected = (m * y / (h * h) + k * rest) / (m / (h * h) + k);
        assert!((x.x - expected).abs() < 1e-14, "{} against {expected}", x.x);
        let (gradient, _) = local_gradient_and_hessian(x, v(y, 0.0, 0.0), m, h, spring());
        assert!(gradient.length() < 1e-9, "a minimum: {gradient:?}");
    }

    #[test]
    fn a_vertex_on_a_surface_steps_into_its_contact_and_keeps_sliding() {
        // A vertex on the ground (φ = 0, where a stop leaves it) sliding at 1 m/s: its step holds
        // the contact's curvature, so it slides on by v h and sinks only to where k_c balances its
        // weight's share, m g / (m/h² + k_c), and nothing stops it at the surface. Outside the
        // contact's potential its step would drop by g h², stop at once and leave it where it was.
        let (m, h, k) = (0.01, 1.0 / 60.0, 1000.0);
        let x = v(0.3, 0.0, 0.2);
        let y = x + v(1.0, 0.0, 0.0) * h + v(0.0, -9.81, 0.0) * (h * h);
        let mut terms = LocalTerms::inertia(x, y, m, h);
        let ground = Surface { distance: 0.0, normal: v(0.0, 1.0, 0.0) };
        terms.add_contact((x, x), ground, v(0.0, 0.0, 0.0), k, 1.0, 0.6, h);
        let stepped = terms.step(x);
        assert!((stepped.x - (x.x + h)).abs() < 1e-12, "slides by v h: {stepped:?}");
        let sink = -9.81 * m / (m / (h * h) + k);
        assert!((stepped.y - sink).abs() < 1e-12, "sinks to {sink}: {stepped:?}");
        assert_eq!(surface_fraction(0.0, stepped.y), None, "a step from the surface is not stopped");
        assert_eq!(surface_fraction(1e-3, -1e-3), Some(0.5), "one from beyond the band is");
    }

    const STIFFNESS: [f64; 3] = [400.0, 200.0, 100.0];

    /// A 9 × 7 cloth of 0.1 m spacing and 0.02 kg a vertex, its first row pinned, crumpled,
    /// with every vertex's inertial prediction a centimetre's step away from where it is.
    struct Crumpled {
        adjacency: Adjacency,
        x: Vec<Vec3<f64>>,
        y: Vec<Vec3<f64>>,
        masses: Vec<f64>,
        free: Vec<bool>,
    }

    impl Crumpled {
        fn new() -> Self {
            let grid = Grid::new(&ClothSpec { resolution: [9, 7], size: [0.8, 0.6], ..Default::default() });
            let springs = crate::springs::generate(&grid, EffectSet::mass_spring());
            let n = grid.vertex_count();
            let wobble = |i: usize| v((1.3 * i as f64).sin(), (0.7 * i as f64).cos(), (2.1 * i as f64).sin()) * 0.02;
            let x: Vec<Vec3<f64>> =
                grid.positions.iter().enumerate().map(|(i, p)| Vec3::from_f64(*p) + wobble(i)).collect();
            let y = x.iter().map(|&p| p + v(0.0, -0.01, 0.003)).collect();
            Self {
                adjacency: Adjacency::new(n, &springs),
                x,
                y,
                masses: vec![0.02; n],
                free: (0..n).map(|i| i >= 9).collect(),
            }
        }

        fn inputs(&self) -> SweepInputs<'_, f64> {
            SweepInputs {
                nx: 9,
                masses: &self.masses,
                free: &self.free,
                predicted: &self.y,
                adjacency: &self.adjacency,
                stiffness: STIFFNESS,
                step: 1e-2,
            }
        }
    }

    #[test]
    fn a_colours_vertices_move_alike_in_any_order() {
        let cloth = Crumpled::new();
        let (x, y, n) = (&cloth.x, &cloth.y, cloth.x.len());
        let inputs = cloth.inputs();
        let forward: Vec<usize> = (0..n).collect();
        let backward: Vec<usize> = (0..n).rev().collect();
        let (mut a, mut b) = (x.clone(), x.clone());
        sweep(&mut a, &inputs, &forward);
        sweep(&mut b, &inputs, &backward);
        assert_eq!(a, b, "no two vertices of a colour share a spring: the order is free");
        assert_ne!(&a, x, "the sweep moved the cloth");
        assert_eq!(a[..9], x[..9], "the pinned row stays");
        // Without the colours (all vertices in one pass, in index order and backward) the
        // result depends on the order: the test could fail.
        let one_pass = |order: &[usize]| {
            let mut p = x.clone();
            for &i in order.iter().filter(|&&i| cloth.free[i]) {
                p[i] = local_step(p[i], y[i], 0.02, 1e-2, springs_of(&p, &cloth.adjacency, i, STIFFNESS));
            }
            p
        };
        assert_ne!(one_pass(&forward), one_pass(&backward));
    }

    #[test]
    fn sweeps_converge_to_the_implicit_step() {
        let cloth = Crumpled::new();
        let (x, y, n) = (&cloth.x, &cloth.y, cloth.x.len());
        let (free, masses, adjacency) = (&cloth.free, &cloth.masses, &cloth.adjacency);
        let inputs = cloth.inputs();
        let stiffness = STIFFNESS;
        let order: Vec<usize> = (0..n).collect();
        let largest_gradient = |p: &[Vec3<f64>]| {
            (0..n)
                .filter(|&i| free[i])
                .map(|i| {
                    let springs = springs_of(p, adjacency, i, stiffness);
                    local_gradient_and_hessian(p[i], y[i], masses[i], 1e-2, springs).0.length()
                })
                .fold(0.0, f64::max)
        };
        let mut p = x.clone();
        let start = largest_gradient(&p);
        for _ in 0..60 {
            sweep(&mut p, &inputs, &order);
        }
        let end = largest_gradient(&p);
        // The minimum of G: every free vertex's gradient vanishes (N).
        assert!(start > 1.0 && end < 1e-6 * start, "largest |g| {start:.3e} N -> {end:.3e} N");

        // Chebyshev's extrapolation, with a rate the plain sweeps show, gets there in fewer.
        let sweeps_to = |rho: Option<f64>, target: f64| {
            let (mut p, mut older, mut previous) = (x.clone(), x.clone(), x.clone());
            for k in 1..=200u32 {
                sweep(&mut p, &inputs, &order);
                if let Some(rho) = rho {
                    let omega = chebyshev_weight(k, rho);
                    for i in 0..n {
                        p[i] = older[i] + (p[i] - older[i]) * omega;
                    }
                }
                older = std::mem::replace(&mut previous, p.clone());
                if largest_gradient(&p) < target {
                    return k;
                }
            }
            u32::MAX
        };
        let target = 1e-6 * start;
        let plain = sweeps_to(None, target);
        // The rate per sweep the plain sweeps had: the gradient fell 1e-6 in `plain` sweeps.
        let rho = 1e-6f64.powf(1.0 / plain as f64);
        let accelerated = sweeps_to(Some(rho), target);
        eprintln!("to 1e-6 of the start: {plain} sweeps, {accelerated} with Chebyshev at ρ = {rho:.3}");
        assert!(accelerated < plain, "Chebyshev at ρ = {rho:.3}: {accelerated} sweeps against {plain}");
    }

    #[test]
    fn chebyshev_weights_follow_the_recurrence() {
        assert_eq!(chebyshev_weight(1, 0.9f64), 1.0);
        let w2: f64 = 2.0 / (2.0 - 0.81);
        assert!((chebyshev_weight(2, 0.9f64) - w2).abs() < 1e-15);
        assert!((chebyshev_weight(3, 0.9f64) - 4.0 / (4.0 - 0.81 * w2)).abs() < 1e-15);
        // The weights rise towards 2 / (1 + √(1 − ρ²)).
        let limit = 2.0 / (1.0 + (1.0f64 - 0.81).sqrt());
        assert!((chebyshev_weight(200, 0.9f64) - limit).abs() < 1e-9);
        assert_eq!(chebyshev_weight(5, 0.0f64), 1.0, "ρ = 0: no extrapolation");
    }
}
