//! Self-intersections of the cloth: cloth edges that pass through a cloth triangle they are not
//! part of. A simulator without self-collision lets a folding cloth pass through itself; this
//! counts where it did, so that it is measured rather than assumed away.
//!
//! **The mesh.** Cell `(i, j)` of the `nx × ny` grid, with corners `a = (i, j)`, `b = (i+1, j)`,
//! `c = (i+1, j+1)`, `d = (i, j+1)`, is split along its diagonal `a–c` into the triangles
//! `(a, b, c)` and `(a, c, d)`, as [`Grid::triangle_indices`](crate::grid::Grid::triangle_indices)
//! and the OBJ export ([`crate::export`]) split it. Its edges are the cell sides and that diagonal.
//!
//! **The test.** An edge `pq` crosses a triangle `abc` that shares no vertex with it when `p` and
//! `q` lie strictly on opposite sides of the triangle's plane and the line `pq` passes strictly
//! inside the triangle:
//!
//! ```text
//! sign orient(a, b, c, p) = −sign orient(a, b, c, q) ≠ 0, and
//! sign orient(p, q, a, b) = sign orient(p, q, b, c) = sign orient(p, q, c, a) ≠ 0,
//! ```
//!
//! where `orient` is the signed volume of a tetrahedron, evaluated exactly on the `f32`
//! positions (Shewchuk's adaptive predicates, the `robust` crate): no rounding can make or hide
//! a crossing. A contact that only touches (an edge lying in the plane, a vertex on an edge) is
//! not a crossing; a flat cloth has none. Edges and triangles with a non-finite vertex are
//! skipped.
//!
//! **The search.** Triangles are put in a uniform grid of cells the size of the mean edge length
//! (a spatial hash, filled by counting sort),
//! and each edge is tested against the triangles of the cells its bounding box touches: about
//! linear in the vertex count for a cloth of roughly even edges. A primitive whose box spans more
//! than [`LARGE_SPAN_CELLS`] cells on an axis (a stretched spring) is tested against every
//! primitive of the other kind instead. A cloth torn apart by an unstable step, whose stretched
//! edges would need more than [`MAX_TESTS_PER_EDGE`] tests an edge on average, is not counted
//! ([`TooTangled`]): its count would take hours and mean nothing.

use rayon::prelude::*;
use robust::{Coord3D, orient3d};

/// Boxes that span more cells than this on an axis are tested by brute force.
pub const LARGE_SPAN_CELLS: i64 = 8;

/// Most segment–triangle tests [`crossings`] runs per edge of the cloth, on average. A cloth at
/// rest or folding needs some tens; one whose edges are stretched across it needs up to the
/// triangle count.
pub const MAX_TESTS_PER_EDGE: usize = 256;

/// The cloth is stretched so far that counting its self-intersections would take more tests
/// than [`MAX_TESTS_PER_EDGE`] allows.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "not counted: the cloth's edges are stretched across it ({tests:.3e} segment-triangle tests, more than the \
     {limit:.3e} allowed); the step is probably unstable"
)]
pub struct TooTangled {
    /// The tests the count would take.
    pub tests: f64,
    /// The tests allowed.
    pub limit: f64,
}

/// The triangles of the grid, two per cell, `(a, b, c)` and `(a, c, d)`.
pub fn triangles(nx: u32, ny: u32) -> Vec<[u32; 3]> {
    let mut out = Vec::with_capacity(2 * nx.saturating_sub(1) as usize * ny.saturating_sub(1) as usize);
    for j in 0..ny.saturating_sub(1) {
        for i in 0..nx.saturating_sub(1) {
            let (a, b, c, d) = (j * nx + i, j * nx + i + 1, (j + 1) * nx + i + 1, (j + 1) * nx + i);
            out.push([a, b, c]);
            out.push([a, c, d]);
        }
    }
    out
}

/// The edges of the grid's triangles: along `u`, along `v`, and each cell's diagonal `a–c`.
pub fn edges(nx: u32, ny: u32) -> Vec<[u32; 2]> {
    let mut out = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let k = j * nx + i;
            if i + 1 < nx {
                out.push([k, k + 1]);
            }
            if j + 1 < ny {
                out.push([k, k + nx]);
            }
            if i + 1 < nx && j + 1 < ny {
                out.push([k, k + nx + 1]);
            }
        }
    }
    out
}

/// One edge passing through one triangle: indices into [`edges`] and [`triangles`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Crossing {
    /// The edge, an index into [`edges`].
    pub edge: u32,
    /// The triangle, an index into [`triangles`].
    pub triangle: u32,
}

