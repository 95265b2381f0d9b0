//! Self-collision: cloth vertices closer than a thickness push each other apart.
//!
//! **The rule** (the `SelfCollision` effect). Two vertices `i`, `j` of the cloth at distance
//! `d = |x_i − x_j|` below the thickness `r` repel each other, unless they are that close at rest
//! (the *rest-distance filter*: grid neighbours, whose springs already hold them, never fight
//! them). With `u = (x_i − x_j) / d` and the relative velocity `v_r = v_i − v_j`, vertex `i` feels
//!
//! ```text
//! F_n = (k_s (r − d) − c_s min(v_r · u, 0)) u              repulsion, and damping of the approach
//! F_t = −min(μ |F_n|, m |v_t| / (2 Δt)) v_t / |v_t|        friction between the layers
//! ```
//!
//! with `v_t = v_r − (v_r · u) u` the sliding velocity; `j` feels the opposite. The friction is
//! Coulomb's, capped at a share of the force that stops the pair's sliding within the substep:
//! each vertex takes half, and a vertex may touch up to [`CONTACTS_PER_VERTEX`] others at once,
//! which together must not overshoot. XPBD treats the rule as the constraint `C = d − r ≥ 0`
//! ([`self_contact_correction`]).
//!
//! **Stability.** Each pair is a spring of stiffness `k_s` that both ends move against; the
//! stability bound ([`crate::stability`]) counts [`CONTACTS_PER_VERTEX`] of them at every
//! vertex.
//!
//! **Why vertex pairs suffice.** A point of a grid triangle is within `Δs/√2` of one of its
//! corners for an unstretched grid of spacing `Δs` (the circumradius of the right triangle), and
//! a point of an edge within `Δs/√2` of an end (a diagonal's half length). An edge crossing a
//! triangle therefore has an end and a corner within `√2 Δs` of each other; a thickness of
//! `1.5 Δs` (the default) keeps every pair that could cross apart, and the rest-distance filter
//! removes only pairs within `1.5 Δs` at rest (neighbours and diagonals), which share a triangle.
//!
//! **The speed limit.** While the effect is on, no free vertex moves more than `s_max Δt` in a
//! substep, nor moves faster than `s_max` ([`limit_speed`]). Two things rest on it: a vertex
//! cannot jump across a layer of thickness `r` in one substep (validation asks
//! `2 s_max Δt ≤ r`), and the spatial hash stays correct between rebuilds.
//!
//! **The spatial hash.** The vertices are sorted into cubic cells of side
//! `h = r + s_max (K + 1) Δt`, rebuilt at the start of every `K`-th substep
//! (`rebuild_interval`). A vertex is listed in the cell of where it was at the rebuild; it
//! queries the 27 cells around where it is now (those that come nearer than `h`). Until the next rebuild a vertex moves at most
//! `s_max K Δt` at the ends of substeps (the speed limit), and the extra substep of margin covers
//! the stage states of velocity Verlet and RK4 inside a substep (whose stage velocities stay near
//! the limited ones). So a pair closer than `r` now was closer than `h` between the query's
//! position and the listed one, and the listed vertex is in one of the 27 cells: the margin
//! `s_max (K + 1) Δt` keeps the hash correct between rebuilds, by construction.
//! The cells are hashed into a table of `T` buckets (a power of two at least the vertex count)
//! and filled by counting sort: counts per bucket, an exclusive prefix sum, a scatter. Each entry
//! keeps its cell's coordinates, so a bucket that two cells share is read once per cell and a
//! vertex found only in its own cell. The GPU builds the same table ([`CellHash`]).

use serde::{Deserialize, Serialize};

use crate::real::{Real, Vec3};
use crate::scene::Scene;

/// How many other vertices one vertex is taken to touch at most at once: about the vertices of
/// another layer within `1.5 Δs`, `π 1.5² ≈ 7`, rounded up. The stability bound counts this many
/// self-contact springs, and the layers' friction gives each contact this share of the stopping
/// force.
pub const CONTACTS_PER_VERTEX: f64 = 8.0;

/// How thick the cloth is for self-collision.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Thickness {
    /// A multiple of the grid spacing (the larger of `Δu`, `Δv`): keeps its meaning when
    /// `--grid` changes the resolution.
    Spacings(f64),
    /// A length, m.
    Meters(f64),
}

