//! The implicit integrators' solver settings (the scene's `solver` field) and the iterations a
//! frame spent.
//!
//! [`crate::Integrator::BackwardEuler`] runs [`SolverSpec::newton_iterations`] Newton iterations a
//! substep, each a linear solve by preconditioned conjugate gradients that stops at
//! [`SolverSpec::cg_tolerance`] or after [`SolverSpec::cg_max_iterations`];
//! [`crate::Integrator::Vbd`] runs [`SolverSpec::vbd_iterations`] sweeps of Vertex Block Descent a
//! substep, optionally accelerated by Chebyshev's weights for the convergence-rate estimate
//! [`SolverSpec::chebyshev_rho`]. The explicit integrators and XPBD ignore the field.

use serde::{Deserialize, Serialize};

/// The implicit integrators' settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SolverSpec {
    /// Newton iterations per backward-Euler substep; the first is Baraff and Witkin's linearised
    /// step. Default 1. With the line search, more iterations bring a stiff cloth's large step
    /// closer to the implicit-Euler solution (measured, `scenes/stiff_drape.ron` at 128 × 128, one
    /// substep a frame, f32: the energy peaked at 378 J with one iteration, 11.1 J with two and
    /// 9.6 J with four, from 8.8 J), at their cost: each is a linearisation and a solve.
    pub newton_iterations: u32,
    /// Whether each Newton iteration's step is cut back where it overshoots the minimum of the
    /// incremental potential along its direction (`docs/model.md` gives the rule). Default true.
    /// Off, every iteration takes its whole step: on stiff springs at a large step the linearised
    /// step overshoots and the iterates gain energy (the stiff drape above peaked at 1.6e7 J with
    /// one iteration, 4.4e4 J with four).
    pub line_search: bool,
    /// Conjugate gradients stop when the residual's norm is at most this fraction of the
    /// right-hand side's (dimensionless). 0 runs exactly [`SolverSpec::cg_max_iterations`] (the
    /// conformance suite's setting, so every backend does the same work). Default 1e-4.
    pub cg_tolerance: f64,
    /// The most conjugate-gradient iterations per Newton iteration. Default 100. (A GPU frame
    /// records three dispatches for each one the solver allows, skipped once a solve is done.)
    pub cg_max_iterations: u32,
    /// Vertex Block Descent sweeps (over the five vertex colours) per substep. Default 10.
    pub vbd_iterations: u32,
    /// The estimate `ρ` of VBD's convergence rate per sweep for Chebyshev acceleration, in
    /// `[0, 1)`; 0 turns it off. Default 0.
    pub chebyshev_rho: f64,
}

impl Default for SolverSpec {
    fn default() -> Self {
        Self {
            newton_iterations: 1,
            line_search: true,
            cg_tolerance: 1e-4,
            cg_max_iterations: 100,
            vbd_iterations: 10,
            chebyshev_rho: 0.0,
        }
    }
}

impl SolverSpec {
    /// Settings written as in a scene's `solver` field, e.g. `(newton_iterations: 8)`; the
    /// fields left out take their defaults. The values are checked with the scene
    /// ([`crate::Scene::validate`]).
    pub fn from_ron_str(text: &str) -> Result<Self, crate::SceneError> {
        ron::de::from_str(text).map_err(crate::SceneError::from_ron)
    }
}

/// The largest [`SolverSpec::cg_max_iterations`] and [`SolverSpec::vbd_iterations`] accepted: a
/// GPU frame records every iteration's dispatches.
pub const MAX_SOLVER_ITERATIONS: u32 = 1000;

/// The largest [`SolverSpec::newton_iterations`] accepted.
pub const MAX_NEWTON_ITERATIONS: u32 = 20;

/// What the implicit solvers spent since the simulation was created (a tool reports a frame's
/// share as the difference of two readings, [`SolverIterations::since`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SolverIterations {
    /// Substeps run.
    pub substeps: u64,
    /// Newton iterations (backward Euler), summed over the substeps.
    pub newton: u64,
    /// Conjugate-gradient iterations (backward Euler), summed over every solve.
    pub cg: u64,
    /// The most conjugate-gradient iterations one solve took.
    pub cg_most: u32,
    /// Vertex Block Descent sweeps, summed over the substeps.
    pub vbd: u64,
}

impl SolverIterations {
    /// Adds one solve's conjugate-gradient iterations.
    pub fn add_solve(&mut self, iterations: u32) {
        self.newton += 1;
        self.cg += u64::from(iterations);
        self.cg_most = self.cg_most.max(iterations);
    }

    /// What was spent between the reading `earlier` and this one (`cg_most` stays this one's:
    /// the most over the whole run).
    pub fn since(&self, earlier: &SolverIterations) -> SolverIterations {
        SolverIterations {
            substeps: self.substeps - earlier.substeps.min(self.substeps),
            newton: self.newton - earlier.newton.min(self.newton),
            cg: self.cg - earlier.cg.min(self.cg),
            cg_most: self.cg_most,
            vbd: self.vbd - earlier.vbd.min(self.vbd),
        }
    }

    /// Conjugate-gradient iterations per Newton iteration, on average (0 before any).
    pub fn cg_per_solve(&self) -> f64 {
        if self.newton == 0 { 0.0 } else { self.cg as f64 / self.newton as f64 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_as_the_scene_writes_them() {
        let s = SolverSpec::from_ron_str("(newton_iterations: 8, line_search: false)").unwrap();
        assert_eq!(s, SolverSpec { newton_iterations: 8, line_search: false, ..SolverSpec::default() });
        assert_eq!(SolverSpec::from_ron_str("()").unwrap(), SolverSpec::default());
        let e = SolverSpec::from_ron_str("(newton: 8)").unwrap_err().to_string();
        assert!(e.contains("newton") && e.contains("newton_iterations"), "{e}");
    }
}