fn coord(p: [f32; 3]) -> Coord3D<f64> {
    Coord3D { x: p[0] as f64, y: p[1] as f64, z: p[2] as f64 }
}

/// Whether segment `pq` passes strictly through triangle `abc` (see the module's documentation).
pub fn segment_crosses_triangle(p: [f32; 3], q: [f32; 3], a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> bool {
    let (p, q, a, b, c) = (coord(p), coord(q), coord(a), coord(b), coord(c));
    let (sp, sq) = (orient3d(a, b, c, p), orient3d(a, b, c, q));
    if sp == 0.0 || sq == 0.0 || (sp > 0.0) == (sq > 0.0) {
        return false;
    }
    let s = [orient3d(p, q, a, b), orient3d(p, q, b, c), orient3d(p, q, c, a)];
    s.iter().all(|&x| x > 0.0) || s.iter().all(|&x| x < 0.0)
}

/// Whether the boxes of a segment and a triangle leave room for a crossing, exactly (it only
/// compares coordinates). A crossing point lies strictly inside both, so on each axis the two
/// ranges must meet, and where both have a length, overlap over a length: grid neighbours that
/// only touch (most of a flat or gently curved cloth's candidates) are rejected without the
/// orientation tests, which are slow on exactly coplanar points.
fn boxes_admit_a_crossing(segment: &[[f32; 3]; 2], triangle: &[[f32; 3]; 3]) -> bool {
    (0..3).all(|k| {
        let range = |points: &[[f32; 3]]| {
            points.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| (lo.min(p[k]), hi.max(p[k])))
        };
        let ((s_lo, s_hi), (t_lo, t_hi)) = (range(segment), range(triangle));
        let (lo, hi) = (s_lo.max(t_lo), s_hi.min(t_hi));
        if s_lo < s_hi && t_lo < t_hi { lo < hi } else { lo <= hi }
    })
}

/// Whether edge `e` and triangle `t` share a vertex (then a crossing is not a self-intersection).
fn adjacent(e: [u32; 2], t: [u32; 3]) -> bool {
    t.contains(&e[0]) || t.contains(&e[1])
}

/// A primitive's box in cells, lowest and highest corner, and whether it spans more than
/// [`LARGE_SPAN_CELLS`] on an axis; `None` for a primitive with a non-finite vertex.
type CellBox = Option<([i64; 3], [i64; 3], bool)>;

/// The bucket of cell `c` in a table of `mask + 1` buckets (a spatial hash: distinct cells can
/// share a bucket, which only adds candidates).
fn bucket(c: [i64; 3], mask: usize) -> usize {
    let h = (c[0] as u64).wrapping_mul(73_856_093)
        ^ (c[1] as u64).wrapping_mul(19_349_663)
        ^ (c[2] as u64).wrapping_mul(83_492_791);
    (h ^ (h >> 29)) as usize & mask
}

/// Every cell of the box `lo..=hi`.
fn cells(lo: [i64; 3], hi: [i64; 3]) -> impl Iterator<Item = [i64; 3]> {
    (lo[0]..=hi[0]).flat_map(move |x| (lo[1]..=hi[1]).flat_map(move |y| (lo[2]..=hi[2]).map(move |z| [x, y, z])))
}