/// The parameters of the `SelfCollision` effect (the scene's `self_collision` field).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SelfCollisionSpec {
    /// The distance `r` below which two vertices repel. Default `Spacings(1.5)`.
    pub thickness: Thickness,
    /// Repulsion stiffness `k_s`, N/m. Default 200.
    pub stiffness: f64,
    /// Damping of the approach `c_s`, N·s/m. Default 0.05.
    pub damping: f64,
    /// Friction coefficient `μ` between layers (dimensionless). Default 0.3.
    pub friction: f64,
    /// The speed limit `s_max` of a free vertex while the effect is on, m/s. Default 6.
    pub max_speed: f64,
    /// Substeps between rebuilds of the spatial hash, `K` (at least 1). Default 4.
    pub rebuild_interval: u32,
}

impl Default for SelfCollisionSpec {
    fn default() -> Self {
        Self {
            thickness: Thickness::Spacings(1.5),
            stiffness: 200.0,
            damping: 0.05,
            friction: 0.3,
            max_speed: 6.0,
            rebuild_interval: 4,
        }
    }
}

/// What a substep needs of self-collision, derived once from the scene, SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SelfCollisionQuantities {
    /// Thickness `r`, m.
    pub thickness: f64,
    /// `k_s`, N/m.
    pub stiffness: f64,
    /// `c_s`, N·s/m.
    pub damping: f64,
    /// `μ`.
    pub friction: f64,
    /// `s_max`, m/s.
    pub max_speed: f64,
    /// `K`, substeps.
    pub rebuild_interval: u32,
    /// The hash's cell side `h = r + s_max (K + 1) Δt`, m.
    pub cell: f64,
    /// Buckets of the hash table, `T` (a power of two, at least the vertex count).
    pub buckets: u32,
    /// The grid spacing along u and v, m (the rest distance of `(Δi, Δj)` is
    /// `√((Δi Δu)² + (Δj Δv)²)`).
    pub spacing: [f64; 2],
}

impl SelfCollisionQuantities {
    /// The quantities of `scene`'s `self_collision` field (whether or not the effect is on).
    pub fn of(scene: &Scene) -> Self {
        let s = &scene.self_collision;
        let spacing = scene.cloth.spacing();
        let thickness = match s.thickness {
            Thickness::Spacings(f) => f * spacing[0].max(spacing[1]),
            Thickness::Meters(m) => m,
        };
        let margin = s.max_speed * (s.rebuild_interval + 1) as f64 * scene.substep_dt();
        Self {
            thickness,
            stiffness: s.stiffness,
            damping: s.damping,
            friction: s.friction,
            max_speed: s.max_speed,
            rebuild_interval: s.rebuild_interval,
            cell: thickness + margin,
            buckets: (scene.vertex_count().max(1) as u32).next_power_of_two(),
            spacing,
        }
    }

    /// Whether vertices `a` and `b` of an `nx`-wide grid are at least the thickness apart at
    /// rest (only those pairs repel): `(Δi Δu)² + (Δj Δv)² ≥ r²`.
    pub fn apart_at_rest(&self, a: u32, b: u32, nx: u32) -> bool {
        let di = (a % nx) as f64 - (b % nx) as f64;
        let dj = (a / nx) as f64 - (b / nx) as f64;
        let (du, dv) = (di * self.spacing[0], dj * self.spacing[1]);
        du * du + dv * dv >= self.thickness * self.thickness
    }
}

/// The rest-distance filter as the kernels evaluate it, in `f32` of precision `R`: the squared
/// rest distance of the pair against `r²` (see [`SelfCollisionQuantities::apart_at_rest`]).
pub fn apart_at_rest<R: Real>(a: usize, b: usize, nx: usize, spacing: [R; 2], thickness: R) -> bool {
    let di = R::of((a % nx) as f64) - R::of((b % nx) as f64);
    let dj = R::of((a / nx) as f64) - R::of((b / nx) as f64);
    let (du, dv) = (di * spacing[0], dj * spacing[1]);
    du * du + dv * dv >= thickness * thickness
}

