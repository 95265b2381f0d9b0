//! Time integrators: how a substep turns forces into new velocities and positions.
//!
//! * [`Integrator::SemiImplicitEuler`], the model's: `v += Δt F(x, v)/m; x += Δt v`. First order,
//!   symplectic, stable for `Δt < 2/ω` (less with damping).
//! * [`Integrator::VelocityVerlet`]: kick–drift–kick, `v½ = v + ½Δt a(x, v)`, `x' = x + Δt v½`,
//!   `v' = v½ + ½Δt a(x', v½)`. Second order for conservative forces, symplectic, same stability
//!   limit `2/ω`; velocity-dependent forces (damping, friction, drag) are evaluated with the
//!   velocity at hand, which keeps second order for them only approximately. The GPU backends run
//!   it as two dispatches per substep (the shaders' `STAGE` constant: kick and drift, then kick).
//! * [`Integrator::RungeKutta4`]: the classical four-stage method on `(x, v)`. Fourth order, not
//!   symplectic (it slowly dissipates energy), stable for `Δt < 2√2/ω` on an undamped spring.
//!   The GPU backends run it as four dispatches per substep (`STAGE` 3 to 6), keeping the
//!   substep's start state and the running sums per vertex. Friction switches between sticking
//!   and sliding, which no combination of RK4's stages can follow, so a vertex that friction holds
//!   at the last stage's state sticks exactly ([`crate::forces::friction_holds`]).
//! * [`Integrator::Xpbd`]: extended position-based dynamics. Gravity and drag predict the
//!   positions, then [`XPBD_ITERATIONS`] Gauss–Seidel sweeps project every spring with the
//!   compliance `α = 1/k` (so a spring of stiffness `k` behaves as Hooke's law in the limit of
//!   many iterations), the spheres as non-penetration constraints, and velocities follow as
//!   `(x' − x)/Δt`. Stable at any step; first order; springs' damping is not modelled (the method
//!   dissipates by itself). The sphere projection is swept along each vertex's path in the
//!   substep, so a long step cannot tunnel through a sphere. Friction keeps the model's Coulomb
//!   meaning on the contact's displacement: the tangential part of the substep's displacement is
//!   undone up to `c_f` times the normal correction (the vertex sticks), and shortened by that
//!   beyond. `Substeps::Auto` keeps `ω Δt` below [`crate::stability::XPBD_AUTO_OMEGA_DT`], where
//!   its sweeps converge. The springs are projected colour by colour
//!   ([`crate::coloring`]): on the GPU one dispatch per colour, on the CPU the same order, so both
//!   compute the same thing.
//!
//! * [`Integrator::BackwardEuler`]: implicit Euler, `v' = v + h M⁻¹ f(x', v')`, `x' = x + h v'`,
//!   solved by Newton's method; the first iteration is Baraff and Witkin's linearised step, each
//!   a linear solve `(M + h C + h² K) Δv = b` by conjugate gradients with a 3 × 3 block-Jacobi
//!   preconditioner ([`crate::implicit`]), its step cut back by a line search where it overshoots
//!   ([`crate::solver::SolverSpec::line_search`]). First order, stable at any step, and numerically
//!   dissipative: it damps the fast modes it cannot resolve.
//! * [`Integrator::Vbd`]: Vertex Block Descent (Chen, Macklin et al. 2024), the same implicit-Euler
//!   problem minimised as an incremental potential by per-vertex Newton steps, Gauss–Seidel over
//!   the five colours of the grid's vertex colouring ([`crate::vbd`], [`crate::coloring`]). First
//!   order, stable at any step; with few sweeps it behaves as a softer cloth.
//!
//! Both take their iteration counts from the scene's `solver` field ([`crate::solver`]).
//!
//! Contact and friction keep the model's meaning under every integrator: they are forces of the
//! state each stage evaluates. The friction's "stop within this step" term uses the step its
//! velocity update spans: `Δt` for Euler and RK4, `½Δt` for each half kick of Verlet.

use serde::{Deserialize, Serialize};

