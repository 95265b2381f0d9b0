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
        let per_frame = scene.vertex_count() as u64 * substeps as u64;
        let work = per_frame.saturating_mul(frames as u64);
        if work > self.max_vertex_substeps {
            let fits = self.max_vertex_substeps / per_frame.max(1);
            // One frame alone may be too much: then fewer frames is no fix.
            let fix = if fits == 0 {
                format!("use a smaller grid or fewer substeps: one frame alone is {per_frame:.3e} vertex-substeps")
            } else {
                format!("run at most {fits} frames, or a smaller grid or fewer substeps")
            };
            return Err(Problem {
                field: "frames".into(),
                message: format!(
                    "{frames} frames of {} vertices × {} substeps is {work:.3e} vertex-substeps, more than the \
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