/// Every crossing of the cloth `positions` (an `nx × ny` grid, row by row), sorted.
///
/// # Errors
/// [`TooTangled`] when the count would take more than [`MAX_TESTS_PER_EDGE`] tests an edge.
///
/// # Panics
/// If `positions` does not hold `nx · ny` vertices.
pub fn crossings(positions: &[[f32; 3]], nx: u32, ny: u32) -> Result<Vec<Crossing>, TooTangled> {
    assert_eq!(positions.len(), nx as usize * ny as usize, "positions of an {nx} x {ny} grid");
    let (tris, edges) = (triangles(nx, ny), edges(nx, ny));
    let at = |k: u32| positions[k as usize];
    let finite = |k: u32| at(k).iter().all(|x| x.is_finite());
    let finite_edge = |e: &[u32; 2]| finite(e[0]) && finite(e[1]);
    let (sum, n) = edges.iter().filter(|e| finite_edge(e)).fold((0.0f64, 0usize), |(s, n), e| {
        let (p, q) = (at(e[0]), at(e[1]));
        (s + (0..3).map(|k| (p[k] as f64 - q[k] as f64).powi(2)).sum::<f64>().sqrt(), n + 1)
    });
    let mean_edge = sum / n.max(1) as f64;
    if n == 0 || mean_edge <= 0.0 || !mean_edge.is_finite() {
        return Ok(Vec::new());
    }
    // Cells of the mean edge's size; a primitive's cell box, and whether it is too large for
    // cells.
    let cell = |x: f32| (x as f64 / mean_edge).floor() as i64;
    let bounds = |vertices: &[u32]| {
        let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
        for &v in vertices {
            for k in 0..3 {
                let c = cell(at(v)[k]);
                (lo[k], hi[k]) = (lo[k].min(c), hi[k].max(c));
            }
        }
        let large = (0..3).any(|k| hi[k].saturating_sub(lo[k]) > LARGE_SPAN_CELLS);
        (lo, hi, large)
    };
    // The triangles by bucket, by counting sort: count each bucket's entries, take the prefix
    // sums as starts, scatter.
    let tri_bounds: Vec<CellBox> = tris.par_iter().map(|t| t.iter().all(|&v| finite(v)).then(|| bounds(t))).collect();
    let entries: usize = tri_bounds
        .iter()
        .flatten()
        .filter(|b| !b.2)
        .map(|(lo, hi, _)| (0..3).map(|k| (hi[k] - lo[k] + 1) as usize).product::<usize>())
        .sum();
    let mask = (2 * entries.max(1)).next_power_of_two() - 1;
    let mut starts = vec![0u32; mask + 2];
    for (lo, hi, _) in tri_bounds.iter().flatten().filter(|b| !b.2) {
        for c in cells(*lo, *hi) {
            starts[bucket(c, mask) + 1] += 1;
        }
    }
    for k in 1..starts.len() {
        starts[k] += starts[k - 1];
    }
    let mut items = vec![0u32; entries];
    let mut fill = starts.clone();
    let mut large_triangles = Vec::new();
    for (t, b) in tri_bounds.iter().enumerate() {
        match b {
            Some((_, _, true)) => large_triangles.push(t as u32),
            Some((lo, hi, false)) => {
                for c in cells(*lo, *hi) {
                    let slot = &mut fill[bucket(c, mask)];
                    items[*slot as usize] = t as u32;
                    *slot += 1;
                }
            }
            None => {}
        }
    }
    let all_triangles: Vec<u32> = (0..tris.len() as u32).filter(|&t| tri_bounds[t as usize].is_some()).collect();
    let in_bucket = |c: [i64; 3]| {
        let b = bucket(c, mask);
        &items[starts[b] as usize..starts[b + 1] as usize]
    };
    let edge_bounds: Vec<CellBox> = edges.par_iter().map(|e| finite_edge(e).then(|| bounds(e))).collect();
    // The tests the search will run, before it runs them.
    let tests: usize = edge_bounds
        .par_iter()
        .flatten()
        .map(|(lo, hi, large)| {
            if *large {
                all_triangles.len()
            } else {
                large_triangles.len() + cells(*lo, *hi).map(|c| in_bucket(c).len()).sum::<usize>()
            }
        })
        .reduce(|| 0, usize::saturating_add);
    let limit = MAX_TESTS_PER_EDGE.saturating_mul(edges.len());
    if tests > limit {
        return Err(TooTangled { tests: tests as f64, limit: limit as f64 });
    }
    let crosses = |e: usize, t: u32| {
        let (edge, tri) = (edges[e], tris[t as usize]);
        let (p, q, a, b, c) = (at(edge[0]), at(edge[1]), at(tri[0]), at(tri[1]), at(tri[2]));
        !adjacent(edge, tri) && boxes_admit_a_crossing(&[p, q], &[a, b, c]) && segment_crosses_triangle(p, q, a, b, c)
    };
    let mut found: Vec<Crossing> = edge_bounds
        .par_iter()
        .enumerate()
        .fold(Vec::new, |mut found, (e, b)| {
            let Some((lo, hi, large)) = *b else { return found };
            let mut test = |t: u32| {
                if crosses(e, t) {
                    found.push(Crossing { edge: e as u32, triangle: t });
                }
            };
            if large {
                all_triangles.iter().for_each(|&t| test(t));
                return found;
            }
            large_triangles.iter().for_each(|&t| test(t));
            for c in cells(lo, hi) {
                for &t in in_bucket(c) {
                    let Some((t_lo, t_hi, false)) = tri_bounds[t as usize] else { continue };
                    // Each pair once: in the cell where the two boxes' overlap begins (a pair that
                    // shares a bucket but not a cell has no such cell among the edge's).
                    let overlap = (0..3).all(|k| t_lo[k] <= hi[k] && lo[k] <= t_hi[k]);
                    if overlap && (0..3).all(|k| c[k] == lo[k].max(t_lo[k])) {
                        test(t);
                    }
                }
            }
            found
        })
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    // A triangle in two cells of one bucket is met twice in that bucket.
    found.sort_unstable();
    found.dedup();
    Ok(found)
}

