//! The summary of a run, as text or JSON.

use std::time::Duration;

use cloth_core::{AdvanceCounts, ClothModel, ClothState, Diagnostics, Energy, Simulator};
use serde::Serialize;

/// Spring counts by kind.
#[derive(Serialize)]
pub struct SpringCounts {
    pub structural: usize,
    pub shear: usize,
    pub bend: usize,
}

/// How many times the cloth passes through itself ([`cloth_core::intersections`]); `None`
/// (`null`) where a cloth torn across itself could not be counted.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct SelfIntersections {
    /// Edge–triangle crossings in the final state.
    #[serde(rename = "final")]
    pub at_end: Option<usize>,
    /// The most crossings in any frame counted (every frame unless `--count-every` says
    /// otherwise), the final one included (`None` if a frame could not be counted).
    pub max: Option<usize>,
}

/// How a GPU backend's self-collision candidate lists fared over the run
/// ([`cloth_core::self_collision`]).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct CandidateLists {
    /// Checks of the lists.
    pub checks: u64,
    /// Rebuilds the checks ordered.
    pub rebuilds: u64,
    /// Lists that did not fit, over all rebuilds (their vertices read the hash until the next).
    pub overflowed_lists: u64,
}

/// What `--export` wrote.
#[derive(Clone, Debug, Serialize)]
pub struct Export {
    /// The file or folder.
    pub path: String,
    /// Frames kept, the start included.
    pub frames: u64,
    /// Bytes written.
    pub bytes: u64,
    /// Wall-clock time spent reading the kept frames back and writing them, s.
    pub seconds: f64,
}

/// What a run measured.
pub struct Measured<'a> {
    pub state: &'a ClothState,
    pub diagnostics: &'a Diagnostics,
    pub counts: &'a AdvanceCounts,
    pub energy: &'a Energy,
    pub frames: u32,
    pub wall: Duration,
    pub self_intersections: SelfIntersections,
    /// The total energy at the start and the most of it at a frame read back (J).
    pub energies: EnergyExtremes,
}

/// The total energy (kinetic, elastic, gravitational, contact; J) at the start, and the most it
/// reached at the frames the run read back (those it counted, drew or exported, and the last):
/// the quantity the stability suite bounds.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct EnergyExtremes {
    pub initial_j: f64,
    pub peak_j: f64,
}

/// What `cloth run` reports.
#[derive(Serialize)]
pub struct Report {
    pub scene: String,
    pub backend: String,
    pub adapter: String,
    pub grid: [u32; 2],
    pub vertices: usize,
    pub springs: SpringCounts,
    pub frames: u32,
    pub substeps_per_frame: u32,
    pub substep_s: f64,
    pub stable_substep_s: f64,
    pub simulated_seconds: f64,
    pub max_penetration_m: f64,
    /// Colliders the cloth meets (0 without `Contact`).
    pub colliders: usize,
    /// The deepest penetration as a fraction of the smallest sphere's radius (`None`: no sphere).
    pub max_penetration_fraction_of_radius: Option<f64>,
    /// The deepest penetration as a fraction of the cloth's spacing (the smaller grid step).
    pub max_penetration_fraction_of_spacing: f64,
    pub nan_count: usize,
    /// Edge–triangle crossings of the cloth through itself, at the end and at most in a frame.
    pub self_intersections: SelfIntersections,
    /// With `SelfCollision` on a GPU backend: its candidate lists' checks and rebuilds.
    pub self_collision_lists: Option<CandidateLists>,
    /// The time integrator's short name.
    pub integrator: &'static str,
    /// With an implicit integrator: the iterations its solver spent over the run.
    pub solver_iterations: Option<cloth_core::solver::SolverIterations>,
    /// With `--export`: what was written (set by the caller once the export is finished).
    pub export: Option<Export>,
    pub final_kinetic_energy_j: f64,
    pub final_total_energy_j: f64,
    /// The total energy at the start and its peak over the frames read back.
    pub total_energy: EnergyExtremes,
    pub final_centroid_m: [f64; 3],
    /// Wall-clock time per frame, the per-frame read-back the self-intersection count needs
    /// included, the counting itself not, ms.
    pub wall_ms_per_frame: f64,
    /// Submissions per frame, counted over the run's `advance` calls.
    pub submissions_per_frame: f64,
    /// Host waits per frame inside `advance` (the final read-back is not counted).
    pub host_waits_per_frame: f64,
    /// Substeps one dispatch advances (more than 1 where the backend fuses them: the tiled
    /// Euler kernel).
    pub substeps_per_dispatch: u32,
}

