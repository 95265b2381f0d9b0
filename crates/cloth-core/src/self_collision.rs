//! Self-collision: cloth vertices closer than a thickness push each other apart.
//!
//! **The rule** (the `SelfCollision` effect). Two vertices `i`, `j` of the cloth at distance
//! `d = |x_i − x_j|` below the thickness `r` repel each other, unless they are that close at rest
//! (the *rest-distance filter*: grid neighbours, whose springs already hold them, never fight
//! them). With `u = (x_i − x_j) / d` and the relative velocity `v_r = v_i − v_j`, vertex `i` feels
//!
//! ```text
//! F_n = (k_s (r − d) − c_s min(v_r · u, 0)) u              repulsion, and damping of the approach
//! F_t = −min(μ |F_n|, m |v_t| / (16 Δt)) v_t / |v_t|       friction between the layers
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
//! substep, nor moves faster than `s_max` ([`limit_speed`]): a vertex cannot jump across a layer
//! of thickness `r` in one substep (validation asks `2 s_max Δt ≤ r`).
//!
//! **Finding the pairs: near and far partners.** The pairs split in two by where they are on the
//! grid, and each vertex sums its repulsions in this order:
//!
//! * *near partners*, within [`NEAR_REACH`] grid steps along both `i` and `j` (a 5 × 5 stencil)
//!   and apart at rest ([`for_each_near_partner`]): read from the grid like the springs, every
//!   substep, row by row;
//! * *far partners*, every other vertex closer than `r` and apart at rest
//!   ([`far_partners`]), in increasing index. A flat or gently curved cloth has none: a vertex
//!   three or more spacings away along the grid is that far away in space unless the cloth
//!   folds or is squeezed to less than `r / 3Δs` of its length.
//!
//! The CPU reference finds the far partners with a spatial hash of cell side `r` built from the
//! state it evaluates ([`CellHash`]). The GPU keeps a list of *candidates* instead, rebuilt only
//! when the cloth has moved enough to make it stale:
//!
//! * at a rebuild, from the positions `X⁰` of that moment, vertex `i`'s candidates are the far
//!   vertices within the *window* `r + W` of it (`W` the `margin`), found with a hash of cell side
//!   `r + W` and kept sorted (at most [`LIST_CAPACITY`]; a vertex with more reads the hash
//!   itself, every substep, until the next rebuild);
//! * a pair that is not a candidate was at least `r + W` apart at the rebuild, so it stays at
//!   least `r` apart as long as no two vertices have moved by more than `W` relative to each
//!   other since: `|x_i − x_j| ≥ |X⁰_i − X⁰_j| − |Δ_i − Δ_j|` with `Δ = x − X⁰`;
//! * each substep bounds that relative motion without a read-back: its kernel takes the extent
//!   `w_k` (maximum less minimum over the cloth) of every vertex's displacement `δ` over the
//!   substep along each of the 13 [`MOTION_DIRECTIONS`] (the axes, the face and the body
//!   diagonals of a cube: a 26-sided bounding polytope), and `|δ_i − δ_j|` is at most
//!   `e = min(√(w_x² + w_y² + w_z²), sec θ · max_k w_k)`: the box's diagonal, or, since every
//!   direction is within `θ` ([`MOTION_COVERING_SECANT`]) of one of the 13 or its opposite, the
//!   widest extent over `cos θ`. Summed over the substeps since the rebuild, `B = Σ e` bounds
//!   `|Δ_i − Δ_j|` for every pair ([`MotionBound`]);
//! * every [`SelfCollisionQuantities::check_interval`] substeps `C`, before the substep, one
//!   invocation compares `B` plus the most the cloth can still move before the next check,
//!   `L = 2 s_max Δt (C − 1 + σ)`, with `W`, and orders a rebuild when they meet
//!   ([`rebuild_due`]; σ = 0 for semi-implicit Euler, whose forces are evaluated at the
//!   substep's start, and 1 for the integrators that evaluate later stage states or iterate, whose
//!   states within a substep are taken to stay within one substep's reach of its start). The
//!   rebuild's dispatches are indirect: their sizes are written on the GPU, zero when no
//!   rebuild is due.
//!
//! `C` is the longest interval (at most [`MAX_CHECK_INTERVAL`]) whose lookahead `L` takes at
//! most half the margin, so a cloth that moves as a whole, falling or swinging, is rebuilt rarely;
//! a cloth whose parts move against each other is rebuilt as often as that motion uses up `W`.
//! Where even one substep's lookahead takes more than half the margin (σ = 1 and `W < 4 s_max Δt`),
//! `C` is 1 and the rest of the margin is all the motion may use: with `L ≥ W` every check
//! rebuilds, which is correct and costs a rebuild a substep.
//! The hash of a rebuild has `T` buckets (a power of two at least the vertex count), each a list
//! of the vertices whose cell falls in it (on the GPU, linked by an atomic exchange of the
//! bucket's head; here, [`CellHash`], sorted by counting).

