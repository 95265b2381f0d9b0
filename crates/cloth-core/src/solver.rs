//! The implicit integrators' solver settings (the scene's `solver` field) and the iterations a
//! frame spent.
//!
//! [`crate::Integrator::BackwardEuler`] runs [`SolverSpec::newton_iterations`] Newton iterations a
//! substep, each a linear solve by preconditioned conjugate gradients that stops at
//! [`SolverSpec::cg_tolerance`] or after [`SolverSpec::cg_max_iterations`];
//! [`crate::Integrator::Vbd`] runs [`SolverSpec::vbd_iterations`] sweeps of Vertex Block Descent a
//! substep, with a multigrid coarse correction before every [`SolverSpec::vbd_multigrid_every`]
//! sweeps and optionally accelerated by Chebyshev's weights for the convergence-rate estimate
//! [`SolverSpec::chebyshev_rho`]. The explicit integrators and XPBD ignore the field.

use serde::{Deserialize, Serialize};

/// The implicit integrators' settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SolverSpec {
    /// Newton iterations per backward-Euler substep; the first is Baraff and Witkin's linearised
    /// step. Default 2. More iterations bring a large step closer to the implicit-Euler solution,
    /// at their cost: each is a linearisation and a solve. (Measured on the CPU, f32, one substep
    /// a frame: one iteration keeps `scenes/drape.ron` and `scenes/stiff_drape.ron` within the
    /// stability suite's energy bound at 128 × 128 but not the drape's landing at 256 × 256, which
    /// two iterations of at most 50 CG iterations do, at the CG budget of one of 100;
    /// `docs/model.md` gives the figures.)
    pub newton_iterations: u32,
    /// Whether each Newton iteration's step is cut back where it overshoots the minimum of the
    /// incremental potential along its direction (`docs/model.md` gives the rule; it measures
    /// [`LINE_SEARCH_SLOPES`] slopes a Newton iteration). Default true. Off, every iteration takes
    /// its whole step.
    pub line_search: bool,
    /// Conjugate gradients stop when the residual's norm is at most this fraction of the
    /// right-hand side's, or of the largest right-hand side of the substep's earlier Newton
    /// iterations where that is larger (dimensionless): a Newton iteration whose right-hand side
    /// is already within the tolerance of the first's changes nothing, rather than solving
    /// rounding noise to the tolerance and line-searching along it. 0 runs exactly
    /// [`SolverSpec::cg_max_iterations`] (the conformance suite's setting, so every backend does
    /// the same work). Default 1e-4.
    pub cg_tolerance: f64,
    /// The most conjugate-gradient iterations per Newton iteration. Default 50. (A GPU frame
    /// records two dispatches for each one the solver allows, skipped once a solve is done.)
    pub cg_max_iterations: u32,
    /// Vertex Block Descent sweeps (over the five vertex colours) per substep. Default 10.
    pub vbd_iterations: u32,
    /// The estimate `ρ` of VBD's convergence rate per sweep for Chebyshev acceleration, in
    /// `[0, 1)`; 0 turns it off. Default 0.
    pub chebyshev_rho: f64,
    /// VBD's multigrid coarse correction ([`crate::multigrid`]) before every this many sweeps:
    /// before sweeps 1, 1 + n, 1 + 2n, … of the substep (only before the first where `n` is at least
    /// the sweeps); 0 turns it off. Default 5 (two
    /// corrections in the default 10 sweeps). The sweeps carry a force about two rows of the grid
    /// each, so without it a large cloth at a large step does not feel its support within the
    /// substep (measured on the CPU, f32, one substep a frame over 2 s: `scenes/drape.ron` at
    /// 128 × 128 peaked at 996 J against its 8.83 J start without it, and never rose above the
    /// start with it; `docs/model.md` gives the figures at 256²). A stiff cloth at a large step needs it
    /// more often: `scenes/stiff_drape.ron` at 256 × 256 and one substep a frame peaked at 16.9 J
    /// with the default and stayed at its start with 1.
    pub vbd_multigrid_every: u32,
}