impl Report {
    pub fn new(sim: &dyn Simulator, model: &ClothModel, run: &Measured<'_>) -> Self {
        let Measured { state, diagnostics, counts, energy, frames, wall, self_intersections, energies } = *run;
        let scene = &model.scene;
        let [structural, shear, bend] = model.spring_counts();
        let min_radius = (scene.colliders.iter())
            .filter_map(|c| match c.shape {
                cloth_core::colliders::Shape::Sphere { radius, .. } => Some(radius),
                _ => None,
            })
            .fold(f64::INFINITY, f64::min);
        let [du, dv] = scene.cloth.spacing();
        Self {
            scene: scene.name.clone(),
            backend: sim.backend_name().to_string(),
            adapter: sim.adapter_name(),
            grid: scene.cloth.resolution,
            vertices: model.vertex_count(),
            springs: SpringCounts { structural, shear, bend },
            frames,
            substeps_per_frame: scene.substeps_per_frame(),
            substep_s: scene.substep_dt(),
            stable_substep_s: cloth_core::stability::stable_substep(scene),
            simulated_seconds: state.time_s,
            max_penetration_m: diagnostics.max_penetration_m,
            colliders: cloth_core::SceneQuantities::of(scene).colliders.len(),
            max_penetration_fraction_of_radius: min_radius
                .is_finite()
                .then(|| diagnostics.max_penetration_m / min_radius),
            max_penetration_fraction_of_spacing: diagnostics.max_penetration_m / du.min(dv),
            nan_count: state.non_finite_count(),
            self_intersections,
            self_collision_lists: diagnostics.candidate_lists.map(|l| CandidateLists {
                checks: l.checks,
                rebuilds: l.rebuilds,
                overflowed_lists: l.overflowed_lists,
            }),
            integrator: scene.integrator.name(),
            solver_iterations: diagnostics.solver,
            export: None,
            final_kinetic_energy_j: energy.kinetic,
            final_total_energy_j: energy.total(),
            total_energy: energies,
            final_centroid_m: state.centroid(),
            wall_ms_per_frame: wall.as_secs_f64() * 1e3 / frames.max(1) as f64,
            submissions_per_frame: counts.submissions as f64 / frames.max(1) as f64,
            host_waits_per_frame: counts.host_waits as f64 / frames.max(1) as f64,
            substeps_per_dispatch: sim.fused_substeps(),
        }
    }

    pub fn print_text(&self) -> std::io::Result<()> {
        let c = self.final_centroid_m;
        out!("scene       {} on {} ({})", self.scene, self.backend, self.adapter)?;
        out!(
            "cloth       {}x{} = {} vertices; springs {} structural, {} shear, {} bend",
            self.grid[0],
            self.grid[1],
            self.vertices,
            self.springs.structural,
            self.springs.shear,
            self.springs.bend
        )?;
        out!(
            "time        {} frames x {} substeps of {:.3e} s = {:.3} s simulated (stable bound {:.3e} s)",
            self.frames,
            self.substeps_per_frame,
            self.substep_s,
            self.simulated_seconds,
            self.stable_substep_s
        )?;
        if self.colliders == 0 {
            out!("contact     no collider")?;
        } else {
            let radius = match self.max_penetration_fraction_of_radius {
                Some(f) => format!(", {:.2}% of the smallest sphere's radius", 100.0 * f),
                None => String::new(),
            };
            out!(
                "contact     max penetration {:.3e} m ({:.2}% of the cloth's spacing{radius})",
                self.max_penetration_m,
                100.0 * self.max_penetration_fraction_of_spacing
            )?;
        }
        match (self.self_intersections.at_end, self.self_intersections.max) {
            (Some(n), Some(most)) => out!(
                "self        {n} edge-triangle crossings of the cloth through itself at the end, at most {most} in a \
                 frame counted"
            ),
            (at_end, _) => out!(
                "self        not counted in every frame: the cloth is torn across itself (the step is probably \
                 unstable){}",
                at_end.map_or(String::new(), |n| format!("; {n} crossings at the end"))
            ),
        }?;
        if let Some(s) = self.solver_iterations {
            let frames = self.frames.max(1) as f64;
            let spent = if s.vbd > 0 {
                format!("{:.0} VBD sweeps a frame", s.vbd as f64 / frames)
            } else {
                format!(
                    "{:.1} Newton iterations and {:.1} CG iterations a frame ({:.1} a solve, at most {})",
                    s.newton as f64 / frames,
                    s.cg as f64 / frames,
                    s.cg_per_solve(),
                    s.cg_most
                )
            };
            out!("solver      {}: {spent}", self.integrator)?;
        }
        if let Some(l) = self.self_collision_lists {
            out!(
                "lists       self-collision's candidate lists checked {} times, rebuilt {} times; {} lists overflowed",
                l.checks,
                l.rebuilds,
                l.overflowed_lists
            )?;
        }
        out!(
            "state       centroid ({:.4}, {:.4}, {:.4}) m; kinetic energy {:.3e} J; NaN vertices {}",
            c[0],
            c[1],
            c[2],
            self.final_kinetic_energy_j,
            self.nan_count
        )?;
        out!(
            "energy      total {:.4e} J at the start, {:.4e} J at the end, at most {:.4e} J in a frame read back",
            self.total_energy.initial_j,
            self.final_total_energy_j,
            self.total_energy.peak_j
        )?;
        out!(
            "speed       {:.3} ms per frame (wall clock); {:.2} submissions and {:.2} host waits per frame; \
             {} substeps per dispatch",
            self.wall_ms_per_frame,
            self.submissions_per_frame,
            self.host_waits_per_frame,
            self.substeps_per_dispatch
        )?;
        Ok(())
    }
}
