//! The linear system of a backward-Euler substep, and the conjugate gradients that solve it.
//!
//! Backward Euler advances a substep of length `h` by `v' = v + Δv`, `x' = x + h v'`, with the
//! forces taken at the end of the substep: `M Δv = h f(x + h v', v')`. Linearising `f` about
//! `(x, v)` (Baraff and Witkin's step, the first Newton iteration) gives
//!
//! ```text
//! (M − h ∂f/∂v − h² ∂f/∂x) Δv = h (f + h ∂f/∂x v)
//! ```
//!
//! Each spring `s` between vertices `a` and `b` contributes its stiffness block `K_s`
//! ([`crate::forces::spring_stiffness_block_floored`], positive semi-definite, its transverse term
//! at least [`TRANSVERSE_STIFFNESS_FLOOR`] of `k`) and damping block
//! `C_s` ([`crate::forces::spring_damping_block`]) with `∂F_a/∂x_a = −K_s`, `∂F_a/∂x_b = K_s`
//! (likewise for `b`, and with `C_s` for the velocities), so the system is
//!
//! ```text
//! A Δv = b,   A = M + h C + h² K,   b = h (f − h K v),
//! (A p)_a = m_a p_a + Σ_s (h C_s + h² K_s)(p_a − p_b)    over the springs s of a
//! ```
//!
//! `A` is symmetric, and positive definite since `M` is and every block is positive
//! semi-definite: conjugate gradients converge on it. It is applied matrix-free, spring by spring
//! ([`LinearisedStep::apply`]), as a GPU applies it from the grid's stencil. A pinned vertex's `Δv`
//! is prescribed by its motion, not solved for: its rows and columns are left out (the solver
//! keeps its entries of `Δv` as given and reads them as zero in `A p`).
//!
//! [`conjugate_gradients`] is preconditioned by the inverse of each vertex's 3 × 3 diagonal block
//! of `A` ([`LinearisedStep::block_jacobi`]) and stops when the residual's norm is at most the
//! tolerance times the right-hand side's, or, in a later Newton iteration of the substep, times the
//! largest right-hand side of its earlier ones where that is larger.

use crate::forces::{spring_damping_block, spring_stiffness_block_floored};
use crate::real::{Mat3, Real, Vec3};

/// The least transverse stiffness of a spring in backward Euler's linearisation, as a fraction of
/// its stiffness `k` (dimensionless): `K_s = k (u uᵀ + max(0.05, 1 − L0/L)(I − u uᵀ))`.
///
/// The exact transverse term `k (1 − L0/L)` vanishes on a spring at its rest length, and on a
/// flat cloth every spring lies in the cloth's plane: the linearised system resists the cloth's
/// motion out of its plane by the vertices' mass alone, a millionth of `h² k` at 256 × 256 and one
/// substep a frame. A Newton change then moves the vertices beside a fold centimetres out of the
/// plane, the springs' true energy rises within a thousandth of the step, and the line search
/// takes almost none of it: on `scenes/stiff_drape.ron` at 256² with four Newton iterations the
/// iterations after the landing's first advanced by 0.1% each, leaving 4 J in the springs. The
/// floor is a modified Newton method: the forces, and so the solution the iterations converge to,
/// are unchanged; the changes are shorter across the springs (that landing then never rose above
/// the starting energy). Compressed springs, whose exact term is negative, get the floor too.
pub const TRANSVERSE_STIFFNESS_FLOOR: f64 = 0.05;

/// A spring's part of the system: its ends and its blocks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpringTerms<R> {
    /// First end (vertex index).
    pub a: usize,
    /// Second end.
    pub b: usize,
    /// `K_s`, N/m.
    pub stiffness: Mat3<R>,
    /// `C_s`, N·s/m.
    pub damping: Mat3<R>,
}

impl<R: Real> SpringTerms<R> {
    /// The blocks of a spring of rest length `rest_length` (m), stiffness `k` (N/m) and damping
    /// `c_d` (N·s/m) between vertices `a` at `x_a` and `b` at `x_b` (m).
    pub fn new(a: usize, b: usize, x_a: Vec3<R>, x_b: Vec3<R>, rest_length: R, k: R, c_d: R) -> Self {
        Self {
            a,
            b,
            stiffness: spring_stiffness_block_floored(x_a, x_b, rest_length, k, R::of(TRANSVERSE_STIFFNESS_FLOOR)),
            damping: spring_damping_block(x_a, x_b, c_d),
        }
    }
}