use serde::{Deserialize, Serialize};

use crate::integrator::Integrator;
use crate::real::{Real, Vec3};
use crate::scene::Scene;

/// How many other vertices one vertex is taken to touch at most at once: about the vertices of
/// another layer within `1.5 Δs`, `π 1.5² ≈ 7`, rounded up. The stability bound counts this many
/// self-contact springs, and the layers' friction gives each contact this share of the stopping
/// force.
pub const CONTACTS_PER_VERTEX: f64 = 8.0;

/// Grid steps along `i` and along `j` within which a pair counts as near partners
/// ([`for_each_near_partner`]), every other pair as far.
pub const NEAR_REACH: usize = 2;

/// The most candidates the GPU keeps for one vertex; a vertex with more reads the hash instead.
/// Lists of 64 remove the overflows of the self-collision bench at 256² but make its frame no
/// faster there and slower at 1024² (docs/performance.md, "What self-collision costs").
pub const LIST_CAPACITY: u32 = 32;

/// The longest interval between two checks of the candidate lists, substeps.
pub const MAX_CHECK_INTERVAL: u32 = 8;

/// The share of the margin kept back for rounding: the lists count as stale once the bound on
/// the relative motion reaches `(1 − MARGIN_ROUNDING) W`.
pub const MARGIN_ROUNDING: f64 = 1.0 / 1024.0;

/// A length that scales with the grid, or a fixed one.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Thickness {
    /// A multiple of the grid spacing (the larger of `Δu`, `Δv`): keeps its meaning when
    /// `--grid` changes the resolution.
    Spacings(f64),
    /// A length, m.
    Meters(f64),
}

impl Thickness {
    /// The length in m on a grid whose larger spacing is `spacing`, m.
    pub fn meters(self, spacing: f64) -> f64 {
        match self {
            Thickness::Spacings(f) => f * spacing,
            Thickness::Meters(m) => m,
        }
    }
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
    /// The margin `W` of the GPU's candidate lists beyond the thickness: how far two vertices may
    /// move relative to each other before the lists are rebuilt. Larger margins rebuild less
    /// often and keep longer lists. Default `Spacings(1.0)`.
    pub margin: Thickness,
}

