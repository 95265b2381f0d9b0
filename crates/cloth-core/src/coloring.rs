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

use crate::springs::{Spring, SpringKind};

/// Number of spring colours on a grid (empty colours are kept, so the count is fixed).
pub const COLOR_COUNT: usize = 12;

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
}