/// The system `A Δv = b` of one backward-Euler substep (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct LinearisedStep<R> {
    /// The substep `h`, s.
    pub step: R,
    /// Each vertex's mass, kg.
    pub masses: Vec<R>,
    /// Whether each vertex is solved for (a pinned vertex's `Δv` is prescribed).
    pub free: Vec<bool>,
    /// Every spring's blocks.
    pub springs: Vec<SpringTerms<R>>,
    /// The contacts' blocks, each on one vertex (`∂F_i/∂x_i = −K_c`, `∂F_i/∂v_i = −C_c`).
    pub contacts: Vec<ContactTerms<R>>,
}

/// A contact's part of the system: its vertex and its blocks
/// ([`crate::forces::contact_stiffness_block`], [`crate::forces::contact_damping_block`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactTerms<R> {
    /// The vertex in contact.
    pub vertex: usize,
    /// `K_c`, N/m.
    pub stiffness: Mat3<R>,
    /// `C_c`, N·s/m.
    pub damping: Mat3<R>,
    /// What the contact's linearisation adds to the model's force at the iterate, N: the
    /// penalty's force and stiffness taken about another point than the iterate (the end
    /// position of the iterate's velocity, see the reference's backward Euler), zero where the
    /// linearisation is about the iterate.
    pub pull: Vec3<R>,
}

impl<R: Real> LinearisedStep<R> {
    /// `out = A p` on the free vertices (zero at the pinned ones, whose entries of `p` are read
    /// as zero), N·s.
    pub fn apply(&self, p: &[Vec3<R>], out: &mut [Vec3<R>]) {
        let h = self.step;
        let at = |i: usize| if self.free[i] { p[i] } else { Vec3::zero() };
        for (i, o) in out.iter_mut().enumerate() {
            *o = at(i) * self.masses[i];
        }
        for s in &self.springs {
            let block = s.damping * h + s.stiffness * (h * h);
            let pushed = block.mul_vec(at(s.a) - at(s.b));
            out[s.a] += pushed;
            out[s.b] -= pushed;
        }
        for c in &self.contacts {
            out[c.vertex] += (c.damping * h + c.stiffness * (h * h)).mul_vec(at(c.vertex));
        }
        for (o, &free) in out.iter_mut().zip(&self.free) {
            if !free {
                *o = Vec3::zero();
            }
        }
    }

    /// `out = K v`, N: the springs' stiffness times the velocities `v` (m/s), for the right-hand
    /// side `b = h (f − h K v)`.
    pub fn stiffness_times(&self, v: &[Vec3<R>], out: &mut [Vec3<R>]) {
        out.fill(Vec3::zero());
        for s in &self.springs {
            let pushed = s.stiffness.mul_vec(v[s.a] - v[s.b]);
            out[s.a] += pushed;
            out[s.b] -= pushed;
        }
    }

    /// `out = K dx + C dv`, N: how much the linearised forces fall when the positions move by `dx`
    /// (m) and the velocities by `dv` (m/s), on every vertex, pinned ones included (a pinned
    /// vertex's prescribed motion enters its free neighbours' right-hand side through it).
    pub fn force_drop(&self, dx: &[Vec3<R>], dv: &[Vec3<R>], out: &mut [Vec3<R>]) {
        out.fill(Vec3::zero());
        for s in &self.springs {
            let pushed = s.stiffness.mul_vec(dx[s.a] - dx[s.b]) + s.damping.mul_vec(dv[s.a] - dv[s.b]);
            out[s.a] += pushed;
            out[s.b] -= pushed;
        }
        for c in &self.contacts {
            out[c.vertex] += c.stiffness.mul_vec(dx[c.vertex]) + c.damping.mul_vec(dv[c.vertex]);
        }
    }

