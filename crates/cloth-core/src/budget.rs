//! How much work a scene and a command may ask for: limits derived from the field types and
//! the backends' speeds, checked before anything runs, so that no accepted command runs for
//! years (or forever) without a word.

use crate::error::Problem;
use crate::scene::Scene;

/// Most substeps one frame may take (`time.substeps`, or what `Auto` picks): a million, which a
/// GPU runs on a small cloth in about a second a frame.
pub const MAX_SUBSTEPS_PER_FRAME: u32 = 1_000_000;

/// Most frames one command may run (`time.frames`, `--frames`, a study's duration): ten million,
/// about 46 hours of simulated time at 60 frames a second.
pub const MAX_FRAMES: u32 = 10_000_000;

/// Smallest and largest magnitude (other than 0) of a value the solver uses, in SI units. The
/// backends compute in `f32` (the reference's `f64` too, to compare with them), whose normal
/// numbers reach 1.2e-38 to 3.4e38: within this range any product of two such values stays
/// there, so a force, a rate or a squared step neither overflows nor vanishes.
pub const F32_MEANINGFUL: [f64; 2] = [1e-15, 1e15];

/// The vertex-substeps one command may run on a backend: what it finishes in minutes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WorkBudget {
    /// The backend it is for.
    pub backend: &'static str,
    /// Most vertex-substeps (vertices × substeps per frame × frames).
    pub max_vertex_substeps: u64,
}

impl WorkBudget {
    /// The CPU backends: 1e11 vertex-substeps, about 20 minutes at the reference's 1e8 a second.
    pub const CPU: Self = Self { backend: "cpu", max_vertex_substeps: 100_000_000_000 };

    /// The GPU backends: 1e13 vertex-substeps, about 4 minutes at a large GPU's 4e10 a second.
    pub const GPU: Self = Self { backend: "gpu", max_vertex_substeps: 10_000_000_000_000 };

    /// The budget of the backend named `name`.
    pub fn for_backend(name: &str) -> Self {
        if name.starts_with("cpu") { Self::CPU } else { Self::GPU }
    }

    /// Checks that `frames` frames of `scene` fit the budget; returns the vertex-substeps.
    ///
    /// # Errors
    /// A [`Problem`] naming what is too much, the limit and a fix.
    pub fn check(&self, scene: &Scene, frames: u32) -> Result<u64, Problem> {
        if frames > MAX_FRAMES {
            return Err(Problem {
                field: "frames".into(),
                message: format!("{frames} frames is more than the {MAX_FRAMES} one command may run"),
                fix: format!("ask for at most {MAX_FRAMES} frames"),
            });
        }
        let substeps = scene.substeps_per_frame();
        if substeps > MAX_SUBSTEPS_PER_FRAME {
            return Err(Problem {
                field: "substeps".into(),
                message: format!(
                    "{substeps} substeps a frame is more than the {MAX_SUBSTEPS_PER_FRAME} one frame may take"
                ),
                fix: format!("ask for at most {MAX_SUBSTEPS_PER_FRAME}"),
            });
        }
        // Saturating: a grid of 2²⁹ × 2²⁹ at 64 substeps overflows u64; the messages use f64.
        let per_frame = (scene.vertex_count() as u64).saturating_mul(substeps as u64);
        let work = per_frame.saturating_mul(frames as u64);
        let (per_frame_f, work_f) = {
            let per_frame = scene.vertex_count() as f64 * substeps as f64;
            (per_frame, per_frame * frames as f64)
        };
        if work > self.max_vertex_substeps {
            let fits = self.max_vertex_substeps / per_frame.max(1);
            // One frame alone may be too much: then fewer frames is no fix.
            let fix = if fits == 0 {
                format!("use a smaller grid or fewer substeps: one frame alone is {per_frame_f:.3e} vertex-substeps")
            } else {
                format!("run at most {fits} frames, or a smaller grid or fewer substeps")
            };
            return Err(Problem {
                field: "frames".into(),
                message: format!(
                    "{frames} frames of {} vertices × {} substeps is {work_f:.3e} vertex-substeps, more than the \
                     {:.0e} one command may run on {}",
                    scene.vertex_count(),
                    scene.substeps_per_frame(),
                    self.max_vertex_substeps as f64,
                    self.backend
                ),
                fix,
            });
        }
        Ok(work)
    }
}

