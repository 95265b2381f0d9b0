//! The interface every backend implements (CPU reference, wgpu, vulkano).

use crate::error::SimError;
use crate::scene::Scene;
use crate::self_collision::SelfCollisionQuantities;

/// The dynamic state of a cloth: what is handed from one backend to another.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ClothState {
    /// Simulated time since the start, s.
    pub time_s: f64,
    /// Vertex positions, m.
    pub positions: Vec<[f32; 3]>,
    /// Vertex velocities, m/s.
    pub velocities: Vec<[f32; 3]>,
}

impl ClothState {
    /// Number of vertices whose position or velocity is NaN or infinite.
    pub fn non_finite_count(&self) -> usize {
        self.positions
            .iter()
            .zip(&self.velocities)
            .filter(|(p, v)| !p.iter().chain(v.iter()).all(|x| x.is_finite()))
            .count()
    }

    /// Mean position of the vertices, m.
    pub fn centroid(&self) -> [f64; 3] {
        let n = self.positions.len().max(1) as f64;
        let mut c = [0.0; 3];
        for p in &self.positions {
            for k in 0..3 {
                c[k] += p[k] as f64 / n;
            }
        }
        c
    }
}

/// Quantities a backend tracks while it runs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Diagnostics {
    /// Deepest any vertex went inside any collider since creation (checked after every
    /// substep), m.
    pub max_penetration_m: f64,
    /// Substeps run since creation.
    pub substeps_run: u64,
    /// With `SelfCollision` on a GPU backend, how its candidate lists fared since creation
    /// (the CPU reference keeps none).
    pub candidate_lists: Option<crate::self_collision::CandidateListStats>,
    /// With an implicit integrator, what its solver spent since creation.
    pub solver: Option<crate::solver::SolverIterations>,
}

/// What the last [`Simulator::advance`] cost in host–device traffic (all zero on the CPU).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AdvanceCounts {
    /// Frames advanced.
    pub frames: u32,
    /// Command submissions to the device.
    pub submissions: u32,
    /// Times the host waited for the device.
    pub host_waits: u32,
}

/// The GPU time of one pass of a profiled frame ([`Simulator::profile_frame`]): every dispatch
/// of one pipeline.
#[derive(Clone, Debug, PartialEq)]
pub struct PassTime {
    /// What the pass does, in words: its pipeline's name (`Euler substep`,
    /// `self-collision check`, …).
    pub name: String,
    /// Its dispatches in the frame.
    pub dispatches: u32,
    /// Its GPU time in the frame, s: for each of its dispatches, the time from the timestamp
    /// after the dispatch before it (the frame's first timestamp for the first) to the timestamp
    /// after it, summed. So it includes the wait at the barrier before the dispatch, and a
    /// dispatch of no workgroups (an indirect one sized to zero) still takes its launch.
    pub seconds: f64,
    /// Its shortest dispatch, s (with [`PassTime::longest_s`]: where a pass's dispatches differ
    /// in kind, a rebuild pass that rebuilds or runs empty, the two kinds).
    pub shortest_s: f64,
    /// Its longest dispatch, s.
    pub longest_s: f64,
}

impl PassTime {
    /// A pass of one dispatch that took `seconds`.
    pub fn of_dispatch(name: &str, seconds: f64) -> Self {
        Self { name: name.into(), dispatches: 1, seconds, shortest_s: seconds, longest_s: seconds }
    }

    /// Adds this pass's dispatches (one dispatch's, or a frame's) to the pass of the same name in
    /// `passes`, or appends it: passes summed by name, in the order they first come.
    pub fn add_to(self, passes: &mut Vec<PassTime>) {
        match passes.iter_mut().find(|p| p.name == self.name) {
            Some(p) => {
                p.dispatches += self.dispatches;
                p.seconds += self.seconds;
                p.shortest_s = p.shortest_s.min(self.shortest_s);
                p.longest_s = p.longest_s.max(self.longest_s);
            }
            None => passes.push(self),
        }
    }
}

/// A cloth simulator. One frame is `scene.substeps_per_frame()` substeps of
/// `scene.substep_dt()`; [`Simulator::advance`] runs whole frames with no host round trip
/// between substeps.
pub trait Simulator {
    /// Creates the simulator for a scene (the scene is validated first).
    ///
    /// # Errors
    /// [`SimError::Scene`] for an invalid scene, [`SimError::Unavailable`] when the backend
    /// cannot run here, [`SimError::TooLarge`] when the scene does not fit the device.
    fn new(scene: &Scene) -> Result<Self, SimError>
    where
        Self: Sized;

