//! The cloth model built from a scene: grid, springs and per-vertex spring lists.
//!
//! This is the single source of truth both the CPU reference and the GPU backends are built
//! from (the GPU backends convert it to `f32` buffers).

use crate::grid::Grid;
use crate::scene::Scene;
use crate::springs::{self, Spring, SpringKind};

/// One end of a spring, as seen from the vertex that owns this entry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NeighbourSpring {
    /// The vertex at the other end.
    pub other: u32,
    /// Kind of the spring.
    pub kind: SpringKind,
    /// Rest length `L0`, m.
    pub rest_length: f64,
}

/// Per-vertex spring lists in compressed-row form: vertex `i` owns
/// `ends[first[i] .. first[i + 1]]`.
///
/// Every spring appears twice, once in each endpoint's list. A GPU thread per vertex then reads
/// only its own list and writes only its own vertex: no atomics and no scatter, at the cost of
/// evaluating each spring twice (the two evaluations give equal and opposite forces).
#[derive(Clone, Debug, Default)]
pub struct Adjacency {
    /// Start of each vertex's list in `ends`; `vertex_count + 1` entries.
    pub first: Vec<u32>,
    /// The spring ends, grouped by owning vertex.
    pub ends: Vec<NeighbourSpring>,
}

impl Adjacency {
    /// Builds the lists from a spring list. Within a vertex, ends keep the order of `springs`,
    /// so every backend sums the forces in the same order.
    pub fn new(vertex_count: usize, springs: &[Spring]) -> Self {
        let mut counts = vec![0u32; vertex_count + 1];
        for s in springs {
            counts[s.a as usize + 1] += 1;
            counts[s.b as usize + 1] += 1;
        }
        for i in 0..vertex_count {
            counts[i + 1] += counts[i];
        }
        let first = counts;
        let mut cursor = first.clone();
        let mut ends =
            vec![NeighbourSpring { other: 0, kind: SpringKind::Structural, rest_length: 0.0 }; springs.len() * 2];
        for s in springs {
            for (owner, other) in [(s.a, s.b), (s.b, s.a)] {
                let slot = &mut cursor[owner as usize];
                ends[*slot as usize] = NeighbourSpring { other, kind: s.kind, rest_length: s.rest_length };
                *slot += 1;
            }
        }
        Self { first, ends }
    }

    /// The springs owned by vertex `i`.
    pub fn of(&self, i: usize) -> &[NeighbourSpring] {
        &self.ends[self.first[i] as usize..self.first[i + 1] as usize]
    }
}

/// Everything built from a scene before simulation starts.
#[derive(Clone, Debug)]
pub struct ClothModel {
    /// The scene this model was built from.
    pub scene: Scene,
    /// Vertex rest positions and pins.
    pub grid: Grid,
    /// Every spring once.
    pub springs: Vec<Spring>,
    /// Per-vertex spring lists.
    pub adjacency: Adjacency,
}

impl ClothModel {
    /// Builds the model. The scene should have been validated (`Scene::validate`); an invalid
    /// scene gives a model that is safe to build but meaningless to simulate.
    pub fn new(scene: &Scene) -> Self {
        let grid = Grid::new(&scene.cloth);
        let springs = springs::generate(&grid, scene.effects);
        let adjacency = Adjacency::new(grid.vertex_count(), &springs);
        Self { scene: scene.clone(), grid, springs, adjacency }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.grid.vertex_count()
    }

    /// The springs grouped into colours that share no vertex (XPBD's projection order).
    pub fn spring_colors(&self) -> crate::coloring::SpringColors {
        crate::coloring::SpringColors::new(&self.springs, self.grid.nx)
    }

    /// The largest strain of a spring in `state`, `max |L / L0 − 1|` over the springs (0: every
    /// spring at its rest length).
    pub fn max_strain(&self, state: &crate::ClothState) -> f64 {
        self.springs
            .iter()
            .map(|s| {
                let (a, b) = (state.positions[s.a as usize], state.positions[s.b as usize]);
                let l = (0..3).map(|k| (a[k] as f64 - b[k] as f64).powi(2)).sum::<f64>().sqrt();
                (l / s.rest_length - 1.0).abs()
            })
            .fold(0.0, f64::max)
    }

    /// Number of springs of each kind, `[structural, shear, bend]`.
    pub fn spring_counts(&self) -> [usize; 3] {
        springs::count_by_kind(&self.springs)
    }

    /// Bytes of host memory building and simulating `scene` takes, from the closed-form spring
    /// counts, without building anything (so that validation can refuse a huge grid before
    /// allocating): per vertex its `f64` position and pin flag, its list offset and four `f64`
    /// state vectors (the reference's current and next positions and velocities); per spring
    /// 32 bytes, and two list entries of 24. Saturates instead of overflowing.
    pub fn estimated_host_bytes(scene: &Scene) -> u64 {
        let [nx, ny] = scene.cloth.resolution.map(u128::from);
        let springs: u128 = SpringKind::ALL
            .iter()
            .filter(|k| scene.effects.contains(k.effect()))
            .map(|k| k.count_in_grid(nx as u64, ny as u64) as u128)
            .sum();
        let bytes = nx * ny * (24 + 1 + 4 + 4 * 24) + springs * (32 + 2 * 24);
        u64::try_from(bytes).unwrap_or(u64::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_strain_is_that_of_the_most_stretched_spring() {
        let scene =
            Scene { cloth: crate::scene::ClothSpec { resolution: [4, 3], ..Default::default() }, ..Default::default() };
        let model = ClothModel::new(&scene);
        let positions: Vec<[f32; 3]> =
            model.grid.positions.iter().map(|p| [p[0] as f32, p[1] as f32, p[2] as f32]).collect();
        let mut state = crate::ClothState { time_s: 0.0, velocities: vec![[0.0; 3]; positions.len()], positions };
        assert!(model.max_strain(&state) < 1e-6, "at rest: {}", model.max_strain(&state));
        // A corner moved out along its row by a fifth of the spacing: its structural spring along
        // the row stretches by 20%, more than any other.
        let spacing = scene.cloth.spacing()[0];
        let [x0, x1] = [model.grid.positions[0][0], model.grid.positions[1][0]];
        let outward = (x0 - x1).signum() * 0.2 * spacing;
        state.positions[0][0] += outward as f32;
        assert!((model.max_strain(&state) - 0.2).abs() < 1e-4, "{}", model.max_strain(&state));
    }

    #[test]
    fn every_spring_is_listed_at_both_ends() {
        let scene =
            Scene { cloth: crate::scene::ClothSpec { resolution: [4, 5], ..Default::default() }, ..Default::default() };
        let model = ClothModel::new(&scene);
        assert_eq!(model.adjacency.ends.len(), 2 * model.springs.len());
        for s in &model.springs {
            assert!(model.adjacency.of(s.a as usize).iter().any(|e| e.other == s.b && e.kind == s.kind));
            assert!(model.adjacency.of(s.b as usize).iter().any(|e| e.other == s.a && e.kind == s.kind));
        }
        // An interior vertex of a large enough grid has 4 + 4 + 4 springs.
        let centre = ClothModel::new(&Scene::default());
        assert_eq!(centre.adjacency.of(16 * 32 + 16).len(), 12);
    }
}