/// The force on vertex `i` at `x_i` moving at `v_i` from vertex `j` at `x_j`, `v_j`, N (the rule
/// of the module documentation); zero at or beyond the thickness `r` and for coincident vertices.
#[allow(clippy::too_many_arguments)]
pub fn repulsion_force<R: Real>(
    x_i: Vec3<R>,
    x_j: Vec3<R>,
    v_i: Vec3<R>,
    v_j: Vec3<R>,
    thickness: R,
    stiffness: R,
    damping: R,
    friction: R,
    mass: R,
    dt: R,
) -> Vec3<R> {
    let delta = x_i - x_j;
    let d2 = delta.dot(delta);
    if d2 >= thickness * thickness || d2 <= R::zero() {
        return Vec3::zero();
    }
    let d = d2.sqrt();
    let u = delta * (R::one() / d);
    let v_r = v_i - v_j;
    let approach = v_r.dot(u);
    let normal = stiffness * (thickness - d) - damping * approach.min(R::zero());
    let mut force = u * normal;
    let v_t = v_r - u * approach;
    let sliding = v_t.length();
    if sliding > R::zero() {
        let stop = mass * sliding / (R::of(2.0 * CONTACTS_PER_VERTEX) * dt);
        force += v_t * (-(stop.min(friction * normal.abs()) / sliding));
    }
    force
}

/// XPBD's correction of free vertex `i` (inverse mass `w_i`) for its contact with vertex `j`
/// (`w_j`, 0 when pinned), m: the constraint `C = |x_i − x_j| − r ≥ 0` projected, `i` taking the
/// share `w_i / (w_i + w_j)` of the depth `r − d` along `u`, and friction removing up to `μ (r − d)`
/// of the pair's relative sliding since the substep's start (`x0_i`, `x0_j`), in the same share.
/// The kernels average the corrections of a vertex's contacts (Jacobi with averaging), so several
/// contacts do not overshoot.
#[allow(clippy::too_many_arguments)]
pub fn self_contact_correction<R: Real>(
    x_i: Vec3<R>,
    x_j: Vec3<R>,
    x0_i: Vec3<R>,
    x0_j: Vec3<R>,
    w_i: R,
    w_j: R,
    thickness: R,
    friction: R,
) -> Option<Vec3<R>> {
    let delta = x_i - x_j;
    let d2 = delta.dot(delta);
    if d2 >= thickness * thickness || d2 <= R::zero() {
        return None;
    }
    let d = d2.sqrt();
    let u = delta * (R::one() / d);
    let depth = thickness - d;
    let share = w_i / (w_i + w_j);
    let mut correction = u * (depth * share);
    let slide = (x_i - x0_i) - (x_j - x0_j);
    let tangential = slide - u * slide.dot(u);
    let length = tangential.length();
    if length > R::zero() {
        correction -= tangential * ((friction * depth).min(length) / length * share);
    }
    Some(correction)
}

/// The speed limit of a free vertex over one substep: a displacement from `x_start` longer than
/// `s_max Δt` is shortened to it, and a velocity faster than `s_max` slowed to it, both keeping
/// their direction. Returns `(x, v)`.
pub fn limit_speed<R: Real>(x_start: Vec3<R>, x: Vec3<R>, v: Vec3<R>, max_speed: R, dt: R) -> (Vec3<R>, Vec3<R>) {
    let step = x - x_start;
    let reach = max_speed * dt;
    let length = step.length();
    let x = if length > reach { x_start + step * (reach / length) } else { x };
    let speed = v.length();
    let v = if speed > max_speed { v * (max_speed / speed) } else { v };
    (x, v)
}

/// Integer coordinates of the hash cell of side `cell` holding `x`: `⌊x / h⌋` per axis.
pub fn cell_of<R: Real>(x: Vec3<R>, cell: R) -> [i32; 3] {
    let inverse = R::one() / cell;
    let c = |a: R| (a * inverse).floor().to_f64_lossy() as i32;
    [c(x.x), c(x.y), c(x.z)]
}

/// The distances from `x` to the low faces of its cell `base` of side `h`, per axis, m (those to
/// the high faces are `h` minus these).
pub fn hash_gaps<R: Real>(x: Vec3<R>, base: [i32; 3], h: R) -> Vec3<R> {
    let low = |c: i32| R::of(c as f64) * h;
    x - Vec3::new(low(base[0]), low(base[1]), low(base[2]))
}