    /// Short backend name, e.g. `"cpu"`, `"wgpu"`.
    fn backend_name(&self) -> &'static str;

    /// The device the backend runs on, in words.
    fn adapter_name(&self) -> String;

    /// The scene being simulated, with any live parameter changes applied.
    fn scene(&self) -> &Scene;

    /// Advances `frames` frames (all substeps inside).
    ///
    /// # Errors
    /// [`SimError::Device`] when the device fails.
    fn advance(&mut self, frames: u32) -> Result<(), SimError>;

    /// Applies new parameters (stiffness, damping, masses, gravity, colliders, time step) without
    /// restarting.
    ///
    /// # Errors
    /// [`SimError::RebuildRequired`] when the change needs a new simulator (grid, pins,
    /// effects, number or kinds of colliders), [`SimError::Scene`] when the new scene is invalid.
    fn update_parameters(&mut self, scene: &Scene) -> Result<(), SimError>;

    /// Reads the current state back.
    ///
    /// # Errors
    /// [`SimError::Device`] when the read-back fails.
    fn read_state(&mut self) -> Result<ClothState, SimError>;

    /// Replaces the current state (e.g. a state handed over from another backend).
    ///
    /// # Errors
    /// [`SimError::StateMismatch`] when the vertex count differs.
    fn write_state(&mut self, state: &ClothState) -> Result<(), SimError>;

    /// Diagnostics tracked since creation.
    ///
    /// # Errors
    /// [`SimError::Device`] when the read-back fails.
    fn diagnostics(&mut self) -> Result<Diagnostics, SimError>;

    /// Substeps one dispatch advances at once where the backend fuses them (semi-implicit
    /// Euler's tiled kernel on the GPU); `1` where each substep is its own pass (and on the CPU).
    fn fused_substeps(&self) -> u32 {
        1
    }

    /// Bytes a vertex of the state the substeps hand each other through device memory: 32 for
    /// the two `vec4`s (position, velocity), 24 where semi-implicit Euler runs on its packed
    /// state; `None` on the CPU backends.
    fn substep_state_bytes(&self) -> Option<u32> {
        None
    }

    /// Submissions and host waits of the last `advance` (no device access).
    fn last_advance_counts(&self) -> AdvanceCounts {
        AdvanceCounts::default()
    }

    /// Turns GPU timing on or off (off by default: no timestamps are written). Returns whether
    /// it is on: `false` where there is no GPU timer (the CPU backends, or a device without
    /// timestamp queries).
    ///
    /// While on, each `advance` writes a timestamp before and after its work. The device holds
    /// the pairs of 256 advances; call [`Simulator::take_gpu_seconds`] at least that often, or
    /// the 257th advance reads them itself (one host wait, counted in its
    /// [`AdvanceCounts::host_waits`]).
    fn set_gpu_timing(&mut self, on: bool) -> bool {
        let _ = on;
        false
    }

    /// GPU execution time of the advances timed since the last call, s (see
    /// [`Simulator::set_gpu_timing`]); `None` when timing is off or unavailable.
    ///
    /// Reading the timestamps waits for the device (one host wait), so call it when the time is
    /// displayed or recorded, not every frame of a benchmark.
    ///
    /// # Errors
    /// [`SimError::Device`] when the read-back fails.
    fn take_gpu_seconds(&mut self) -> Result<Option<f64>, SimError> {
        Ok(None)
    }

    /// Advances one frame, as `advance(1)` does, with a timestamp before its first dispatch and
    /// after each, and returns where its GPU time went, pass by pass, in the order the passes
    /// first run. `None`, without advancing, where there are no GPU passes (the CPU backends) or
    /// the device cannot write timestamps between dispatches. The timer of
    /// [`Simulator::set_gpu_timing`] does not count the frame.
    ///
    /// A diagnostic, not a benchmark: it waits for the device (one host wait), and a timestamp
    /// after every dispatch may hold the next one back a little, so the passes can add up to
    /// somewhat more than the frame takes unprofiled ([`Simulator::set_gpu_timing`]).
    ///
    /// # Errors
    /// [`SimError::Device`] when the device fails.
    fn profile_frame(&mut self) -> Result<Option<Vec<PassTime>>, SimError> {
        Ok(None)
    }
}