/// Which time integrator a scene uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Integrator {
    /// The model's semi-implicit (symplectic) Euler. Default.
    #[default]
    SemiImplicitEuler,
    /// Velocity Verlet (kick–drift–kick).
    VelocityVerlet,
    /// Classical fourth-order Runge–Kutta.
    RungeKutta4,
    /// Extended position-based dynamics (stable at large steps).
    Xpbd,
    /// Backward Euler: Newton iterations of preconditioned conjugate gradients.
    BackwardEuler,
    /// Vertex Block Descent: per-vertex Newton steps over a vertex colouring.
    Vbd,
}

/// Gauss–Seidel sweeps over the constraints per XPBD substep.
pub const XPBD_ITERATIONS: u32 = 10;

impl Integrator {
    /// Every integrator.
    pub const ALL: [Integrator; 6] = [
        Integrator::SemiImplicitEuler,
        Integrator::VelocityVerlet,
        Integrator::RungeKutta4,
        Integrator::Xpbd,
        Integrator::BackwardEuler,
        Integrator::Vbd,
    ];

    /// The force-based (explicit) integrators: conditionally stable, with a theoretical order.
    pub const EXPLICIT: [Integrator; 3] =
        [Integrator::SemiImplicitEuler, Integrator::VelocityVerlet, Integrator::RungeKutta4];

    /// The integrators that solve the implicit-Euler problem of each substep.
    pub const IMPLICIT: [Integrator; 2] = [Integrator::BackwardEuler, Integrator::Vbd];

    /// Whether it solves each substep's implicit-Euler problem (backward Euler, VBD).
    pub fn is_implicit(self) -> bool {
        Integrator::IMPLICIT.contains(&self)
    }

    /// Whether it has no stability limit, so that `Substeps::Auto` chooses its step for
    /// accuracy (XPBD and the implicit integrators).
    pub fn unconditionally_stable(self) -> bool {
        self.stability_limit().is_infinite()
    }

    /// Order of accuracy of the positions for smooth, conservative forces.
    pub fn order(self) -> u32 {
        match self {
            Integrator::SemiImplicitEuler => 1,
            Integrator::VelocityVerlet => 2,
            Integrator::RungeKutta4 => 4,
            Integrator::Xpbd | Integrator::BackwardEuler | Integrator::Vbd => 1,
        }
    }

    /// `ω Δt` at the edge of stability on an undamped harmonic oscillator.
    pub fn stability_limit(self) -> f64 {
        match self {
            Integrator::SemiImplicitEuler | Integrator::VelocityVerlet => 2.0,
            // RK4's stability region reaches ±2√2 along the imaginary axis (undamped springs).
            Integrator::RungeKutta4 => 2.0 * std::f64::consts::SQRT_2,
            Integrator::Xpbd | Integrator::BackwardEuler | Integrator::Vbd => f64::INFINITY,
        }
    }

    /// Passes over the springs per substep (force evaluations, constraint sweeps for XPBD, at
    /// the `solver`'s settings for the implicit integrators: a linearisation, one a
    /// conjugate-gradient iteration at most and one a line-search slope a Newton iteration, or one a VBD
    /// sweep).
    pub fn stages(self, solver: &crate::solver::SolverSpec) -> u32 {
        match self {
            Integrator::SemiImplicitEuler => 1,
            Integrator::VelocityVerlet => 2,
            Integrator::RungeKutta4 => 4,
            Integrator::Xpbd => XPBD_ITERATIONS,
            Integrator::BackwardEuler => {
                let line_search = if solver.line_search { crate::solver::LINE_SEARCH_SLOPES } else { 0 };
                solver.newton_iterations * (1 + solver.cg_max_iterations + line_search)
            }
            Integrator::Vbd => solver.vbd_iterations,
        }
    }

    /// The integrator of a short name ([`Integrator::name`]), if any.
    pub fn from_name(name: &str) -> Option<Integrator> {
        Integrator::ALL.into_iter().find(|i| i.name() == name)
    }

    /// Short name for tables and file names.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::SemiImplicitEuler => "euler",
            Integrator::VelocityVerlet => "verlet",
            Integrator::RungeKutta4 => "rk4",
            Integrator::Xpbd => "xpbd",
            Integrator::BackwardEuler => "backward-euler",
            Integrator::Vbd => "vbd",
        }
    }
}
