//! Springs of the three kinds, generated from the grid's connectivity.
//!
//! * structural: `(i,j)–(i+1,j)` and `(i,j)–(i,j+1)`: `nx(ny-1) + ny(nx-1)` springs;
//! * shear: both diagonals of every cell: `2(nx-1)(ny-1)` springs;
//! * bend: `(i,j)–(i+2,j)` and `(i,j)–(i,j+2)`: `nx(ny-2) + ny(nx-2)` springs.
//!
//! Rest lengths are the distances in the initial grid, computed from the grid spacing
//! ([`rest_length`]). A spring kind whose effect the scene
//! leaves out is not generated at all.

use serde::{Deserialize, Serialize};

use crate::effects::{Effect, EffectSet};
use crate::grid::Grid;

/// The three kinds of cloth springs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[repr(u32)]
pub enum SpringKind {
    /// Between 4-neighbours: resists stretching.
    Structural = 0,
    /// Along cell diagonals: resists shearing.
    Shear = 1,
    /// Between vertices two apart: resists bending.
    Bend = 2,
}

impl SpringKind {
    /// All kinds, in index order.
    pub const ALL: [SpringKind; 3] = [SpringKind::Structural, SpringKind::Shear, SpringKind::Bend];

    /// The effect that switches this kind on.
    pub fn effect(self) -> Effect {
        match self {
            SpringKind::Structural => Effect::StructuralSprings,
            SpringKind::Shear => Effect::ShearSprings,
            SpringKind::Bend => Effect::BendSprings,
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            SpringKind::Structural => "structural",
            SpringKind::Shear => "shear",
            SpringKind::Bend => "bend",
        }
    }

    /// Closed-form number of springs of this kind in an `nx × ny` grid.
    pub fn count_in_grid(self, nx: u64, ny: u64) -> u64 {
        match self {
            SpringKind::Structural => {
                nx.saturating_mul(ny.saturating_sub(1)).saturating_add(ny.saturating_mul(nx.saturating_sub(1)))
            }
            SpringKind::Shear => 2u64.saturating_mul(nx.saturating_sub(1)).saturating_mul(ny.saturating_sub(1)),
            SpringKind::Bend => {
                nx.saturating_mul(ny.saturating_sub(2)).saturating_add(ny.saturating_mul(nx.saturating_sub(2)))
            }
        }
    }

    /// Grid offsets `(di, dj)` of the springs of this kind that start at a vertex
    /// (each spring is listed once, from its lower-index end).
    pub fn stencil(self) -> &'static [(i64, i64)] {
        match self {
            SpringKind::Structural => &[(1, 0), (0, 1)],
            SpringKind::Shear => &[(1, 1), (-1, 1)],
            SpringKind::Bend => &[(2, 0), (0, 2)],
        }
    }
}

/// One spring between vertices `a` and `b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spring {
    /// First vertex index.
    pub a: u32,
    /// Second vertex index.
    pub b: u32,
    /// Which kind.
    pub kind: SpringKind,
    /// Rest length `L0`, m.
    pub rest_length: f64,
}

/// Generates the springs of every kind present in `effects`.
pub fn generate(grid: &Grid, effects: EffectSet) -> Vec<Spring> {
    let (nx, ny) = (grid.nx as i64, grid.ny as i64);
    let mut springs = Vec::new();
    for kind in SpringKind::ALL {
        if !effects.contains(kind.effect()) {
            continue;
        }
        for j in 0..ny {
            for i in 0..nx {
                for &(di, dj) in kind.stencil() {
                    let (i2, j2) = (i + di, j + dj);
                    if i2 < 0 || i2 >= nx || j2 >= ny {
                        continue;
                    }
                    let a = (j * nx + i) as u32;
                    let b = (j2 * nx + i2) as u32;
                    springs.push(Spring { a, b, kind, rest_length: rest_length(grid.spacing, di, dj) });
                }
            }
        }
    }
    springs
}

/// Rest length of a spring spanning `(di, dj)` grid steps, m: `√((di·Δu)² + (dj·Δv)²)` with
/// `spacing = [Δu, Δv]`. The initial distance in exact arithmetic; computed from the spacing so
/// that every spring of a kind and direction has the same rest length, which is what lets the
/// GPU kernels compute the springs from the grid (a stencil) instead of reading a spring list.
/// Axis-aligned springs get `|di|·Δu` or `|dj|·Δv` exactly.
pub fn rest_length(spacing: [f64; 2], di: i64, dj: i64) -> f64 {
    let (u, v) = (di.unsigned_abs() as f64 * spacing[0], dj.unsigned_abs() as f64 * spacing[1]);
    if dj == 0 {
        u
    } else if di == 0 {
        v
    } else {
        (u * u + v * v).sqrt()
    }
}

/// Number of springs of each kind, `[structural, shear, bend]`.
pub fn count_by_kind(springs: &[Spring]) -> [usize; 3] {
    let mut counts = [0; 3];
    for s in springs {
        counts[s.kind as usize] += 1;
    }
    counts
}

pub(crate) fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::ClothSpec;

    fn grid(nx: u32, ny: u32) -> Grid {
        Grid::new(&ClothSpec {
            resolution: [nx, ny],
            size: [(nx - 1) as f64 * 0.1, (ny - 1) as f64 * 0.2],
            ..Default::default()
        })
    }

    #[test]
    fn counts_match_the_closed_forms() {
        for (nx, ny) in [(2, 2), (3, 3), (2, 5), (7, 13), (16, 9), (33, 31)] {
            let springs = generate(&grid(nx, ny), EffectSet::mass_spring());
            let counts = count_by_kind(&springs);
            let (x, y) = (nx as usize, ny as usize);
            assert_eq!(counts[0], x * (y - 1) + y * (x - 1), "structural {nx}x{ny}");
            assert_eq!(counts[1], 2 * (x - 1) * (y - 1), "shear {nx}x{ny}");
            assert_eq!(counts[2], x * (y - 2) + y * (x - 2), "bend {nx}x{ny}");
            for kind in SpringKind::ALL {
                assert_eq!(counts[kind as usize] as u64, kind.count_in_grid(nx as u64, ny as u64));
            }
        }
    }

    #[test]
    fn rest_lengths_are_the_initial_distances() {
        // Cell 0.1 m along u, 0.2 m along v.
        let springs = generate(&grid(7, 13), EffectSet::mass_spring());
        let diag = (0.1f64 * 0.1 + 0.2 * 0.2).sqrt();
        for s in &springs {
            let (du, dv) = ((s.a % 7) as i64 - (s.b % 7) as i64, (s.a / 7) as i64 - (s.b / 7) as i64);
            let expected = ((du as f64 * 0.1).powi(2) + (dv as f64 * 0.2).powi(2)).sqrt();
            assert!((s.rest_length - expected).abs() < 1e-12, "{s:?}");
            match s.kind {
                SpringKind::Structural => assert!((expected - 0.1).abs() < 1e-12 || (expected - 0.2).abs() < 1e-12),
                SpringKind::Shear => assert!((expected - diag).abs() < 1e-12),
                SpringKind::Bend => assert!((expected - 0.2).abs() < 1e-12 || (expected - 0.4).abs() < 1e-12),
            }
        }
    }

    #[test]
    fn an_absent_kind_generates_no_springs() {
        let effects = EffectSet::mass_spring().without(crate::effects::Effect::BendSprings);
        let counts = count_by_kind(&generate(&grid(5, 5), effects));
        assert_eq!(counts[2], 0);
        assert!(counts[0] > 0 && counts[1] > 0);
    }
}