impl Scene {
    /// If `new` differs from `self` in something only a rebuild can change, says what.
    pub fn rebuild_reason(&self, new: &Scene) -> Option<String> {
        let (a, b) = (&self.cloth, &new.cloth);
        if a.resolution != b.resolution {
            Some("the grid resolution".into())
        } else if a.size != b.size || a.orientation != b.orientation {
            Some("the cloth size or orientation (spring rest lengths)".into())
        } else if a.pins != b.pins || a.pin_groups.iter().map(|g| &g.pins).ne(b.pin_groups.iter().map(|g| &g.pins)) {
            // (A group's motion is a parameter; which vertices it holds is the grid's.)
            Some("the pins".into())
        } else if self.effects != new.effects {
            Some("the set of effects".into())
        } else if self.colliders.len() != new.colliders.len() {
            Some("the number of colliders".into())
        } else if self.colliders.iter().zip(&new.colliders).any(|(a, b)| a.kind() != b.kind()) {
            Some("the kind of a collider".into())
        } else if self.colliders.iter().zip(&new.colliders).any(|(a, b)| mesh_source(&a.shape) != mesh_source(&b.shape))
        {
            Some("a mesh collider's file, scale or cells".into())
        } else if self.integrator != new.integrator {
            Some("the integrator".into())
        } else if self.integrator.is_implicit() && self.solver != new.solver {
            // A GPU plan records the implicit solver's iterations as dispatches and sizes its
            // buffers for them.
            Some("the implicit solver's settings".into())
        } else if self.effects.contains(crate::Effect::SelfCollision)
            && SelfCollisionQuantities::of(self).check_interval != SelfCollisionQuantities::of(new).check_interval
        {
            Some("self-collision's check interval (the GPU's schedule of candidate-list checks)".into())
        } else {
            None
        }
    }
}

/// Checks that a state fits a simulator of `expected` vertices.
///
/// # Errors
/// [`SimError::StateMismatch`] when it does not.
pub fn check_state_size(expected: usize, state: &ClothState) -> Result<(), SimError> {
    if state.positions.len() != expected || state.velocities.len() != expected {
        return Err(SimError::StateMismatch { expected, got: state.positions.len().min(state.velocities.len()) });
    }
    Ok(())
}

/// What a mesh collider's distance field is computed from (`None` for the other kinds).
fn mesh_source(shape: &crate::colliders::Shape) -> Option<(&str, u64, u32)> {
    match shape {
        crate::colliders::Shape::Mesh { file, scale, cells, .. } => Some((file.as_str(), scale.to_bits(), *cells)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::PassTime;
    use crate::scene::{Edge, Motion, Pin, PinGroup, Scene};

    fn pass(name: &str, dispatches: u32, seconds: f64, shortest_s: f64, longest_s: f64) -> PassTime {
        PassTime { name: name.into(), dispatches, seconds, shortest_s, longest_s }
    }

    #[test]
    fn frames_add_up_pass_by_pass_whatever_passes_each_ran() {
        let mut total = Vec::new();
        // The first frame starts with the forced check; the later ones check as usual.
        let frames = [
            vec![pass("forced", 1, 1.0, 1.0, 1.0), pass("step", 4, 8.0, 1.0, 3.0)],
            vec![pass("step", 4, 6.0, 0.5, 2.0), pass("check", 2, 2.0, 1.0, 1.0)],
        ];
        frames.into_iter().flatten().for_each(|p| p.add_to(&mut total));
        let expected =
            vec![pass("forced", 1, 1.0, 1.0, 1.0), pass("step", 8, 14.0, 0.5, 3.0), pass("check", 2, 2.0, 1.0, 1.0)];
        assert_eq!(total, expected);
    }

    #[test]
    fn other_pins_rebuild_a_simulator_and_other_pin_motions_do_not() {
        let a = Scene::default();
        let mut b = a.clone();
        b.cloth.pin_groups.push(PinGroup { pins: vec![Pin::Edge(Edge::Top)], motion: Motion::default() });
        assert_eq!(a.rebuild_reason(&b).as_deref(), Some("the pins"));
        let mut c = b.clone();
        c.cloth.pin_groups[0].motion.angular_velocity = [0.0, 1.0, 0.0];
        assert_eq!(b.rebuild_reason(&c), None);
    }

    #[test]
    fn other_solver_settings_rebuild_an_implicit_simulator_only() {
        let mut a = Scene::default();
        let mut b = a.clone();
        b.solver.cg_max_iterations += 10;
        assert_eq!(a.rebuild_reason(&b), None, "the explicit integrators do not use the solver");
        a.integrator = crate::integrator::Integrator::BackwardEuler;
        b.integrator = a.integrator;
        assert_eq!(a.rebuild_reason(&b).as_deref(), Some("the implicit solver's settings"));
        a.integrator = crate::integrator::Integrator::Vbd;
        b.integrator = a.integrator;
        b.solver = a.solver;
        b.solver.vbd_iterations += 1;
        assert_eq!(a.rebuild_reason(&b).as_deref(), Some("the implicit solver's settings"));
    }
}
