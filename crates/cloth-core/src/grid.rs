//! The cloth mesh: an `nx × ny` subdivided rectangle.
//!
//! Vertex `(i, j)` (column `i < nx`, row `j < ny`) has index `j·nx + i`.

use crate::scene::{ClothSpec, Corner, Edge, Orientation, Pin};

/// Vertex positions of a cloth grid and which of them are pinned.
#[derive(Clone, Debug)]
pub struct Grid {
    /// Vertices along u.
    pub nx: u32,
    /// Vertices along v.
    pub ny: u32,
    /// Rest (initial) position of each vertex, m.
    pub positions: Vec<[f64; 3]>,
    /// `true` for pinned vertices.
    pub pinned: Vec<bool>,
    /// The pin group whose motion a pinned vertex follows: 0 for `cloth.pins`, `k + 1` for
    /// `cloth.pin_groups[k]` (0 on free vertices).
    pub pin_group: Vec<u8>,
    /// Distance between grid neighbours along u and along v, m.
    pub spacing: [f64; 2],
}

impl Grid {
    /// Builds the grid of a cloth: positions placed and oriented as the spec says, pins resolved.
    /// Pins that fall outside the grid are ignored here; scene validation reports them.
    pub fn new(spec: &ClothSpec) -> Self {
        let [nx, ny] = spec.resolution;
        let (u, v) = spec.orientation.axes();
        let [su, sv] = spec.size;
        let n = normalise([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]);
        let ripple = spec.ripple;
        let mut positions = Vec::with_capacity(nx as usize * ny as usize);
        for j in 0..ny {
            for i in 0..nx {
                let a = (i as f64 / (nx - 1).max(1) as f64 - 0.5) * su;
                let b = (j as f64 / (ny - 1).max(1) as f64 - 0.5) * sv;
                let w = if ripple.amplitude != 0.0 {
                    ripple.amplitude * (std::f64::consts::TAU * (b + 0.5 * sv) / ripple.wavelength).sin()
                } else {
                    0.0
                };
                positions.push([0, 1, 2].map(|k| spec.center[k] + a * u[k] + b * v[k] + w * n[k]));
            }
        }
        let mut pinned = vec![false; positions.len()];
        let mut pin_group = vec![0u8; positions.len()];
        let groups = std::iter::once(&spec.pins).chain(spec.pin_groups.iter().map(|g| &g.pins));
        for (group, pins) in groups.enumerate() {
            for index in pins.iter().flat_map(|pin| pin_indices(pin, nx, ny)) {
                if let Some(p) = pinned.get_mut(index as usize) {
                    *p = true;
                    pin_group[index as usize] = group as u8;
                }
            }
        }
        Self { nx, ny, positions, pinned, pin_group, spacing: spec.spacing() }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Index of vertex `(i, j)`.
    pub fn index(&self, i: u32, j: u32) -> u32 {
        j * self.nx + i
    }

    /// Triangle list (two triangles per cell, counter-clockwise seen from the +normal side),
    /// for rendering.
    pub fn triangle_indices(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(6 * (self.nx as usize - 1) * (self.ny as usize - 1));
        for j in 0..self.ny.saturating_sub(1) {
            for i in 0..self.nx.saturating_sub(1) {
                let a = self.index(i, j);
                let b = self.index(i + 1, j);
                let c = self.index(i + 1, j + 1);
                let d = self.index(i, j + 1);
                out.extend_from_slice(&[a, b, c, a, c, d]);
            }
        }
        out
    }
}

/// Vertex indices a pin refers to (possibly out of range; validation reports those).
pub fn pin_indices(pin: &Pin, nx: u32, ny: u32) -> Vec<u64> {
    let idx = |i: u32, j: u32| j as u64 * nx as u64 + i as u64;
    let (last_i, last_j) = (nx.saturating_sub(1), ny.saturating_sub(1));
    match pin {
        Pin::Corner(Corner::BottomLeft) => vec![idx(0, 0)],
        Pin::Corner(Corner::BottomRight) => vec![idx(last_i, 0)],
        Pin::Corner(Corner::TopLeft) => vec![idx(0, last_j)],
        Pin::Corner(Corner::TopRight) => vec![idx(last_i, last_j)],
        Pin::Edge(Edge::Bottom) => (0..nx).map(|i| idx(i, 0)).collect(),
        Pin::Edge(Edge::Top) => (0..nx).map(|i| idx(i, last_j)).collect(),
        Pin::Edge(Edge::Left) => (0..ny).map(|j| idx(0, j)).collect(),
        Pin::Edge(Edge::Right) => (0..ny).map(|j| idx(last_i, j)).collect(),
        Pin::Vertex(k) => vec![*k as u64],
        Pin::GridPoint(i, j) => {
            if *i < nx && *j < ny {
                vec![idx(*i, *j)]
            } else {
                vec![u64::MAX]
            }
        }
    }
}

impl Orientation {
    /// The two unit directions `(u, v)` spanned by the cloth.
    pub fn axes(&self) -> ([f64; 3], [f64; 3]) {
        match self {
            Orientation::Horizontal => ([1.0, 0.0, 0.0], [0.0, 0.0, -1.0]),
            Orientation::Vertical => ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            Orientation::Axes { u, v } => (normalise(*u), normalise(*v)),
        }
    }
}

fn normalise(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    if l > 0.0 { [a[0] / l, a[1] / l, a[2] / l] } else { a }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_spans_the_requested_rectangle() {
        let spec = ClothSpec { resolution: [5, 3], size: [4.0, 2.0], center: [0.0, 1.0, 0.0], ..Default::default() };
        let g = Grid::new(&spec);
        assert_eq!(g.vertex_count(), 15);
        assert_eq!(g.positions[0], [-2.0, 1.0, 1.0]);
        assert_eq!(g.positions[14], [2.0, 1.0, -1.0]);
        assert_eq!(g.triangle_indices().len(), 6 * 4 * 2);
    }

    #[test]
    fn a_ripple_moves_the_rows_along_the_normal() {
        let ripple = crate::scene::Ripple { amplitude: 0.1, wavelength: 4.0 };
        let spec = ClothSpec { resolution: [2, 5], size: [1.0, 4.0], ripple, ..Default::default() };
        let g = Grid::new(&spec);
        // Horizontal: the normal is +Y; rows 0..4 are 1 m apart, a quarter wavelength.
        let heights: Vec<f64> = (0..5).map(|j| g.positions[2 * j][1] - spec.center[1]).collect();
        for (h, expected) in heights.iter().zip([0.0, 0.1, 0.0, -0.1, 0.0]) {
            assert!((h - expected).abs() < 1e-12, "{heights:?}");
        }
    }

    #[test]
    fn named_pins_resolve_to_the_documented_vertices() {
        let (nx, ny) = (4, 3);
        assert_eq!(pin_indices(&Pin::Corner(Corner::TopLeft), nx, ny), vec![8]);
        assert_eq!(pin_indices(&Pin::Corner(Corner::TopRight), nx, ny), vec![11]);
        assert_eq!(pin_indices(&Pin::Edge(Edge::Left), nx, ny), vec![0, 4, 8]);
        assert_eq!(pin_indices(&Pin::GridPoint(1, 2), nx, ny), vec![9]);
    }
}
