//! Measurements over time for the stats panel.

use std::collections::VecDeque;

/// One sample.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sample {
    /// Simulated time, s.
    pub time_s: f64,
    /// Kinetic energy, J.
    pub kinetic_j: f64,
    /// Elastic energy of all springs, J.
    pub elastic_j: f64,
    /// Deepest penetration so far, m.
    pub max_penetration_m: f64,
    /// Edge–triangle crossings of the cloth through itself (`None`: not counted, the grid is
    /// larger than [`crate::app::MAX_COUNTED_VERTICES`] or the cloth is torn across itself).
    pub self_intersections: Option<usize>,
    /// With `SelfCollision` on a GPU backend, how its candidate lists fared since it was created.
    pub candidate_lists: Option<cloth_core::self_collision::CandidateListStats>,
    /// With an implicit integrator, what its solver spent since the backend was created.
    pub solver: Option<cloth_core::solver::SolverIterations>,
}

/// Rolling history and the latest timings.
#[derive(Default)]
pub struct Stats {
    /// Recent samples (at most `CAPACITY`).
    pub samples: VecDeque<Sample>,
    /// Wall-clock ms of the last `advance` of one frame, smoothed.
    pub ms_per_frame: f64,
    /// Vertex-substeps per second at that rate.
    pub vertex_substeps_per_s: f64,
}

impl Stats {
    const CAPACITY: usize = 2000;

    /// Records a sample.
    pub fn push(&mut self, s: Sample) {
        if self.samples.len() == Self::CAPACITY {
            self.samples.pop_front();
        }
        self.samples.push_back(s);
    }

    /// Records the cost of advancing `frames` frames of `vertex_substeps` work each.
    pub fn record_timing(&mut self, seconds: f64, frames: u32, vertex_substeps_per_frame: f64) {
        if frames == 0 || seconds <= 0.0 {
            return;
        }
        let ms = seconds * 1e3 / frames as f64;
        self.ms_per_frame = if self.ms_per_frame == 0.0 { ms } else { 0.9 * self.ms_per_frame + 0.1 * ms };
        self.vertex_substeps_per_s = vertex_substeps_per_frame / (self.ms_per_frame * 1e-3);
    }

    /// Forgets everything (after a reset or rebuild).
    pub fn clear(&mut self) {
        *self = Self::default();
    }
}