impl Default for SelfCollisionSpec {
    fn default() -> Self {
        Self {
            thickness: Thickness::Spacings(1.5),
            stiffness: 200.0,
            damping: 0.05,
            friction: 0.3,
            max_speed: 6.0,
            margin: Thickness::Spacings(1.0),
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
    /// The candidate lists' margin `W`, m.
    pub margin: f64,
    /// The candidate window `r + W`, m: the cell side of the GPU's hash.
    pub window: f64,
    /// Substeps between two checks of the candidate lists, `C` (1 to [`MAX_CHECK_INTERVAL`]).
    pub check_interval: u32,
    /// The most two vertices can move relative to each other between a check and the last state
    /// evaluated before the next, `L = 2 s_max Δt (C − 1 + σ)`, m.
    pub lookahead: f64,
    /// Buckets of a hash table, `T` (a power of two, at least the vertex count).
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
        let larger = spacing[0].max(spacing[1]);
        let (thickness, margin) = (s.thickness.meters(larger), s.margin.meters(larger));
        // σ: the states within a substep that the forces or constraints see, in substeps beyond
        // its start.
        let stages = if scene.integrator == Integrator::SemiImplicitEuler { 0.0 } else { 1.0 };
        let relative_step = 2.0 * s.max_speed * scene.substep_dt();
        let lookahead = |c: u32| relative_step * ((c - 1) as f64 + stages);
        let check_interval = (1..=MAX_CHECK_INTERVAL).rev().find(|&c| lookahead(c) <= margin / 2.0).unwrap_or(1);
        Self {
            thickness,
            stiffness: s.stiffness,
            damping: s.damping,
            friction: s.friction,
            max_speed: s.max_speed,
            margin,
            window: thickness + margin,
            check_interval,
            lookahead: lookahead(check_interval),
            buckets: (scene.vertex_count().max(1) as u32).next_power_of_two(),
            spacing,
        }
    }

    /// Whether every check rebuilds the candidate lists whatever the cloth does: the lookahead
    /// alone reaches the margin ([`rebuild_due`] with nothing moved yet), so the lists are rebuilt
    /// every substep. A wider margin, or a lower speed limit, leaves the cloth room to move.
    pub fn every_check_rebuilds(&self) -> bool {
        rebuild_due(0.0, self.lookahead, self.margin)
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

/// Whether vertices `a` and `b` of an `nx`-wide grid are within [`NEAR_REACH`] steps of each
/// other along both grid directions (near partners, when also apart at rest).
pub fn within_near_reach(a: usize, b: usize, nx: usize) -> bool {
    (a % nx).abs_diff(b % nx) <= NEAR_REACH && (a / nx).abs_diff(b / nx) <= NEAR_REACH
}

/// Calls `visit(j)` for each near partner `j` of vertex `i` of an `nx × ny` grid: the vertices
/// within [`NEAR_REACH`] steps along both directions that are apart at rest, row by row
/// (`Δj` from −2 to 2, and within a row `Δi` from −2 to 2), as the kernels visit them.
pub fn for_each_near_partner<R: Real>(
    i: usize,
    nx: usize,
    ny: usize,
    spacing: [R; 2],
    thickness: R,
    mut visit: impl FnMut(usize),
) {
    let reach = NEAR_REACH as isize;
    let (ci, cj) = ((i % nx) as isize, (i / nx) as isize);
    for dj in -reach..=reach {
        for di in -reach..=reach {
            let (ni, nj) = (ci + di, cj + dj);
            if ni < 0 || nj < 0 || ni >= nx as isize || nj >= ny as isize {
                continue;
            }
            let j = nj as usize * nx + ni as usize;
            if apart_at_rest(i, j, nx, spacing, thickness) {
                visit(j);
            }
        }
    }
}

/// The far partners of vertex `i` within `window` of it (m), in increasing index: every vertex
/// of `positions` beyond [`NEAR_REACH`] along the grid, apart at rest and with
/// `|x_i − x_j|² < window²`, found through `hash` (whose cell side must be at least `window`).
/// With `window = r` these are the far vertices that repel `i`; with `window = r + W` at the
/// positions of a rebuild, the GPU's candidates.
#[allow(clippy::too_many_arguments)]
pub fn far_partners<R: Real>(
    hash: &CellHash,
    positions: &[Vec3<R>],
    i: usize,
    nx: usize,
    spacing: [R; 2],
    thickness: R,
    window: R,
) -> Vec<usize> {
    let x = positions[i];
    let mut found = Vec::new();
    hash.for_each_near(x, |j| {
        let d = positions[j] - x;
        if !within_near_reach(i, j, nx) && apart_at_rest(i, j, nx, spacing, thickness) && d.dot(d) < window * window {
            found.push(j);
        }
    });
    found.sort_unstable();
    found
}

/// How a GPU backend's candidate lists fared (`Diagnostics::candidate_lists`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CandidateListStats {
    /// Checks run.
    pub checks: u64,
    /// Rebuilds the checks ordered.
    pub rebuilds: u64,
    /// Lists that did not fit [`LIST_CAPACITY`], over all rebuilds (a vertex's at each rebuild;
    /// its vertex reads the hash instead until the next).
    pub overflowed_lists: u64,
}

/// The directions along which the kernels measure the extent of a substep's displacements: the
/// three axes, the six face diagonals and the four body diagonals of a cube (not normalised).
/// Every unit vector is within [`MOTION_COVERING_SECANT`]'s angle of one of them or its opposite.
pub const MOTION_DIRECTIONS: [[i8; 3]; 13] = [
    [1, 0, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 1, 0],
    [1, -1, 0],
    [1, 0, 1],
    [1, 0, -1],
    [0, 1, 1],
    [0, 1, -1],
    [1, 1, 1],
    [1, 1, -1],
    [1, -1, 1],
    [-1, 1, 1],
];

/// `sec θ`, with `θ` the largest angle between a unit vector and the nearest of
/// ±[`MOTION_DIRECTIONS`]: the vector farthest from them, in the triangle of `(1, 0, 0)`,
/// `(1, 1, 0)/√2` and `(1, 1, 1)/√3`, is equally far from the three,
/// `(1, √2 − 1, √3 − √2)` normalised, at `cos θ = 1/√(9 − 2√2 − 2√6)` (θ ≈ 27.6°). Rounded up.
pub const MOTION_COVERING_SECANT: f64 = 1.128_09;

/// The factor that turns the extent of the displacements along each of [`MOTION_DIRECTIONS`]
/// (the integer direction's own units) into a bound on `|δ_i − δ_j|`: `sec θ / |u_k|`.
pub fn motion_extent_factors() -> [f64; 13] {
    MOTION_DIRECTIONS.map(|u| {
        let length = u.iter().map(|&c| f64::from(c) * f64::from(c)).sum::<f64>().sqrt();
        MOTION_COVERING_SECANT / length
    })
}

/// A displacement's projections on [`MOTION_DIRECTIONS`], m (not normalised: `u_k · δ`).
pub fn motion_projections(d: [f64; 3]) -> [f64; 13] {
    MOTION_DIRECTIONS.map(|u| f64::from(u[0]) * d[0] + f64::from(u[1]) * d[1] + f64::from(u[2]) * d[2])
}

/// The most two vertices can have moved relative to each other in a substep whose displacements'
/// projections on [`MOTION_DIRECTIONS`] span `extents` (maximum less minimum, m):
/// `e = min(√(w_x² + w_y² + w_z²), max_k sec θ w_k / |u_k|)` (the module documentation).
pub fn relative_motion_bound(extents: [f64; 13]) -> f64 {
    let diagonal = (extents[0] * extents[0] + extents[1] * extents[1] + extents[2] * extents[2]).sqrt();
    let polytope = (extents.iter().zip(motion_extent_factors())).map(|(w, f)| w * f).fold(0.0, f64::max);
    diagonal.min(polytope)
}

/// The bound `B` on how far any two vertices have moved relative to each other since the
/// candidate lists were built (see the module documentation), as the GPU keeps it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionBound {
    /// `B`, m.
    pub bound: f64,
}

impl MotionBound {
    /// Adds `substeps` substeps whose displacements' projections on [`MOTION_DIRECTIONS`] span
    /// `extents` (m): each adds at most [`relative_motion_bound`] to `|Δ_i − Δ_j|`.
    pub fn add(&mut self, extents: [f64; 13], substeps: u32) {
        self.bound += substeps as f64 * relative_motion_bound(extents);
    }
}

/// Whether the candidate lists must be rebuilt before the next substep: when the motion since
/// the rebuild, `bound`, plus the most the cloth can still move before the next check,
/// `lookahead`, may exceed the margin (less its rounding share, [`MARGIN_ROUNDING`]). A bound that
/// is not a number (a state that is not) always rebuilds.
pub fn rebuild_due(bound: f64, lookahead: f64, margin: f64) -> bool {
    let within = (bound + lookahead).partial_cmp(&(margin * (1.0 - MARGIN_ROUNDING)));
    !matches!(within, Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal))
}