/// Whether the cell at offset `d` (each −1, 0 or 1) from `x`'s comes nearer `x` than the cell
/// side `h`, given `x`'s distances `below` from its cell's low faces: a vertex listed there is
/// farther than `h` from `x`, and between rebuilds a pair closer than the thickness was listed
/// nearer than `h`, so the cell can hold none of `x`'s contacts. About half of the 27 cells
/// around a vertex are out of reach.
pub fn cell_in_reach<R: Real>(below: Vec3<R>, d: [i32; 3], h: R) -> bool {
    let gap = |below: R, d: i32| match d {
        -1 => below,
        1 => h - below,
        _ => R::zero(),
    };
    let e = Vec3::new(gap(below.x, d[0]), gap(below.y, d[1]), gap(below.z, d[2]));
    e.dot(e) < h * h
}

/// The bucket of cell `c` in a table of `buckets` (a power of two): the three coordinates times
/// large primes, combined by exclusive or (wrapping `u32` arithmetic, as the kernels compute it).
pub fn bucket_of(c: [i32; 3], buckets: u32) -> u32 {
    let h = (c[0] as u32).wrapping_mul(73_856_093)
        ^ (c[1] as u32).wrapping_mul(19_349_663)
        ^ (c[2] as u32).wrapping_mul(83_492_791);
    h & (buckets - 1)
}

/// The spatial hash of the cloth's vertices: the table the GPU builds, filled on the CPU by the
/// same counting sort (entries of a bucket in vertex order).
#[derive(Clone, Debug, Default)]
pub struct CellHash {
    /// Cell side `h`, m.
    pub cell: f64,
    /// `start[b]..start[b + 1]` are the entries of bucket `b` (`T + 1` values).
    pub start: Vec<u32>,
    /// Each entry's vertex and the cell it was listed in.
    pub entries: Vec<(u32, [i32; 3])>,
}

impl CellHash {
    /// Sorts `positions` into cells of side `cell` hashed into `buckets` buckets: count, prefix
    /// sum, scatter.
    pub fn build<R: Real>(positions: &[Vec3<R>], cell: f64, buckets: u32) -> Self {
        let h = R::of(cell);
        let cells: Vec<[i32; 3]> = positions.iter().map(|&x| cell_of(x, h)).collect();
        let mut start = vec![0u32; buckets as usize + 1];
        for &c in &cells {
            start[bucket_of(c, buckets) as usize + 1] += 1;
        }
        for b in 0..buckets as usize {
            start[b + 1] += start[b];
        }
        let mut fill = start.clone();
        let mut entries = vec![(0, [0; 3]); positions.len()];
        for (i, &c) in cells.iter().enumerate() {
            let b = bucket_of(c, buckets) as usize;
            entries[fill[b] as usize] = (i as u32, c);
            fill[b] += 1;
        }
        Self { cell, start, entries }
    }