impl Default for SolverSpec {
    fn default() -> Self {
        Self {
            newton_iterations: 2,
            line_search: true,
            cg_tolerance: 1e-4,
            cg_max_iterations: 50,
            vbd_iterations: 10,
            chebyshev_rho: 0.0,
            vbd_multigrid_every: 5,
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

/// The slopes of the incremental potential backward Euler's line search measures a Newton
/// iteration ([`LineSearchBracket`]): at the full step, then at two secant roots. Each costs
/// about what one conjugate-gradient iteration does (a force evaluation and a reduction).
pub const LINE_SEARCH_SLOPES: u32 = 3;

/// Backward Euler's line search on the slope `g(α)` of the incremental potential along a Newton
/// change (`docs/model.md`): a bracket `[lo, hi]` of step lengths with `g(lo) < 0 ≤ g(hi)`, cut at
/// the secant's root (regula falsi). The Illinois rule keeps a steep end from pinning the roots
/// near the other: an end kept through two cuts in a row has its slope halved. Dimensionless
/// lengths, slopes in J. The GPU backends keep the same bracket between their passes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineSearchBracket<R> {
    /// The step length with a negative slope, and the slope (halved by the Illinois rule).
    pub lo: (R, R),
    /// The step length with a non-negative slope, and the slope (halved by the Illinois rule).
    pub hi: (R, R),
    /// Which end the last cut replaced: −1 `lo`, 1 `hi`, 0 none yet.
    pub last: i8,
}

impl<R: crate::real::Real> LineSearchBracket<R> {
    /// The bracket `[0, 1]` of a full step that overshoots: `g(0) < 0 < g(1)`.
    pub fn new(at_start: R, at_full: R) -> Self {
        Self { lo: (R::zero(), at_start), hi: (R::one(), at_full), last: 0 }
    }

    /// The root of the secant through the bracket's ends, `lo + (hi − lo) g(lo) / (g(lo) − g(hi))`.
    pub fn secant(&self) -> R {
        let ((lo, g_lo), (hi, g_hi)) = (self.lo, self.hi);
        lo + (hi - lo) * g_lo / (g_lo - g_hi)
    }

    /// The bracket after measuring the slope `g` at its secant root: that root replaces the end
    /// whose slope has the same sign; the other end's slope is halved if the same end was
    /// replaced the cut before.
    pub fn cut(&mut self, g: R) {
        let at = self.secant();
        let half = R::of(0.5);
        if g < R::zero() {
            self.lo = (at, g);
            if self.last == -1 {
                self.hi.1 = self.hi.1 * half;
            }
            self.last = -1;
        } else {
            self.hi = (at, g);
            if self.last == 1 {
                self.lo.1 = self.lo.1 * half;
            }
            self.last = 1;
        }
    }
}

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

    /// The bracket keeps the root between its ends and closes in on it: on a linear slope the
    /// first secant root is the root; on a slope that steepens past the root (as a spring's
    /// energy does), where plain regula falsi's roots creep from the shallow end (0.043 from the
    /// root at 0.05 after six cuts), the Illinois rule brings them within 0.01 of it.
    #[test]
    fn the_line_search_bracket_closes_in_on_the_slopes_root() {
        let linear = |a: f64| 3.0 * a - 1.2;
        let bracket = LineSearchBracket::new(linear(0.0), linear(1.0));
        assert!((bracket.secant() - 0.4).abs() < 1e-12);

        let steep = |a: f64| a.powi(5) * 40.0 + a - 0.05;
        let root = 0.05 - 40.0 * 0.05f64.powi(5); // within 1e-8 of the exact root
        let error_after_six_cuts = |illinois: bool| {
            let mut bracket = LineSearchBracket::new(steep(0.0), steep(1.0));
            for _ in 0..6 {
                let at = bracket.secant();
                assert!(bracket.lo.0 < at && at < bracket.hi.0, "{at} outside {bracket:?}");
                if !illinois {
                    bracket.last = 0;
                }
                bracket.cut(steep(at));
                assert!(bracket.lo.1 < 0.0 && bracket.hi.1 >= 0.0, "{bracket:?}");
            }
            (bracket.secant() - root).abs()
        };
        let (illinois, plain) = (error_after_six_cuts(true), error_after_six_cuts(false));
        assert!(plain > 0.04, "plain regula falsi: {plain} from the root");
        assert!(illinois < 0.01, "with the Illinois rule: {illinois} from the root");
    }
}