    /// The inverse of each vertex's 3 × 3 diagonal block of `A`, `m I + Σ_s (h C_s + h² K_s)`
    /// (the identity at a pinned vertex): the block-Jacobi preconditioner.
    pub fn block_jacobi(&self) -> Vec<Mat3<R>> {
        let h = self.step;
        let mut diagonal: Vec<Mat3<R>> = self.masses.iter().map(|&m| Mat3::identity() * m).collect();
        for s in &self.springs {
            let block = s.damping * h + s.stiffness * (h * h);
            diagonal[s.a] = diagonal[s.a] + block;
            diagonal[s.b] = diagonal[s.b] + block;
        }
        for c in &self.contacts {
            diagonal[c.vertex] = diagonal[c.vertex] + c.damping * h + c.stiffness * (h * h);
        }
        diagonal
            .iter()
            .zip(&self.free)
            // A free vertex's block is its mass (positive) plus positive semi-definite blocks:
            // invertible.
            .map(|(d, &free)| if free { d.inverse().unwrap_or_else(Mat3::identity) } else { Mat3::identity() })
            .collect()
    }
}

/// How a solve went.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CgReport<R> {
    /// Iterations run (each one product with `A`).
    pub iterations: u32,
    /// `|b − A x| / |b|` at the end (0 for `b = 0`).
    pub relative_residual: R,
    /// `|b|` over the free vertices, N·s.
    pub rhs_norm: R,
}

fn dot<R: Real>(a: &[Vec3<R>], b: &[Vec3<R>]) -> R {
    a.iter().zip(b).fold(R::zero(), |sum, (x, y)| sum + x.dot(*y))
}