/// How many crossings the cloth `positions` has ([`crossings`]).
///
/// # Errors
/// [`TooTangled`], as [`crossings`].
pub fn count(positions: &[[f32; 3]], nx: u32, ny: u32) -> Result<usize, TooTangled> {
    crossings(positions, nx, ny).map(|c| c.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every edge against every triangle, with no acceleration: the counter's oracle.
    fn brute_force(positions: &[[f32; 3]], nx: u32, ny: u32) -> Vec<Crossing> {
        let (tris, edges) = (triangles(nx, ny), edges(nx, ny));
        let at = |k: u32| positions[k as usize];
        let mut out = Vec::new();
        for (e, edge) in edges.iter().enumerate() {
            for (t, tri) in tris.iter().enumerate() {
                if !adjacent(*edge, *tri)
                    && segment_crosses_triangle(at(edge[0]), at(edge[1]), at(tri[0]), at(tri[1]), at(tri[2]))
                {
                    out.push(Crossing { edge: e as u32, triangle: t as u32 });
                }
            }
        }
        out
    }

    fn flat(nx: u32, ny: u32) -> Vec<[f32; 3]> {
        (0..ny).flat_map(|j| (0..nx).map(move |i| [i as f32 * 0.1, j as f32 * 0.1, 0.0])).collect()
    }

    #[test]
    fn the_mesh_has_two_triangles_a_cell_and_their_edges() {
        let (t, e) = (triangles(4, 3), edges(4, 3));
        assert_eq!((t.len(), e.len()), (2 * 3 * 2, 3 * 3 + 4 * 2 + 3 * 2));
        assert_eq!(t[0..2], [[0, 1, 5], [0, 5, 4]]);
        // Every triangle's three edges are edges of the mesh.
        for tri in t {
            for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
                assert!(e.contains(&[a.min(b), a.max(b)]), "{tri:?}");
            }
        }
    }

    #[test]
    fn a_segment_through_a_triangle_crosses_it_and_a_touching_one_does_not() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert!(segment_crosses_triangle([0.2, 0.2, -1.0], [0.2, 0.2, 1.0], a, b, c));
        assert!(!segment_crosses_triangle([0.8, 0.8, -1.0], [0.8, 0.8, 1.0], a, b, c), "outside");
        assert!(!segment_crosses_triangle([0.2, 0.2, 0.5], [0.2, 0.2, 1.0], a, b, c), "one side");
        assert!(!segment_crosses_triangle([0.2, 0.2, 0.0], [0.2, 0.2, 1.0], a, b, c), "ends on it");
        assert!(!segment_crosses_triangle([0.5, 0.0, -1.0], [0.5, 0.0, 1.0], a, b, c), "through its edge");
        assert!(!segment_crosses_triangle([-1.0, 0.2, 0.0], [2.0, 0.2, 0.0], a, b, c), "in its plane");
    }

    #[test]
    fn a_flat_cloth_has_none() {
        assert_eq!(count(&flat(16, 12), 16, 12), Ok(0));
    }

    /// A 6 × 2 strip: columns 0-2 lie flat on z = 0 over x ∈ [0, 1], column 3 is far away, and
    /// columns 4-5 stand across that flat part at x = 0.3, from z = 1 down to z = −1. Three of
    /// their edges pierce it: the edge of row y = 0.2 at (0.3, 0.2), below the first cell's
    /// diagonal y = 2x (triangle 0), the edge of row y = 0.8 at (0.3, 0.8), above it (triangle
    /// 1), and the diagonal between them at (0.3, 0.5), below it (triangle 0). Where two sheets
    /// cross, edges of each pierce the other: the flat cell's diagonal y = 2x meets x = 0.3 at
    /// (0.3, 0.6, 0), inside the standing cell's triangle (4, 11, 10) (triangle 9), whose
    /// boundary at y = 0.6 runs from z = −1/3 to z = 1.
    fn pierced_strip() -> Vec<[f32; 3]> {
        let columns: [([f32; 2], f32); 6] = [
            ([0.0, 0.0], 0.0),
            ([0.5, 0.0], 0.0),
            ([1.0, 0.0], 0.0),
            ([5.0, 0.0], 5.0),
            ([0.3, 0.0], 1.0),
            ([0.3, 0.0], -1.0),
        ];
        let row_y = [0.2f32, 0.8];
        let mut p = vec![[0.0; 3]; 12];
        for (i, ([x, _], z)) in columns.iter().enumerate() {
            for (j, y) in [0.0f32, 1.0].iter().enumerate() {
                // The flat part spans y ∈ [0, 1]; the standing part is at y = 0.2 and 0.8.
                let y = if i >= 4 { row_y[j] } else { *y };
                p[j * 6 + i] = [*x, y, *z];
            }
        }
        p
    }

    #[test]
    fn a_strip_through_itself_has_the_crossings_counted_by_hand() {
        let p = pierced_strip();
        let found = crossings(&p, 6, 2).unwrap();
        assert_eq!(found, brute_force(&p, 6, 2));
        let edges = edges(6, 2);
        let pierced: Vec<([u32; 2], u32)> = found.iter().map(|c| (edges[c.edge as usize], c.triangle)).collect();
        // Edges by vertex: row 0 is 0-5, row 1 is 6-11; column 4 is 4 and 10, column 5 is 5 and 11.
        assert_eq!(pierced, [([0, 7], 9), ([4, 5], 0), ([4, 11], 0), ([10, 11], 1)], "{found:?}");
    }

    #[test]
    fn the_grid_search_finds_what_brute_force_finds_on_crumpled_cloths() {
        // Pseudo-random crumpling (a fixed linear congruential sequence), from slight to wild,
        // with a few stretched edges that take the brute-force path.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 33) as f64 / (1u64 << 31) as f64) as f32 - 0.5
        };
        for (nx, ny, amplitude) in [(8, 8, 0.05f32), (10, 7, 0.2), (12, 12, 0.6), (6, 9, 3.0), (30, 30, 0.15)] {
            let mut p = flat(nx, ny);
            for v in &mut p {
                for x in v.iter_mut() {
                    *x += amplitude * next();
                }
            }
            p[3][2] += 10.0;
            let found = crossings(&p, nx, ny).unwrap();
            assert_eq!(found, brute_force(&p, nx, ny), "{nx} x {ny} at {amplitude}");
            if amplitude >= 0.15 {
                assert!(!found.is_empty(), "a wildly crumpled cloth passes through itself");
            }
        }
    }

    #[test]
    fn a_cloth_draped_over_the_sphere_has_none() {
        use crate::Simulator;
        // The default drape at 24 x 24: it falls, lands on the sphere and hangs around it, curved
        // but with no fold through itself.
        let mut scene = crate::Scene::default();
        scene.cloth.resolution = [24, 24];
        let mut sim = crate::CpuSimulator::new(&scene).unwrap();
        sim.advance(150).unwrap();
        let state = sim.read_state().unwrap();
        assert!(state.centroid()[1] < 1.4, "the cloth has landed: {:?}", state.centroid());
        let bent = state.positions.iter().map(|p| p[1]).fold(f32::INFINITY, f32::min) < 1.0;
        assert!(bent, "the cloth hangs below the sphere's centre");
        assert_eq!(crossings(&state.positions, 24, 24).unwrap(), brute_force(&state.positions, 24, 24));
        assert_eq!(count(&state.positions, 24, 24), Ok(0));
    }

    #[test]
    fn a_cloth_torn_across_itself_is_not_counted() {
        // Every other vertex of a 40 x 40 cloth thrown 1000 spacings away: most edges span the
        // cloth, and counting would test nearly every edge against every triangle.
        let mut p = flat(40, 40);
        for (k, v) in p.iter_mut().enumerate().filter(|(k, _)| k % 2 == 0) {
            v[k % 3] += if k % 4 == 0 { 100.0 } else { -100.0 };
        }
        let e = crossings(&p, 40, 40).unwrap_err();
        assert!(e.tests > e.limit && e.to_string().starts_with("not counted: the cloth's edges are stretched"), "{e}");
    }

    #[test]
    fn non_finite_vertices_are_skipped() {
        let mut p = pierced_strip();
        p[7][0] = f32::NAN;
        assert_eq!(
            crossings(&p, 6, 2).unwrap(),
            brute_force(&p, 6, 2)
                .into_iter()
                .filter(|c| {
                    let (e, t) = (edges(6, 2)[c.edge as usize], triangles(6, 2)[c.triangle as usize]);
                    !e.contains(&7) && !t.contains(&7)
                })
                .collect::<Vec<_>>()
        );
    }
}