    /// Calls `visit(j)` for every vertex listed in one of the 27 cells around `x`'s cell that
    /// comes nearer `x` than the cell side ([`cell_in_reach`]), each once, in the order the
    /// kernels visit them (cells by `z`, `y`, `x` offset, entries in order).
    pub fn for_each_near<R: Real>(&self, x: Vec3<R>, buckets: u32, mut visit: impl FnMut(usize)) {
        let h = R::of(self.cell);
        let base = cell_of(x, h);
        let [cx, cy, cz] = base;
        let below = hash_gaps(x, base, h);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if !cell_in_reach(below, [dx, dy, dz], h) {
                        continue;
                    }
                    let c = [cx + dx, cy + dy, cz + dz];
                    let b = bucket_of(c, buckets) as usize;
                    for &(j, listed) in &self.entries[self.start[b] as usize..self.start[b + 1] as usize] {
                        if listed == c {
                            visit(j as usize);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f64, y: f64, z: f64) -> Vec3<f64> {
        Vec3::new(x, y, z)
    }

    #[test]
    fn close_vertices_repel_and_far_ones_do_not() {
        let f = repulsion_force(
            v(0., 0., 0.),
            v(0., 0.01, 0.),
            v(0., 0., 0.),
            v(0., 0., 0.),
            0.03,
            100.0,
            0.0,
            0.0,
            1e-3,
            1e-3,
        );
        assert!((f.y + 2.0).abs() < 1e-12, "k (r − d) = 100 × 0.02 = 2 N away from j: {f:?}");
        let f = repulsion_force(
            v(0., 0., 0.),
            v(0., 0.03, 0.),
            v(0., 0., 0.),
            v(0., 0., 0.),
            0.03,
            100.0,
            0.0,
            0.0,
            1e-3,
            1e-3,
        );
        assert_eq!(f, Vec3::zero());
    }

    #[test]
    fn friction_between_layers_is_capped_by_coulomb_and_by_stopping() {
        // Pressed together with 2 N, sliding at 1 m/s: Coulomb allows 0.6 N, stopping needs
        // m v / (2 · 8 Δt) = 0.5 N for m = 8 g.
        let f = repulsion_force(
            v(0., 0., 0.),
            v(0., 0.01, 0.),
            v(1., 0., 0.),
            v(0., 0., 0.),
            0.03,
            100.0,
            0.0,
            0.3,
            8e-3,
            1e-3,
        );
        assert!((f.x + 0.5).abs() < 1e-12, "{f:?}");
        let f = repulsion_force(
            v(0., 0., 0.),
            v(0., 0.01, 0.),
            v(1., 0., 0.),
            v(0., 0., 0.),
            0.03,
            100.0,
            0.0,
            0.3,
            8e-2,
            1e-3,
        );
        assert!((f.x + 0.6).abs() < 1e-12, "{f:?}");
    }

    #[test]
    fn the_speed_limit_shortens_the_step_and_the_velocity() {
        let (x, vel) = limit_speed(v(0., 0., 0.), v(0., -0.5, 0.), v(0., -20., 0.), 10.0, 0.01);
        assert!((x.y + 0.1).abs() < 1e-12 && (vel.y + 10.0).abs() < 1e-12);
        let (x, vel) = limit_speed(v(0., 0., 0.), v(0., -0.05, 0.), v(0., -5., 0.), 10.0, 0.01);
        assert_eq!((x, vel), (v(0., -0.05, 0.), v(0., -5., 0.)));
    }

    #[test]
    fn the_rest_distance_filter_spares_neighbours_and_diagonals_at_one_and_a_half_spacings() {
        let mut scene = Scene::default();
        scene.cloth.resolution = [11, 11];
        scene.cloth.size = [1.0, 1.0];
        let q = SelfCollisionQuantities::of(&scene);
        assert!((q.thickness - 0.15).abs() < 1e-12);
        let at = |i: u32, j: u32| j * 11 + i;
        assert!(!q.apart_at_rest(at(5, 5), at(6, 5), 11));
        assert!(!q.apart_at_rest(at(5, 5), at(6, 6), 11));
        assert!(q.apart_at_rest(at(5, 5), at(7, 5), 11));
        assert!(q.apart_at_rest(at(0, 0), at(10, 0), 11), "the row's ends are far apart");
        let index = |i: u32, j: u32| at(i, j) as usize;
        assert!(!apart_at_rest(index(5, 5), index(6, 6), 11, [0.1f32, 0.1], 0.15));
        assert!(apart_at_rest(index(5, 5), index(7, 5), 11, [0.1f32, 0.1], 0.15));
    }

    /// The hash finds exactly the pairs a search of every pair finds, for vertices that moved by
    /// up to the margin since the rebuild; and misses some when they moved further.
    #[test]
    fn the_hash_finds_every_close_pair_within_its_margin() {
        let (r, margin) = (0.05, 0.02);
        let mut seed = 12345u64;
        let mut random = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let listed: Vec<Vec3<f64>> = (0..600).map(|_| v(random(), random() * 0.3, random())).collect();
        let mut check = |moved_by: f64| -> usize {
            let now: Vec<Vec3<f64>> = listed
                .iter()
                .map(|&x| {
                    let d = v(random(), random(), random());
                    x + d * (moved_by / d.length())
                })
                .collect();
            let hash = CellHash::build(&listed, r + margin, 1024);
            let mut missed = 0;
            for (i, &xi) in now.iter().enumerate() {
                let mut found = Vec::new();
                hash.for_each_near(xi, 1024, |j| found.push(j));
                let mut sorted = found.clone();
                sorted.sort_unstable();
                sorted.dedup();
                assert_eq!(sorted.len(), found.len(), "a vertex is visited once");
                for (j, &xj) in now.iter().enumerate() {
                    if j != i && (xi - xj).length() < r && !found.contains(&j) {
                        missed += 1;
                    }
                }
            }
            missed
        };
        assert_eq!(check(margin * 0.999), 0, "within the margin nothing is missed");
        assert!(check(margin * 3.0) > 0, "beyond it the hash misses pairs (the test can fail)");
    }
}