/// Every simulation one command plans, added up per budget before any of them runs: each run
/// must fit its backend's [`WorkBudget`] alone, and all of them together too (a sweep of many
/// runs, each small enough, can still add up to years).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WorkPlan {
    /// Vertex-substeps planned on the CPU backends.
    pub cpu: u64,
    /// Vertex-substeps planned on the GPU backends.
    pub gpu: u64,
    /// The runs planned: `(backend, substeps per frame, frames, vertex-substeps)`.
    pub runs: Vec<(String, u32, u32, u64)>,
}

impl WorkPlan {
    /// Adds `frames` frames of `scene` on `backend`, which must fit that backend's budget alone.
    ///
    /// # Errors
    /// What [`WorkBudget::check`] finds.
    pub fn add(&mut self, backend: &str, scene: &Scene, frames: u32) -> Result<u64, Problem> {
        let budget = WorkBudget::for_backend(backend);
        let work = budget.check(scene, frames)?;
        self.add_work(backend, scene.substeps_per_frame(), frames, work);
        Ok(work)
    }

    /// Adds `work` vertex-substeps counted by the caller (e.g. a bisection's trials).
    pub fn add_work(&mut self, backend: &str, substeps: u32, frames: u32, work: u64) {
        let total = if WorkBudget::for_backend(backend) == WorkBudget::CPU { &mut self.cpu } else { &mut self.gpu };
        *total = total.saturating_add(work);
        self.runs.push((backend.to_string(), substeps, frames, work));
    }

    /// Checks that the runs together fit each budget; `fix` says how to ask for less.
    ///
    /// # Errors
    /// A [`Problem`] for the first budget exceeded.
    pub fn check(&self, field: &str, fix: &str) -> Result<(), Problem> {
        for (total, budget) in [(self.cpu, WorkBudget::CPU), (self.gpu, WorkBudget::GPU)] {
            if total > budget.max_vertex_substeps {
                return Err(Problem {
                    field: field.to_string(),
                    message: format!(
                        "the {} runs of this command add up to {total:.3e} vertex-substeps on the {} backends, more \
                         than the {:.0e} one command may run there",
                        self.runs.len(),
                        budget.backend,
                        budget.max_vertex_substeps as f64
                    ),
                    fix: fix.to_string(),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(n: u32, substeps: u32) -> Scene {
        let mut s = Scene::default();
        s.cloth.resolution = [n, n];
        s.time.substeps = crate::Substeps::Fixed(substeps);
        s
    }

    #[test]
    fn runs_that_fit_alone_can_still_be_too_many_together() {
        let mut plan = WorkPlan::default();
        // 1000² × 1000 substeps × 90 frames: 9e10 on the CPU, under 1e11 alone.
        let work = plan.add("cpu", &scene(1000, 1000), 90).unwrap();
        assert_eq!(work, 90_000_000_000);
        assert!(plan.check("--substeps", "fewer").is_ok());
        plan.add("cpu-f64", &scene(1000, 1000), 90).unwrap();
        let e = plan.check("--substeps", "sweep fewer").unwrap_err();
        assert_eq!((e.field.as_str(), e.fix.as_str()), ("--substeps", "sweep fewer"));
        assert!(e.message.contains("1.800e11 vertex-substeps on the cpu backends"), "{e}");
        // The GPU budget is separate.
        let mut gpu = WorkPlan::default();
        gpu.add("wgpu", &scene(1000, 1000), 90).unwrap();
        gpu.add("vulkano", &scene(1000, 1000), 90).unwrap();
        assert!(gpu.check("x", "y").is_ok());
        assert_eq!((gpu.cpu, gpu.gpu, gpu.runs.len()), (0, 180_000_000_000, 2));
    }

    #[test]
    fn a_grid_whose_work_overflows_u64_is_refused_with_its_real_size() {
        // Found by the command line's property test: `cloth bench --grids 536870912`.
        let e = WorkBudget::GPU.check(&scene(536_870_912, 64), 11).unwrap_err();
        assert!(e.message.contains("is 2.029e20 vertex-substeps"), "{e}");
        assert!(e.fix.contains("one frame alone is 1.845e19"), "{e}");
    }

    #[test]
    fn a_run_too_large_alone_is_refused_and_not_added() {
        let mut plan = WorkPlan::default();
        let e = plan.add("cpu", &scene(1000, 1000), 200).unwrap_err();
        assert_eq!(e.field, "frames");
        assert!(e.fix.contains("run at most 100 frames"), "{e}");
        assert_eq!(plan, WorkPlan::default());
        // Saturating, never wrapping, however much is added.
        plan.add_work("wgpu", 1, 1, u64::MAX);
        plan.add_work("wgpu", 1, 1, u64::MAX);
        assert_eq!(plan.gpu, u64::MAX);
        assert!(plan.check("a", "b").is_err());
    }
}