/// Solves `A x = b` for the free vertices by conjugate gradients preconditioned with
/// `preconditioner` (one block a vertex, e.g. [`LinearisedStep::block_jacobi`]), from the
/// initial guess in `x`; stops when `|b − A x| ≤ tolerance max(|b|, reference)` or after
/// `max_iterations`. `reference` (N·s) is a right-hand side's norm the residual is measured
/// against where `b`'s is smaller: a later Newton iteration passes the largest `|b|` of its
/// substep's earlier ones, so that a right-hand side already within the tolerance of the first
/// is solved by no iteration at all (zero for a solve of its own).
/// `x`'s pinned entries are left as they are; `b`'s are ignored.
#[allow(clippy::too_many_arguments)]
pub fn conjugate_gradients<R: Real>(
    system: &LinearisedStep<R>,
    preconditioner: &[Mat3<R>],
    b: &[Vec3<R>],
    x: &mut [Vec3<R>],
    tolerance: R,
    reference: R,
    max_iterations: u32,
) -> CgReport<R> {
    let n = b.len();
    let free = |v: &mut [Vec3<R>]| {
        for (e, &f) in v.iter_mut().zip(&system.free) {
            if !f {
                *e = Vec3::zero();
            }
        }
    };
    let mut rhs = b.to_vec();
    free(&mut rhs);
    let b_norm = dot(&rhs, &rhs).sqrt();
    let threshold = tolerance * b_norm.max(reference);
    let mut q = vec![Vec3::zero(); n];
    system.apply(x, &mut q);
    let mut r: Vec<Vec3<R>> = rhs.iter().zip(&q).map(|(&b, &q)| b - q).collect();
    let report = |r: &[Vec3<R>], iterations| CgReport {
        iterations,
        relative_residual: if b_norm > R::zero() { dot(r, r).sqrt() / b_norm } else { dot(r, r).sqrt() },
        rhs_norm: b_norm,
    };
    if dot(&r, &r).sqrt() <= threshold {
        return report(&r, 0);
    }
    let precondition = |r: &[Vec3<R>], z: &mut Vec<Vec3<R>>| {
        z.clear();
        z.extend(r.iter().zip(preconditioner).map(|(&r, m)| m.mul_vec(r)));
    };
    let mut z = Vec::with_capacity(n);
    precondition(&r, &mut z);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    for iteration in 1..=max_iterations {
        system.apply(&p, &mut q);
        let pq = dot(&p, &q);
        if pq <= R::zero() {
            return report(&r, iteration - 1);
        }
        let alpha = rz / pq;
        for k in 0..n {
            if system.free[k] {
                x[k] += p[k] * alpha;
            }
            r[k] -= q[k] * alpha;
        }
        if dot(&r, &r).sqrt() <= threshold {
            return report(&r, iteration);
        }
        precondition(&r, &mut z);
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for k in 0..n {
            p[k] = z[k] + p[k] * beta;
        }
    }
    report(&r, max_iterations)
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

    /// A deterministic, varied vector field: vertex `i`'s entry.
    fn field(i: usize, seed: f64) -> Vec3<f64> {
        let t = i as f64 + seed;
        v((1.3 * t).sin(), (0.7 * t + 1.0).cos(), (2.1 * t).sin() * 0.5)
    }

    /// The system of a 7 × 5 grid of 0.1 m spacing, crumpled (some springs stretched, some
    /// compressed), 0.02 kg a vertex, its first row pinned when `pinned`.
    fn crumpled_cloth(pinned: bool) -> LinearisedStep<f64> {
        let grid = Grid::new(&ClothSpec { resolution: [7, 5], size: [0.6, 0.4], ..Default::default() });
        let x: Vec<Vec3<f64>> =
            grid.positions.iter().enumerate().map(|(i, p)| Vec3::from_f64(*p) + field(i, 0.3) * 0.03).collect();
        let springs = crate::springs::generate(&grid, EffectSet::mass_spring());
        let terms = springs
            .iter()
            .map(|s| {
                let (a, b) = (s.a as usize, s.b as usize);
                let k = [400.0, 200.0, 100.0][s.kind as usize];
                SpringTerms::new(a, b, x[a], x[b], s.rest_length, k, 0.02)
            })
            .collect();
        let n = grid.vertex_count();
        LinearisedStep {
            step: 1e-2,
            masses: vec![0.02; n],
            free: (0..n).map(|i| !pinned || i >= 7).collect(),
            springs: terms,
            // Two vertices pressed into a tilted plane, one of them approaching it.
            contacts: [(10, 0.0), (23, -0.4)]
                .map(|(vertex, approach)| {
                    let normal = v(0.0, 0.8, 0.6);
                    let surface = crate::colliders::Surface { distance: -0.004, normal };
                    ContactTerms {
                        vertex,
                        stiffness: crate::forces::contact_stiffness_block(surface, 2000.0),
                        damping: crate::forces::contact_damping_block(normal * approach, surface, 0.3),
                        pull: Vec3::zero(),
                    }
                })
                .to_vec(),
        }
    }

    #[test]
    fn the_system_is_symmetric_and_positive_definite() {
        let system = crumpled_cloth(false);
        let n = system.masses.len();
        let (p, q): (Vec<_>, Vec<_>) = (0..n).map(|i| (field(i, 0.0), field(i, 5.0))).unzip();
        let (mut ap, mut aq) = (vec![Vec3::zero(); n], vec![Vec3::zero(); n]);
        system.apply(&p, &mut ap);
        system.apply(&q, &mut aq);
        let (pq, qp) = (dot(&p, &aq), dot(&q, &ap));
        assert!((pq - qp).abs() <= 1e-12 * pq.abs().max(1.0), "pᵀAq = {pq}, qᵀAp = {qp}");
        assert!(dot(&p, &ap) > 0.0 && dot(&q, &aq) > 0.0);
        // The springs add to the mass: pᵀAp > pᵀMp for a p that stretches them.
        assert!(dot(&p, &ap) > 0.02 * dot(&p, &p));
    }

    #[test]
    fn conjugate_gradients_solve_the_cloth_system() {
        for pinned in [false, true] {
            let system = crumpled_cloth(pinned);
            let n = system.masses.len();
            let b: Vec<Vec3<f64>> = (0..n).map(|i| field(i, 2.0) * 1e-3).collect();
            let mut x = vec![Vec3::zero(); n];
            let report = conjugate_gradients(&system, &system.block_jacobi(), &b, &mut x, 1e-10, 0.0, 500);
            assert!(report.relative_residual <= 1e-10, "{pinned}: {report:?}");
            assert!(report.iterations > 1 && report.iterations < 3 * n as u32, "{pinned}: {report:?}");
            // The residual it reports is the system's.
            let mut ax = vec![Vec3::zero(); n];
            system.apply(&x, &mut ax);
            for i in 0..n {
                if system.free[i] {
                    assert!((ax[i] - b[i]).length() <= 1e-9 * 1e-3, "{pinned}: vertex {i}");
                } else {
                    assert_eq!(x[i], Vec3::zero(), "{pinned}: a pinned vertex keeps its change");
                }
            }
        }
    }

    #[test]
    fn a_right_hand_side_within_the_tolerance_of_an_earlier_one_takes_no_iteration() {
        let system = crumpled_cloth(false);
        let n = system.masses.len();
        let b: Vec<Vec3<f64>> = (0..n).map(|i| field(i, 2.0) * 1e-3).collect();
        let b_norm = dot(&b, &b).sqrt();
        let solve = |reference: f64| {
            let mut x = vec![Vec3::zero(); n];
            let report = conjugate_gradients(&system, &system.block_jacobi(), &b, &mut x, 1e-4, reference, 500);
            (report, x)
        };
        // Measured against itself (a first Newton iteration), the solve runs.
        let (own, _) = solve(0.0);
        assert!(own.iterations > 1 && own.relative_residual <= 1e-4, "{own:?}");
        assert!((own.rhs_norm - b_norm).abs() <= 1e-12 * b_norm);
        // A later iteration whose |b| is below the tolerance of the substep's first: nothing to do.
        let (later, x) = solve(1.01 * b_norm / 1e-4);
        assert_eq!(later.iterations, 0, "{later:?}");
        assert!(x.iter().all(|e| *e == Vec3::zero()), "the change stays zero");
        // Just above it, the solve runs, and stops at the earlier |b|'s tolerance: fewer
        // iterations than against its own.
        let (coarser, _) = solve(0.5 * b_norm / 1e-4);
        assert!(coarser.iterations >= 1 && coarser.iterations < own.iterations, "{coarser:?} against {own:?}");
    }

    #[test]
    fn one_spring_matches_the_closed_form() {
        // Vertex 0 pinned at the origin, vertex 1 at 0.12 m along x moving at 0.5 m/s, a spring
        // of rest length 0.1 m: along x, A = m + h c + h² k and b = h (f − h k v).
        let (m, k, c, h, rest) = (0.05, 300.0, 0.4, 4e-3, 0.1);
        let (x0, x1, v1) = (v(0.0, 0.0, 0.0), v(0.12, 0.0, 0.0), 0.5);
        let system = LinearisedStep {
            step: h,
            masses: vec![m, m],
            free: vec![false, true],
            springs: vec![SpringTerms::new(0, 1, x0, x1, rest, k, c)],
            contacts: Vec::new(),
        };
        let f = -k * (0.12 - rest) - c * v1;
        let mut kv = vec![Vec3::zero(); 2];
        system.stiffness_times(&[Vec3::zero(), v(v1, 0.0, 0.0)], &mut kv);
        assert!((kv[1].x - k * v1).abs() < 1e-12, "K v at the free end: {:?}", kv[1]);
        let mut drop = vec![Vec3::zero(); 2];
        system.force_drop(&[Vec3::zero(), v(v1, 0.0, 0.0)], &[Vec3::zero(), v(2.0, 0.0, 0.0)], &mut drop);
        assert!((drop[1].x - (k * v1 + c * 2.0)).abs() < 1e-12, "K dx + C dv: {:?}", drop[1]);
        let b = vec![Vec3::zero(), v(h * (f - h * kv[1].x), 0.0, 0.0)];
        let mut dv = vec![Vec3::zero(); 2];
        let report = conjugate_gradients(&system, &system.block_jacobi(), &b, &mut dv, 1e-14, 0.0, 10);
        let expected = h * (f - h * k * v1) / (m + h * c + h * h * k);
        assert!((dv[1].x - expected).abs() < 1e-15, "{} against {expected} ({report:?})", dv[1].x);
        assert!(dv[1].y.abs() < 1e-18 && dv[1].z.abs() < 1e-18);
        // A 1 × 1 system preconditioned by its own inverse: one iteration.
        assert_eq!(report.iterations, 1);
    }
}
