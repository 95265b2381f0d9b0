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
    /// step. Default 1. More iterations are Newton's method without a line search: on the
    /// penalty contacts and the compressed springs (whose Hessians are clamped) its iterates need
    /// not converge, and the stability suite measured no gain from them (a stiff cloth landing on
    /// a sphere at 100 times the explicit stability bound peaked at 1.41 J with one iteration,
    /// 1.57 with two, 1.50 with four, 1.54 with ten, from 1.37 J).
    pub newton_iterations: u32,
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
            cg_tolerance: 1e-4,
            cg_max_iterations: 100,
            vbd_iterations: 10,
            chebyshev_rho: 0.0,
        }
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
