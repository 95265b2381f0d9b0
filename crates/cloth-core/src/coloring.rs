//! Spring colours: the springs split into sets that share no vertex.
//!
//! XPBD projects one spring at a time (Gauss–Seidel): each projection moves the spring's two
//! ends, and the next projection sees the moved positions. Two springs that share no vertex can
//! be projected in either order, or at the same time, with the same result. Colouring the springs
//! so that no two springs of one colour share a vertex therefore lets a GPU project a whole colour
//! in one dispatch (one invocation per spring, no atomics), and the CPU reference, projecting the
//! colours in the same order, computes exactly what the GPU computes.
//!
//! On the grid the colouring is closed-form. A spring is listed from its lower-index end `(i, j)`
//! with a stencil offset `(di, dj)` (see [`crate::springs`]); it shares a vertex with another
//! spring of the same offset only when their starts differ by exactly that offset. So the parity
//! of the start along the offset's direction separates them:
//!
//! | kind | offset | colour parity |
//! |---|---|---|
//! | structural | (1, 0) | `i mod 2` |
//! | structural | (0, 1) | `j mod 2` |
//! | shear | (1, 1), (−1, 1) | `i mod 2` |
//! | bend | (2, 0) | `⌊i/2⌋ mod 2` |
//! | bend | (0, 2) | `⌊j/2⌋ mod 2` |
//!
//! Six offsets × two parities: at most [`COLOR_COUNT`] colours.
//!
//! **Vertex colours.** A solver that updates one vertex at a time from its springs (Vertex Block
//! Descent: a 3 × 3 Newton step on the vertex's own energy) can update at once every vertex of a
//! colour in which no two vertices share a spring. The grid's springs join offsets
//! `(±1, 0), (0, ±1)` (structural), `(±1, ±1)` (shear) and `(±2, 0), (0, ±2)` (bend), and
//!
//! ```text
//! c(i, j) = (i + 2 j) mod 5
//! ```
//!
//! gives them the colour differences `di + 2 dj` = ±1, ±2, ±1 and ±3, ±2 and ±4: none a multiple
//! of 5, so no spring joins two vertices of a colour. Five is the fewest
//! ([`VERTEX_COLOR_COUNT`]): the four corners of a grid cell are joined pairwise (two structural
//! springs along each side, two shear springs across), so they take four colours `a, b, c, d`
//! (at `(0,0), (1,0), (0,1), (1,1)`); with no fifth, each further vertex is forced: `(2, 0)` is
//! joined to `a, b, d`, so it is `c`; `(0, 2)` is joined to `a, c, d`, so it is `b`; and `(1, 2)`
//! is then joined to `(1, 1) = d`, `(1, 0) = b`, `(0, 1) = c`, `(2, 1)` and `(0, 2) = b`, where
//! `(2, 1)`, joined to `b, c, d`, is `a`: no colour is left. The test
//! `four_colours_cannot_colour_the_stencil` finds the same by trying every colouring of a patch.

use crate::springs::{Spring, SpringKind};

/// Number of spring colours on a grid (empty colours are kept, so the count is fixed).
pub const COLOR_COUNT: usize = 12;

/// Number of vertex colours on a grid (see the module documentation: the fewest the springs allow).
pub const VERTEX_COLOR_COUNT: usize = 5;

/// The colour of vertex `(i, j)`, in `0..VERTEX_COLOR_COUNT`: `(i + 2 j) mod 5`. No spring joins
/// two vertices of one colour.
pub fn vertex_color(i: u32, j: u32) -> usize {
    ((i as u64 + 2 * j as u64) % VERTEX_COLOR_COUNT as u64) as usize
}

/// The colour of a spring of an `nx`-wide grid, in `0..COLOR_COUNT`.
pub fn color_of(spring: &Spring, nx: u32) -> usize {
    let (a, b) = (spring.a as i64, spring.b as i64);
    let nx = nx as i64;
    let (i, j) = (a % nx, a / nx);
    let (di, dj) = (b % nx - i, b / nx - j);
    // (offset slot, parity)
    let (slot, parity) = match (spring.kind, di, dj) {
        (SpringKind::Structural, _, 0) => (0, i % 2),
        (SpringKind::Structural, _, _) => (1, j % 2),
        (SpringKind::Shear, 1, _) => (2, i % 2),
        (SpringKind::Shear, _, _) => (3, i % 2),
        (SpringKind::Bend, _, 0) => (4, (i / 2) % 2),
        (SpringKind::Bend, _, _) => (5, (j / 2) % 2),
    };
    (2 * slot + parity) as usize
}

/// The springs grouped by colour: `order[first[c]..first[c + 1]]` are the indices (into the
/// model's spring list) of colour `c`, in spring-list order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct SpringColors {
    /// Spring indices, grouped by colour.
    pub order: Vec<u32>,
    /// Start of each colour in `order`; `COLOR_COUNT + 1` entries.
    pub first: Vec<u32>,
}