/// The key of `f` whose unsigned order is the order of the numbers (negative numbers' bits
/// inverted, the others' sign bit set): the kernels keep the extents of the displacements with
/// `atomicMax` on keys, and on inverted keys for the minimum. Key 0 means nothing recorded.
pub fn order_key(f: f32) -> u32 {
    let bits = f.to_bits();
    if bits & 0x8000_0000 != 0 { !bits } else { bits | 0x8000_0000 }
}

/// The number whose [`order_key`] is `key`.
pub fn from_order_key(key: u32) -> f32 {
    f32::from_bits(if key & 0x8000_0000 != 0 { key & 0x7fff_ffff } else { !key })
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
/// nearer than `h`, so the cell can hold none of `x`'s contacts. The 6 cells that share a face
/// with `x`'s are always in reach; of the 20 others about 6 are out of reach, on average.
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

/// A spatial hash of the cloth's vertices: each bucket's vertices (in vertex order), sorted into
/// buckets by counting (counts per bucket, an exclusive prefix sum, a scatter).
#[derive(Clone, Debug, Default)]
pub struct CellHash {
    /// Cell side `h`, m.
    pub cell: f64,
    /// Buckets `T`, a power of two.
    pub buckets: u32,
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
        Self { cell, buckets, start, entries }
    }

    /// Calls `visit(j)` for every vertex listed in one of the 27 cells around `x`'s cell that
    /// comes nearer `x` than the cell side ([`cell_in_reach`]), each once: cells by `z`, `y`, `x`
    /// offset, entries in order. Every vertex within the cell side of `x` is among them.
    pub fn for_each_near<R: Real>(&self, x: Vec3<R>, mut visit: impl FnMut(usize)) {
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
                    let b = bucket_of(c, self.buckets) as usize;
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

    /// The hash finds every pair within its cell side.
    #[test]
    fn the_hash_finds_every_pair_within_its_cell() {
        let (h, n) = (0.05, 600);
        let mut random = random_numbers(12345);
        let points: Vec<Vec3<f64>> = (0..n).map(|_| v(random(), random() * 0.3, random())).collect();
        let hash = CellHash::build(&points, h, 1024);
        for (i, &xi) in points.iter().enumerate() {
            let mut found = Vec::new();
            hash.for_each_near(xi, |j| found.push(j));
            let mut sorted = found.clone();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), found.len(), "a vertex is visited once");
            for (j, &xj) in points.iter().enumerate() {
                if (xi - xj).length() < h {
                    assert!(found.contains(&j), "{i} and {j} are {} apart", (xi - xj).length());
                }
            }
        }
    }

    /// A pseudo-random sequence in [−0.5, 0.5).
    fn random_numbers(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        }
    }

    /// An `n × n` grid of spacing `s` crumpled into a ball: every vertex moved by up to `3 s` at
    /// random, so that many pairs far apart on the grid come close.
    fn crumpled(n: usize, s: f64, seed: u64) -> Vec<Vec3<f64>> {
        let mut random = random_numbers(seed);
        (0..n * n)
            .map(|k| {
                let (i, j) = ((k % n) as f64, (k / n) as f64);
                v(i * s * 0.3 + 6.0 * s * random(), j * s * 0.3 + 6.0 * s * random(), 6.0 * s * random())
            })
            .collect()
    }

    /// Near and far partners together are exactly the pairs a search of every pair finds closer
    /// than the thickness and apart at rest, each once.
    #[test]
    fn near_and_far_partners_are_every_close_pair_once() {
        let (n, s) = (20, 0.01);
        let r = 1.5 * s;
        let x = crumpled(n, s, 7);
        let hash = CellHash::build(&x, r, 512);
        let mut far_pairs = 0;
        for i in 0..n * n {
            let mut found = Vec::new();
            for_each_near_partner(i, n, n, [s, s], r, |j| {
                if (x[i] - x[j]).length() < r {
                    found.push(j);
                }
            });
            let far = far_partners(&hash, &x, i, n, [s, s], r, r);
            far_pairs += far.len();
            assert!(far.windows(2).all(|w| w[0] < w[1]), "far partners in increasing index");
            found.extend(far);
            let mut expected: Vec<usize> =
                (0..n * n).filter(|&j| (x[i] - x[j]).length() < r && apart_at_rest(i, j, n, [s, s], r)).collect();
            expected.sort_unstable();
            found.sort_unstable();
            assert_eq!(found, expected, "vertex {i}");
        }
        assert!(far_pairs > 100, "the crumpled grid has far contacts ({far_pairs})");
    }

    /// The GPU's candidate lists: built at `X⁰` with the window `r + W`, they hold every far pair
    /// closer than `r` at any later state whose relative motion stays within the margin `W`; the
    /// test can fail: with three times the motion, pairs are missed.
    #[test]
    fn candidate_lists_hold_every_far_contact_within_the_margin() {
        let (n, s) = (20, 0.01);
        let (r, w) = (1.5 * s, 1.0 * s);
        let rebuild = crumpled(n, s, 99);
        let hash = CellHash::build(&rebuild, r + w, 512);
        let lists: Vec<Vec<usize>> =
            (0..n * n).map(|i| far_partners(&hash, &rebuild, i, n, [s, s], r, r + w)).collect();
        let mut random = random_numbers(5);
        let mut missed_after = |relative: f64| -> usize {
            // Each vertex moves by at most half the relative motion, so two move apart by at most it.
            let now: Vec<Vec3<f64>> = rebuild
                .iter()
                .map(|&x| {
                    let d = v(random(), random(), random());
                    x + d * (0.5 * relative / d.length())
                })
                .collect();
            let hash_now = CellHash::build(&now, r, 512);
            (0..n * n)
                .map(|i| {
                    far_partners(&hash_now, &now, i, n, [s, s], r, r).iter().filter(|j| !lists[i].contains(j)).count()
                })
                .sum()
        };
        assert_eq!(missed_after(w * (1.0 - MARGIN_ROUNDING)), 0, "within the margin nothing is missed");
        assert!(missed_after(3.0 * w) > 0, "beyond it pairs are missed (the test can fail)");
    }

    #[test]
    fn the_motion_bound_adds_each_substeps_bound_and_a_rebuild_is_due_at_the_margin() {
        let extents = |displacements: &[[f64; 3]]| {
            let projections: Vec<[f64; 13]> = displacements.iter().map(|&d| motion_projections(d)).collect();
            std::array::from_fn(|k| {
                let along = projections.iter().map(|p| p[k]);
                along.clone().fold(f64::MIN, f64::max) - along.fold(f64::MAX, f64::min)
            })
        };
        // Displacements along an axis: the box's diagonal, exactly.
        let mut b = MotionBound::default();
        b.add(extents(&[[0.0, -1e-3, 0.0], [0.0, 4e-3, 0.0]]), 2);
        assert!((b.bound - 1e-2).abs() < 1e-15, "2 × 5 mm: {}", b.bound);
        // Eight displacements at the corners of a cube of side 2 mm: the box's diagonal is the
        // cube's, 2√3 mm; the widest extent (along a body diagonal) gives sec θ · 2√3 mm, so
        // the diagonal holds.
        let corners: Vec<[f64; 3]> =
            (0..8).map(|c| [0, 1, 2].map(|k| if c >> k & 1 == 1 { 1e-3 } else { -1e-3 })).collect();
        assert!((relative_motion_bound(extents(&corners)) - 2e-3 * 3f64.sqrt()).abs() < 1e-15);
        // Displacements spread in a disc of radius 1 mm in the xz plane: the box's diagonal is
        // 2√2 mm, the polytope's bound at most sec θ · 2 mm, much nearer the diameter, 2 mm.
        let disc: Vec<[f64; 3]> =
            (0..360).map(|a| f64::from(a).to_radians()).map(|a| [1e-3 * a.cos(), 0.0, 1e-3 * a.sin()]).collect();
        let e = relative_motion_bound(extents(&disc));
        assert!((2e-3 * (1.0 - 1e-12)..=MOTION_COVERING_SECANT * 2e-3 * (1.0 + 1e-12)).contains(&e), "{e}");
        assert!(e < 0.8 * 2e-3 * 2f64.sqrt(), "{e}: well under the box's diagonal");
        let mut b = MotionBound::default();
        b.add(extents(&[[0.0, -1e-3, 0.0], [3e-3, 3e-3, 0.0]]), 2);
        assert!((b.bound - 1e-2).abs() < 1e-15, "2 × |(3, 4, 0)| mm: {}", b.bound);
        assert!(!rebuild_due(b.bound, 0.005, 0.016));
        assert!(rebuild_due(b.bound, 0.006, 0.016));
        assert!(rebuild_due(f64::NAN, 0.0, 1.0), "a state that is not a number rebuilds");
    }

    #[test]
    fn every_direction_is_within_the_covering_angle_and_the_bound_holds_every_pair() {
        let mut random = random_numbers(17);
        let factors = motion_extent_factors();
        let mut nearest_worst: f64 = 1.0;
        for _ in 0..100_000 {
            let d = [random(), random(), random()];
            let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            // |u_k · d| / |u_k| / |d|: the cosine to the nearest direction or its opposite.
            let nearest = (motion_projections(d).iter().zip(factors))
                .map(|(p, f)| p.abs() * f / MOTION_COVERING_SECANT / length)
                .fold(0.0, f64::max);
            nearest_worst = nearest_worst.min(nearest);
        }
        assert!(nearest_worst >= 1.0 / MOTION_COVERING_SECANT, "{nearest_worst}");
        assert!(nearest_worst < 1.0 / MOTION_COVERING_SECANT + 2e-3, "the angle is not far from the worst");
        for _ in 0..200 {
            let set: Vec<[f64; 3]> = (0..12).map(|_| [random(), 0.3 * random(), random()]).collect();
            let projections: Vec<[f64; 13]> = set.iter().map(|&d| motion_projections(d)).collect();
            let extents = std::array::from_fn(|k| {
                let along = projections.iter().map(|p| p[k]);
                along.clone().fold(f64::MIN, f64::max) - along.fold(f64::MAX, f64::min)
            });
            let e = relative_motion_bound(extents);
            for a in &set {
                for b in &set {
                    let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
                    assert!(d <= e * (1.0 + 1e-12), "{d} > {e}");
                }
            }
        }
    }

    #[test]
    fn order_keys_order_like_the_numbers() {
        let values = [-3.5f32, -1e-30, -0.0, 0.0, 1e-30, 2.0, 7e20];
        for pair in values.windows(2) {
            assert!(order_key(pair[0]) <= order_key(pair[1]), "{pair:?}");
            assert!(!order_key(pair[0]) >= !order_key(pair[1]), "inverted keys order the other way");
        }
        for &x in &values {
            assert_eq!(from_order_key(order_key(x)).to_bits(), x.to_bits());
            assert_ne!(order_key(x), 0, "0 means nothing recorded");
        }
    }

    #[test]
    fn the_check_interval_leaves_half_the_margin_to_the_measured_motion() {
        let mut scene = Scene::default();
        scene.cloth.resolution = [101, 101];
        scene.cloth.size = [1.0, 1.0];
        scene.self_collision.max_speed = 3.0;
        scene.time.substeps = crate::scene::Substeps::Fixed(64);
        let q = SelfCollisionQuantities::of(&scene);
        let relative_step = 2.0 * 3.0 * scene.substep_dt();
        assert!((q.margin - 0.01).abs() < 1e-12 && (q.window - 0.025).abs() < 1e-12);
        assert!(q.lookahead <= q.margin / 2.0);
        assert!(q.check_interval == MAX_CHECK_INTERVAL || relative_step * q.check_interval as f64 > q.margin / 2.0);
        assert_eq!(q.lookahead, relative_step * (q.check_interval - 1) as f64, "Euler evaluates the substep's start");
        scene.integrator = Integrator::RungeKutta4;
        let rk4 = SelfCollisionQuantities::of(&scene);
        assert_eq!(rk4.lookahead, relative_step * rk4.check_interval as f64, "RK4's stages reach one substep further");
        assert!(!q.every_check_rebuilds() && !rk4.every_check_rebuilds());
        // A margin below one substep's relative step: RK4's lookahead alone reaches it, Euler's
        // (which looks no further than the substep's start at C = 1) does not.
        scene.self_collision.margin = Thickness::Meters(0.5 * relative_step);
        assert!(SelfCollisionQuantities::of(&scene).every_check_rebuilds());
        scene.integrator = Integrator::SemiImplicitEuler;
        assert!(!SelfCollisionQuantities::of(&scene).every_check_rebuilds());
    }
}