impl SpringColors {
    /// Colours the springs of an `nx`-wide grid.
    pub fn new(springs: &[Spring], nx: u32) -> Self {
        let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); COLOR_COUNT];
        for (index, spring) in springs.iter().enumerate() {
            buckets[color_of(spring, nx)].push(index as u32);
        }
        let mut first = Vec::with_capacity(COLOR_COUNT + 1);
        let mut order = Vec::with_capacity(springs.len());
        for bucket in buckets {
            first.push(order.len() as u32);
            order.extend(bucket);
        }
        first.push(order.len() as u32);
        Self { order, first }
    }

    /// The spring indices of colour `c`.
    pub fn color(&self, c: usize) -> &[u32] {
        &self.order[self.first[c] as usize..self.first[c + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::EffectSet;
    use crate::grid::Grid;
    use crate::scene::ClothSpec;

    #[test]
    fn no_two_springs_of_a_colour_share_a_vertex() {
        for (nx, ny) in [(2, 2), (3, 5), (4, 4), (7, 6), (16, 9), (33, 17)] {
            let grid = Grid::new(&ClothSpec { resolution: [nx, ny], ..Default::default() });
            let springs = crate::springs::generate(&grid, EffectSet::mass_spring());
            let colors = SpringColors::new(&springs, nx);
            let mut all: Vec<u32> = colors.order.clone();
            all.sort_unstable();
            assert_eq!(all, (0..springs.len() as u32).collect::<Vec<_>>(), "{nx}x{ny}: every spring once");
            for c in 0..COLOR_COUNT {
                let mut seen = vec![false; grid.vertex_count()];
                for &s in colors.color(c) {
                    for v in [springs[s as usize].a, springs[s as usize].b] {
                        assert!(!seen[v as usize], "{nx}x{ny}: colour {c} touches vertex {v} twice");
                        seen[v as usize] = true;
                    }
                }
            }
        }
    }

    #[test]
    fn no_spring_joins_two_vertices_of_a_colour() {
        for (nx, ny) in [(2, 2), (3, 5), (7, 6), (16, 9), (33, 17)] {
            let grid = Grid::new(&ClothSpec { resolution: [nx, ny], ..Default::default() });
            let springs = crate::springs::generate(&grid, EffectSet::mass_spring());
            assert!(!springs.is_empty());
            let color = |v: u32| vertex_color(v % nx, v / nx);
            let mut used = [false; VERTEX_COLOR_COUNT];
            for spring in &springs {
                assert_ne!(color(spring.a), color(spring.b), "{nx}x{ny}: {spring:?}");
                used[color(spring.a)] = true;
            }
            if nx >= 5 {
                assert_eq!(used, [true; VERTEX_COLOR_COUNT], "{nx}x{ny}: every colour is used");
            }
        }
    }

    /// Tries every colouring of a 5 × 5 patch of the grid with `colors` colours, the patch's
    /// vertices in row order, each against the springs to the vertices before it: whether one
    /// leaves no spring joining two vertices of a colour.
    fn patch_colorable(colors: usize) -> bool {
        const SIDE: usize = 5;
        let springs = [(1, 0), (0, 1), (1, 1), (-1, 1), (2, 0), (0, 2)];
        // The earlier vertices each vertex is joined to.
        let earlier: Vec<Vec<usize>> = (0..SIDE * SIDE)
            .map(|v| {
                let (i, j) = ((v % SIDE) as i64, (v / SIDE) as i64);
                springs
                    .iter()
                    .map(|&(di, dj)| (i - di, j - dj))
                    .filter(|&(a, b)| (0..SIDE as i64).contains(&a) && (0..SIDE as i64).contains(&b))
                    .map(|(a, b)| b as usize * SIDE + a as usize)
                    .collect()
            })
            .collect();
        fn extend(v: usize, assigned: &mut Vec<usize>, earlier: &[Vec<usize>], colors: usize) -> bool {
            if v == earlier.len() {
                return true;
            }
            for c in 0..colors {
                if earlier[v].iter().all(|&u| assigned[u] != c) {
                    assigned.push(c);
                    if extend(v + 1, assigned, earlier, colors) {
                        return true;
                    }
                    assigned.pop();
                }
            }
            false
        }
        extend(0, &mut Vec::new(), &earlier, colors)
    }

    #[test]
    fn four_colours_cannot_colour_the_stencil() {
        assert!(!patch_colorable(VERTEX_COLOR_COUNT - 1), "a 5x5 patch has a 4-colouring");
        assert!(patch_colorable(VERTEX_COLOR_COUNT), "the search finds the 5-colouring");
    }
}
